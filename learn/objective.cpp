#include "learn/internal/objective.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "core/seed_streams.hpp"
#include "env/runs.hpp"
#include "learn/internal/precision.hpp"

namespace scout::learn {

RolloutBatch make_batch(const worlds::LabeledImages& data, std::span<const int> indices, int rollouts,
                        const worlds::World& world, const grid::FloorFrame& frame, std::uint64_t stream,
                        std::uint64_t first_robot) {
  if (rollouts <= 0) throw std::invalid_argument("make_batch: rollouts must be positive");
  RolloutBatch batch;
  batch.count = static_cast<int>(indices.size()) * rollouts;
  const auto area = static_cast<std::size_t>(frame.area_px());
  batch.floors.resize(area * batch.count);
  batch.labels.resize(batch.count);
  batch.starts.resize(batch.count);
  batch.seeds.resize(batch.count);
  batch.motion_seeds.resize(batch.count);
  for (std::size_t i = 0; i < indices.size(); ++i) {
    const int image = indices[i];
    if (image < 0 || image >= data.images.count) throw std::out_of_range("make_batch: image index out of range");
    for (int k = 0; k < rollouts; ++k) {
      const std::size_t r = i * rollouts + k;
      std::copy_n(data.images.image(image), area, batch.floors.data() + area * r);
      batch.labels[r] = data.labels[image];
      const std::uint64_t robot_seed = core::derive_seed(stream, first_robot + r);
      batch.seeds[r] = core::derive_seed(robot_seed, streams::kRobotPolicy);
      batch.motion_seeds[r] = core::derive_seed(robot_seed, streams::kRobotMotion);
      core::Rng start_rng(core::derive_seed(robot_seed, streams::kRobotStart));
      batch.starts[r] = env::draw_start(world, frame, batch.motion_seeds[r], start_rng);
    }
  }
  return batch;
}

BatchOutcome run_batch(agent::AgentImpl& agent, RolloutEngine& engine, AgentPolicy& policy, const RolloutBatch& batch,
                       const Sampling& sampling, const EstimatorOptions& estimator) {
  // One guard for the whole batch, so that each weight is cast to bf16 once, not once per move.
  const ComputePrecision precision(sampling.precision);
  policy.begin(batch.seeds, sampling);
  engine.run(batch.floors, batch.starts, batch.motion_seeds, policy, /*record=*/false);
  std::optional<torch::NoGradGuard> no_grad;
  if (!sampling.with_grad) no_grad.emplace();
  torch::Tensor log_probs =
      classifier_log_probs(agent, revealed_images(engine.state(), batch.count), sampling.precision);
  // A copy: autograd keeps the index for backward, which may run after `batch` is gone.
  torch::Tensor labels =
      torch::from_blob(const_cast<std::int64_t*>(batch.labels.data()), {batch.count, 1}, torch::kLong).clone();
  torch::Tensor reward = log_probs.gather(1, labels).squeeze(1);
  const bool learned = sampling.learned_goals || sampling.learned_actions;
  torch::Tensor objective = surrogate_objective(learned ? policy.log_pi() : torch::Tensor(), reward, estimator,
                                                learned ? policy.entropy() : torch::Tensor());
  return {objective, log_probs.detach(), reward.detach()};
}

void clear_gradients(torch::nn::Module& module) {
  for (torch::Tensor& p : module.parameters()) p.mutable_grad() = torch::Tensor();
}

double backward_if_finite(const torch::Tensor& loss) {
  const double value = loss.item<double>();
  if (std::isfinite(value) && loss.requires_grad()) loss.backward();
  return value;
}

void apply_gradient_hook(torch::nn::Module& module, const std::function<void(std::span<float>)>& hook) {
  std::vector<torch::Tensor> trainable;
  std::int64_t total = 0;
  for (const torch::Tensor& p : module.parameters())
    if (p.requires_grad()) {
      trainable.push_back(p);
      total += p.numel();
    }
  torch::Tensor flat = torch::zeros({total}, torch::kFloat32);
  std::int64_t offset = 0;
  for (const torch::Tensor& p : trainable) {
    if (p.grad().defined()) flat.narrow(0, offset, p.numel()).copy_(p.grad().reshape({-1}));
    offset += p.numel();
  }
  hook(std::span<float>(flat.data_ptr<float>(), static_cast<std::size_t>(total)));
  offset = 0;
  for (torch::Tensor& p : trainable) {
    const torch::Tensor slice = flat.narrow(0, offset, p.numel()).view(p.sizes());
    if (p.grad().defined()) {
      p.mutable_grad().copy_(slice);
    } else if (slice.ne(0).any().item<bool>()) {
      p.mutable_grad() = slice.clone();
    }
    offset += p.numel();
  }
}

double gradient_norm(torch::nn::Module& module) {
  double squares = 0;
  for (const torch::Tensor& p : module.parameters())
    if (p.grad().defined()) squares += p.grad().square().sum(torch::kDouble).item<double>();
  return std::sqrt(squares);
}

Sampling sampling_for(Stage stage, bool with_grad, agent::Precision precision) {
  Sampling s;
  s.precision = precision;
  s.learned_goals = stage == Stage::ModeII || stage == Stage::ModeIII;
  s.learned_actions = stage == Stage::ModeIII;
  s.with_grad = with_grad;
  return s;
}

int count_correct(const torch::Tensor& log_probs, std::span<const std::int64_t> labels, int top) {
  torch::Tensor best = std::get<1>(log_probs.topk(top, 1)).contiguous();  // [count, top]
  const std::int64_t* b = best.data_ptr<std::int64_t>();
  int correct = 0;
  for (std::size_t r = 0; r < labels.size(); ++r)
    correct += std::count(b + r * top, b + (r + 1) * top, labels[r]) > 0 ? 1 : 0;
  return correct;
}

}  // namespace scout::learn
