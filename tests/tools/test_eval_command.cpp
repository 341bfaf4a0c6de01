// scout eval (tools/eval_command.cpp): the reference report (a fixed model, fixed digits and seed,
// fp32), the same bits twice on one machine and within fp32's rounding of tests/tools/golden/ on
// every CPU.
//
// Then `scout eval` end to end on tiny checkpoints made here by `scout train` (EvalRun).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "agent/config.hpp"
#include "learn/auto_precision.hpp"
#include "tests/support/cli.hpp"
#include "tests/support/eval_run_fixture.hpp"
#include "tests/support/temp_dir.hpp"

namespace scout::testing {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

std::string read_text(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// The rows of a predictions CSV: index, label, then D probabilities printed to 6 decimals.
std::vector<std::vector<double>> csv_rows(const fs::path& file) {
  std::vector<std::vector<double>> rows;
  std::ifstream in(file);
  std::string line;
  std::getline(in, line);  // the header
  while (std::getline(in, line)) {
    std::vector<double> row;
    std::istringstream cells(line);
    for (std::string cell; std::getline(cells, cell, ',');) row.push_back(std::stod(cell));
    rows.push_back(std::move(row));
  }
  return rows;
}

// A printed probability may differ from the reference by this much on another CPU. The reference
// was made on an AMD EPYC (AVX-512 BF16) and is reproduced bit for bit on an Intel Xeon (AVX-512,
// AMX); another CPU's kernels may sum in another order (unit roundoff u = 2^-24 = 6.0e-8). The
// classifier's longest sums are its global average over 28 x 28 = 784 positions (its dense 3 x 3
// convolutions sum at most 49 x 9 = 441 terms), each off by about sqrt(n) u <= 1.7e-6 relative;
// through its five stages (three convolutions, the pooling, the head) the logits are off by about
// 8.4e-6 relative, 8.4e-5 for logits up to 10 in size, and a softmax probability moves by at most
// 2 p (1 - p) <= 1/2 of that: 4.2e-5. Printing to 6 decimals adds up to one unit, 1e-6, where a
// value lies at a rounding boundary: 4.3e-5, so 5e-5. (Measured: the files made with AVX-512 and
// with AVX2 kernels differed in 3 of 640 printed values, by 1e-6 each.) The report's figures are
// counts of right guesses and seen pixels: equal on every CPU unless one of the run's ~4,000
// sampled moves flips, which probabilities moved by ~1e-6 make a matter of chance (of order 1e-2
// per run) that is not budgeted for: such a CPU fails the comparison, and the reference would be
// rewritten there to see it.
constexpr double kPrintedProbabilityTolerance = 5e-5;

// The reference evaluation: a fixed model (the 8,000-digit model of December 2026, kept in
// tests/data so that retraining the shipped model does not move it), 64 fixed test digits, seed
// 5, three runs, fp32. Evaluated twice: the report and the probabilities are the same bits both
// times on this machine, and on every CPU the report equals tests/tools/golden/eval-fp32.json and
// the probabilities lie within kPrintedProbabilityTolerance of eval-fp32-predictions.csv. A change
// meant to change them rewrites the golden files with scripts/write_reference.sh and says why.
TEST(EvalCommand, TheReferenceReportIsReproducedOnEveryCpu) {
  const fs::path source = SCOUT_SOURCE_DIR;
  const fs::path golden = source / "tests/tools/golden";
  TempDir temp("eval-reference");
  const fs::path subset = source / "tests/data/mnist-subset";
  auto evaluate = [&](const std::string& name) {
    const fs::path report = temp.path() / (name + ".json"), predictions = temp.path() / (name + ".csv");
    const CliResult r = run_cli(
        SCOUT_BINARY, "eval --checkpoint " + (source / "tests/data/mnist-8k-v1.safetensors").string() + " --images " +
                          (subset / "t10k-images-idx3-ubyte").string() + " --labels " +
                          (subset / "t10k-labels-idx1-ubyte").string() + " --runs 3 --seed 5 --precision fp32 --json " +
                          report.string() + " --predictions " + predictions.string());
    EXPECT_EQ(r.status, 0) << r.output;
    json got = json::parse(read_text(report));
    // What depends on the machine, the clock or the paths is not compared.
    for (const char* volatile_key : {"seconds", "manifest", "checkpoint"}) got.erase(volatile_key);
    return std::pair{got, predictions};
  };
  const auto [got, predictions] = evaluate("first");
  if (const char* write = std::getenv("SCOUT_WRITE_REFERENCE"); write != nullptr && std::string(write) == "1") {
    std::ofstream(golden / "eval-fp32.json") << got.dump(2) << "\n";
    fs::copy_file(predictions, golden / "eval-fp32-predictions.csv", fs::copy_options::overwrite_existing);
    GTEST_SKIP() << "wrote " << golden;
  }
  const auto [again, again_predictions] = evaluate("second");
  EXPECT_EQ(again, got) << "two evaluations on one machine differ";
  EXPECT_EQ(read_text(again_predictions), read_text(predictions)) << "two evaluations on one machine differ";
  EXPECT_EQ(got, json::parse(read_text(golden / "eval-fp32.json"))) << "got " << got.dump(1);
  const std::vector<std::vector<double>> rows = csv_rows(predictions),
                                         want = csv_rows(golden / "eval-fp32-predictions.csv");
  ASSERT_EQ(rows.size(), want.size());
  double largest = 0;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    ASSERT_EQ(rows[i].size(), want[i].size()) << "row " << i;
    EXPECT_EQ(rows[i][0], want[i][0]) << "row " << i << ": index";
    EXPECT_EQ(rows[i][1], want[i][1]) << "row " << i << ": label";
    for (std::size_t c = 2; c < rows[i].size(); ++c) {
      largest = std::max(largest, std::abs(rows[i][c] - want[i][c]));
      EXPECT_NEAR(rows[i][c], want[i][c], kPrintedProbabilityTolerance) << "row " << i << ", p" << c - 2;
    }
  }
  std::printf("[ measured ] largest difference from the reference probabilities %.3g\n", largest);
}

}  // namespace
}  // namespace scout::testing

