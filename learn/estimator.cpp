#include "learn/internal/estimator.hpp"

#include <stdexcept>
#include <string>

namespace scout::learn {

torch::Tensor surrogate_objective(const torch::Tensor& log_pi, const torch::Tensor& reward,
                                  const EstimatorOptions& options, const torch::Tensor& entropy,
                                  const torch::Tensor& cost) {
  if (reward.dim() != 1) throw std::invalid_argument("surrogate_objective: reward must be one value per robot");
  const int64_t robots = reward.size(0), n = options.rollouts_per_image;
  if (n <= 0 || robots % n != 0)
    throw std::invalid_argument("surrogate_objective: " + std::to_string(robots) +
                                " robots are not a multiple of N = " + std::to_string(n));
  if (options.leave_one_out && n < 2) throw std::invalid_argument("surrogate_objective: the baseline needs N >= 2");
  // sg(r): the REINFORCE weight carries no gradient; the second r term trains the classifier.
  torch::Tensor weight = reward.detach();
  if (cost.defined()) weight = weight - cost.detach();
  if (options.leave_one_out) {
    torch::Tensor per_image = weight.view({robots / n, n});
    torch::Tensor others_mean = (per_image.sum(1, true) - per_image) / static_cast<double>(n - 1);
    weight = (per_image - others_mean).view({robots});
  }
  torch::Tensor objective = reward;
  if (log_pi.defined()) objective = objective + log_pi * weight;
  if (options.entropy_bonus != 0 && entropy.defined()) objective = objective + options.entropy_bonus * entropy;
  return objective.mean();
}

}  // namespace scout::learn
