#pragma once
/// A trained agent loaded from a checkpoint, driving a rollout batch (for `scout run
/// --checkpoint`). Torch-free facade over AgentPolicy and the classifier.
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <vector>

#include "learn/checkpoint.hpp"
#include "learn/rollout.hpp"
#include "learn/trainer.hpp"

namespace scout::learn {

/// The layers a checkpoint drives with: goals once it has trained in mode (ii) or (iii), actions
/// once in mode (iii) (METHOD.md: a learned layer never returns to i.i.d.); i.i.d. otherwise.
struct LearnedLayers {
  bool goals = false;
  bool actions = false;
};
/// What a checkpoint's history (its finished epochs) says it has learned.
LearnedLayers learned_layers(const std::vector<EpochMetrics>& history);

class TrainedAgent {
 public:
  /// Loads RUN/checkpoint.safetensors or a model file; throws InputError naming the file. The networks run
  /// in `precision` (Auto: this CPU's best), whatever precision the checkpoint was trained in.
  static std::unique_ptr<TrainedAgent> load(const std::filesystem::path& checkpoint,
                                            agent::Precision precision = agent::Precision::Auto);
  /// The same from a checkpoint already opened (open_checkpoint): its networks are shared, not read again.
  static std::unique_ptr<TrainedAgent> load(const Checkpoint& checkpoint,
                                            agent::Precision precision = agent::Precision::Auto);
  ~TrainedAgent();

  /// The checkpoint's config (its world, network and training options).
  const TrainConfig& config() const;
  /// The layers the agent drives with (the others choose i.i.d.).
  LearnedLayers learned() const;
  /// Prepares the policy for a batch on `frame` (floors must have the checkpoint's channels).
  /// Drives with the layers the checkpoint has learned (learned()); `greedy`: argmax.
  void begin(const grid::FloorFrame& frame, int patch_px, std::span<const std::uint64_t> seeds, bool greedy,
             bool record_goal_maps);
  Policy& policy();
  /// pi_g of robot i in episode e (H * W), when begin() asked to record goal maps.
  const std::vector<float>& goal_map(int robot, int episode) const;
  /// pi_c of the first `count` robots of the state (count * D floats).
  std::vector<float> classify(const BatchState& state, int count);
  int classes() const;
  /// The arithmetic the networks run in here (resolved: fp32 or bf16).
  agent::Precision precision() const;

 private:
  struct Impl;
  explicit TrainedAgent(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace scout::learn
