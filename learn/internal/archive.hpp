#pragma once
#include "learn/internal/private.hpp"

/// Scout's own reading of a LibTorch archive (checkpoints and model files), before LibTorch
/// parses it. LibTorch 1.13's reader trusts its input: a crafted zip directory, a pickle that
/// underflows its stack or a tensor record that points past its storage can crash the process or
/// make it allocate without bound. So every file is first held against what Scout's writer
/// produces (torch::serialize::OutputArchive of an agent, an Adam optimizer and a few values):
///
/// - the zip directory: one folder of entries, stored or deflated, CRC-32 checked; only the
///   entries the writer makes (data.pkl, constants.pkl, version, data/N, code/__torch__[/
///   ___torch_mangle_N].py and their .debug_pkl); each local header and data descriptor repeating
///   the directory; every byte of the file in an entry, the directory or the end records (entries
///   back to back from byte 0, no prefix, gap or unlisted record);
/// - data.pkl and the other pickles: run by a small pickle machine that knows only the opcodes
///   and globals the writer emits and refuses anything else (stack underflow, an unknown global,
///   a wrong argument, values nested more than 150 deep, a value that contains itself);
/// - each tensor: as the writer makes it, a storage record of its own that it fills from its first
///   element with the contiguous strides of its sizes (no stride 0, no offset, no shared storage;
///   the product of its sizes overflow-checked); every data/N record is some tensor's storage;
/// - code/*.py: TorchScript class stubs (attribute declarations only), checked line by line, so
///   LibTorch's compiler only ever sees code of the shape the writer produces; each module in
///   data.pkl has exactly the attributes its class stub declares, each of the declared type, and
///   every stub is some module's class.
///
/// Memory: inspect_archive works on bytes already in memory and allocates at most a few times the
/// size of data.pkl (itself at most kMaxPickleBytes). Torch-free.
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace scout::learn {

/// A tensor the archive holds, by the dotted attribute path from the root object
/// ("agent.goal.body.blocks.0.weight").
struct ArchiveTensor {
  std::string path;
  std::string dtype;  ///< the storage's element type as LibTorch names it: "Float", "Long", "Byte", ...
  std::vector<std::int64_t> sizes;
  std::int64_t elements = 0;          ///< the product of sizes (checked): its storage holds exactly these
  std::optional<std::int64_t> value;  ///< a one-element Long tensor's value (Adam's "params/size")
  std::int64_t numel() const { return elements; }
};

/// What inspect_archive found: every tensor and every plain value, by dotted path ("config",
/// "optimizer.param_groups.param_groups/0.options.lr").
struct ArchiveContents {
  std::map<std::string, std::string> strings;
  std::map<std::string, std::int64_t> ints;
  std::map<std::string, double> floats;
  std::map<std::string, bool> bools;
  std::map<std::string, std::pair<double, double>> float_pairs;  ///< Tuple[float, float] (Adam's betas)
  std::vector<ArchiveTensor> tensors;
};

inline constexpr std::size_t kMaxArchiveEntries = 100000;
inline constexpr std::size_t kMaxPickleBytes = std::size_t{16} << 20;      ///< data.pkl
inline constexpr std::size_t kMaxSmallEntryBytes = std::size_t{1} << 20;   ///< a code, debug or constants entry
inline constexpr std::size_t kMaxSmallBytesTotal = std::size_t{32} << 20;  ///< all of them together

/// The deepest nesting of arrays and objects in the JSON the archive's strings hold (the config,
/// the progress): Scout's writer nests them 3 deep; a crafted 400,000 deep is refused before
/// nlohmann's parser builds it.
inline constexpr int kMaxJsonNesting = 16;

/// Where `text` (JSON) first opens an array or object more than `max_depth` deep; nullopt when it
/// never does. Counts brackets outside strings only; the JSON parser checks the rest.
std::optional<std::size_t> json_nested_beyond(std::string_view text, int max_depth);

/// Checks `bytes` as above; throws std::runtime_error with a one-line reason ("entry
/// archive/data/3: ..."), never anything else.
ArchiveContents inspect_archive(std::string_view bytes);

}  // namespace scout::learn
