// Evaluation (METHOD.md § Evaluation) and the trained-agent facade on a tiny checkpoint trained
// here through modes (i) - (iii) on synthetic 12 x 12 floors, with the real physics and camera.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <numeric>
#include <string>
#include <utility>
#include <vector>

#include "agent/state.hpp"
#include "core/error.hpp"
#include "core/random.hpp"
#include "env/runs.hpp"
#include "learn/evaluation.hpp"
#include "learn/internal/agent_policy.hpp"
#include "learn/internal/checkpoint.hpp"
#include "learn/internal/objective.hpp"
#include "learn/rollout.hpp"
#include "learn/trained_agent.hpp"
#include "learn/trainer.hpp"
#include "tests/support/temp_dir.hpp"
#include "worlds/idx.hpp"
#include "worlds/world.hpp"

namespace scout::learn {
namespace {

namespace fs = std::filesystem;
using scout::testing::TempDir;

constexpr int kSide = 12;
constexpr int kClasses = 3;

// Class 0: a bright vertical bar, 1: a horizontal bar, 2: a bright square; at a random offset,
// over noise. Only what the robot sees tells them apart.
worlds::ImageSet synthetic_images(const std::vector<std::uint8_t>& labels, std::uint64_t seed) {
  worlds::ImageSet set;
  set.count = static_cast<int>(labels.size());
  set.rows = set.cols = kSide;
  set.pixels.resize(static_cast<std::size_t>(set.count) * kSide * kSide);
  core::Rng rng(seed);
  for (int i = 0; i < set.count; ++i) {
    std::uint8_t* img = set.pixels.data() + static_cast<std::size_t>(i) * kSide * kSide;
    for (int k = 0; k < kSide * kSide; ++k) img[k] = static_cast<std::uint8_t>(core::uniform_below(rng, 40));
    const int at = 3 + static_cast<int>(core::uniform_below(rng, 6));
    for (int y = 0; y < kSide; ++y)
      for (int x = 0; x < kSide; ++x) {
        const bool on = labels[i] == 0   ? (x == at || x == at + 1)
                        : labels[i] == 1 ? (y == at || y == at + 1)
                                         : (std::abs(x - 6) <= 2 && std::abs(y - 6) <= 2);
        if (on) img[y * kSide + x] = 230;
      }
  }
  return set;
}

std::vector<std::uint8_t> cycling_labels(int count, int classes) {
  std::vector<std::uint8_t> labels(count);
  for (int i = 0; i < count; ++i) labels[i] = static_cast<std::uint8_t>(i % classes);
  return labels;
}

void write_split(const fs::path& folder, const std::string& prefix, const std::vector<std::uint8_t>& labels,
                 std::uint64_t seed) {
  worlds::write_idx_images(folder / (prefix + "-images-idx3-ubyte"), synthetic_images(labels, seed));
  worlds::write_idx_labels(folder / (prefix + "-labels-idx1-ubyte"), labels);
}

std::string world_yaml(const fs::path& data) {
  return "floor: {dataset: " + data.string() +
         ", split: test, index: random}\n"
         "camera: {patch_px: 3}\n"
         "task: {episodes: 2, steps: 2, step_px: 2}\n"
         "seed: 5\n";
}

// One checkpoint for the whole suite: training it is the slow part.
class Evaluation : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    temp_ = new TempDir("scout_eval");
    const fs::path data = temp_->path() / "data";
    fs::create_directories(data);
    write_split(data, "train", cycling_labels(36, kClasses), 1);
    write_split(data, "validation", cycling_labels(6, kClasses), 2);
    // The test digits show classes 0 and 1 only: class 2's confusion row has no images.
    write_split(data, "t10k", cycling_labels(10, 2), 3);
    const fs::path world_file = temp_->write("world.yaml", world_yaml(data));
    TrainConfig config;
    config.world = worlds::load_world(world_file);
    config.data_folder = data;
    config.network.classes = kClasses;
    config.network.planner_width = 4;
    config.network.planner_depth = 1;
    config.network.classifier_width = 4;
    config.network.classifier_depth = 1;
    config.epochs = {1, 1, 1};
    config.precision = agent::Precision::Float32;
    config.rollouts = 2;
    config.batch_images = 12;
    config.seed = 9;
    const fs::path run = temp_->path() / "run";
    fs::create_directories(run);
    Trainer trainer(config, run, 1);
    const TrainResult result = trainer.run({});
    ASSERT_EQ(result.outcome, TrainOutcome::Finished) << result.message;
    checkpoint_ = new fs::path(trainer.checkpoint_file());
  }
  static void TearDownTestSuite() {
    delete checkpoint_;
    delete temp_;
    checkpoint_ = nullptr;
    temp_ = nullptr;
  }

