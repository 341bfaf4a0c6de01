#pragma once
#ifndef SCOUT_LEARN_INTERNAL
#error "learn/internal/ is private to scout_learn and its tests (CMake target scout_learn_internal); include learn/*.hpp"
#endif
/// One batch of rollouts through the agent, ending in the classifier's verdict and J-hat: the
/// step that training, evaluation and the estimator test share. Torch header: learn/ and tests.
#include <torch/torch.h>

#include <cstdint>
#include <span>
#include <vector>

#include "learn/internal/agent_policy.hpp"
#include "learn/internal/estimator.hpp"
#include "learn/rollout.hpp"
#include "learn/training.hpp"
#include "worlds/dataset.hpp"

namespace scout::learn {

/// The robots of one batch: robot r drives over floors[r] from starts[r], sampling with seeds[r].
struct RolloutBatch {
  int count = 0;
  std::vector<std::uint8_t> floors;  ///< count * H * W bytes
  std::vector<std::int64_t> labels;  ///< one per robot
  std::vector<grid::Cell> starts;
  std::vector<std::uint64_t> seeds;
};

/// N robots per image: robot i*N + k drives over image indices[i]. Robot r's start and sampling
/// seed derive from (stream, r) only, so a batch is reproducible from its stream seed.
RolloutBatch make_batch(const worlds::LabeledImages& data, std::span<const int> indices, int rollouts,
                        const worlds::World& world, const grid::FloorFrame& frame, std::uint64_t stream);

/// What one batch gave.
struct BatchOutcome {
  torch::Tensor objective;  ///< J-hat (scalar, with its graph when sampling.with_grad)
  torch::Tensor log_probs;  ///< log pi_c per robot [count, D] (detached)
  torch::Tensor reward;     ///< r per robot [count] (detached)
};

/// Drives the batch with the physics and the camera in the loop, classifies u_c = y after the
/// last move, and computes J-hat with `estimator`.
BatchOutcome run_batch(agent::AgentImpl& agent, RolloutEngine& engine, AgentPolicy& policy, const RolloutBatch& batch,
                       const Sampling& sampling, const EstimatorOptions& estimator);

/// Clears every gradient of `module`: undefined, not zero. Adam skips a parameter without a
/// gradient but would keep moving one with a zero gradient on its momentum (a frozen layer, or an
/// action planner that no robot consulted in this batch).
void clear_gradients(torch::nn::Module& module);

/// Seconds in the two halves of an optimisation step (scout bench train).
struct DescentSeconds {
  double backward_s = 0;
  double optimizer_s = 0;
};

/// The end of a training step: `value` gets the loss; when it is finite, backward and one
/// optimizer step follow (nothing to do when no layer is trainable: the loss has no graph).
/// Returns false, having changed nothing, for a NaN or infinite loss.
bool descend(const torch::Tensor& loss, torch::optim::Optimizer& optimizer, double& value,
             DescentSeconds* seconds = nullptr);

/// The sampling of a training stage (ModeI..ModeIII): which layers choose, in `precision`.
Sampling sampling_for(Stage stage, bool with_grad, agent::Precision precision);

/// Per-robot correctness of a batch's predictions (argmax == label), and top-2.
int count_correct(const torch::Tensor& log_probs, std::span<const std::int64_t> labels, int top = 1);

}  // namespace scout::learn