namespace scout::testing::eval_command_eval_run_tests {

using namespace scout::testing::eval_run_support;

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

// eval runs in this CPU's best precision (auto) unless --precision says otherwise, whatever the
// checkpoint was trained in; the report names it, never "auto".
TEST_F(EvalRun, EvalUsesThisCpusPrecisionUnlessTold) {
  ASSERT_EQ(
      scout("eval --checkpoint " + checkpoint() + test_data() + " --runs 2 --json " + path("default.json")).status, 0);
  ASSERT_EQ(scout("eval --checkpoint " + checkpoint() + test_data() + " --runs 2 --precision fp32 --json " +
                  path("fp32.json"))
                .status,
            0);
  const std::string resolved = scout::agent::to_string(scout::learn::resolve_precision(scout::agent::Precision::Auto));
  EXPECT_EQ(read_json(path("default.json"))["precision"], resolved);
  EXPECT_EQ(read_json(path("fp32.json"))["precision"], "fp32");
  const Result automatic = scout("eval --checkpoint " + checkpoint() + test_data() +
                                 " --runs 2 --precision auto --json " + path("auto.json"));
  ASSERT_EQ(automatic.status, 0) << automatic.output;
  EXPECT_NE(automatic.output.find("precision: " + resolved + " ("), std::string::npos) << automatic.output;
  // The progress line, at least at the end.
  EXPECT_NE(automatic.output.find("scout eval: greedy run: "), std::string::npos) << automatic.output;
  EXPECT_NE(automatic.output.find(" rollouts (100 %), "), std::string::npos) << automatic.output;
  EXPECT_EQ(read_json(path("auto.json"))["precision"], resolved);
  const Result bad = scout("eval --checkpoint " + checkpoint() + test_data() + " --precision fp16");
  EXPECT_EQ(bad.status, 2) << bad.output;
  EXPECT_NE(bad.output.find("--precision"), std::string::npos) << bad.output;
  EXPECT_EQ(bad.output.find('\n'), bad.output.size() - 1) << bad.output;
}

// A model trained in bf16 (tests/data/mnist-8k-v1.safetensors) on a CPU without native bf16 (oneDNN capped
// to AVX2: the stand-in for one) runs in fp32 and says why. Under the stand-in bf16 cannot run at
// all (LibTorch sends it to oneDNN, which the cap forbids): asked for, it is refused with one line.
TEST(EvalCommand, ABf16ModelRunsInFp32WhereBf16IsNotNative) {
  TempDir temp("eval-precision");
  const fs::path source = SCOUT_SOURCE_DIR;
  const fs::path subset = source / "tests/data/mnist-subset";
  const std::string no_native_bf16 =
      "env ONEDNN_MAX_CPU_ISA=AVX2 ATEN_CPU_CAPABILITY=avx2 " + std::string(SCOUT_BINARY);
  const std::string args = "eval --checkpoint " + (source / "tests/data/mnist-8k-v1.safetensors").string() +
                           " --images " + (subset / "t10k-images-idx3-ubyte").string() + " --labels " +
                           (subset / "t10k-labels-idx1-ubyte").string() + " --runs 1 --limit 8 --json ";
  const CliResult automatic = run_cli(no_native_bf16, args + (temp.path() / "auto.json").string());
  ASSERT_EQ(automatic.status, 0) << automatic.output;
  EXPECT_EQ(json::parse(read_text(temp.path() / "auto.json"))["precision"], "fp32");
  EXPECT_NE(automatic.output.find("precision: fp32 ("), std::string::npos) << automatic.output;
  EXPECT_NE(automatic.output.find("the model was trained in bf16"), std::string::npos) << automatic.output;
  const CliResult forced = run_cli(no_native_bf16, args + (temp.path() / "bf16.json").string() + " --precision bf16");
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512dq")) {
    EXPECT_EQ(forced.status, 2) << forced.output;
    EXPECT_NE(forced.output.find("--precision: bf16: ONEDNN_MAX_CPU_ISA=AVX2"), std::string::npos) << forced.output;
    EXPECT_EQ(forced.output.find('\n'), forced.output.size() - 1) << forced.output;
    EXPECT_FALSE(fs::exists(temp.path() / "bf16.json"));
    return;
  }
  // A CPU without AVX-512: bf16 runs emulated (LibTorch's own kernels), and says so.
  ASSERT_EQ(forced.status, 0) << forced.output;
  EXPECT_EQ(json::parse(read_text(temp.path() / "bf16.json"))["precision"], "bf16");
  EXPECT_NE(forced.output.find("emulated"), std::string::npos) << forced.output;
}

