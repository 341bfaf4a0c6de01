#pragma once
/// Checkpoint files (RUN/checkpoint.pt): weights, optimizer state, the resolved config, where
/// the schedule stands and the metrics so far, written atomically. Torch header: learn/ only.
#include <torch/torch.h>

#include <filesystem>
#include <string>
#include <vector>

#include "agent/networks.hpp"
#include "learn/checkpoint.hpp"
#include "learn/internal/private.hpp"
#include "learn/trainer.hpp"

namespace scout::learn {

/// Running sums of an epoch in progress: what its metrics row is made of.
struct EpochSums {
  double reward = 0;         ///< sum of r over the epoch's rollouts
  double loss = 0;           ///< sum of the batches' -J-hat
  double train_seconds = 0;  ///< time in training steps (validation excluded)
  long correct = 0;          ///< rollouts classified right
  long robots = 0;           ///< rollouts
  long images = 0;           ///< training images
  long batches = 0;          ///< batches
};

/// Everything in a checkpoint besides tensors.
struct CheckpointState {
  TrainConfig config;
  ScheduleCursor cursor;
  std::vector<EpochMetrics> history;
  EpochSums partial;   ///< of the epoch in progress (after a stop), so that a resumed epoch reports the same
  int world_size = 1;  ///< processes the run trained with (1 in files written before data-parallel runs)
  int threads = 0;     ///< LibTorch threads per process it trained with (0: not recorded)
};

/// Writes the checkpoint atomically (a temporary file beside it, then a rename). `optimizer`
/// may be null (a model file: weights and config only).
void save_checkpoint(const std::filesystem::path& file, agent::AgentImpl& agent, torch::optim::Optimizer* optimizer,
                     const CheckpointState& state);
/// What save_checkpoint writes, in memory (rank 0 broadcasts it to the other ranks).
std::string checkpoint_bytes(agent::AgentImpl& agent, torch::optim::Optimizer* optimizer, const CheckpointState& state);
/// The state and weights of checkpoint_bytes' output; `origin` names the source in errors.
CheckpointState read_checkpoint_state_bytes(const std::string& bytes, const std::string& origin);
void load_checkpoint_weights_bytes(const std::string& bytes, const std::string& origin, agent::AgentImpl& agent,
                                   torch::optim::Optimizer* optimizer);
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
