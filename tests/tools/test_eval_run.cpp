// `scout eval` and `scout run --checkpoint` end to end, on tiny checkpoints that `scout train`
// makes here from synthetic 12 x 12 IDX files (real Box2D, real OSMesa).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "agent/config.hpp"
#include "tests/support/cli.hpp"
#include "tests/support/temp_dir.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

using Result = scout::testing::CliResult;

Result scout(const std::string& args) { return scout::testing::run_cli(SCOUT_BINARY, args); }

constexpr int kSide = 12;
constexpr int kTestImages = 9;

// Raw IDX files (big-endian header) of `count` 12 x 12 images of three classes: a vertical bar,
// a horizontal bar, a square.
void write_idx(const fs::path& folder, const std::string& prefix, int count) {
  std::string images, labels;
  scout::testing::put_idx_headers(images, labels, count, kSide, kSide);
  for (int i = 0; i < count; ++i) {
    const int label = i % 3, at = 3 + (i * 7) % 6;
    labels.push_back(static_cast<char>(label));
    for (int y = 0; y < kSide; ++y)
      for (int x = 0; x < kSide; ++x) {
        const bool on = label == 0   ? (x == at || x == at + 1)
                        : label == 1 ? (y == at || y == at + 1)
                                     : (std::abs(x - 6) <= 2 && std::abs(y - 6) <= 2);
        images.push_back(static_cast<char>(on ? 230 : (x * 13 + y * 7 + i) % 40));
      }
  }
  std::ofstream(folder / (prefix + "-images-idx3-ubyte"), std::ios::binary) << images;
  std::ofstream(folder / (prefix + "-labels-idx1-ubyte"), std::ios::binary) << labels;
}

json read_json(const fs::path& file) {
  std::ifstream in(file);
  return json::parse(in);
}

// Two checkpoints for the suite, trained once: through modes (i) - (iii), and mode (i) only.
class EvalRun : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    temp_ = new scout::testing::TempDir("scout_eval_run");
    const fs::path data = temp_->path() / "data";
    fs::create_directories(data);
    write_idx(data, "train", 24);
    write_idx(data, "validation", 6);
    write_idx(data, "t10k", kTestImages);
    temp_->write("world.yaml", "floor: {dataset: " + data.string() +
                                   ", split: test, index: random}\n"
                                   "camera: {patch_px: 3}\n"
                                   "task: {episodes: 2, steps: 2}\n");
    const std::string common =
        " --seed 3 --planner-width 4 --planner-depth 1 --classifier-width 4 "
        "--classifier-depth 1 --batch 8 --rollouts 2 --threads 1";
    for (const auto& [run, epochs] : {std::pair{"run", "1,1,1"}, std::pair{"run_i", "1,0,0"}}) {
      const Result r = scout("train " + world() + " --out " + path(run) + " --epochs " + epochs + common);
      ASSERT_EQ(r.status, 0) << r.output;
      ASSERT_TRUE(fs::exists(path(run) + "/checkpoint.pt")) << r.output;
    }
  }
  static void TearDownTestSuite() {
    delete temp_;
    temp_ = nullptr;
  }

  static std::string path(const std::string& name) { return (temp_->path() / name).string(); }
  static std::string world() { return path("world.yaml"); }
  static std::string checkpoint(const std::string& run = "run") { return path(run) + "/checkpoint.pt"; }
  static std::string test_data() {
    return " --images " + path("data/t10k-images-idx3-ubyte") + " --labels " + path("data/t10k-labels-idx1-ubyte");
  }

  static scout::testing::TempDir* temp_;
};

scout::testing::TempDir* EvalRun::temp_ = nullptr;

