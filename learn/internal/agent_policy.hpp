#pragma once
/// The learned policy: the agent's goal and action planners choosing for a rollout batch, and
/// the log-probabilities the estimator needs. Torch header: include from learn/ sources only.
#include <torch/torch.h>

#include <cstdint>
#include <span>
#include <vector>

#include "agent/networks.hpp"
#include "agent/state.hpp"
#include "core/random.hpp"
#include "learn/internal/private.hpp"
#include "learn/rollout.hpp"

namespace scout::learn {

/// Which layers choose in a rollout (METHOD.md § Training modes) and how.
struct Sampling {
  bool learned_goals = false;     ///< goals from the goal planner; else i.i.d. uniform over the pixels
  bool learned_actions = false;   ///< axes from the action planner; else i.i.d. 1/2 - 1/2
  bool greedy = false;            ///< argmax instead of sampling (evaluation extra)
  bool with_grad = false;         ///< keep the autograd graph of log pi (training)
  bool record_goal_maps = false;  ///< keep pi_g of every robot and episode (pictures)
  agent::Precision precision = agent::Precision::Float32;  ///< the networks' arithmetic
};

/// Where the policy's time went, seconds (scout bench train).
struct PolicyTiming {
  double state_s = 0;    ///< writing y, l, h, g_l into the planners' input tensors
  double forward_s = 0;  ///< the planners' forward passes, log pi and the sampling
};

/// Goals and axes from the agent's planners (or i.i.d. where a layer is not learned). Robot i
/// samples from its own generator seeded with seeds[i]: its choices never depend on the others.
/// Only robots whose action protocol says Choose (chi = 1) are run through the action planner.
class AgentPolicy final : public Policy {
 public:
  AgentPolicy(agent::AgentImpl& agent, const grid::FloorFrame& frame, int patch_px, int max_robots);

  /// Starts a batch: new generators, log pi and entropy reset to zero.
  void begin(std::span<const std::uint64_t> seeds, const Sampling& sampling);
  void choose_goals(const BatchState& state, int episode, std::span<grid::Cell> goals) override;
  void choose_axes(const BatchState& state, std::span<std::uint8_t> need, std::span<grid::Axis> axes) override;

  /// Sum over the batch so far of the sampled log-probabilities of the learned layers, per robot
  /// [count] (zeros when no layer is learned). Carries the graph when sampling.with_grad.
  torch::Tensor log_pi() const { return log_pi_; }
  /// Sum of the entropies of the learned layers' distributions at each decision, per robot [count].
  torch::Tensor entropy() const { return entropy_; }
  /// pi_g of robot i in episode e (H * W floats), when record_goal_maps.
  const std::vector<float>& goal_map(int robot, int episode) const;
  /// Decisions taken by the action planner in this batch (robots x steps with chi = 1).
  long action_decisions() const { return action_decisions_; }
  const PolicyTiming& timing() const { return timing_; }
  void reset_timing() { timing_ = {}; }

 private:
  int sample(core::Rng& rng, const float* probabilities, int n) const;
  /// Goals for the robots of `rows` (all of the batch, or one member of every team) from one
  /// forward pass of the goal planner.
  void sample_goals(const BatchState& state, std::span<const std::int64_t> rows, std::span<grid::Cell> goals);
  /// Robot i's view for the planners; with the teammates' channels, its teammates' poses and the
  /// goals they hold (`team_goals`, where `has_goal`), gathered into teammate_scratch_.
  agent::RobotView view_of(const BatchState& state, int i, const grid::Cell* goal,
                           std::span<const grid::Cell> team_goals, std::span<const std::uint8_t> has_goal);
  /// Whether the route rule applies to this state: the agent has it and the world has obstacles.
  bool routes_free(const BatchState& state) const;
  /// The route rule's goals: reachable_[r * area + c] = 1 where a monotone free route joins robot
  /// rows[r]'s cell to cell c.
  void reachable_goals(const BatchState& state, std::span<const std::int64_t> rows);
  /// The route rule's axes: for every robot with need[i], the axis is set and need[i] cleared where
  /// only one of the two moves keeps a monotone free route to the goal.
  void route_axes(const BatchState& state, std::span<std::uint8_t> need, std::span<grid::Axis> axes);

  agent::AgentImpl& agent_;
  grid::FloorFrame frame_;
  int patch_px_;
  int max_robots_;
  Sampling sampling_;
  int count_ = 0;
  std::vector<core::Rng> rngs_;
  torch::Tensor log_pi_, entropy_;
  std::vector<std::vector<std::vector<float>>> goal_maps_;
  std::vector<std::int64_t> rows_;
  std::vector<grid::Cell> goals_now_;                        // the goals the robots hold during a choice
  std::vector<std::uint8_t> has_goal_;                       // ... where they hold one
  std::vector<std::uint8_t> all_goals_;                      // all ones: while moving, every robot holds a goal
  std::vector<grid::Cell> teammate_poses_, teammate_goals_;  // one robot's teammates (scratch)
  std::vector<std::uint8_t> reachable_, route_scratch_;      // the route rule's (scratch)
  long action_decisions_ = 0;
  PolicyTiming timing_;
};

/// u_c = y for the first `count` robots of a batch: [count, c, H, W] floats (c: the floors' channels).
torch::Tensor revealed_images(const BatchState& state, int count);

/// Full floors (u_c = x) as the classifier's input: [count, c, H, W] from count * c * H * W bytes.
torch::Tensor full_images(std::span<const std::uint8_t> floors, int count, const grid::FloorFrame& frame);

}  // namespace scout::learn
