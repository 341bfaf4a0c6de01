#pragma once
#include "learn/internal/private.hpp"

/// Scout's own reading of a LibTorch archive (checkpoints and model files), before LibTorch
/// parses it. LibTorch 1.13's reader trusts its input: a crafted zip directory, a pickle that
/// underflows its stack or a tensor record that points past its storage can crash the process or
/// make it allocate without bound. So every file is first held against what Scout's writer
/// produces (torch::serialize::OutputArchive of an agent, an Adam optimizer and a few values):
///
/// - the zip directory: one folder of entries, stored or deflated, in bounds, not overlapping,
///   CRC-32 checked; only the entries the writer makes (data.pkl, constants.pkl, version,
///   data/N, code/__torch__[/___torch_mangle_N].py and their .debug_pkl);
/// - data.pkl and the other pickles: run by a small pickle machine that knows only the opcodes
///   and globals the writer emits and refuses anything else (stack underflow, an unknown global,
///   a wrong argument);
/// - each tensor: its storage record exists and holds exactly numel x element size bytes, and
///   its offset, sizes and strides stay inside that storage;
/// - code/*.py: TorchScript class stubs (attribute declarations only), checked line by line, so
///   LibTorch's compiler only ever sees code of the shape the writer produces.
///
/// Memory: inspect_archive works on bytes already in memory and allocates at most a few times the
/// size of data.pkl (itself at most kMaxPickleBytes). Torch-free.
#include <cstdint>
#include <map>
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
  std::int64_t numel() const;
};

/// What inspect_archive found: the root object's plain attributes and every tensor.
struct ArchiveContents {
  std::map<std::string, std::string> strings;  ///< root attributes holding a string (config, progress)
  std::map<std::string, std::int64_t> ints;    ///< root attributes holding an integer
  std::vector<ArchiveTensor> tensors;
};

inline constexpr std::size_t kMaxArchiveEntries = 100000;
inline constexpr std::size_t kMaxPickleBytes = std::size_t{16} << 20;      ///< data.pkl
inline constexpr std::size_t kMaxSmallEntryBytes = std::size_t{1} << 20;   ///< a code, debug or constants entry
inline constexpr std::size_t kMaxSmallBytesTotal = std::size_t{32} << 20;  ///< all of them together

/// Checks `bytes` as above; throws std::runtime_error with a one-line reason ("entry
/// archive/data/3: ..."), never anything else.
ArchiveContents inspect_archive(std::string_view bytes);

}  // namespace scout::learn
