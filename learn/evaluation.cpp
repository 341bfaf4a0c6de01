// Evaluation (METHOD.md § Evaluation): R stochastic runs of the checkpoint's policy over a set of
// digits with the physics and the camera in the loop, the two random baselines, the classifier on
// full images and one greedy run.
#include "learn/evaluation.hpp"

#include <fmt/format.h>
#include <torch/torch.h>

#include <algorithm>
#include <boost/math/distributions/students_t.hpp>
#include <chrono>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "core/error.hpp"
#include "core/random.hpp"
#include "core/seed_streams.hpp"
#include "core/timing.hpp"
#include "learn/auto_precision.hpp"
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

struct Data {
  worlds::LabeledImages set;
  worlds::FloorComposer composer{0, 0};  // the world's layout over the images
  std::uint64_t floor_key = 0;           // the evaluated floors' key: the same in every pass
  std::vector<int> labels;               // each floor's label (a digit's, or the sum of a floor's digits)
  grid::FloorFrame frame;

  worlds::FloorSource floors() const { return {&set, composer, floor_key}; }
};

Data read_data(const EvalConfig& config, const worlds::World& world, int classes, std::uint64_t seed) {
  Data d;
  if (config.image_limit < 0)
    throw InputError(fmt::format("image_limit: expected 0 (all) or a positive count, got {}", config.image_limit));
  d.set = worlds::read_labeled_idx(config.images, config.labels);
  const std::string images = config.images.string(), labels = config.labels.string();
  if (config.image_limit > 0 && config.image_limit < d.set.images.count) {
    d.set.images.count = config.image_limit;
    d.set.images.pixels.resize(static_cast<std::size_t>(config.image_limit) * d.set.images.rows * d.set.images.cols);
    d.set.labels.resize(static_cast<std::size_t>(config.image_limit));
  }
  // The networks are fully convolutional, so any floor size works that the camera can hold and
  // the world's patch and start fit.
  if (d.set.images.cols > worlds::kMaxFloorPx || d.set.images.rows > worlds::kMaxFloorPx)
    throw InputError(fmt::format("{}: expected images of at most {} x {} pixels, got {} x {}", images,
                                 worlds::kMaxFloorPx, worlds::kMaxFloorPx, d.set.images.cols, d.set.images.rows));
  d.composer = worlds::FloorComposer(world, d.set.images.cols, d.set.images.rows);
  d.floor_key = core::derive_seed(seed, streams::kEvalFloors);
  worlds::check_against_floor(world, d.composer.width_px(), d.composer.height_px());
  d.labels.resize(d.set.labels.size());
  for (std::size_t i = 0; i < d.set.labels.size(); ++i) {
    d.labels[i] = d.composer.label(d.set.labels, static_cast<int>(i), d.floor_key);
    if (d.labels[i] >= classes)
      throw InputError(fmt::format("{}: label {} at index {}: expected a class in 0..{} (the checkpoint's network has "
                                   "{} classes)",
                                   labels, d.labels[i], i, classes - 1, classes) +
                       (d.composer.digits() > 1
                            ? fmt::format(" (a floor of {} digits is labelled by their sum)", d.composer.digits())
                            : std::string()));
  }
  d.frame = {
      .width_px = d.composer.width_px(), .height_px = d.composer.height_px(), .pixel_size_m = world.floor.pixel_size_m};
  return d;
}

