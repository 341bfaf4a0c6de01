#pragma once
/// Checkpoint and model files from outside (torch-free, for the CLI): what a file says about
/// itself, where a run keeps it, and exporting a model. Writing and loading weights is
/// learn/internal/checkpoint.hpp's.
#include <filesystem>
#include <vector>

#include "learn/trainer.hpp"

namespace scout::learn {

/// What a checkpoint file says about itself, without loading weights.
struct CheckpointInfo {
  int format_version = 0;
  TrainConfig config;
  ScheduleCursor cursor;
  std::vector<EpochMetrics> history;
  int world_size = 1;  ///< processes the run trained with
};
/// Reads a checkpoint's header; throws InputError with one line naming the file for anything
/// that is not a Scout checkpoint of this format version.
CheckpointInfo read_checkpoint_info(const std::filesystem::path& file);

/// The checkpoint file a path names: RUN/checkpoint.pt for a run folder, else the path itself.
std::filesystem::path resolve_checkpoint(const std::filesystem::path& path);

/// Writes a model file (what `scout run --checkpoint` and `scout eval` read): the checkpoint's
/// weights, config and metrics history, without the optimizer's state. Atomic; throws InputError
/// naming the checkpoint for anything that is not a Scout checkpoint. Returns what the model holds.
CheckpointInfo export_model(const std::filesystem::path& checkpoint, const std::filesystem::path& model_file);

/// The checkpoint format this build writes and reads.
inline constexpr int kCheckpointFormat = 1;

}  // namespace scout::learn
