#include "learn/internal/objective.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "core/seed_streams.hpp"
#include "env/runs.hpp"
#include "learn/internal/precision.hpp"

namespace scout::learn {

void RolloutBatch::append(const RolloutBatch& other) {
  if (count > 0 && other.team != team) throw std::invalid_argument("RolloutBatch::append: another team size");
  team = other.team;
  count += other.count;
  floors.insert(floors.end(), other.floors.begin(), other.floors.end());
  labels.insert(labels.end(), other.labels.begin(), other.labels.end());
  starts.insert(starts.end(), other.starts.begin(), other.starts.end());
  seeds.insert(seeds.end(), other.seeds.begin(), other.seeds.end());
  motion_seeds.insert(motion_seeds.end(), other.motion_seeds.begin(), other.motion_seeds.end());
}

RolloutBatch make_batch(const worlds::FloorSource& floors, std::span<const int> indices, int rollouts,
                        const worlds::World& world, const grid::FloorFrame& frame, std::uint64_t stream,
                        std::uint64_t first_robot) {
  if (rollouts <= 0) throw std::invalid_argument("make_batch: rollouts must be positive");
  RolloutBatch batch;
  batch.team = world.team.robots;
  const int K = batch.team;
  const int teams = static_cast<int>(indices.size()) * rollouts;
  batch.count = teams * K;
  const auto area = static_cast<std::size_t>(frame.area_px());
  if (floors.width_px() != frame.width_px || floors.height_px() != frame.height_px)
    throw std::invalid_argument("make_batch: the floors' size differs from the frame's");
  batch.floors.resize(area * batch.count);
  batch.labels.resize(teams);
  batch.starts.resize(batch.count);
  batch.seeds.resize(batch.count);
  batch.motion_seeds.resize(batch.count);
  for (std::size_t i = 0; i < indices.size(); ++i) {
    const int image = indices[i];
    if (image < 0 || image >= floors.count()) throw std::out_of_range("make_batch: image index out of range");
    // The image's floor, composed once; its N rollouts and a team's K robots drive over copies.
    const std::size_t first_row = i * rollouts * K;
    const int label = floors.floor(image, std::span(batch.floors.data() + area * first_row, area));
    for (int k = 0; k < rollouts; ++k) {
      const std::size_t t = i * rollouts + k;
      batch.labels[t] = label;
      const std::uint64_t robot_seed = core::derive_seed(stream, first_robot + t);
      const std::uint64_t policy_seed = core::derive_seed(robot_seed, streams::kRobotPolicy);
      const std::uint64_t motion_seed = core::derive_seed(robot_seed, streams::kRobotMotion);
      core::Rng start_rng(core::derive_seed(robot_seed, streams::kRobotStart));
      const std::vector<grid::Cell> starts = env::draw_team_starts(world, frame, motion_seed, start_rng);
      for (int m = 0; m < K; ++m) {
        const std::size_t r = t * K + m;
        if (r != first_row) std::copy_n(batch.floors.data() + area * first_row, area, batch.floors.data() + area * r);
        batch.seeds[r] = env::member_seed(policy_seed, m);
        batch.motion_seeds[r] = env::member_seed(motion_seed, m);
        batch.starts[r] = starts[m];
      }
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
  const int rollouts = batch.rollouts();
  // A team's robots hold the same y (the team's): its first robot's is classified.
  torch::Tensor images = revealed_images(engine.state(), batch.count);
  if (batch.team > 1) images = images.slice(0, 0, batch.count, batch.team);
  torch::Tensor log_probs = classifier_log_probs(agent, images, sampling.precision);
  // A copy: autograd keeps the index for backward, which may run after `batch` is gone.
  torch::Tensor labels =
      torch::from_blob(const_cast<std::int64_t*>(batch.labels.data()), {rollouts, 1}, torch::kLong).clone();
  torch::Tensor reward = log_probs.gather(1, labels).squeeze(1);
  const bool learned = sampling.learned_goals || sampling.learned_actions;
  // The team's joint log-probability and entropy: its robots choose independently given the state.
  auto per_rollout = [&](const torch::Tensor& per_robot) {
    return batch.team > 1 ? per_robot.view({rollouts, batch.team}).sum(1) : per_robot;
  };
  torch::Tensor cost;
  if (learned && estimator.stalled_move_cost > 0) {
    const std::span<const int> stalled = engine.stalled_moves();
    cost = torch::tensor(std::vector<float>(stalled.begin(), stalled.end())) * estimator.stalled_move_cost;
    cost = per_rollout(cost);
  }
  torch::Tensor objective =
      surrogate_objective(learned ? per_rollout(policy.log_pi()) : torch::Tensor(), reward, estimator,
                          learned ? per_rollout(policy.entropy()) : torch::Tensor(), cost);
  if (estimator.distillation > 0 && sampling.with_grad) {
    // The teacher: the classifier on the whole floor (what u_c would be had the robot seen it all),
    // without gradient; the student: the same classifier on what the rollout revealed.
    torch::Tensor teacher;
    {
      const torch::NoGradGuard no_teacher_gradient;
      torch::Tensor floors = full_images(batch.floors, batch.count, engine.state().frame);
      if (batch.team > 1) floors = floors.slice(0, 0, batch.count, batch.team);
      teacher = classifier_log_probs(agent, floors, sampling.precision).exp();
    }
    objective = objective + estimator.distillation * (teacher * log_probs).sum(1).mean();
  }
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
