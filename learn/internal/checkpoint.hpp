#pragma once
#ifndef SCOUT_LEARN_INTERNAL
#error "learn/internal/ is private to scout_learn and its tests (CMake target scout_learn_internal); include learn/*.hpp"
#endif
/// Checkpoint files (RUN/checkpoint.pt): weights, optimizer state, the resolved config, where
/// the schedule stands and the metrics so far, written atomically. Torch header: learn/ only.
#include <torch/torch.h>

#include <filesystem>
#include <string>
#include <vector>

#include "agent/networks.hpp"
#include "learn/training.hpp"

namespace scout::learn {

inline constexpr const char* kCheckpointName = "checkpoint.pt";

/// Everything in a checkpoint besides tensors.
struct CheckpointState {
  TrainConfig config;
  ScheduleCursor cursor;
  std::vector<EpochMetrics> history;
  /// Sums of the epoch in progress (after an interrupt), so that a resumed epoch reports the same.
  struct Partial {
    double reward = 0, loss = 0, train_seconds = 0;
    long correct = 0, robots = 0, images = 0, batches = 0;
  } partial;
};

/// Writes the checkpoint atomically (a temporary file beside it, then a rename). `optimizer`
/// may be null (a model file: weights and config only).
void save_checkpoint(const std::filesystem::path& file, agent::AgentImpl& agent, torch::optim::Optimizer* optimizer,
                     const CheckpointState& state);
/// Reads the non-tensor part; throws InputError ("FILE: not a Scout checkpoint ...", "FILE:
/// checkpoint format N, this build reads M", "FILE: config: ...") with one line.
CheckpointState read_checkpoint_state(const std::filesystem::path& file);
/// Loads weights (and the optimizer's state when given and present) into an agent built from
/// the checkpoint's config. Throws InputError naming the file.
void load_checkpoint_weights(const std::filesystem::path& file, agent::AgentImpl& agent,
                             torch::optim::Optimizer* optimizer);

/// The agent stored in a checkpoint, built from its config and loaded, in eval mode.
/// Throws InputError naming the file.
agent::Agent load_agent(const std::filesystem::path& file, CheckpointState* state = nullptr);

}  // namespace scout::learn