TEST_F(EvalRun, EvalRefusesBadInputWithOneLine) {
  const std::string text = temp_->write("notes.txt", "not a checkpoint\n").string();
  Result r = scout("eval --checkpoint " + text + test_data() + " --json " + path("r.json"));
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(r.output.rfind("scout: error: " + text + ": not a valid safetensors file", 0), 0u) << r.output;
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

  r = scout("eval --checkpoint " + path("missing.safetensors") + test_data());
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(r.output.rfind("scout: error: " + path("missing.safetensors"), 0), 0u) << r.output;

  // A bad command line is a usage error.
  r = scout("eval --checkpoint " + checkpoint() + test_data() + " --runs 0");
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.output.rfind("scout: usage error: --runs", 0), 0u) << r.output;
}

// SIGINT once the evaluation has started (eval says so on stderr once its inputs are read):
// exit 130, and neither the report nor the predictions are written.
TEST_F(EvalRun, AnInterruptedEvalWritesNothing) {
  const std::string out = path("i_stdout.txt"), err = path("i_stderr.txt");
  const pid_t child =
      scout::testing::spawn({SCOUT_BINARY, "eval", "--checkpoint", checkpoint(), "--images",
                             path("data/t10k-images-idx3-ubyte"), "--labels", path("data/t10k-labels-idx1-ubyte"),
                             "--runs", "10000", "--json", path("i.json"), "--predictions", path("i.csv")},
                            out, err);
  ASSERT_GT(child, 0);
  int early = 0;
  const bool started = scout::testing::wait_for_text(child, err, "scout eval: evaluating, 10000 runs", 600, &early);
  if (!started) kill(child, SIGKILL);
  ASSERT_TRUE(started) << "eval never started (status " << early << "): " << scout::testing::read_file(err);
  kill(child, SIGINT);
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130) << scout::testing::read_file(err);
  EXPECT_FALSE(fs::exists(path("i.json")));
  EXPECT_FALSE(fs::exists(path("i.csv")));
  EXPECT_EQ(scout::testing::read_file(out), "") << "a table was printed";
}