  static EvalConfig config(int runs, std::uint64_t seed) {
    EvalConfig c;
    c.checkpoint = *checkpoint_;
    c.images = temp_->path() / "data" / "t10k-images-idx3-ubyte";
    c.labels = temp_->path() / "data" / "t10k-labels-idx1-ubyte";
    c.runs = runs;
    c.seed = seed;
    c.batch_robots = 4;  // several batches per pass
    return c;
  }

  // The one-line InputError that evaluate() throws for `c` (empty if none).
  static std::string refusal(const EvalConfig& c) {
    try {
      evaluate(c);
    } catch (const InputError& e) {
      return e.what();
    }
    return {};
  }

  static TempDir* temp_;
  static fs::path* checkpoint_;
};

TempDir* Evaluation::temp_ = nullptr;
fs::path* Evaluation::checkpoint_ = nullptr;

TEST(StudentT, MatchesTheTables) {
  EXPECT_NEAR(student_t_975(1), 12.7062, 1e-3);
  EXPECT_NEAR(student_t_975(2), 4.3027, 1e-3);
  EXPECT_NEAR(student_t_975(5), 2.5706, 1e-3);
  EXPECT_NEAR(student_t_975(19), 2.0930, 1e-3);
  EXPECT_NEAR(student_t_975(30), 2.0423, 1e-3);
  EXPECT_NEAR(student_t_975(100), 1.9840, 1e-3);
  EXPECT_NEAR(student_t_975(100000), 1.95996, 1e-3);
  EXPECT_THROW(student_t_975(0), std::invalid_argument);
}

TEST(StudentT, IntervalsOverRuns) {
  const std::vector<double> two = {0.0, 1.0};
  const Interval a = mean_ci95(two);
  EXPECT_DOUBLE_EQ(a.mean, 0.5);
  EXPECT_NEAR(a.ci95, 12.7062 * std::sqrt(0.5) / std::sqrt(2.0), 1e-3);
  // Identical runs (values whose mean is not exactly representable) and one run: no spread.
  const std::vector<double> same(20, 0.1);
  EXPECT_EQ(mean_ci95(same).ci95, 0.0);
  EXPECT_EQ(mean_ci95(same).mean, 0.1);
  const std::vector<double> one = {0.7};
  EXPECT_EQ(mean_ci95(one).ci95, 0.0);
  EXPECT_EQ(mean_ci95(one).mean, 0.7);
}

TEST(LearnedLayers, FollowTheModesInTheHistory) {
  auto row = [](Stage s) {
    EpochMetrics m;
    m.stage = s;
    return m;
  };
  EXPECT_FALSE(learned_layers({}).goals);
  const LearnedLayers mode_i = learned_layers({row(Stage::Pretrain), row(Stage::ModeI)});
  EXPECT_FALSE(mode_i.goals);
  EXPECT_FALSE(mode_i.actions);
  const LearnedLayers mode_ii = learned_layers({row(Stage::ModeI), row(Stage::ModeII)});
  EXPECT_TRUE(mode_ii.goals);
  EXPECT_FALSE(mode_ii.actions);
  const LearnedLayers mode_iii = learned_layers({row(Stage::ModeIII)});
  EXPECT_TRUE(mode_iii.goals);
  EXPECT_TRUE(mode_iii.actions);
}

