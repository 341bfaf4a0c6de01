#pragma once
/// One batch of rollouts through the agent, ending in the classifier's verdict and J-hat: the
/// step that training, evaluation and the estimator test share. Torch header: learn/ and tests.
#include <torch/torch.h>

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "learn/internal/agent_policy.hpp"
#include "learn/internal/estimator.hpp"
#include "learn/internal/private.hpp"
#include "learn/rollout.hpp"
#include "learn/trainer.hpp"
#include "worlds/dataset.hpp"
#include "worlds/floor_layout.hpp"

namespace scout::learn {

/// The robots of one batch: robot r drives over floors[r] from starts[r], sampling with seeds[r],
/// its motion errors and pushes (worlds that have them) from motion_seeds[r]. In a world with
/// teams of K robots (world.team), robots tK .. tK + K - 1 are rollout t: one floor, one label,
/// one classifier decision.
struct RolloutBatch {
  int count = 0;                     ///< robots
  int team = 1;                      ///< K robots per rollout
  std::vector<std::uint8_t> floors;  ///< count * H * W bytes
  std::vector<std::int64_t> labels;  ///< one per rollout (count / team)
  std::vector<grid::Cell> starts;
  std::vector<std::uint64_t> seeds;
  std::vector<std::uint64_t> motion_seeds;

  int rollouts() const { return count / team; }
  /// Adds `other`'s rollouts after this batch's (the same team size).
  void append(const RolloutBatch& other);
};

/// N rollouts per image: rollout i*N + k drives over image indices[i]. These are rollouts
/// first_robot, first_robot + 1, ... of the global batch (the whole mini-batch, which several
/// processes may share): rollout r's starts and seeds derive from (stream, first_robot + r) only,
/// so a rollout draws the same whichever process drives it. A team's robot m draws from
/// env::member_seed(.., m) of the rollout's seeds, and the team's starts are apart
/// (env::draw_team_starts).
/// Floor i is `floors`' floor i (composed by the world's layout; its label the floor's).
RolloutBatch make_batch(const worlds::FloorSource& floors, std::span<const int> indices, int rollouts,
                        const worlds::World& world, const grid::FloorFrame& frame, std::uint64_t stream,
                        std::uint64_t first_robot = 0);
/// The same over the images themselves (today's floors).
inline RolloutBatch make_batch(const worlds::LabeledImages& data, std::span<const int> indices, int rollouts,
                               const worlds::World& world, const grid::FloorFrame& frame, std::uint64_t stream,
                               std::uint64_t first_robot = 0) {
  return make_batch(worlds::FloorSource::of_images(data), indices, rollouts, world, frame, stream, first_robot);
}

/// What one batch gave.
struct BatchOutcome {
  torch::Tensor objective;  ///< J-hat (scalar, with its graph when sampling.with_grad)
  torch::Tensor log_probs;  ///< log pi_c per rollout [rollouts, D] (detached)
  torch::Tensor reward;     ///< r per rollout [rollouts] (detached)
};

/// Drives the batch with the physics and the camera in the loop, classifies u_c = y after the
/// last move, and computes J-hat with `estimator`. A team is one rollout: one decision on the
/// team's y, and log pi the sum of its robots' (docs/SCENARIOS.md § Several robots).
BatchOutcome run_batch(agent::AgentImpl& agent, RolloutEngine& engine, AgentPolicy& policy, const RolloutBatch& batch,
                       const Sampling& sampling, const EstimatorOptions& estimator);

/// Clears every gradient of `module`: undefined, not zero. Adam skips a parameter without a
/// gradient but would keep moving one with a zero gradient on its momentum (a frozen layer, or an
/// action planner that no robot consulted in this batch).
void clear_gradients(torch::nn::Module& module);

// A training step has three parts, in the shape data-parallel training needs (the LibTorch
// distributed example): (1) forward and backward, (2) a hook on the gradients (an all-reduce
// across processes), (3) the optimizer's step. Trainer and the bench both run these.

/// The end of part (1): the loss's value and, when it is finite and has a graph, backward.
/// A NaN or infinite loss changes nothing (the caller stops); a loss without a graph (every layer
/// of the stage frozen) has nothing to differentiate.
double backward_if_finite(const torch::Tensor& loss);

/// Part (2): hands `hook` every trainable parameter's gradient flattened into one fp32 buffer
/// (parameter order; zeros for a parameter without a gradient) and writes the buffer back. A
/// parameter that had no gradient gets one only if its slice came back non-zero, so that Adam
/// still skips what no process used.
void apply_gradient_hook(torch::nn::Module& module, const std::function<void(std::span<float>)>& hook);

/// The L2 norm of all of `module`'s gradients together (those it has; summed in double).
double gradient_norm(torch::nn::Module& module);

/// The sampling of a training stage (ModeI..ModeIII): which layers choose, in `precision`.
Sampling sampling_for(Stage stage, bool with_grad, agent::Precision precision);

/// Per-robot correctness of a batch's predictions (argmax == label), and top-2.
int count_correct(const torch::Tensor& log_probs, std::span<const std::int64_t> labels, int top = 1);

}  // namespace scout::learn
