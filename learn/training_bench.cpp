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
#include "learn/distributed.hpp"
#include "learn/internal/agent_policy.hpp"
#include "learn/internal/objective.hpp"

namespace scout::learn {

namespace {

using core::Clock;
using core::seconds_since;

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
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
  const worlds::LabeledImages train = worlds::load_split(c.data_folder, worlds::Split::Train);
  if (train.images.count == 0) throw InputError(c.data_folder.string() + ": no training images");
  worlds::check_against_floor(c.world, train.images.cols, train.images.rows);
  const grid::FloorFrame frame{
      .width_px = train.images.cols, .height_px = train.images.rows, .pixel_size_m = c.world.floor.pixel_size_m};
  agent::NetworkConfig network = c.network;
  network.classes = std::max(2, *std::max_element(train.labels.begin(), train.labels.end()) + 1);
  network.image_channels = train.images.channels;
  const agent::Precision precision = agent::resolve_precision(c.precision);
  const int ranks = group ? group->size() : 1, rank = group ? group->rank() : 0;
  if (c.batch_images % ranks != 0)
    throw InputError(
        fmt::format("--batch: B = {} images do not divide evenly over {} processes", c.batch_images, ranks));
  // This rank's share of every batch's images.
  const int first = c.batch_images / ranks * rank, share = c.batch_images / ranks;
  const int robots = share * c.rollouts;
  report.robots = c.batch_images * c.rollouts;
  report.world_size = ranks;
  report.data_files = train.files;
  TrainConfig estimated = c;
  estimated.network = network;
  estimated.precision = precision;
  report.estimated_bytes = estimate_training_bytes(estimated, frame.width_px, frame.height_px, ranks);
  core::check_memory(report.estimated_bytes,
                     fmt::format("benchmarking B x N = {} x {} robots on {} x {} floors with these networks",
                                 c.batch_images, c.rollouts, frame.width_px, frame.height_px),
                     config.force_memory);
  RolloutEngine engine(c.world, frame, robots);
  const EstimatorOptions estimator{
      .rollouts_per_image = c.rollouts, .leave_one_out = c.leave_one_out, .entropy_bonus = c.entropy_bonus};

  for (Stage mode : config.modes) {
    // Fresh weights per mode, so that the figures do not depend on which modes ran before.
    torch::manual_seed(c.seed);
    agent::Agent agent(network);
    agent->train();
    torch::optim::Adam optimizer(agent->parameters(), torch::optim::AdamOptions(c.learning_rate));
    AgentPolicy policy(*agent, frame, c.world.camera.patch_px, robots);
    const Sampling sampling = sampling_for(mode, /*with_grad=*/true, precision);

    ModeBench bench;
    bench.mode = mode;
    std::vector<double> steps;
    core::Rng order(core::derive_seed(c.seed, static_cast<std::uint64_t>(mode)));
    for (int b = 0; b < config.warmup + config.batches; ++b) {
      stop.throw_if_requested();
      std::vector<int> indices(c.batch_images);
      for (int& i : indices)
        i = static_cast<int>(core::uniform_below(order, static_cast<std::uint64_t>(train.images.count)));
      const RolloutBatch batch =
          make_batch(train, std::span<const int>(indices).subspan(first, share), c.rollouts, c.world, frame,
                     core::derive_seed(c.seed, b), static_cast<std::uint64_t>(first) * c.rollouts);
      engine.reset_timing();
      policy.reset_timing();
      StepTimes t;
      const auto t0 = Clock::now();
      clear_gradients(*agent);
      const auto t_run = Clock::now();
      const BatchOutcome out = run_batch(*agent, engine, policy, batch, sampling, estimator);
      const double run_s = seconds_since(t_run);
      // The step's other parts as Trainer runs them: backward (of this rank's share, weighted),
      // the gradients summed over the ranks, Adam.
      const auto t_backward = Clock::now();
      const torch::Tensor loss =
          ranks > 1 ? -out.objective * (static_cast<double>(share) / c.batch_images) : -out.objective;
      if (!std::isfinite(backward_if_finite(loss)))
        throw std::runtime_error("bench train: the loss is not finite in mode " + std::string(to_string(mode)));
      const auto t_reduce = Clock::now();
      if (group)
        apply_gradient_hook(*agent, [&](std::span<float> gradients) {
          group->all_reduce_sum(gradients);
          report.all_reduce_bytes = static_cast<double>(gradients.size_bytes());
        });
      t.all_reduce_s = seconds_since(t_reduce);
      const auto t_step = Clock::now();
      optimizer.step();
      t.backward_s = std::chrono::duration<double>(t_reduce - t_backward).count();
      t.optimizer_s = seconds_since(t_step);
      t.total_s = seconds_since(t0);

      const RolloutTiming& rt = engine.timing();
      const PolicyTiming& pt = policy.timing();
      const double engine_s = rt.physics_s + rt.render_s + rt.other_s;
      t.physics_s = rt.physics_s;
      t.render_s = rt.render_s;
      // The engine's own bookkeeping (writing patches into y and h, the action protocol) counts
      // as state building; its "other" time also holds the policy's calls, split out here.
      t.state_s = pt.state_s + std::max(0.0, rt.other_s - pt.state_s - pt.forward_s);
      // Classifier, J-hat and everything in run_batch outside the rollout.
      t.forward_s = pt.forward_s + std::max(0.0, run_s - engine_s);
      if (b < config.warmup) continue;
      steps.push_back(t.total_s);
      bench.sum.physics_s += t.physics_s;
      bench.sum.render_s += t.render_s;
      bench.sum.state_s += t.state_s;
      bench.sum.forward_s += t.forward_s;
      bench.sum.backward_s += t.backward_s;
      bench.sum.optimizer_s += t.optimizer_s;
      bench.sum.all_reduce_s += t.all_reduce_s;
      bench.sum.total_s += t.total_s;
      bench.action_decisions += static_cast<double>(policy.action_decisions());
      ++bench.batches;
    }
    bench.median_step_s = median(steps);
    bench.images_per_s = c.batch_images / bench.median_step_s;
    bench.action_decisions /= bench.batches;
    report.modes.push_back(bench);
  }
  report.peak_bytes = core::peak_resident_bytes();
  return report;
}

}  // namespace scout::learn
