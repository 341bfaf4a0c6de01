#pragma once
/// Checkpoint files (RUN/checkpoint.safetensors): weights, optimizer state, the resolved config,
/// where the schedule stands and the metrics so far, written atomically. Torch header: learn/ only.
#include <torch/torch.h>

#include <filesystem>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "agent/networks.hpp"
#include "learn/checkpoint.hpp"
#include "learn/internal/private.hpp"
#include "learn/internal/safetensors.hpp"
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
  EpochSums partial;     ///< of the epoch in progress (after a stop), so that a resumed epoch reports the same
  int world_size = 1;    ///< processes the run trained with (1 in files written before data-parallel runs)
  int threads = 0;       ///< LibTorch threads per process it trained with (0: not recorded)
  std::string manifest;  ///< the run's manifest.json (JSON text; empty where none was given)
};

/// The file's tensor names: "agent." and the network's own parameter or buffer name; Adam's state
/// per parameter under "optimizer." and the parameter's name, then ".step", ".exp_avg" or
/// ".exp_avg_sq".
inline const std::string kAgentPrefix = "agent.";
inline const std::string kOptimizerPrefix = "optimizer.";

/// The largest metadata entries read (and written: a longer one is refused before the file is):
/// Scout writes configs of about 2 KB, a progress of about 450 bytes per epoch trained (so about
/// 7,000 epochs fit), manifests of 4-30 KB, and Adam's options in 150 bytes.
inline constexpr std::size_t kMaxConfigBytes = std::size_t{64} << 10;
inline constexpr std::size_t kMaxProgressBytes = std::size_t{3} << 20;
inline constexpr std::size_t kMaxManifestBytes = std::size_t{512} << 10;
inline constexpr std::size_t kMaxOptimizerBytes = 4096;

/// The key under which LibTorch's optimizer keeps a parameter's state: its TensorImpl's address
/// as text in LibTorch 1.x, the pointer itself in 2.x. (A template, so that only the branch of
/// the LibTorch in use is compiled.)
template <class Optimizer = torch::optim::Optimizer>
auto adam_state_key(const torch::Tensor& parameter) {
  using Key = typename std::decay_t<decltype(std::declval<Optimizer&>().state())>::key_type;
  if constexpr (std::is_same_v<Key, std::string>) {
    std::ostringstream text;
    text << parameter.unsafeGetTensorImpl();
    return text.str();
  } else {
    return static_cast<Key>(parameter.unsafeGetTensorImpl());
  }
}

/// Writes the checkpoint atomically (a temporary file beside it, then a rename). `optimizer`
/// may be null (a model file: weights and config only).
void save_checkpoint(const std::filesystem::path& file, agent::AgentImpl& agent, torch::optim::Optimizer* optimizer,
                     const CheckpointState& state);
/// What save_checkpoint writes, in memory (rank 0 broadcasts it to the other ranks): a safetensors
/// file (learn/internal/safetensors.hpp) whose __metadata__ holds the format, the config, the
/// progress, the manifest and Adam's options as JSON text.
std::string checkpoint_bytes(agent::AgentImpl& agent, torch::optim::Optimizer* optimizer, const CheckpointState& state);

/// An opened checkpoint (open_checkpoint): read, parsed and checked once. Not copied or moved:
/// `tensors` views its own `bytes`.
struct Checkpoint::Contents {
  Contents() = default;
  Contents(const Contents&) = delete;
  Contents& operator=(const Contents&) = delete;

  std::filesystem::path file;  ///< as messages name it
  std::string bytes;           ///< the whole file
  safetensors::File tensors;   ///< views into `bytes`, checked against the config
  CheckpointState state;
  CheckpointInfo info;
  mutable agent::Agent model{nullptr};  ///< networks(), once built

  /// The checkpoint's networks, built from its config with its weights, in eval mode: built on
  /// first use, then shared by every caller that runs the model (none of them trains it).
  agent::Agent networks() const;
  /// Loads the weights, and the optimizer's state when `optimizer` is given, into `agent` (a
  /// resumed run's own, built from the same config). Throws InputError naming the file.
  void load_into(agent::AgentImpl& agent, torch::optim::Optimizer* optimizer) const;
};

/// A checkpoint's "progress" JSON (the schedule's position, the epoch in progress, the history,
/// the run's processes and threads) into `state`; throws InputError naming `origin`.
void read_progress(const std::string& text, const std::string& origin, CheckpointState& state);

/// open_checkpoint for bytes already in memory (checkpoint_bytes' output, broadcast by rank 0);
/// `origin` names them in errors.
Checkpoint open_checkpoint_bytes(std::string bytes, const std::string& origin);

/// An opened checkpoint's networks (Contents::networks), and its state when `state` is given.
agent::Agent load_agent(const Checkpoint& checkpoint, CheckpointState* state = nullptr);
/// The same for a file, opened once.
agent::Agent load_agent(const std::filesystem::path& file, CheckpointState* state = nullptr);

/// How many times open_checkpoint and open_checkpoint_bytes have run in this process (the tests
/// hold each reader to one open).
int checkpoints_opened();

}  // namespace scout::learn
