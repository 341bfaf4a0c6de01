#pragma once
/// Checkpoint and model files from outside (torch-free, for the CLI): opening one once, what it
/// says about itself, where a run keeps it, and exporting a model. Writing and loading weights is
/// learn/internal/checkpoint.hpp's.
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "learn/trainer.hpp"

namespace scout::learn {

/// What a checkpoint file says about itself.
struct CheckpointInfo {
  int format_version = 0;
  std::string manifest;  ///< the manifest it carries (JSON text; empty where none)
  TrainConfig config;
  ScheduleCursor cursor;
  std::vector<EpochMetrics> history;
  int world_size = 1;  ///< processes the run trained with
};

/// A checkpoint or model file read, checked and parsed once (open_checkpoint): what every reader
/// takes — a resumed run, evaluation, the report, export, `scout run` and scout.Agent. Copies
/// share the one opened file. Torch-free: its contents are learn/internal/checkpoint.hpp's.
class Checkpoint {
 public:
  struct Contents;  ///< learn/internal/checkpoint.hpp: the state, the parsed file, the networks
  explicit Checkpoint(std::shared_ptr<const Contents> contents);
  /// The file, as messages name it.
  const std::filesystem::path& file() const;
  const CheckpointInfo& info() const;
  const Contents& contents() const { return *contents_; }

 private:
  std::shared_ptr<const Contents> contents_;
};

/// Opens RUN/checkpoint.safetensors (for a run folder) or a model file: reads it once, parses it
/// (learn/internal/safetensors.hpp: every offset, size, dtype and shape against the file's length)
/// and holds it against what Scout's writer makes (the format, the config, the progress against
/// the schedule, every tensor against the networks the config describes, Adam's state in its
/// ranges). Throws InputError with one line naming the file for anything that is not a Scout
/// checkpoint of this format version.
Checkpoint open_checkpoint(const std::filesystem::path& path);

/// A tensor of an opened checkpoint as Scout has loaded it, by its name in the file.
struct LoadedTensor {
  std::string name;
  bool integer = false;  ///< I64 (else F32)
  std::vector<std::int64_t> shape;
  std::vector<float> floats;           ///< an F32 tensor's values
  std::vector<std::int64_t> integers;  ///< an I64 tensor's values
};

/// Every tensor of `checkpoint` read back out of LibTorch after Scout's loader put it there: the
/// networks' parameters and buffers, and for a checkpoint Adam's step and moments (from the
/// optimizer's own state). What scout.checkpoint_tensors gives Python, to hold against other readers.
std::vector<LoadedTensor> loaded_tensors(const Checkpoint& checkpoint);

/// The checkpoint file a path names: RUN/checkpoint.safetensors for a run folder, else the path itself.
std::filesystem::path resolve_checkpoint(const std::filesystem::path& path);

/// Writes a model file (what `scout run --checkpoint` and `scout eval` read): the checkpoint's
/// weights, config and metrics history, without the optimizer's state. Atomic. Returns what the
/// model holds.
CheckpointInfo export_model(const Checkpoint& checkpoint, const std::filesystem::path& model_file);

/// The checkpoint format this build writes and reads: 2, safetensors (format 1, LibTorch's
/// torch::save archive, is read only by convert_legacy_checkpoint).
inline constexpr int kCheckpointFormat = 2;

/// The file name extension of checkpoints and models.
inline constexpr const char* kCheckpointExtension = ".safetensors";

/// Converts a checkpoint or model file of format 1 (`.pt`: LibTorch's zip of pickles) to format 2
/// at `out`, with `manifest` (JSON text, may be empty) as its manifest plus "converted_from" (the
/// .pt file's path and SHA-256): the same weights, Adam's state and schedule, so that a converted
/// checkpoint resumes as the old one did. Nothing is written unless the result passes every check
/// open_checkpoint makes. Reads `legacy`
/// with LibTorch's own unpickler, which trusts its input: only for files the user trusts. Returns
/// what the new file holds (opened again with every check).
CheckpointInfo convert_legacy_checkpoint(const std::filesystem::path& legacy, const std::filesystem::path& out,
                                         const std::string& manifest);

/// The largest checkpoint or model file Scout reads (open_checkpoint refuses a larger one from its
/// size, before reading a byte) and writes (a new run whose checkpoints would be larger is
/// refused: check_checkpoint_size). 2 GiB holds about 170 million parameters with Adam's two
/// moments; the shipped models are 1-3 MB, ResNet-18 at width 64 with Adam about 135 MB.
inline constexpr std::uint64_t kMaxCheckpointBytes = std::uint64_t{2} << 30;

/// Refuses (InputError) networks whose checkpoints (weights and Adam's two moments) would be
/// larger than kMaxCheckpointBytes, before a run starts: Scout never writes a file it cannot read.
void check_checkpoint_size(const agent::NetworkConfig& network);

}  // namespace scout::learn