TEST_F(Evaluation, ReportsFractionsIntervalsConfusionAndProbabilities) {
  const EvalReport r = evaluate(config(3, 11));
  EXPECT_EQ(r.runs, 3);
  EXPECT_EQ(r.images, 10);
  EXPECT_TRUE(r.learned_goals);
  EXPECT_TRUE(r.learned_actions);
  for (double f : {r.accuracy.mean, r.top2.mean, r.iid_accuracy, r.goals_only_accuracy, r.full_image_accuracy,
                   r.greedy_accuracy}) {
    EXPECT_GE(f, 0.0);
    EXPECT_LE(f, 1.0);
  }
  // Accuracies over 10 images are multiples of 1/10 per run.
  EXPECT_NEAR(r.full_image_accuracy * 10, std::round(r.full_image_accuracy * 10), 1e-9);
  EXPECT_NEAR(r.greedy_accuracy * 10, std::round(r.greedy_accuracy * 10), 1e-9);
  EXPECT_GE(r.top2.mean, r.accuracy.mean);
  EXPECT_GE(r.accuracy.ci95, 0.0);
  EXPECT_GE(r.top2.ci95, 0.0);
  EXPECT_GT(r.seconds, 0.0);

  ASSERT_EQ(r.confusion.size(), static_cast<std::size_t>(kClasses));
  for (int row = 0; row < kClasses; ++row) {
    ASSERT_EQ(r.confusion[row].size(), static_cast<std::size_t>(kClasses));
    const double sum = std::accumulate(r.confusion[row].begin(), r.confusion[row].end(), 0.0);
    EXPECT_NEAR(sum, row < 2 ? 1.0 : 0.0, 1e-12) << "row " << row;  // label 2 has no test images
    for (double v : r.confusion[row]) EXPECT_GE(v, 0.0);
  }
  // The diagonal's mean weight (by row size: 5 images each) is the mean accuracy.
  EXPECT_NEAR((r.confusion[0][0] + r.confusion[1][1]) / 2, r.accuracy.mean, 1e-12);

  ASSERT_EQ(r.labels, (std::vector<int>{0, 1, 0, 1, 0, 1, 0, 1, 0, 1}));
  ASSERT_EQ(r.probabilities.size(), 10u);
  // The accuracy is the share of (run, image) argmaxes that are right; the mean probabilities
  // are a distribution per image.
  for (const std::vector<double>& p : r.probabilities) {
    ASSERT_EQ(p.size(), static_cast<std::size_t>(kClasses));
    EXPECT_NEAR(std::accumulate(p.begin(), p.end(), 0.0), 1.0, 1e-6);
    for (double v : p) EXPECT_GT(v, 0.0);
  }

  const nlohmann::json j = nlohmann::json::parse(report_json(r));
  EXPECT_EQ(j["accuracy"]["mean"].get<double>(), r.accuracy.mean);
  EXPECT_EQ(j["top2"]["ci95"].get<double>(), r.top2.ci95);
  EXPECT_EQ(j["baselines"]["iid"].get<double>(), r.iid_accuracy);
  EXPECT_EQ(j["baselines"]["goals_only"].get<double>(), r.goals_only_accuracy);
  EXPECT_EQ(j["confusion"].size(), 3u);
  EXPECT_EQ(j["runs"], 3);
  EXPECT_EQ(j["images"], 10);
  EXPECT_EQ(j["seed"], 11);
  EXPECT_EQ(j["checkpoint"], checkpoint_->string());
  EXPECT_EQ(j["world"], (temp_->path() / "world.yaml").string());
  for (const char* key : {"full_image_accuracy", "greedy_accuracy", "seconds"}) EXPECT_TRUE(j.contains(key)) << key;
}

TEST_F(Evaluation, TheSeedDecidesTheReport) {
  const EvalReport a = evaluate(config(2, 21));
  const EvalReport b = evaluate(config(2, 21));
  const EvalReport c = evaluate(config(2, 22));
  EXPECT_EQ(a.accuracy.mean, b.accuracy.mean);
  EXPECT_EQ(a.accuracy.ci95, b.accuracy.ci95);
  EXPECT_EQ(a.confusion, b.confusion);
  EXPECT_EQ(a.iid_accuracy, b.iid_accuracy);
  EXPECT_EQ(a.goals_only_accuracy, b.goals_only_accuracy);
  EXPECT_EQ(a.greedy_accuracy, b.greedy_accuracy);
  EXPECT_EQ(a.probabilities, b.probabilities);  // bit for bit
  // Another seed: other starts and choices, so other revealed pixels and other probabilities.
  EXPECT_NE(a.probabilities, c.probabilities);
  // The classifier on full images does not depend on the seed.
  EXPECT_EQ(a.full_image_accuracy, c.full_image_accuracy);
}