TEST_F(EvalRun, EvalPrintsATableAndWritesTheReportAndPredictions) {
  const Result r = scout("eval --checkpoint " + checkpoint() + test_data() + " --runs 3 --seed 2 --json " +
                         path("report.json") + " --predictions " + path("p.csv"));
  ASSERT_EQ(r.status, 0) << r.output;
  for (const char* row : {"accuracy", "top-2 accuracy", "i.i.d. baseline", "goals-only baseline", "full images",
                          "greedy", "runs", "images", "seconds"})
    EXPECT_NE(r.output.find(row), std::string::npos) << row << "\n" << r.output;

  const json j = read_json(path("report.json"));
  for (const char* key : {"checkpoint", "world", "seed", "accuracy", "top2", "confusion", "baselines",
                          "full_image_accuracy", "greedy_accuracy", "runs", "images", "seconds"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["runs"], 3);
  EXPECT_EQ(j["images"], kTestImages);
  EXPECT_EQ(j["seed"], 2);
  EXPECT_EQ(j["checkpoint"], checkpoint());
  EXPECT_EQ(j["world"], world());
  for (const char* interval : {"accuracy", "top2"}) {
    EXPECT_GE(j[interval]["mean"].get<double>(), 0.0) << interval;
    EXPECT_LE(j[interval]["mean"].get<double>(), 1.0) << interval;
    EXPECT_GE(j[interval]["ci95"].get<double>(), 0.0) << interval;
  }
  for (const char* baseline : {"iid", "goals_only"}) {
    EXPECT_GE(j["baselines"][baseline].get<double>(), 0.0) << baseline;
    EXPECT_LE(j["baselines"][baseline].get<double>(), 1.0) << baseline;
  }
  ASSERT_EQ(j["confusion"].size(), 3u);  // scout train takes D from the training labels: 0, 1, 2
  for (int row = 0; row < 3; ++row) {
    ASSERT_EQ(j["confusion"][row].size(), 3u);
    double sum = 0;
    for (const json& v : j["confusion"][row]) sum += v.get<double>();
    EXPECT_NEAR(sum, 1.0, 1e-9) << row;  // every label 0..2 is present
  }
  EXPECT_EQ(j["manifest"]["checkpoint_sha256"].get<std::string>().size(), 64u);

  std::ifstream csv(path("p.csv"));
  std::string line;
  ASSERT_TRUE(std::getline(csv, line));
  EXPECT_EQ(line, "index,label,p0,p1,p2");
  int rows = 0;
  while (std::getline(csv, line)) {
    std::stringstream fields(line);
    std::string field;
    std::vector<double> values;
    while (std::getline(fields, field, ',')) values.push_back(std::stod(field));
    ASSERT_EQ(values.size(), 5u) << line;
    EXPECT_EQ(values[0], rows);
    EXPECT_EQ(values[1], rows % 3);
    double sum = 0;
    for (std::size_t k = 2; k < values.size(); ++k) sum += values[k];
    EXPECT_NEAR(sum, 1.0, 1e-4) << line;
    ++rows;
  }
  EXPECT_EQ(rows, kTestImages);

  // The same seed gives the same figures.
  ASSERT_EQ(scout("eval --checkpoint " + checkpoint() + test_data() + " --runs 3 --seed 2 --json " + path("again.json"))
                .status,
            0);
  const json again = read_json(path("again.json"));
  EXPECT_EQ(again["accuracy"], j["accuracy"]);
  EXPECT_EQ(again["confusion"], j["confusion"]);
  EXPECT_EQ(again["baselines"], j["baselines"]);
}

// eval runs in the precision the checkpoint was trained in (the CLI's default, auto, resolved
// for this CPU) unless --precision says otherwise; the report names it, never "auto".
TEST_F(EvalRun, EvalUsesTheCheckpointsPrecisionUnlessTold) {
  ASSERT_EQ(scout("eval --checkpoint " + checkpoint() + test_data() + " --runs 2 --json " + path("bf16.json")).status, 0);
  ASSERT_EQ(
      scout("eval --checkpoint " + checkpoint() + test_data() + " --runs 2 --precision fp32 --json " + path("fp32.json"))
          .status,
      0);
  const std::string resolved = scout::agent::to_string(scout::agent::resolve_precision(scout::agent::Precision::Auto));
  EXPECT_EQ(read_json(path("bf16.json"))["precision"], resolved);
  EXPECT_EQ(read_json(path("fp32.json"))["precision"], "fp32");
  const Result automatic = scout("eval --checkpoint " + checkpoint() + test_data() +
                                 " --runs 2 --precision auto --json " + path("auto.json"));
  ASSERT_EQ(automatic.status, 0) << automatic.output;
  EXPECT_NE(automatic.output.find("precision: " + resolved + " ("), std::string::npos) << automatic.output;
  EXPECT_EQ(read_json(path("auto.json"))["precision"], resolved);
  const Result bad = scout("eval --checkpoint " + checkpoint() + test_data() + " --precision fp16");
  EXPECT_EQ(bad.status, 2) << bad.output;
  EXPECT_NE(bad.output.find("--precision"), std::string::npos) << bad.output;
  EXPECT_EQ(bad.output.find('\n'), bad.output.size() - 1) << bad.output;
}

TEST_F(EvalRun, EvalRefusesBadInputWithOneLine) {
  const std::string text = temp_->write("notes.txt", "not a checkpoint\n").string();
  Result r = scout("eval --checkpoint " + text + test_data() + " --json " + path("r.json"));
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(r.output.rfind("scout: error: " + text + ": not a Scout checkpoint", 0), 0u) << r.output;
  EXPECT_EQ(r.output.find('\n'), r.output.size() - 1) << r.output;
  EXPECT_FALSE(fs::exists(path("r.json")));

  r = scout("eval --checkpoint " + checkpoint() + " --images " + path("data/t10k-labels-idx1-ubyte") + " --labels " +
            path("data/t10k-labels-idx1-ubyte"));
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(r.output.rfind("scout: error: " + path("data/t10k-labels-idx1-ubyte"), 0), 0u) << r.output;
  EXPECT_EQ(r.output.find('\n'), r.output.size() - 1) << r.output;

  r = scout("eval --checkpoint " + checkpoint() + " --images " + path("data/t10k-images-idx3-ubyte") + " --labels " +
            path("data/train-labels-idx1-ubyte"));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("expected 9 labels"), std::string::npos) << r.output;

  r = scout("eval --checkpoint " + path("missing.pt") + test_data());
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(r.output.rfind("scout: error: " + path("missing.pt"), 0), 0u) << r.output;

  // A bad command line is a usage error.
  r = scout("eval --checkpoint " + checkpoint() + test_data() + " --runs 0");
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.output.rfind("scout: usage error: --runs", 0), 0u) << r.output;
}

