#pragma once
/// Evaluation (METHOD.md § Evaluation): R independent stochastic runs over a set of digits with
/// the physics and the camera in the loop, Student-t intervals, confusion matrix, the two random
/// baselines, full-image and greedy accuracy. Torch-free: the CLI includes this header.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "agent/config.hpp"
#include "core/stop.hpp"
#include "learn/checkpoint.hpp"
#include "worlds/world.hpp"

namespace scout::learn {

/// How far an evaluation has got, in rollouts (one digit driven once, by any policy) of this process.
struct EvalProgress {
  long rollouts_done = 0, rollouts_total = 0;
  int run = 0, runs = 0;  ///< the stochastic run under way (1-based), of R; 0: the final greedy run
  double seconds = 0;     ///< since the evaluation started
};

struct EvalConfig {
  std::filesystem::path checkpoint;                 ///< RUN/checkpoint.safetensors or a model file
  std::optional<Checkpoint> opened;                 ///< `checkpoint` already opened: not read again
  std::filesystem::path images, labels;             ///< any IDX image and label files
  std::optional<std::filesystem::path> world_file;  ///< default: the checkpoint's world
  int runs = 20;                                    ///< R
  /// The baselines (i.i.d. moves, goals only) drive the first min(baseline_runs, R) runs' digits
  /// too: they are context for the agent's figure, and 5 runs give them an interval at a quarter
  /// of the cost of 20.
  int baseline_runs = 5;
  std::uint64_t seed = 1;                               ///< run k uses derive_seed(seed, k)
  int batch_robots = 240;                               ///< robots per rollout batch
  agent::Precision precision = agent::Precision::Auto;  ///< Auto: this CPU's best (never the checkpoint's)
  /// A world given whole (scout report's budget sweep: other m, E, T); overrides world_file.
  std::optional<worlds::World> world;
  int image_limit = 0;      ///< the first K images only (0: all)
  bool agent_only = false;  ///< only the R stochastic runs: no baselines, full images or greedy run
  int threads = 0;          ///< LibTorch threads (0: one per core)
  /// Called after every rollout batch with how far this process has got (a long evaluation that
  /// prints nothing looks hung); unset: nothing is reported.
  std::function<void(const EvalProgress&)> on_progress;
};

/// A mean over runs and the half-width of its 95 % Student-t interval (R - 1 degrees of freedom).
struct Interval {
  double mean = 0;
  double ci95 = 0;
};

struct EvalReport {
  Interval accuracy;  ///< stochastic, the checkpoint's learned layers
  Interval top2;
  std::vector<std::vector<double>> confusion;  ///< D x D, rows = true label, row-normalised, mean over runs
  double iid_accuracy = 0;                     ///< baseline: i.i.d. goals and actions, same classifier (mean)
  double goals_only_accuracy = 0;              ///< baseline: learned goals, i.i.d. actions (NaN: no learned goal layer)
  double iid_ci95 = 0, goals_only_ci95 = 0;    ///< the baselines' 95 % half-widths over their runs
  int baseline_runs = 0;                       ///< runs of each baseline (0: not measured)
  double full_image_accuracy = 0;              ///< the classifier on full images (u_c = x)
  double greedy_accuracy = 0;                  ///< argmax goals and actions (one run)
  double revealed_fraction = 0;                ///< share of the floor's pixels seen by the end, stochastic runs
  /// The agent's axis decisions (learn/rollout.hpp AxisTally) over its R runs: how many per rollout
  /// (chi = 1), the share whose two candidate moves would reveal different numbers of new pixels,
  /// the share of those where the chosen axis reveals more (1/2 for i.i.d. axes), and the mean
  /// difference in pixels where they differ.
  double axis_decisions_per_rollout = 0, axis_differing_share = 0, axis_chose_more_share = 0, axis_gap_px = 0;
  /// The agent's moves per rollout (a team's: all its robots') that did not arrive: blocked by an
  /// obstacle or a teammate, or out of ticks (RolloutEngine::stalled_moves).
  double stalled_moves_per_rollout = 0;
  int runs = 0, images = 0;
  double seconds = 0;
  std::vector<int> labels;                                 ///< per image
  std::vector<std::vector<double>> probabilities;          ///< per image: mean pi_c over the runs (D values)
  std::string checkpoint;                                  ///< the checkpoint file, as given
  std::string world;                                       ///< the world file used (--world or the checkpoint's)
  int patch_px = 0, episodes = 0, steps = 0;               ///< the task evaluated: m, E, T
  std::uint64_t seed = 0;                                  ///< the evaluation's seed
  bool learned_goals = false;                              ///< the checkpoint's history has a mode (ii) or (iii) epoch
  bool learned_actions = false;                            ///< ... a mode (iii) epoch
  agent::Precision precision = agent::Precision::Float32;  ///< the networks' arithmetic in this evaluation
  agent::Precision trained_precision = agent::Precision::Float32;  ///< what the checkpoint was trained in
};

class ProcessGroup;  // learn/distributed.hpp

/// Runs the evaluation. `stop` is polled between batches (Ctrl-C): a stop throws core::Stopped
/// and nothing of the evaluation is kept. Throws InputError for bad files or a mismatch between
/// the data and the checkpoint. With a `group`, every rank calls this with the same config and
/// evaluates a share of the images; every rank returns the whole report, the same figures as one
/// process gives (each image's rollouts depend on its index alone).
EvalReport evaluate(const EvalConfig& config, const core::StopToken& stop = {}, ProcessGroup* group = nullptr);

/// The report as JSON text (fractions in [0, 1], intervals as half-widths).
std::string report_json(const EvalReport& report);
/// The 97.5 % quantile of Student's t with `dof` degrees of freedom (dof >= 1).
double student_t_975(int dof);
/// The mean of `values` and its 95 % half-width t(R-1) * sd / sqrt(R), sd with R - 1. With one
/// value (or none) there is no spread to estimate and ci95 is 0; equal values give exactly 0.
Interval mean_ci95(std::span<const double> values);

}  // namespace scout::learn