// What one pass over all images gave: per image, log pi_c.
struct Pass {
  int correct = 0, top2 = 0;
  long revealed_px = 0;     // summed over the images: pixels seen by the end of the rollout
  long stalled_moves = 0;   // summed over the images: moves that did not arrive (a team's, all its robots')
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
    // A team of K robots is one rollout: batches of whole teams.
    const int K = world.team.robots;
    const int rollouts = std::max(1, std::min(batch_robots / K, images));
    const int robots = rollouts * K;
    try {
      engine_ = std::make_unique<RolloutEngine>(world, data.frame, robots);
    } catch (const std::runtime_error& e) {
      throw InputError(std::string("the camera cannot start: ") + one_line(e.what()));
    }
    policy_ = std::make_unique<AgentPolicy>(agent, data.frame, world.camera.patch_px, robots);
    batch_ = rollouts;
  }

  AxisTally axis_tally() const { return engine_->axis_tally(); }
  void reset_axis_tally() { engine_->reset_axis_tally(); }

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
      for (int image = first; image < first + k; ++image)
        batch.append(make_batch(floors_, std::span(&image, 1), 1, world_, data_.frame,
                                core::derive_seed(stream_seed, static_cast<std::uint64_t>(image))));
      const BatchOutcome out = run_batch(agent_, *engine_, *policy_, batch, sampling,
                                         {.rollouts_per_image = 1, .leave_one_out = false, .entropy_bonus = 0});
      for (int i = 0; i < k; ++i)  // a team's robots hold its seen pixels
        pass.revealed_px += engine_->state().seen[static_cast<std::size_t>(i) * batch.team].count();
      for (const int stalled : engine_->stalled_moves()) pass.stalled_moves += stalled;
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
      floor_buffer_.resize(area * k);
      floors_.floors(first, k, floor_buffer_);
      torch::Tensor x = full_images(floor_buffer_, k, data_.frame);
      const std::vector<std::int64_t> labels(data_.labels.begin() + first, data_.labels.begin() + first + k);
      correct += count_correct(classifier_log_probs(agent_, x, precision_), labels, 1);
    }
    return correct;
  }

 private:
  agent::AgentImpl& agent_;
  const worlds::World& world_;
  const Data& data_;
  worlds::FloorSource floors_ = data_.floors();
  std::vector<std::uint8_t> floor_buffer_;  // full floors for the classifier
  agent::Precision precision_;
  core::StopToken stop_;
  std::function<void(int)> on_batch_;  // after each rollout batch: its robots
  std::unique_ptr<RolloutEngine> engine_;
  std::unique_ptr<AgentPolicy> policy_;
  int batch_ = 1;
};

}  // namespace

