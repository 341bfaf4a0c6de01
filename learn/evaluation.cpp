// Evaluation (METHOD.md § Evaluation): R stochastic runs of the checkpoint's policy over a set of
// digits with the physics and the camera in the loop, the two random baselines, the classifier on
// full images and one greedy run.
#include "learn/evaluation.hpp"

#include <fmt/format.h>
#include <torch/torch.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "core/error.hpp"
#include "core/random.hpp"
#include "core/seed_streams.hpp"
#include "core/timing.hpp"
#include "learn/distributed.hpp"
#include "learn/internal/agent_policy.hpp"
#include "learn/internal/checkpoint.hpp"
#include "learn/internal/objective.hpp"
#include "learn/internal/precision.hpp"
#include "learn/trained_agent.hpp"
#include "worlds/dataset.hpp"
#include "worlds/floors.hpp"
#include "worlds/idx.hpp"

namespace scout::learn {

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;

namespace {

// The continued fraction of the regularized incomplete beta I_x(a, b), evaluated by the modified
// Lentz method (as Numerical Recipes' betacf).
double beta_continued_fraction(double a, double b, double x) {
  constexpr double kTiny = 1e-300;
  const double qab = a + b, qap = a + 1, qam = a - 1;
  double c = 1, d = 1 - qab * x / qap;
  if (std::abs(d) < kTiny) d = kTiny;
  d = 1 / d;
  double h = d;
  for (int m = 1; m <= 10000; ++m) {
    const double m2 = 2.0 * m;
    double aa = m * (b - m) * x / ((qam + m2) * (a + m2));
    d = 1 + aa * d;
    if (std::abs(d) < kTiny) d = kTiny;
    c = 1 + aa / c;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1 / d;
    h *= d * c;
    aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
    d = 1 + aa * d;
    if (std::abs(d) < kTiny) d = kTiny;
    c = 1 + aa / c;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1 / d;
    const double delta = d * c;
    h *= delta;
    if (std::abs(delta - 1) < 1e-15) break;
  }
  return h;
}

// The regularized incomplete beta function I_x(a, b), x in [0, 1].
double incomplete_beta(double a, double b, double x) {
  if (x <= 0) return 0;
  if (x >= 1) return 1;
  const double front =
      std::exp(std::lgamma(a + b) - std::lgamma(a) - std::lgamma(b) + a * std::log(x) + b * std::log1p(-x));
  // The continued fraction converges fast for x < (a + 1) / (a + b + 2); use the symmetry beyond.
  if (x < (a + 1) / (a + b + 2)) return front * beta_continued_fraction(a, b, x) / a;
  return 1 - front * beta_continued_fraction(b, a, 1 - x) / b;
}

struct Data {
  worlds::LabeledImages set;
  grid::FloorFrame frame;
};

Data read_data(const EvalConfig& config, const worlds::World& world, int classes) {
  Data d;
  d.set.images = worlds::read_idx_images(config.images);
  d.set.labels = worlds::read_idx_labels(config.labels);
  d.set.files = {config.images, config.labels};
  if (config.image_limit < 0)
    throw InputError(fmt::format("image_limit: expected 0 (all) or a positive count, got {}", config.image_limit));
  const std::string images = config.images.string(), labels = config.labels.string();
  if (d.set.images.count == 0) throw InputError(images + ": expected at least one image, the file has none");
  if (d.set.labels.size() != static_cast<std::size_t>(d.set.images.count))
    throw InputError(fmt::format("{}: expected {} labels (one per image of {}), got {}", labels, d.set.images.count,
                                 images, d.set.labels.size()));
  if (config.image_limit > 0 && config.image_limit < d.set.images.count) {
    d.set.images.count = config.image_limit;
    d.set.images.pixels.resize(static_cast<std::size_t>(config.image_limit) * d.set.images.rows * d.set.images.cols);
    d.set.labels.resize(static_cast<std::size_t>(config.image_limit));
  }
  for (std::size_t i = 0; i < d.set.labels.size(); ++i)
    if (d.set.labels[i] >= classes)
      throw InputError(
          fmt::format("{}: label {} at index {}: expected a class in 0..{} (the checkpoint's network has "
                      "{} classes)",
                      labels, static_cast<int>(d.set.labels[i]), i, classes - 1, classes));
  // The networks are fully convolutional, so any floor size works that the camera can hold and
  // the world's patch and start fit.
  if (d.set.images.cols > worlds::kMaxFloorPx || d.set.images.rows > worlds::kMaxFloorPx)
    throw InputError(fmt::format("{}: expected images of at most {} x {} pixels, got {} x {}", images,
                                 worlds::kMaxFloorPx, worlds::kMaxFloorPx, d.set.images.cols, d.set.images.rows));
  worlds::check_against_floor(world, d.set.images.cols, d.set.images.rows);
  d.frame = {.width_px = d.set.images.cols, .height_px = d.set.images.rows, .pixel_size_m = world.floor.pixel_size_m};
  return d;
}

// What one pass over all images gave: per image, log pi_c.
struct Pass {
  int correct = 0, top2 = 0;
  long revealed_px = 0;     // summed over the images: pixels seen by the end of the rollout
  torch::Tensor log_probs;  // [images, D]
};

class Evaluator {
 public:
  // `images`: the most images this process evaluates (its share).
  Evaluator(agent::AgentImpl& agent, const worlds::World& world, const Data& data, int batch_robots, int images,
            agent::Precision precision, core::StopToken stop, std::function<void(int)> on_batch)
      : agent_(agent),
        world_(world),
        data_(data),
        precision_(precision),
        stop_(std::move(stop)),
        on_batch_(std::move(on_batch)) {
    const int robots = std::max(1, std::min(batch_robots, images));
    try {
      engine_ = std::make_unique<RolloutEngine>(world, data.frame, robots);
    } catch (const std::runtime_error& e) {
      throw InputError(std::string("the camera cannot start: ") + one_line(e.what()));
    }
    policy_ = std::make_unique<AgentPolicy>(agent, data.frame, world.camera.patch_px, robots);
    batch_ = robots;
  }