TEST_F(Evaluation, BatchingDoesNotChangeTheFigures) {
  // Image i's start and choices derive from (seed, run, i): 3 batches of 4 or one of 10 agree.
  EvalConfig one_batch = config(2, 21);
  one_batch.batch_robots = 240;
  const EvalReport a = evaluate(config(2, 21));
  const EvalReport b = evaluate(one_batch);
  EXPECT_EQ(a.accuracy.mean, b.accuracy.mean);
  EXPECT_EQ(a.confusion, b.confusion);
  EXPECT_EQ(a.iid_accuracy, b.iid_accuracy);
  EXPECT_EQ(a.greedy_accuracy, b.greedy_accuracy);
  ASSERT_EQ(a.probabilities.size(), b.probabilities.size());
  for (std::size_t i = 0; i < a.probabilities.size(); ++i)
    for (int c = 0; c < kClasses; ++c) EXPECT_NEAR(a.probabilities[i][c], b.probabilities[i][c], 1e-5);
}

TEST_F(Evaluation, OneRunHasNoInterval) {
  const EvalReport r = evaluate(config(1, 4));
  EXPECT_EQ(r.runs, 1);
  EXPECT_EQ(r.accuracy.ci95, 0.0);
  EXPECT_EQ(r.top2.ci95, 0.0);
}

TEST_F(Evaluation, AStopRequestInterrupts) {
  int polls = 0;
  EXPECT_THROW(evaluate(config(2, 1), core::StopToken([&] { return ++polls > 2; })), core::Stopped);
  EXPECT_EQ(polls, 3);
}

TEST_F(Evaluation, BadInputIsOneLineNamingTheFile) {
  const fs::path dir = temp_->path() / "bad";
  fs::create_directories(dir);
  // Fewer labels than images.
  worlds::write_idx_labels(dir / "short-labels", cycling_labels(9, 2));
  EvalConfig c = config(1, 1);
  c.labels = dir / "short-labels";
  std::string why = refusal(c);
  EXPECT_EQ(why.rfind((dir / "short-labels").string() + ": expected 10 labels", 0), 0u) << why;
  // A label the network has no class for.
  std::vector<std::uint8_t> labels = cycling_labels(10, 2);
  labels[7] = 3;
  worlds::write_idx_labels(dir / "big-labels", labels);
  c = config(1, 1);
  c.labels = dir / "big-labels";
  why = refusal(c);
  EXPECT_EQ(why.rfind((dir / "big-labels").string() + ": label 3 at index 7: expected a class in 0..2", 0), 0u) << why;
  // Floors smaller than the camera patch (3 px): the world's patch does not fit.
  worlds::ImageSet tiny;
  tiny.count = 10;
  tiny.rows = tiny.cols = 2;
  tiny.pixels.assign(40, 0);
  worlds::write_idx_images(dir / "tiny-images", tiny);
  c = config(1, 1);
  c.images = dir / "tiny-images";
  c.labels = temp_->path() / "data" / "t10k-labels-idx1-ubyte";
  why = refusal(c);
  EXPECT_NE(why.find("camera.patch_px"), std::string::npos) << why;
  // Not a checkpoint; a missing image file; a label file given as images.
  const fs::path text = temp_->write("bad/not-a-checkpoint.safetensors", "hello\n");
  c = config(1, 1);
  c.checkpoint = text;
  why = refusal(c);
  EXPECT_EQ(why.rfind(text.string() + ": not a valid safetensors file", 0), 0u) << why;
  c = config(1, 1);
  c.images = dir / "missing";
  why = refusal(c);
  EXPECT_EQ(why.rfind((dir / "missing").string(), 0), 0u) << why;
  c = config(1, 1);
  c.images = c.labels;
  why = refusal(c);
  EXPECT_EQ(why.rfind(c.labels.string(), 0), 0u) << why;
  EXPECT_EQ(why.find('\n'), std::string::npos) << why;
}

TEST_F(Evaluation, OtherFloorSizesWork) {
  // The networks are fully convolutional: 16 x 10 floors evaluate with the same checkpoint.
  worlds::ImageSet wide;
  wide.count = 4;
  wide.rows = 10;
  wide.cols = 16;
  wide.pixels.resize(4 * 16 * 10);
  for (std::size_t k = 0; k < wide.pixels.size(); ++k) wide.pixels[k] = static_cast<std::uint8_t>(k * 37);
  const fs::path dir = temp_->path() / "wide";
  fs::create_directories(dir);
  worlds::write_idx_images(dir / "images", wide);
  worlds::write_idx_labels(dir / "labels", {0, 1, 2, 0});
  EvalConfig c = config(2, 3);
  c.images = dir / "images";
  c.labels = dir / "labels";
  const EvalReport r = evaluate(c);
  EXPECT_EQ(r.images, 4);
  for (int row = 0; row < kClasses; ++row)
    EXPECT_NEAR(std::accumulate(r.confusion[row].begin(), r.confusion[row].end(), 0.0), 1.0, 1e-12);
}