double student_t_975(int dof) {
  if (dof < 1) throw std::invalid_argument("student_t_975: dof must be at least 1, got " + std::to_string(dof));
  // As the upper 2.5 % tail: 1 - 0.975 would lose digits to cancellation.
  return boost::math::quantile(boost::math::complement(boost::math::students_t(dof), 0.025));
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

namespace {

// Every figure of an evaluation is a sum of per-image counts: each process counts its share of the
// images, and the counts are summed over the processes in one all-reduce of `storage`, which the
// named spans below view (the tally is neither copied nor moved, so they stay valid).
struct EvalTally {
  EvalTally(int runs, int images, int classes)
      : cells(static_cast<std::size_t>(classes) * classes),
        storage(kPerRun * runs + runs * cells + static_cast<std::size_t>(images) * classes + 2 + 5, 0.0) {
    std::span<double> rest(storage);
    auto take = [&](std::size_t count) {
      const std::span<double> part = rest.first(count);
      rest = rest.subspan(count);
      return part;
    };
    const auto r = static_cast<std::size_t>(runs);
    correct = take(r);
    top2 = take(r);
    revealed_px = take(r);
    iid_correct = take(r);
    goals_only_correct = take(r);
    confusion = take(r * cells);
    probability_sums = take(static_cast<std::size_t>(images) * classes);
    full_image_correct = &take(1)[0];
    greedy_correct = &take(1)[0];
    axes = take(4);
    stalled_moves = &take(1)[0];
  }
  void add(const AxisTally& t) {
    axes[0] += static_cast<double>(t.decisions);
    axes[1] += static_cast<double>(t.differing);
    axes[2] += static_cast<double>(t.chose_more);
    axes[3] += static_cast<double>(t.gap_px);
  }
  EvalTally(const EvalTally&) = delete;
  EvalTally& operator=(const EvalTally&) = delete;

  void sum_over(ProcessGroup* group) {
    if (group) group->all_reduce_sum(std::span<double>(storage));
  }
  // Run k's confusion counts: [true label * D + predicted].
  std::span<double> confusion_of_run(int k) const { return confusion.subspan(k * cells, cells); }

  static constexpr std::size_t kPerRun = 5;  // the per-run spans below
  const std::size_t cells;                   // D x D
  std::vector<double> storage;
  std::span<double> correct, top2, revealed_px, iid_correct, goals_only_correct;  // per run
  std::span<double> confusion;                                                    // per run, D x D
  std::span<double> probability_sums;  // per image: pi_c summed over the runs (D values)
  double* full_image_correct = nullptr;
  double* greedy_correct = nullptr;
  std::span<double> axes;           // the agent's runs' AxisTally: decisions, differing, chose_more, gap_px
  double* stalled_moves = nullptr;  // the agent's runs' moves that did not arrive
};

// What an evaluation reads before it drives: the checkpoint, the world, the digits, the policies.
struct EvalSetup {
  CheckpointState state;
  agent::Agent agent{nullptr};
  worlds::World world;
  Data data;
  LearnedLayers learned;
  agent::Precision precision = agent::Precision::Float32;
  Sampling sampling, iid, goals_only, greedy;
};

EvalSetup prepare(const EvalConfig& config) {
  if (config.runs < 1) throw InputError(fmt::format("--runs: expected a positive integer, got {}", config.runs));
  if (config.baseline_runs < 1)
    throw InputError(fmt::format("--baseline-runs: expected a positive integer, got {}", config.baseline_runs));
  if (config.batch_robots < 1)
    throw std::invalid_argument("evaluate: batch_robots must be positive, got " + std::to_string(config.batch_robots));
  EvalSetup s;
  s.agent = load_agent(config.opened ? *config.opened : open_checkpoint(config.checkpoint), &s.state);
  const agent::NetworkConfig& network = s.state.config.network;
  if (network.image_channels != worlds::ImageSet::channels)
    throw InputError(fmt::format("{}: network.image_channels: expected {} (the floors' channels), got {}",
                                 config.checkpoint.string(), worlds::ImageSet::channels, network.image_channels));
  s.world = config.world        ? *config.world
            : config.world_file ? worlds::load_world(*config.world_file)
                                : s.state.config.world;
  s.data = read_data(config, s.world, network.classes, config.seed);
  s.learned = learned_layers(s.state.history);
  s.precision = resolve_precision(config.precision);
  s.sampling.learned_goals = s.learned.goals;
  s.sampling.learned_actions = s.learned.actions;
  s.sampling.precision = s.precision;
  s.iid.precision = s.precision;
  s.goals_only = s.iid;
  s.goals_only.learned_goals = true;
  s.greedy = s.sampling;
  s.greedy.greedy = true;
  return s;
}

// Drives this process's share [begin, end) of the images through every pass and counts.
void count_passes(const EvalConfig& config, EvalSetup& s, int begin, int end, const core::StopToken& stop,
                  EvalTally& tally, core::Clock::time_point t0) {
  const int classes = s.state.config.network.classes, runs = config.runs;
  const int baseline_runs = config.agent_only ? 0 : std::min(config.baseline_runs, runs);
  // Progress in rollouts: the agent's passes, the baselines' (one or two per baseline run), then
  // the greedy pass.
  const long passes = runs + static_cast<long>(baseline_runs) * (s.learned.goals ? 2 : 1) + (config.agent_only ? 0 : 1);
  EvalProgress progress{.rollouts_total = static_cast<long>(end - begin) * passes, .runs = runs};
  auto on_batch = [&](int robots) {
    progress.rollouts_done += robots;
    progress.seconds = core::seconds_since(t0);
    if (config.on_progress) config.on_progress(progress);
  };
  Evaluator evaluator(*s.agent, s.world, s.data, config.batch_robots, end - begin, s.precision, stop, on_batch);
  torch::Tensor probability_sum = torch::zeros({end - begin, classes}, torch::kDouble);
  for (int k = 0; k < runs; ++k) {
    const std::uint64_t seed_k = core::derive_seed(config.seed, static_cast<std::uint64_t>(k));
    progress.run = k + 1;
    evaluator.reset_axis_tally();
    const Pass pass = evaluator.run(s.sampling, seed_k, begin, end);
    tally.add(evaluator.axis_tally());
    *tally.stalled_moves += static_cast<double>(pass.stalled_moves);
    tally.correct[k] = pass.correct;
    tally.top2[k] = pass.top2;
    tally.revealed_px[k] = static_cast<double>(pass.revealed_px);
    probability_sum += pass.log_probs.to(torch::kDouble).exp();
    const torch::Tensor predicted = pass.log_probs.argmax(1).contiguous();
    const std::int64_t* p = predicted.data_ptr<std::int64_t>();
    const std::span<double> confusion = tally.confusion_of_run(k);
    for (int i = begin; i < end; ++i) confusion[s.data.labels[i] * classes + p[i - begin]] += 1;
    if (k >= baseline_runs) continue;
    tally.iid_correct[k] = evaluator.run(s.iid, core::derive_seed(seed_k, streams::kEvalIid), begin, end).correct;
    // Without a learned goal layer the baseline would only measure an untrained planner.
    if (s.learned.goals)
      tally.goals_only_correct[k] =
          evaluator.run(s.goals_only, core::derive_seed(seed_k, streams::kEvalGoalsOnly), begin, end).correct;
  }
  const torch::Tensor mine = probability_sum.contiguous();
  std::copy_n(mine.data_ptr<double>(), mine.numel(),
              tally.probability_sums.begin() + static_cast<std::ptrdiff_t>(begin) * classes);
  if (config.agent_only) return;
  progress.run = 0;
  *tally.full_image_correct = evaluator.full_image_correct(begin, end);
  *tally.greedy_correct =
      evaluator.run(s.greedy, core::derive_seed(config.seed, streams::kEvalGreedy), begin, end).correct;
}

// The figures of the summed counts.
void summarise(const EvalConfig& config, const EvalSetup& s, const EvalTally& tally, EvalReport& report) {
  const int n = s.data.set.images.count, classes = s.state.config.network.classes, runs = config.runs;
  const int baseline_runs = config.agent_only ? 0 : std::min(config.baseline_runs, runs);
  std::vector<double> accuracy(runs), top2(runs), iid_accuracy(baseline_runs), goals_only_accuracy(baseline_runs);
  double revealed_px = 0;
  std::vector<long> row_counts(classes, 0);
  for (int label : report.labels) ++row_counts[label];
  for (int k = 0; k < runs; ++k) {
    accuracy[k] = tally.correct[k] / n;
    top2[k] = tally.top2[k] / n;
    revealed_px += tally.revealed_px[k];
    if (k < baseline_runs) {
      iid_accuracy[k] = tally.iid_correct[k] / n;
      goals_only_accuracy[k] =
          s.learned.goals ? tally.goals_only_correct[k] / n : std::numeric_limits<double>::quiet_NaN();
    }
    // This run's confusion counts, row-normalised; rows of absent labels stay 0.
    const std::span<const double> counts = tally.confusion_of_run(k);
    for (int row = 0; row < classes; ++row)
      for (int col = 0; col < classes; ++col)
        if (row_counts[row] > 0) report.confusion[row][col] += counts[row * classes + col] / row_counts[row] / runs;
  }
  report.accuracy = mean_ci95(accuracy);
  report.top2 = mean_ci95(top2);
  report.revealed_fraction = revealed_px / (static_cast<double>(n) * runs * s.data.frame.area_px());
  if (config.agent_only) {
    constexpr double kNotMeasured = std::numeric_limits<double>::quiet_NaN();
    report.iid_accuracy = report.goals_only_accuracy = report.full_image_accuracy = report.greedy_accuracy =
        kNotMeasured;
  } else {
    const Interval iid = mean_ci95(iid_accuracy), goals_only = mean_ci95(goals_only_accuracy);
    report.iid_accuracy = iid.mean;
    report.iid_ci95 = iid.ci95;
    report.goals_only_accuracy = goals_only.mean;
    report.goals_only_ci95 = goals_only.ci95;
    report.baseline_runs = baseline_runs;
    report.full_image_accuracy = *tally.full_image_correct / n;
    report.greedy_accuracy = *tally.greedy_correct / n;
  }
  const double decisions = tally.axes[0], differing = tally.axes[1];
  report.axis_decisions_per_rollout = decisions / (static_cast<double>(n) * runs);
  report.axis_differing_share = decisions > 0 ? differing / decisions : 0;
  report.axis_chose_more_share = differing > 0 ? tally.axes[2] / differing : 0;
  report.axis_gap_px = differing > 0 ? tally.axes[3] / differing : 0;
  report.stalled_moves_per_rollout = *tally.stalled_moves / (static_cast<double>(n) * runs);
  report.probabilities.resize(n);
  for (int i = 0; i < n; ++i) {
    const std::span<const double> sums = tally.probability_sums.subspan(static_cast<std::size_t>(i) * classes, classes);
    report.probabilities[i].resize(classes);
    for (int c = 0; c < classes; ++c) report.probabilities[i][c] = sums[c] / runs;
  }
}

// What the report says of the task and the checkpoint, before any figure.
EvalReport report_header(const EvalConfig& config, const EvalSetup& s) {
  EvalReport report;
  const int classes = s.state.config.network.classes;
  report.runs = config.runs;
  report.images = s.data.set.images.count;
  report.checkpoint = config.checkpoint.string();
  report.world = config.world_file && !config.world ? config.world_file->string() : s.world.file.string();
  report.patch_px = s.world.camera.patch_px;
  report.episodes = s.world.task.episodes;
  report.steps = s.world.task.steps;
  report.seed = config.seed;
  report.learned_goals = s.learned.goals;
  report.learned_actions = s.learned.actions;
  report.precision = s.precision;
  report.trained_precision = s.state.config.precision;
  report.labels.assign(s.data.labels.begin(), s.data.labels.end());
  report.confusion.assign(classes, std::vector<double>(classes, 0.0));
  return report;
}

}  // namespace

EvalReport evaluate(const EvalConfig& config, const core::StopToken& stop, ProcessGroup* group) {
  const auto t0 = core::Clock::now();
  EvalSetup setup = prepare(config);
  set_torch_threads(config.threads);
  torch::NoGradGuard no_grad;
  setup.agent->eval();
  EvalReport report = report_header(config, setup);
  // In a group each process evaluates a contiguous share of the images.
  const auto [begin, end] = share_of(report.images, group ? group->rank() : 0, group ? group->size() : 1);
  EvalTally tally(config.runs, report.images, setup.state.config.network.classes);
  count_passes(config, setup, begin, end, stop, tally, t0);
  tally.sum_over(group);
  summarise(config, setup, tally, report);
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
  j["baselines"] = {{"iid", report.iid_accuracy},
                    {"goals_only", nullptr},
                    {"iid_ci95", report.iid_ci95},
                    {"goals_only_ci95", nullptr},
                    {"runs", report.baseline_runs}};
  if (!std::isnan(report.goals_only_accuracy)) {
    j["baselines"]["goals_only"] = report.goals_only_accuracy;
    j["baselines"]["goals_only_ci95"] = report.goals_only_ci95;
  }
  j["full_image_accuracy"] = report.full_image_accuracy;
  j["greedy_accuracy"] = report.greedy_accuracy;
  j["revealed_fraction"] = report.revealed_fraction;
  j["stalled_moves_per_rollout"] = report.stalled_moves_per_rollout;
  j["axis_decisions"] = {{"per_rollout", report.axis_decisions_per_rollout},
                         {"differing_share", report.axis_differing_share},
                         {"chose_more_share", report.axis_chose_more_share},
                         {"gap_px", report.axis_gap_px}};
  j["runs"] = report.runs;
  j["images"] = report.images;
  j["seconds"] = report.seconds;
  return j.dump(2) + "\n";
}

}  // namespace scout::learn