  // One rollout per image of [begin, end). Image i's start and choices derive from
  // (stream_seed, i) alone, so a run's figures do not depend on how the images are split into
  // batches or over processes.
  Pass run(const Sampling& sampling, std::uint64_t stream_seed, int begin, int end) {
    Pass pass;
    std::vector<torch::Tensor> parts;
    for (int first = begin; first < end; first += batch_) {
      stop_.throw_if_requested();
      const int k = std::min(batch_, end - first);
      RolloutBatch batch;
      for (int image = first; image < first + k; ++image) {
        const RolloutBatch one = make_batch(data_.set, std::span(&image, 1), 1, world_, data_.frame,
                                            core::derive_seed(stream_seed, static_cast<std::uint64_t>(image)));
        batch.floors.insert(batch.floors.end(), one.floors.begin(), one.floors.end());
        batch.labels.push_back(one.labels[0]);
        batch.starts.push_back(one.starts[0]);
        batch.seeds.push_back(one.seeds[0]);
      }
      batch.count = k;
      const BatchOutcome out = run_batch(agent_, *engine_, *policy_, batch, sampling,
                                         {.rollouts_per_image = 1, .leave_one_out = false, .entropy_bonus = 0});
      for (int i = 0; i < k; ++i) pass.revealed_px += engine_->state().seen[static_cast<std::size_t>(i)].count();
      pass.correct += count_correct(out.log_probs, batch.labels, 1);
      pass.top2 += count_correct(out.log_probs, batch.labels, std::min(2, agent_.config().classes));
      parts.push_back(out.log_probs);
      if (on_batch_) on_batch_(k);
    }
    pass.log_probs = parts.empty() ? torch::zeros({0, agent_.config().classes}) : torch::cat(parts, 0);
    return pass;
  }