TEST_F(Evaluation, TheTrainedAgentDrivesAndClassifiesABatch) {
  const auto agent = TrainedAgent::load(*checkpoint_);
  EXPECT_EQ(agent->classes(), kClasses);
  EXPECT_TRUE(agent->learned().goals);
  EXPECT_TRUE(agent->learned().actions);
  const worlds::World& world = agent->config().world;
  const grid::FloorFrame frame{kSide, kSide, world.floor.pixel_size_m};
  const worlds::ImageSet floors = synthetic_images(cycling_labels(5, kClasses), 4);
  std::vector<grid::Cell> starts;
  std::vector<std::uint64_t> seeds;
  core::Rng rng(1);
  for (int i = 0; i < 5; ++i) {
    starts.push_back(env::draw_start(world, frame, rng));
    seeds.push_back(core::derive_seed(7, i));
  }
  RolloutEngine engine(world, frame, 5);
  auto drive = [&](bool greedy) {
    agent->begin(frame, world.camera.patch_px, seeds, greedy, true);
    const auto records = engine.run(floors.pixels, starts, std::vector<std::uint64_t>(starts.size()), agent->policy());
    std::vector<grid::Cell> goals;
    for (const RolloutRecord& r : records)
      for (const StepRecord& s : r.steps) goals.push_back(s.goal);
    return goals;
  };
  const std::vector<grid::Cell> sampled = drive(false);
  const std::vector<float> p = agent->classify(engine.state(), 5);
  ASSERT_EQ(p.size(), 5u * kClasses);
  for (int i = 0; i < 5; ++i) EXPECT_NEAR(p[3 * i] + p[3 * i + 1] + p[3 * i + 2], 1.0f, 1e-5f);
  // pi_g over the floor's pixels, and the goal drawn from it has positive probability.
  const int steps_per_episode = world.task.steps, episodes = world.task.episodes;
  for (int i = 0; i < 5; ++i)
    for (int e = 0; e < episodes; ++e) {
      const std::vector<float>& map = agent->goal_map(i, e);
      ASSERT_EQ(map.size(), static_cast<std::size_t>(kSide * kSide));
      EXPECT_NEAR(std::accumulate(map.begin(), map.end(), 0.0), 1.0, 1e-4);
      const grid::Cell goal = sampled[static_cast<std::size_t>(i * episodes + e) * steps_per_episode];
      EXPECT_GT(map[goal.y() * kSide + goal.x()], 0.0f);
    }
  // Greedy: each episode's goal is the argmax of its map.
  const std::vector<grid::Cell> greedy = drive(true);
  for (int i = 0; i < 5; ++i)
    for (int e = 0; e < episodes; ++e) {
      const std::vector<float>& map = agent->goal_map(i, e);
      const auto best = std::max_element(map.begin(), map.end()) - map.begin();
      const grid::Cell goal = greedy[static_cast<std::size_t>(i * episodes + e) * steps_per_episode];
      EXPECT_EQ(goal.y() * kSide + goal.x(), best) << "robot " << i << " episode " << e;
    }
  EXPECT_EQ(sampled.size(), greedy.size());
}

// --- Every figure is recounted independently ---------------------------------------------------------------------
//
// The report's figures against a replay written here from the same public pieces (make_batch,
// RolloutEngine, AgentPolicy, run_batch, count_correct) but with its own loop: one robot per
// batch (evaluate batches 4 here), each image's start and choices from derive_seed(stream, image),
// where run k's stream is derive_seed(seed, k) and the baselines' streams are derived from it as
// METHOD.md § Evaluation says. The stream numbers are evaluation.cpp's (kIidStream = 2^40, then
// +1 for goals-only, +2 for greedy): this test pins them too.
constexpr std::uint64_t kIidStream = std::uint64_t{1} << 40;
constexpr std::uint64_t kGoalsOnlyStream = kIidStream + 1;
constexpr std::uint64_t kGreedyStream = kIidStream + 2;

