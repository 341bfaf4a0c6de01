#include "learn/training_bench.hpp"

#include <fmt/format.h>
#include <torch/torch.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "core/error.hpp"
#include "core/memory.hpp"
#include "core/random.hpp"
#include "core/timing.hpp"
#include "learn/auto_precision.hpp"
#include "learn/distributed.hpp"
#include "learn/internal/agent_policy.hpp"
#include "learn/internal/objective.hpp"

namespace scout::learn {

namespace {

using core::Clock;
using core::median;
using core::seconds_since;

// What every mode's bench shares: the training digits, the floor, the networks' shape and
// arithmetic, and this rank's share of every batch.
struct BenchSetup {
  worlds::LabeledImages train;
  worlds::FloorComposer composer{0, 0};  // the world's floor layout over the training images
  grid::FloorFrame frame{.width_px = 0, .height_px = 0, .pixel_size_m = 0};
  agent::NetworkConfig network;
  agent::Precision precision = agent::Precision::Float32;
  int ranks = 1, first = 0, share = 0, robots = 0;
};

BenchSetup gather_bench(const TrainBenchConfig& config, ProcessGroup* group, TrainBenchReport& report) {
  const TrainConfig& c = config.train;
  BenchSetup b;
  b.train = worlds::load_split(c.data_folder, worlds::Split::Train);
  const worlds::LabeledImages& train = b.train;
  if (train.images.count == 0) throw InputError(c.data_folder.string() + ": no training images");
  b.composer = worlds::FloorComposer(c.world, train.images.cols, train.images.rows);
  worlds::check_against_floor(c.world, b.composer.width_px(), b.composer.height_px());
  b.frame = {.width_px = b.composer.width_px(),
             .height_px = b.composer.height_px(),
             .pixel_size_m = c.world.floor.pixel_size_m};
  b.network = c.network;
  b.network.classes = std::max(2, b.composer.classes(*std::max_element(train.labels.begin(), train.labels.end()) + 1));
  b.network.image_channels = train.images.channels;
  b.precision = resolve_precision(c.precision);
  b.ranks = group ? group->size() : 1;
  const int rank = group ? group->rank() : 0;
  if (c.batch_images % b.ranks != 0)
    throw InputError(
        fmt::format("--batch: B = {} images do not divide evenly over {} processes", c.batch_images, b.ranks));
  // This rank's share of every batch's images.
  b.first = c.batch_images / b.ranks * rank;
  b.share = c.batch_images / b.ranks;
  b.robots = b.share * c.rollouts * c.world.team.robots;
  report.robots = c.batch_images * c.rollouts * c.world.team.robots;
  report.world_size = b.ranks;
  report.data_files = train.files;
  TrainConfig estimated = c;
  estimated.network = b.network;
  estimated.precision = b.precision;
  report.estimated_bytes = estimate_training_bytes(estimated, b.frame.width_px, b.frame.height_px, b.ranks);
  core::check_memory(report.estimated_bytes,
                     fmt::format("benchmarking B x N = {} x {} robots on {} x {} floors with these networks",
                                 c.batch_images, c.rollouts, b.frame.width_px, b.frame.height_px),
                     config.force_memory);
  return b;
}

// The networks, Adam and the policy of one mode's bench: fresh weights per mode, so that the
// figures do not depend on which modes ran before.
struct ModeState {
  agent::Agent agent{nullptr};
  std::unique_ptr<torch::optim::Adam> optimizer;
  std::unique_ptr<AgentPolicy> policy;
};

// One training step timed as Trainer runs it: the rollouts and J-hat, backward (of this rank's
// share, weighted), the gradients summed over the ranks, Adam.
StepTimes time_step(const TrainConfig& c, const BenchSetup& b, const RolloutBatch& batch, Stage mode,
                    const Sampling& sampling, RolloutEngine& engine, ModeState& m, ProcessGroup* group,
                    TrainBenchReport& report) {
  const EstimatorOptions estimator{.rollouts_per_image = c.rollouts,
                                   .leave_one_out = c.leave_one_out,
                                   .entropy_bonus = c.entropy_bonus,
                                   .distillation = c.distillation,
                                   .stalled_move_cost = c.stalled_move_cost};
  agent::AgentImpl& agent = *m.agent;
  engine.reset_timing();
  m.policy->reset_timing();
  StepTimes t;
  const auto t0 = Clock::now();
  clear_gradients(agent);
  const auto t_run = Clock::now();
  const BatchOutcome out = run_batch(agent, engine, *m.policy, batch, sampling, estimator);
  const double run_s = seconds_since(t_run);
  const auto t_backward = Clock::now();
  const torch::Tensor loss =
      b.ranks > 1 ? -out.objective * (static_cast<double>(b.share) / c.batch_images) : -out.objective;
  if (!std::isfinite(backward_if_finite(loss)))
    throw std::runtime_error("bench train: the loss is not finite in mode " + std::string(to_string(mode)));
  const auto t_reduce = Clock::now();
  if (group)
    apply_gradient_hook(agent, [&](std::span<float> gradients) {
      group->all_reduce_sum(gradients);
      report.all_reduce_bytes = static_cast<double>(gradients.size_bytes());
    });
  t.all_reduce_s = seconds_since(t_reduce);
  const auto t_step = Clock::now();
  m.optimizer->step();
  t.backward_s = std::chrono::duration<double>(t_reduce - t_backward).count();
  t.optimizer_s = seconds_since(t_step);
  t.total_s = seconds_since(t0);

  const RolloutTiming& rt = engine.timing();
  const PolicyTiming& pt = m.policy->timing();
  const double other_s = rt.env.observe_s + rt.other_s;
  const double engine_s = rt.env.physics_s + rt.env.render_s + other_s;
  t.physics_s = rt.env.physics_s;
  t.render_s = rt.env.render_s;
  // The engine's own bookkeeping (writing patches into y and h, the action protocol) counts
  // as state building; its "other" time also holds the policy's calls, split out here.
  t.state_s = pt.state_s + std::max(0.0, other_s - pt.state_s - pt.forward_s);
  // Classifier, J-hat and everything in run_batch outside the rollout.
  t.forward_s = pt.forward_s + std::max(0.0, run_s - engine_s);
  return t;
}

void add_step(const StepTimes& t, ModeBench& bench) {
  bench.sum.physics_s += t.physics_s;
  bench.sum.render_s += t.render_s;
  bench.sum.state_s += t.state_s;
  bench.sum.forward_s += t.forward_s;
  bench.sum.backward_s += t.backward_s;
  bench.sum.optimizer_s += t.optimizer_s;
  bench.sum.all_reduce_s += t.all_reduce_s;
  bench.sum.total_s += t.total_s;
}

ModeBench bench_mode(const TrainBenchConfig& config, const BenchSetup& b, Stage mode, RolloutEngine& engine,
                     const core::StopToken& stop, ProcessGroup* group, TrainBenchReport& report) {
  const TrainConfig& c = config.train;
  ModeState m;
  torch::manual_seed(c.seed);
  m.agent = agent::Agent(b.network);
  m.agent->train();
  m.optimizer = std::make_unique<torch::optim::Adam>(m.agent->parameters(), torch::optim::AdamOptions(c.learning_rate));
  m.policy = std::make_unique<AgentPolicy>(*m.agent, b.frame, c.world.camera.patch_px, b.robots);
  const Sampling sampling = sampling_for(mode, /*with_grad=*/true, b.precision);

  ModeBench bench;
  bench.mode = mode;
  std::vector<double> steps;
  core::Rng order(core::derive_seed(c.seed, static_cast<std::uint64_t>(mode)));
  for (int k = 0; k < config.warmup + config.batches; ++k) {
    stop.throw_if_requested();
    std::vector<int> indices(c.batch_images);
    for (int& i : indices)
      i = static_cast<int>(core::uniform_below(order, static_cast<std::uint64_t>(b.train.images.count)));
    const RolloutBatch batch = make_batch(
        worlds::FloorSource{&b.train, b.composer, c.seed}, std::span<const int>(indices).subspan(b.first, b.share),
        c.rollouts, c.world, b.frame, core::derive_seed(c.seed, k), static_cast<std::uint64_t>(b.first) * c.rollouts);
    const StepTimes t = time_step(c, b, batch, mode, sampling, engine, m, group, report);
    if (k < config.warmup) continue;
    steps.push_back(t.total_s);
    add_step(t, bench);
    bench.action_decisions += static_cast<double>(m.policy->action_decisions());
    ++bench.batches;
  }
  bench.median_step_s = median(steps);
  bench.images_per_s = c.batch_images / bench.median_step_s;
  bench.action_decisions /= bench.batches;
  return bench;
}

}  // namespace

TrainBenchReport bench_training(const TrainBenchConfig& config, const core::StopToken& stop, ProcessGroup* group) {
  const TrainConfig& c = config.train;
  c.validate();
  if (config.batches < 1) throw InputError("--batches: expected a positive integer");
  if (config.warmup < 0) throw InputError("--warmup: expected a non-negative integer");
  for (Stage s : config.modes)
    if (s == Stage::Pretrain)
      throw InputError("--modes: expected i, ii or iii (full-image pretraining has no rollouts)");

  TrainBenchReport report;
  report.threads = set_torch_threads(config.threads);
  const BenchSetup setup = gather_bench(config, group, report);
  RolloutEngine engine(c.world, setup.frame, setup.robots);
  for (Stage mode : config.modes) report.modes.push_back(bench_mode(config, setup, mode, engine, stop, group, report));
  report.peak_bytes = core::peak_resident_bytes();
  return report;
}

}  // namespace scout::learn