  // The classifier on the full images of [begin, end) (u_c = x).
  int full_image_correct(int begin, int end) {
    const auto area = static_cast<std::size_t>(data_.frame.area_px());
    int correct = 0;
    for (int first = begin; first < end; first += batch_) {
      stop_.throw_if_requested();
      const int k = std::min(batch_, end - first);
      torch::Tensor x = full_images(std::span(data_.set.images.image(first), area * k), k, data_.frame);
      const std::vector<std::int64_t> labels(data_.set.labels.begin() + first, data_.set.labels.begin() + first + k);
      correct += count_correct(classifier_log_probs(agent_, x, precision_), labels, 1);
    }
    return correct;
  }

 private:
  agent::AgentImpl& agent_;
  const worlds::World& world_;
  const Data& data_;
  agent::Precision precision_;
  core::StopToken stop_;
  std::function<void(int)> on_batch_;  // after each rollout batch: its robots
  std::unique_ptr<RolloutEngine> engine_;
  std::unique_ptr<AgentPolicy> policy_;
  int batch_ = 1;
};

double mean_of(const std::vector<double>& v) {
  double sum = 0;
  for (double x : v) sum += x;
  return v.empty() ? 0 : sum / static_cast<double>(v.size());
}

}  // namespace

double student_t_975(int dof) {
  if (dof < 1) throw std::invalid_argument("student_t_975: dof must be at least 1, got " + std::to_string(dof));
  // P(|T| > t) = I_{v / (v + t^2)}(v / 2, 1 / 2), decreasing in t; the 97.5 % quantile is where
  // it is 0.05. Bisection to double precision (the tail at t = 1e3 is below 0.05 for every dof).
  const double v = dof;
  double lo = 0, hi = 1000;
  for (int i = 0; i < 200 && hi - lo > 1e-13 * hi; ++i) {
    const double t = 0.5 * (lo + hi);
    const double tail = incomplete_beta(v / 2, 0.5, v / (v + t * t));
    (tail > 0.05 ? lo : hi) = t;
  }
  return 0.5 * (lo + hi);
}

Interval mean_ci95(std::span<const double> values) {
  Interval out;
  const std::size_t r = values.size();
  if (r == 0) return out;
  double sum = 0;
  for (double x : values) sum += x;
  out.mean = sum / static_cast<double>(r);
  // Equal values: exactly 0 (the mean can differ from them in the last bit).
  if (r == 1 || std::all_of(values.begin(), values.end(), [&](double x) { return x == values[0]; })) {
    if (r > 1) out.mean = values[0];
    return out;
  }
  double squares = 0;
  for (double x : values) squares += (x - out.mean) * (x - out.mean);
  const double sd = std::sqrt(squares / static_cast<double>(r - 1));
  out.ci95 = student_t_975(static_cast<int>(r - 1)) * sd / std::sqrt(static_cast<double>(r));
  return out;
}

EvalReport evaluate(const EvalConfig& config, const core::StopToken& stop, ProcessGroup* group) {
  const auto t0 = core::Clock::now();
  if (config.runs < 1) throw InputError(fmt::format("--runs: expected a positive integer, got {}", config.runs));
  if (config.batch_robots < 1)
    throw std::invalid_argument("evaluate: batch_robots must be positive, got " + std::to_string(config.batch_robots));
  CheckpointState state;
  agent::Agent agent = load_agent(config.checkpoint, &state);
  const std::string checkpoint = config.checkpoint.string();
  const agent::NetworkConfig& network = state.config.network;
  if (network.image_channels != worlds::ImageSet::channels)
    throw InputError(fmt::format("{}: network.image_channels: expected {} (the floors' channels), got {}", checkpoint,
                                 worlds::ImageSet::channels, network.image_channels));
  const worlds::World world = config.world        ? *config.world
                              : config.world_file ? worlds::load_world(*config.world_file)
                                                  : state.config.world;
  const Data data = read_data(config, world, network.classes);
  set_torch_threads(config.threads);
  torch::NoGradGuard no_grad;
  agent->eval();

  const LearnedLayers learned = learned_layers(state.history);
  const agent::Precision precision = agent::resolve_precision(config.precision);
  Sampling sampling;
  sampling.learned_goals = learned.goals;
  sampling.learned_actions = learned.actions;
  sampling.precision = precision;
  Sampling iid;
  iid.precision = precision;
  Sampling goals_only = iid;
  goals_only.learned_goals = true;
  Sampling greedy = sampling;
  greedy.greedy = true;

  const int n = data.set.images.count, classes = network.classes, runs = config.runs;
  EvalReport report;
  report.runs = runs;
  report.images = n;
  report.checkpoint = checkpoint;
  report.world = config.world_file && !config.world ? config.world_file->string() : world.file.string();
  report.patch_px = world.camera.patch_px;
  report.episodes = world.task.episodes;
  report.steps = world.task.steps;
  report.seed = config.seed;
  report.learned_goals = learned.goals;
  report.learned_actions = learned.actions;
  report.precision = precision;
  report.trained_precision = state.config.precision;
  report.labels.assign(data.set.labels.begin(), data.set.labels.end());
  report.confusion.assign(classes, std::vector<double>(classes, 0.0));

  // In a group each process evaluates a contiguous share of the images; every figure is a sum of
  // per-image counts, gathered in one tally and summed over the processes once at the end.
  const int ranks = group ? group->size() : 1, rank = group ? group->rank() : 0;
  const int begin = static_cast<int>(static_cast<long>(n) * rank / ranks);
  const int end = static_cast<int>(static_cast<long>(n) * (rank + 1) / ranks);
  // Progress in rollouts: per run the agent's pass and its baselines, then the greedy pass.
  const long share = end - begin;
  const int passes_per_run = config.agent_only ? 1 : (learned.goals ? 3 : 2);
  EvalProgress progress{
      .rollouts_total = share * (static_cast<long>(passes_per_run) * runs + (config.agent_only ? 0 : 1)), .runs = runs};
  auto on_batch = [&](int robots) {
    progress.rollouts_done += robots;
    progress.seconds = core::seconds_since(t0);
    if (config.on_progress) config.on_progress(progress);
  };
  Evaluator evaluator(*agent, world, data, config.batch_robots, end - begin, precision, stop, on_batch);
  // Per run: correct, top-2, revealed pixels, i.i.d. correct, goals-only correct; then per run the
  // confusion counts (D x D), per image the probabilities summed over the runs, and the
  // full-image and greedy counts.
  constexpr std::size_t kPerRun = 5;
  const std::size_t cells = static_cast<std::size_t>(classes) * classes;
  std::vector<double> tally(kPerRun * runs + runs * cells + static_cast<std::size_t>(n) * classes + 2, 0.0);
  double* const confusion_counts = tally.data() + kPerRun * runs;
  double* const probability_sums = confusion_counts + runs * cells;
  double* const final_counts = probability_sums + static_cast<std::size_t>(n) * classes;
  torch::Tensor probability_sum = torch::zeros({end - begin, classes}, torch::kDouble);
  for (int k = 0; k < runs; ++k) {
    double* const figures = tally.data() + kPerRun * k;
    const std::uint64_t seed_k = core::derive_seed(config.seed, static_cast<std::uint64_t>(k));
    progress.run = k + 1;
    const Pass pass = evaluator.run(sampling, seed_k, begin, end);
    figures[0] = pass.correct;
    figures[1] = pass.top2;
    figures[2] = static_cast<double>(pass.revealed_px);
    probability_sum += pass.log_probs.to(torch::kDouble).exp();
    const torch::Tensor predicted = pass.log_probs.argmax(1).contiguous();
    const std::int64_t* p = predicted.data_ptr<std::int64_t>();
    for (int i = begin; i < end; ++i) confusion_counts[k * cells + report.labels[i] * classes + p[i - begin]] += 1;
    if (config.agent_only) continue;
    figures[3] = evaluator.run(iid, core::derive_seed(seed_k, streams::kEvalIid), begin, end).correct;
    // Without a learned goal layer the baseline would only measure an untrained planner.
    if (learned.goals)
      figures[4] = evaluator.run(goals_only, core::derive_seed(seed_k, streams::kEvalGoalsOnly), begin, end).correct;
  }
  const torch::Tensor mine = probability_sum.contiguous();
  std::copy_n(mine.data_ptr<double>(), mine.numel(), probability_sums + static_cast<std::size_t>(begin) * classes);
  if (!config.agent_only) {
    progress.run = 0;
    final_counts[0] = evaluator.full_image_correct(begin, end);
    final_counts[1] = evaluator.run(greedy, core::derive_seed(config.seed, streams::kEvalGreedy), begin, end).correct;
  }
  if (group) group->all_reduce_sum(std::span<double>(tally));

  std::vector<double> accuracy(runs), top2(runs), iid_accuracy(runs), goals_only_accuracy(runs);
  double revealed_px = 0;
  std::vector<long> row_counts(classes, 0);
  for (int label : report.labels) ++row_counts[label];
  for (int k = 0; k < runs; ++k) {
    const double* const figures = tally.data() + kPerRun * k;
    accuracy[k] = figures[0] / n;
    top2[k] = figures[1] / n;
    revealed_px += figures[2];
    iid_accuracy[k] = figures[3] / n;
    goals_only_accuracy[k] = learned.goals ? figures[4] / n : std::numeric_limits<double>::quiet_NaN();
    // This run's confusion counts, row-normalised; rows of absent labels stay 0.
    for (int row = 0; row < classes; ++row)
      for (int col = 0; col < classes; ++col)
        if (row_counts[row] > 0)
          report.confusion[row][col] += confusion_counts[k * cells + row * classes + col] / row_counts[row] / runs;
  }
  report.accuracy = mean_ci95(accuracy);
  report.top2 = mean_ci95(top2);
  report.revealed_fraction = revealed_px / (static_cast<double>(n) * runs * data.frame.area_px());
  if (config.agent_only) {
    constexpr double kNotMeasured = std::numeric_limits<double>::quiet_NaN();
    report.iid_accuracy = report.goals_only_accuracy = report.full_image_accuracy = report.greedy_accuracy =
        kNotMeasured;
  } else {
    report.iid_accuracy = mean_of(iid_accuracy);
    report.goals_only_accuracy = mean_of(goals_only_accuracy);
    report.full_image_accuracy = final_counts[0] / n;
    report.greedy_accuracy = final_counts[1] / n;
  }
  report.probabilities.resize(n);
  for (int i = 0; i < n; ++i) {
    report.probabilities[i].resize(classes);
    for (int c = 0; c < classes; ++c)
      report.probabilities[i][c] = probability_sums[static_cast<std::size_t>(i) * classes + c] / runs;
  }
  report.seconds = core::seconds_since(t0);
  return report;
}

std::string report_json(const EvalReport& report) {
  json j;
  j["checkpoint"] = report.checkpoint;
  j["world"] = report.world;
  j["seed"] = report.seed;
  j["learned"] = {{"goals", report.learned_goals}, {"actions", report.learned_actions}};
  j["precision"] = agent::to_string(report.precision);
  j["trained_precision"] = agent::to_string(report.trained_precision);
  j["accuracy"] = {{"mean", report.accuracy.mean}, {"ci95", report.accuracy.ci95}};
  j["top2"] = {{"mean", report.top2.mean}, {"ci95", report.top2.ci95}};
  j["confusion"] = report.confusion;
  j["baselines"] = {{"iid", report.iid_accuracy}, {"goals_only", nullptr}};
  if (!std::isnan(report.goals_only_accuracy)) j["baselines"]["goals_only"] = report.goals_only_accuracy;
  j["full_image_accuracy"] = report.full_image_accuracy;
  j["greedy_accuracy"] = report.greedy_accuracy;
  j["revealed_fraction"] = report.revealed_fraction;
  j["runs"] = report.runs;
  j["images"] = report.images;
  j["seconds"] = report.seconds;
  return j.dump(2) + "\n";
}

}  // namespace scout::learn