struct Replay {
  agent::Agent agent{nullptr};
  worlds::World world;
  worlds::LabeledImages data;
  grid::FloorFrame frame{kSide, kSide, 0.1};

  // Images whose argmax after driving with `sampling` is right (top = 1) or in the top `top`.
  std::pair<int, int> correct(const Sampling& sampling, std::uint64_t stream) {
    RolloutEngine engine(world, frame, 1);
    AgentPolicy policy(*agent, frame, world.camera.patch_px, 1);
    int right = 0, top2 = 0;
    for (int i = 0; i < data.images.count; ++i) {
      const int index[] = {i};
      const RolloutBatch batch =
          make_batch(data, index, 1, world, frame, core::derive_seed(stream, static_cast<std::uint64_t>(i)));
      const BatchOutcome out = run_batch(*agent, engine, policy, batch, sampling, {1, false, 0});
      right += count_correct(out.log_probs, batch.labels);
      top2 += count_correct(out.log_probs, batch.labels, 2);
    }
    return {right, top2};
  }
  // Images the classifier gets right from the whole floor: u_c = pixel_value(x), fp32, by hand.
  int full_image_correct() {
    torch::NoGradGuard no_grad;
    const int n = data.images.count;
    torch::Tensor x = torch::empty({n, 1, kSide, kSide});
    float* dst = x.data_ptr<float>();
    for (std::size_t k = 0; k < data.images.pixels.size(); ++k) dst[k] = agent::pixel_value(data.images.pixels[k]);
    const torch::Tensor predicted = agent->classifier->forward(x).argmax(1);
    int right = 0;
    for (int i = 0; i < n; ++i) right += predicted[i].item<std::int64_t>() == data.labels[i];
    return right;
  }
};

TEST_F(Evaluation, EveryFigureIsTheCountOfAnIndependentReplay) {
  constexpr int kRuns = 2;
  constexpr std::uint64_t kSeed = 21;
  EvalConfig c = config(kRuns, kSeed);
  c.precision = agent::Precision::Float32;
  const EvalReport r = evaluate(c);

  Replay replay;
  CheckpointState state;
  replay.agent = load_agent(*checkpoint_, &state);
  replay.agent->eval();
  torch::NoGradGuard no_grad;
  replay.world = state.config.world;
  replay.data.images = worlds::read_idx_images(c.images);
  replay.data.labels = worlds::read_idx_labels(c.labels);
  replay.frame = {kSide, kSide, replay.world.floor.pixel_size_m};
  const double n = replay.data.images.count;
  ASSERT_EQ(r.images, 10);

  Sampling learned, iid, goals_only;
  learned.learned_goals = learned.learned_actions = true;
  goals_only.learned_goals = true;
  std::vector<double> accuracy, top2;
  double iid_sum = 0, goals_only_sum = 0;
  for (int k = 0; k < kRuns; ++k) {
    const std::uint64_t seed_k = core::derive_seed(kSeed, static_cast<std::uint64_t>(k));
    const auto [right, in_top2] = replay.correct(learned, seed_k);
    accuracy.push_back(right / n);
    top2.push_back(in_top2 / n);
    iid_sum += replay.correct(iid, core::derive_seed(seed_k, kIidStream)).first / n;
    goals_only_sum += replay.correct(goals_only, core::derive_seed(seed_k, kGoalsOnlyStream)).first / n;
  }
  EXPECT_DOUBLE_EQ(r.accuracy.mean, (accuracy[0] + accuracy[1]) / 2);
  EXPECT_DOUBLE_EQ(r.top2.mean, (top2[0] + top2[1]) / 2);
  EXPECT_DOUBLE_EQ(r.iid_accuracy, iid_sum / kRuns);
  EXPECT_DOUBLE_EQ(r.goals_only_accuracy, goals_only_sum / kRuns);
  Sampling greedy = learned;
  greedy.greedy = true;
  EXPECT_DOUBLE_EQ(r.greedy_accuracy, replay.correct(greedy, core::derive_seed(kSeed, kGreedyStream)).first / n);
  EXPECT_DOUBLE_EQ(r.full_image_accuracy, replay.full_image_correct() / n);
  // Two runs: the interval's half-width is t(0.975, 1) * |a0 - a1| / 2 (sd = |a0 - a1| / sqrt 2).
  EXPECT_NEAR(r.accuracy.ci95, 12.706204736174707 * std::abs(accuracy[0] - accuracy[1]) / 2, 1e-9);
}