TEST_F(EvalRun, AnInterruptedEvalWritesNothing) {
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    const std::string ckpt = checkpoint(), images = path("data/t10k-images-idx3-ubyte"),
                      labels = path("data/t10k-labels-idx1-ubyte"), json_out = path("i.json"), csv_out = path("i.csv");
    std::freopen("/dev/null", "w", stderr);
    std::freopen("/dev/null", "w", stdout);
    execl(SCOUT_BINARY, SCOUT_BINARY, "eval", "--checkpoint", ckpt.c_str(), "--images", images.c_str(), "--labels",
          labels.c_str(), "--runs", "10000", "--json", json_out.c_str(), "--predictions", csv_out.c_str(),
          static_cast<char*>(nullptr));
    _exit(127);
  }
  usleep(1500 * 1000);  // well into the runs (10,000 take minutes)
  kill(child, SIGINT);
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130);
  EXPECT_FALSE(fs::exists(path("i.json")));
  EXPECT_FALSE(fs::exists(path("i.csv")));
}

TEST_F(EvalRun, RunWithACheckpointPredictsAndDrawsIt) {
  const Result r =
      scout("run " + world() + " --out " + path("out") + " --count 2 --checkpoint " + checkpoint() + " --heat-map");
  ASSERT_EQ(r.status, 0) << r.output;
  const json t = read_json(path("out") + "/trajectory.json");
  ASSERT_EQ(t["runs"].size(), 2u);
  for (const json& run : t["runs"]) {
    ASSERT_TRUE(run.contains("prediction")) << run.dump();
    const std::vector<double> p = run["probabilities"].get<std::vector<double>>();
    ASSERT_EQ(p.size(), 3u);
    double sum = 0;
    int best = 0;
    for (int c = 0; c < 3; ++c) {
      sum += p[c];
      if (p[c] > p[best]) best = c;
    }
    EXPECT_NEAR(sum, 1.0, 1e-5);
    EXPECT_EQ(run["prediction"].get<int>(), best);
    EXPECT_EQ(run["steps"].size(), 4u);
  }
  // E + 1 pictures a run; all carry the class bars (wider than the 120-px floor), the episode
  // pictures also the heat map's colour scale (wider than the final one).
  for (int k = 0; k < 2; ++k) {
    const std::string prefix = path("out") + "/images/run00" + std::to_string(k);
    const cv::Mat final_png = cv::imread(prefix + "_final.png");
    ASSERT_FALSE(final_png.empty());
    EXPECT_EQ(final_png.rows, 120);
    EXPECT_GT(final_png.cols, 120);
    for (int e = 0; e < 2; ++e) {
      const cv::Mat episode = cv::imread(prefix + "_episode" + std::to_string(e) + ".png");
      ASSERT_FALSE(episode.empty());
      EXPECT_GT(episode.cols, final_png.cols);
    }
  }
  const json m = read_json(path("out") + "/manifest.json");
  EXPECT_EQ(m["checkpoint"]["path"], checkpoint());
  EXPECT_EQ(m["checkpoint"]["sha256"].get<std::string>().size(), 64u);

  // Greedy: every choice is an argmax (both layers are learned), so from a fixed start on a fixed
  // digit the seed changes nothing.
  temp_->write("fixed.yaml", "floor: {dataset: " + path("data") +
                                 ", split: test, index: 4}\n"
                                 "robot: {start: [5, 6]}\n"
                                 "camera: {patch_px: 3}\n"
                                 "task: {episodes: 2, steps: 2}\n");
  for (const char* seed : {"4", "5"}) {
    const Result g = scout("run " + path("fixed.yaml") + " --out " + path(std::string("g") + seed) +
                           " --no-images --checkpoint " + checkpoint() + " --greedy --seed " + seed);
    ASSERT_EQ(g.status, 0) << g.output;
  }
  const json g4 = read_json(path("g4") + "/trajectory.json"), g5 = read_json(path("g5") + "/trajectory.json");
  EXPECT_EQ(g4["runs"][0]["steps"], g5["runs"][0]["steps"]);
  EXPECT_EQ(g4["runs"][0]["probabilities"], g5["runs"][0]["probabilities"]);

  // Without --checkpoint nothing of this appears.
  ASSERT_EQ(scout("run " + world() + " --out " + path("plain") + " --no-images").status, 0);
  const json plain = read_json(path("plain") + "/trajectory.json");
  EXPECT_FALSE(plain["runs"][0].contains("prediction"));
  EXPECT_FALSE(plain["runs"][0].contains("probabilities"));
  EXPECT_FALSE(read_json(path("plain") + "/manifest.json").contains("checkpoint"));
}

TEST_F(EvalRun, RunRefusesCheckpointOptionsThatCannotApply) {
  Result r = scout("run " + world() + " --out " + path("o1") + " --greedy");
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.output.rfind("scout: usage error: --greedy requires --checkpoint", 0), 0u) << r.output;
  r = scout("run " + world() + " --out " + path("o2") + " --heat-map");
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.output.rfind("scout: usage error: --heat-map requires --checkpoint", 0), 0u) << r.output;
  // Mode (i) only: no goal planner to draw.
  r = scout("run " + world() + " --out " + path("o3") + " --checkpoint " + checkpoint("run_i") + " --heat-map");
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(r.output.rfind("scout: error: " + checkpoint("run_i") + ": --heat-map: expected", 0), 0u) << r.output;
  const std::string text = temp_->write("notes.pt", "x").string();
  r = scout("run " + world() + " --out " + path("o4") + " --checkpoint " + text);
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(r.output.rfind("scout: error: " + text + ": not a Scout checkpoint", 0), 0u) << r.output;
  for (const char* o : {"o1", "o2", "o3", "o4"}) EXPECT_FALSE(fs::exists(path(o))) << o;
}

}  // namespace
