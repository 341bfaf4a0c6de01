#pragma once
/// The generalized policy gradient's estimator with the unified reward (METHOD.md § The
/// estimator). Torch header: include from learn/ sources and tests only.
#include <torch/torch.h>

#include "learn/internal/private.hpp"

namespace scout::learn {

/// Options beyond the paper (both off in the paper preset).
struct EstimatorOptions {
  int rollouts_per_image = 4;  ///< N: robots i*N .. i*N+N-1 drove over image i
  bool leave_one_out = false;  ///< subtract the mean reward of the image's other N-1 rollouts from sg(r)
  double entropy_bonus = 0;  ///< beta: adds beta * (mean over robots of the summed entropies of its learned decisions)
  /// lambda: adds lambda * (mean over robots of sum_c p_full(c) log pi_c(c)), p_full the classifier's
  /// own probabilities on the whole floor without gradient: a teacher that sees everything (run_batch).
  double distillation = 0;
  /// kappa: each move of the rollout that did not arrive (blocked by an obstacle or a teammate,
  /// RolloutEngine::stalled_moves) costs kappa in the planners' reward: r' = r - kappa * stalled.
  double stalled_move_cost = 0;
};

/// J-hat = mean over robots of [log_pi * sg(r - cost - b) + r] (+ beta * entropy), b = 0 or the
/// leave-one-out baseline of r - cost. log_pi, entropy and cost may be undefined (no learned
/// layer; no cost). The loss is -J-hat.
/// reward: [B*N] = log pi_c[label], with its graph to the classifier; cost: [B*N], what each
/// rollout's moves cost the planners (not the classifier, whose term stays r).
torch::Tensor surrogate_objective(const torch::Tensor& log_pi, const torch::Tensor& reward,
                                  const EstimatorOptions& options, const torch::Tensor& entropy = {},
                                  const torch::Tensor& cost = {});

}  // namespace scout::learn