// A camera that sees the whole floor at the start (a 12 x 12 patch on 12 x 12 floors, the robot
// starting at (6, 6): its window is columns and rows 0 .. 11): whatever the goals and actions,
// y is the whole floor before the first move, so the stochastic, i.i.d., goals-only and greedy
// accuracies all equal the classifier's accuracy on full images, which is counted here by hand.
TEST_F(Evaluation, WithTheWholeFloorInViewEveryFigureIsTheFullImageAccuracy) {
  const fs::path world_file = temp_->write("whole.yaml", "floor: {dataset: " + (temp_->path() / "data").string() +
                                                             ", split: test, index: random}\n"
                                                             "robot: {start: [6, 6]}\n"
                                                             "camera: {patch_px: 12}\n"
                                                             "task: {episodes: 2, steps: 2, step_px: 2}\n");
  EvalConfig c = config(2, 4);
  c.world_file = world_file;
  c.precision = agent::Precision::Float32;
  const EvalReport r = evaluate(c);
  Replay replay;
  replay.agent = load_agent(*checkpoint_);
  replay.agent->eval();
  replay.data.images = worlds::read_idx_images(c.images);
  replay.data.labels = worlds::read_idx_labels(c.labels);
  const double full = replay.full_image_correct() / 10.0;
  EXPECT_DOUBLE_EQ(r.full_image_accuracy, full);
  EXPECT_DOUBLE_EQ(r.accuracy.mean, full);
  EXPECT_EQ(r.accuracy.ci95, 0.0);
  EXPECT_DOUBLE_EQ(r.iid_accuracy, full);
  EXPECT_DOUBLE_EQ(r.goals_only_accuracy, full);
  EXPECT_DOUBLE_EQ(r.greedy_accuracy, full);
}

// scout report's budget sweep: a world given whole, the first K images, only the agent's runs,
// and the share of the floor revealed.
TEST_F(Evaluation, AWorldGivenWholeOnTheFirstImagesRevealsItsShareOfTheFloor) {
  const fs::path whole_file = temp_->write("whole2.yaml", "floor: {dataset: " + (temp_->path() / "data").string() +
                                                              ", split: test, index: random}\n"
                                                              "robot: {start: [6, 6]}\n"
                                                              "camera: {patch_px: 12}\n"
                                                              "task: {episodes: 2, steps: 2, step_px: 2}\n");
  EvalConfig c = config(2, 4);
  c.world = worlds::load_world(whole_file);
  c.world_file = temp_->path() / "no-such-world.yaml";  // the whole world wins
  c.image_limit = 4;
  c.agent_only = true;
  c.precision = agent::Precision::Float32;
  const EvalReport r = evaluate(c);
  EXPECT_EQ(r.images, 4);
  EXPECT_EQ(r.labels.size(), 4u);
  EXPECT_EQ(r.patch_px, 12);
  EXPECT_EQ(r.revealed_fraction, 1.0);  // a 12 x 12 window centred on the 12 x 12 floor
  Replay replay;
  replay.agent = load_agent(*checkpoint_);
  replay.agent->eval();
  replay.data.images = worlds::read_idx_images(c.images);
  replay.data.labels = worlds::read_idx_labels(c.labels);
  replay.data.images.count = 4;
  replay.data.images.pixels.resize(4 * 144);
  replay.data.labels.resize(4);
  EXPECT_DOUBLE_EQ(r.accuracy.mean, replay.full_image_correct() / 4.0);
  EXPECT_TRUE(std::isnan(r.iid_accuracy));
  EXPECT_TRUE(std::isnan(r.greedy_accuracy));
  EXPECT_TRUE(std::isnan(r.full_image_accuracy));

  // A 1-pixel camera sees one pixel per pose: the start and E x T = 4 moves, at most 5 of 144.
  worlds::World pinhole = *c.world;
  pinhole.camera.patch_px = 1;
  pinhole.robot.start.reset();
  c.world = pinhole;
  const EvalReport narrow = evaluate(c);
  EXPECT_GE(narrow.revealed_fraction, 1.0 / 144);
  EXPECT_LE(narrow.revealed_fraction, 5.0 / 144);
  c.image_limit = -1;
  EXPECT_EQ(refusal(c), "image_limit: expected 0 (all) or a positive count, got -1");
}

}  // namespace
}  // namespace scout::learn
