#pragma once
/// Training (METHOD.md § The estimator, § Training modes): the hierarchical schedule
/// (full images) -> (i) -> (ii) -> (iii) over rollouts with the physics and the camera in the
/// loop, checkpointed every epoch. Torch-free: the CLI includes this header.
#include <array>
#include <chrono>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "core/stop.hpp"
#include "learn/train_config.hpp"

namespace scout::learn {

class ProcessGroup;  // learn/distributed.hpp
class Checkpoint;    // learn/checkpoint.hpp

/// One row of metrics.csv.
struct EpochMetrics {
  Stage stage = Stage::ModeI;
  int epoch = 0;                   ///< 1-based, within the stage
  double reward = 0;               ///< mean r = log pi_c[label] over the epoch's rollouts
  double loss = 0;                 ///< mean -J-hat over the epoch's batches
  double train_accuracy = 0;       ///< share of the epoch's rollouts classified right
  double validation_accuracy = 0;  ///< one stochastic pass over the validation digits, this stage's policy
  // The same classifier under the baselines' policies, and on full images (one pass each over the
  // validation digits); empty in rows written before they were measured.
  std::optional<double> validation_iid;         ///< i.i.d. goals and actions
  std::optional<double> validation_goals_only;  ///< learned goals, i.i.d. actions
  std::optional<double> validation_full_image;  ///< the classifier on full, unmasked images
  double images_per_s = 0;                      ///< training images per second (validation excluded)
  double seconds = 0;                           ///< wall time of the epoch, validation included
  double learning_rate = 0;                     ///< Adam's step size in this epoch (may be lowered on --resume)
  /// The mean over the epoch's steps of the L2 norm of the gradient each step applied (in a
  /// data-parallel run, the sum over the processes that every one of them applies); empty in rows
  /// written before it was measured, and for an epoch resumed from such a checkpoint.
  std::optional<double> gradient_norm;
};
/// metrics.csv's header line and one row.
std::string metrics_csv_header();
std::string metrics_csv_row(const EpochMetrics& m);

/// Reported after every batch.
struct Progress {
  Stage stage = Stage::ModeI;
  int epoch = 0, epochs = 0;   ///< 1-based epoch within the stage, and the stage's epochs
  int batch = 0, batches = 0;  ///< batches done in this epoch, and its batches
  double images_per_s = 0;     ///< this epoch so far
  double reward = 0;           ///< mean reward this epoch so far
  double eta_s = 0;            ///< rest of the schedule at this epoch's rate
};

/// What a caller sees of a run, and the one place it may act inside a training step.
struct TrainHooks {
  core::StopToken stop;                               ///< polled between batches (Ctrl-C)
  std::function<void(const Progress&)> on_progress;   ///< after every batch
  std::function<void(const EpochMetrics&)> on_epoch;  ///< after every epoch (metrics written)
  /// Between backward and the optimizer step (the place data-parallel training all-reduces):
  /// every trainable parameter's gradient, flattened into one fp32 buffer in parameter order (a
  /// parameter without a gradient contributes zeros). Changes are written back: a non-zero slice
  /// gives its parameter a gradient, so Adam moves it. Unset: nothing is flattened.
  std::function<void(std::span<float> gradients)> on_gradients;
  /// Also checkpoint inside an epoch, after the first batch that ends this long after the last
  /// checkpoint, so that a hard kill loses minutes, not an epoch (0: at epoch ends only).
  std::chrono::milliseconds checkpoint_every{0};
};

enum class TrainOutcome { Finished, NonFinite };
struct TrainResult {
  TrainOutcome outcome = TrainOutcome::Finished;
  std::string message;  ///< one line for the user
};

/// Where the schedule stands (stored in checkpoints).
struct ScheduleCursor {
  Stage stage = Stage::Pretrain;  ///< Done once the schedule has no epoch left
  int epoch = 0;                  ///< epochs done within that stage
  int batch = 0;                  ///< batches done within the next epoch (non-zero only after an interrupt)
};

/// The files of a run folder.
inline constexpr const char* kCheckpointFile = "checkpoint.safetensors";  ///< weights, Adam, config, schedule
inline constexpr const char* kMetricsFile = "metrics.csv";                ///< one row per epoch

/// What `Trainer::resume` may change; an unset field keeps the run's own.
struct ResumeOptions {
  /// A longer schedule; a mode that precedes one already trained cannot grow (METHOD.md: a
  /// learned layer never returns to i.i.d.).
  std::optional<std::array<int, 3>> epochs = std::nullopt;
  /// The same data, moved (every file is checked against the run's digests by the CLI).
  std::optional<std::filesystem::path> data_folder = std::nullopt;
  /// Adam's step size from the next batch on (fine-tuning at a lower rate); metrics.csv records
  /// each epoch's rate, so nothing of the history is lost.
  std::optional<double> learning_rate = std::nullopt;
  /// The networks' arithmetic from the next batch on (a bf16 run continued in fp32 on a CPU without
  /// native bf16): the weights, Adam's state and the schedule carry over; the continuation is no
  /// longer bit for bit what an uninterrupted run in the old precision would give.
  std::optional<agent::Precision> precision = std::nullopt;
  /// The full-image teacher's weight lambda from the next batch on (TrainConfig::distillation).
  std::optional<double> distillation = std::nullopt;
};

/// A training run in a folder: RUN/checkpoint.safetensors (every epoch, atomically), RUN/metrics.csv.
/// Run by one process, or by a group of them (distribute) that split each batch's images.
class Trainer {
 public:
  /// A new run. `run_dir` must exist; nothing is written until run() finishes a batch or epoch.
  /// Refuses (InputError) a config whose estimated memory (estimate_training_bytes) exceeds what
  /// the machine has available, unless `force_memory`. With `initial_weights` (a model or
  /// checkpoint whose networks are `config.network`), the networks start from its weights instead
  /// of the seed's initialisation, with a fresh optimizer: fine-tuning a trained agent.
  Trainer(const TrainConfig& config, std::filesystem::path run_dir, int threads, bool force_memory = false,
          const Checkpoint* initial_weights = nullptr);
  /// Continues RUN/checkpoint.safetensors with what `options` changes. `threads` 0: the run's own count
  /// (LibTorch's sums depend on it: only the same count continues bit for bit), else one per
  /// core for checkpoints that do not record it. Throws InputError for a bad or foreign
  /// checkpoint, or an option that contradicts the run.
  static std::unique_ptr<Trainer> resume(const std::filesystem::path& run_dir, int threads,
                                         const ResumeOptions& options = {});
  /// The same from RUN/checkpoint.safetensors already opened (open_checkpoint): nothing is read again.
  static std::unique_ptr<Trainer> resume(const Checkpoint& checkpoint, const std::filesystem::path& run_dir,
                                         int threads, const ResumeOptions& options = {});
  /// Data-parallel training over `group` (learn/distributed.hpp); every rank calls this. Rank 0
  /// builds its trainer with `make_leader` (a new run or a resume, as above) and broadcasts its
  /// whole state (weights, Adam, config, schedule position, history); the other ranks load their
  /// data from `data_folder` (default: the path in rank 0's config). `own_config` is what this
  /// rank's command line asks for (nullopt: take rank 0's, as on a resume). Every rank's world,
  /// networks, training settings and data (SHA-256) must agree with rank 0's, else every rank
  /// throws InputError naming what differs. Rank 0 alone writes the run's files; the others need
  /// no run folder. An error in `make_leader` reaches the others as a GroupError.
  static std::unique_ptr<Trainer> distribute(ProcessGroup& group, int threads,
                                             const std::function<std::unique_ptr<Trainer>()>& make_leader,
                                             const std::optional<TrainConfig>& own_config,
                                             const std::optional<std::filesystem::path>& data_folder);
  ~Trainer();
  Trainer(const Trainer&) = delete;
  Trainer& operator=(const Trainer&) = delete;

  /// Trains until the schedule is done or the loss is not finite (the last good checkpoint is
  /// kept). A stop requested through `hooks.stop` saves a checkpoint, then throws core::Stopped
  /// saying where the run stopped and where the checkpoint is.
  TrainResult run(const TrainHooks& hooks);

  const TrainConfig& config() const;
  const ScheduleCursor& cursor() const;
  /// True when no epoch of the schedule is left.
  bool finished() const;
  const std::vector<EpochMetrics>& history() const;
  int threads() const;
  /// Processes training together (1 alone) and this one's rank.
  int world_size() const;
  int rank() const;
  std::filesystem::path checkpoint_file() const;
  /// The data files read (for manifests).
  const std::vector<std::filesystem::path>& data_files() const;
  /// The run's manifest (JSON text), stored in every checkpoint from the next one on (a resumed
  /// run keeps its checkpoint's until given another).
  void set_manifest(std::string manifest);

 private:
  struct Impl;
  explicit Trainer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// Sets LibTorch's intra-op threads (0: one per core) and returns the number in use.
int set_torch_threads(int threads);

}  // namespace scout::learn