// A checkpoint without a learned goal layer (mode (i) only) has no goals-only baseline: `null` in
// the report, "n/a" in the table; the one through mode (iii) has a number there.
TEST_F(EvalRun, TheGoalsOnlyBaselineIsNullForAModeICheckpoint) {
  const Result r =
      scout("eval --checkpoint " + checkpoint("run_i") + test_data() + " --runs 2 --json " + path("i.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("n/a (no learned goal layer)"), std::string::npos) << r.output;
  const json j = read_json(path("i.json"));
  ASSERT_TRUE(j["baselines"].contains("goals_only")) << j.dump(1);
  EXPECT_TRUE(j["baselines"]["goals_only"].is_null()) << j.dump(1);
  EXPECT_EQ(j["learned"]["goals"], false);
  EXPECT_TRUE(j["baselines"]["iid"].is_number()) << j.dump(1);

  ASSERT_EQ(scout("eval --checkpoint " + checkpoint() + test_data() + " --runs 2 --json " + path("iii.json")).status,
            0);
  const json iii = read_json(path("iii.json"));
  EXPECT_TRUE(iii["baselines"]["goals_only"].is_number()) << iii.dump(1);
  EXPECT_EQ(iii["learned"]["goals"], true);
}

// --world with another task (a 5 x 5 patch, one episode of three moves): the report names that
// world, and the same seed gives other figures than the checkpoint's own world.
TEST_F(EvalRun, AnotherWorldChangesTheTaskAndTheReportNamesIt) {
  const std::string other = temp_
                                ->write("other_task.yaml", "floor: {dataset: " + path("data") +
                                                               ", split: test, index: random}\n"
                                                               "camera: {patch_px: 5}\n"
                                                               "task: {episodes: 1, steps: 3}\n")
                                .string();
  const std::string common = test_data() + " --runs 3 --seed 4 --precision fp32";
  ASSERT_EQ(scout("eval --checkpoint " + checkpoint() + common + " --json " + path("own.json") + " --predictions " +
                  path("own.csv"))
                .status,
            0);
  const Result r = scout("eval --checkpoint " + checkpoint() + common + " --world " + other + " --json " +
                         path("other.json") + " --predictions " + path("other.csv"));
  ASSERT_EQ(r.status, 0) << r.output;
  const json own = read_json(path("own.json")), moved = read_json(path("other.json"));
  EXPECT_EQ(own["world"], world());
  EXPECT_EQ(moved["world"], other);
  EXPECT_EQ(moved["images"], kTestImages);
  // The classifier on full images does not depend on the task; what the robots see does.
  EXPECT_EQ(moved["full_image_accuracy"], own["full_image_accuracy"]);
  EXPECT_NE(scout::testing::read_file(path("other.csv")), scout::testing::read_file(path("own.csv")));
}

}  // namespace scout::testing::eval_command_eval_run_tests
