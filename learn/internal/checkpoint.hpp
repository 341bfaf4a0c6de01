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
  long rollouts = 0;         ///< rollouts driven (stored under the key "robots", as ever)
  long images = 0;           ///< training images
  long batches = 0;          ///< batches
  double gradient_norm = 0;  ///< sum of the steps' gradient norms
  long gradient_steps = 0;   ///< steps whose norm is in that sum (fewer than `batches` in an epoch begun by an
                             ///< older build: its row then has no gradient norm)
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

/// An opened checkpoint (open_checkpoint): read, checked and parsed by LibTorch once.
struct Checkpoint::Contents {
  std::filesystem::path file;  ///< as messages name it
  CheckpointState state;
  CheckpointInfo info;
  mutable torch::serialize::InputArchive archive;  ///< LibTorch's parse (its reads are not const)
  mutable agent::Agent model{nullptr};             ///< networks(), once built

  /// The checkpoint's networks, built from its config with its weights, in eval mode: built on
  /// first use, then shared by every caller that runs the model (none of them trains it).
  agent::Agent networks() const;
  /// Loads the weights, and the optimizer's state when `optimizer` is given, into `agent` (a
  /// resumed run's own, built from the same config). Throws InputError naming the file.
  void load_into(agent::AgentImpl& agent, torch::optim::Optimizer* optimizer) const;
};

/// open_checkpoint for bytes already in memory (checkpoint_bytes' output, broadcast by rank 0);
/// `origin` names them in errors.
Checkpoint open_checkpoint_bytes(const std::string& bytes, const std::string& origin);

/// An opened checkpoint's networks (Contents::networks), and its state when `state` is given.
agent::Agent load_agent(const Checkpoint& checkpoint, CheckpointState* state = nullptr);
/// The same for a file, opened once.
agent::Agent load_agent(const std::filesystem::path& file, CheckpointState* state = nullptr);

/// How many times open_checkpoint and open_checkpoint_bytes have run in this process (the tests
/// hold each reader to one open).
int checkpoints_opened();

}  // namespace scout::learn
