// `scout train` end to end: a tiny run on synthetic 12 x 12 IDX floors writes its checkpoint,
// metrics and manifest; Ctrl-C saves a checkpoint that --resume finishes; bad checkpoints and
// conflicting options are refused with one line (real Box2D, real OSMesa, real LibTorch).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "agent/config.hpp"
#include "tests/support/cli.hpp"
#include "tests/support/temp_dir.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr int kSide = 12;

std::string read_text(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// Raw IDX train-* files of `count` 12 x 12 floors of two classes, told apart only by the
// top-left 3 x 3 block (black or white) over noise in [64, 192).
void write_train_idx(const fs::path& folder, int count) {
  fs::create_directories(folder);
  std::string images, labels;
  scout::testing::put_idx_headers(images, labels, count, kSide, kSide);
  std::uint32_t state = 12345;
  auto next = [&] { return state = state * 1664525u + 1013904223u; };
  for (int i = 0; i < count; ++i) {
    const int label = i % 2;
    labels.push_back(static_cast<char>(label));
    for (int y = 0; y < kSide; ++y)
      for (int x = 0; x < kSide; ++x) {
        const bool block = x < 3 && y < 3;
        images.push_back(static_cast<char>(block ? (label ? 255 : 0) : 64 + (next() >> 16) % 128));
      }
  }
  std::ofstream(folder / "train-images-idx3-ubyte", std::ios::binary) << images;
  std::ofstream(folder / "train-labels-idx1-ubyte", std::ios::binary) << labels;
}

struct Result {
  int status = -1;
  std::string out, err;
};

// Runs `scout ARGS` with stdout and stderr captured apart.
Result scout(const std::string& args, const fs::path& scratch) {
  const fs::path out = scratch / "stdout.txt", err = scratch / "stderr.txt";
  const std::string command =
      std::string(SCOUT_BINARY) + " " + args + " > '" + out.string() + "' 2> '" + err.string() + "'";
  Result r;
  const int raw = std::system(command.c_str());
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  r.out = read_text(out);
  r.err = read_text(err);
  return r;
}

// Options of every run here: tiny networks, one LibTorch thread (with more, OpenMP's busy-waiting
// makes runs side by side, as under `ctest -j`, many times slower).
const char* const kTiny =
    " --threads 1 --planner-width 4 --planner-depth 1 --classifier-width 8 --classifier-depth 2 --batch 10 "
    "--rollouts 2 --lr 0.003";

class TrainCli : public ::testing::Test {
 protected:
  // One data folder, world file and finished one-epoch run for the whole suite.
  static void SetUpTestSuite() {
    temp_ = new scout::testing::TempDir("scout_train_cli");
    const fs::path dir = temp_->path();
    write_train_idx(dir / "data", 48);  // 44 train + 4 validation, carved
    std::ofstream(dir / "world.yaml") << world_text(dir / "data", 3);
    std::ofstream(dir / "other.yaml") << world_text(dir / "data", 4);
    const Result r = scout(
        "train " + (dir / "world.yaml").string() + " --out " + (dir / "base").string() + " --epochs 1,0,0" + kTiny,
        dir);
    ASSERT_EQ(r.status, 0) << r.out << r.err;
  }
  static void TearDownTestSuite() {
    delete temp_;
    temp_ = nullptr;
  }
  static std::string world_text(const fs::path& data, int steps) {
    return "floor: {dataset: " + data.string() + ", split: train, index: random}\ncamera: {patch_px: 3}\n" +
           "task: {episodes: 1, steps: " + std::to_string(steps) + ", step_px: 2}\nseed: 5\n";
  }

  // A folder of this test, removed afterwards.
  scout::testing::TempDir local_{"scout_train_cli_test"};
  std::string path(const std::string& name) const { return (local_.path() / name).string(); }
  static std::string world() { return (temp_->path() / "world.yaml").string(); }
  static std::string base() { return (temp_->path() / "base").string(); }
  Result run(const std::string& args) const { return scout(args, local_.path()); }

  // A copy of the finished base run.
  std::string copy_of_base(const std::string& name) const {
    fs::copy(base(), path(name), fs::copy_options::recursive);
    return path(name);
  }

  static scout::testing::TempDir* temp_;
};
scout::testing::TempDir* TrainCli::temp_ = nullptr;

// Exit status 1, nothing on stdout, and exactly one line on stderr: "scout: error: ..." holding
// every one of `names`.
// status 1: "scout: error: ..." (bad input or files); status 2: "scout: usage error: ..." (a
// malformed command line).
void expect_one_line_error(const Result& r, const std::vector<std::string>& names, int status = 1) {
  EXPECT_EQ(r.status, status) << r.out << r.err;
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(r.err.rfind(status == 1 ? "scout: error: " : "scout: usage error: ", 0), 0u) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_EQ(r.err.back(), '\n') << r.err;
  for (const std::string& name : names) EXPECT_NE(r.err.find(name), std::string::npos) << name << " in " << r.err;
}

TEST_F(TrainCli, ATinyRunWritesCheckpointMetricsAndManifest) {
  const Result r = run("train " + world() + " --out " + path("run") + " --epochs 1,1,1 --seed 7" + kTiny);
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("(1 LibTorch threads, bf16;"), std::string::npos) << r.out;
  for (const char* mode : {"mode i   epoch   1:", "mode ii  epoch   1:", "mode iii epoch   1:"})
    EXPECT_NE(r.out.find(mode), std::string::npos) << mode << " in " << r.out;
  EXPECT_TRUE(fs::is_regular_file(path("run") + "/checkpoint.pt"));
  EXPECT_GT(fs::file_size(path("run") + "/checkpoint.pt"), 1000u);

  const std::vector<std::string> rows = lines_of(read_text(path("run") + "/metrics.csv"));
  ASSERT_EQ(rows.size(), 4u);
  EXPECT_EQ(rows[0], "mode,epoch,reward,loss,train_accuracy,validation_accuracy,images_per_s,seconds,learning_rate");
  const char* modes[] = {"i", "ii", "iii"};
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(rows[k + 1].rfind(std::string(modes[k]) + ",1,", 0), 0u) << rows[k + 1];
    EXPECT_EQ(std::count(rows[k + 1].begin(), rows[k + 1].end(), ','), 8) << rows[k + 1];
    // Accuracies are fractions.
    std::vector<double> fields;
    std::istringstream in(rows[k + 1].substr(rows[k + 1].find(',', rows[k + 1].find(',') + 1) + 1));
    for (std::string f; std::getline(in, f, ',');) fields.push_back(std::stod(f));
    ASSERT_EQ(fields.size(), 7u);
    EXPECT_LE(fields[0], 0.0);  // reward = log pi_c[label]
    for (int a : {2, 3}) {
      EXPECT_GE(fields[a], 0.0);
      EXPECT_LE(fields[a], 1.0);
    }
    EXPECT_GT(fields[4], 0.0);      // images per second
    EXPECT_EQ(fields[6], 0.003);    // the epoch's learning rate (--lr)
  }

  std::ifstream in(path("run") + "/manifest.json");
  const json m = json::parse(in);
  ASSERT_TRUE(m.contains("command_line")) << m.dump(2);
  EXPECT_EQ(m["command_line"][1], "train");
  EXPECT_FALSE(m["git_commit"].get<std::string>().empty());
  ASSERT_TRUE(m["libraries"].contains("libtorch")) << m.dump(2);
  EXPECT_FALSE(m["libraries"]["libtorch"].get<std::string>().empty());
  // The data files read: train-* only (validation is carved out of them).
  ASSERT_EQ(m["data_sha256"].size(), 2u) << m.dump(2);
  for (const auto& [file, hash] : m["data_sha256"].items()) {
    EXPECT_NE(file.find("train-"), std::string::npos) << file;
    EXPECT_EQ(hash.get<std::string>().size(), 64u) << file;
  }
  EXPECT_EQ(m["torch_threads"], 1);
  EXPECT_EQ(m["config"]["network"]["planner_width"], 4);
  EXPECT_EQ(m["config"]["epochs"], json::parse("[1,1,1]"));
  EXPECT_EQ(m["config"]["seed"], 7);
  EXPECT_NE(m["world"].get<std::string>().find("patch_px: 3"), std::string::npos);
}

// Ctrl-C in a long schedule: exit 130, a checkpoint is saved (and said so), and --resume
// continues it to the end of a shortened schedule: one row per epoch, in order.
TEST_F(TrainCli, ControlCSavesACheckpointThatResumeFinishes) {
  const std::string out = path("stdout_long.txt"), err = path("stderr_long.txt"), run_dir = path("run");
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    const int out_fd = open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int err_fd = open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(out_fd, 1);
    dup2(err_fd, 2);
    const std::string args =
        std::string(SCOUT_BINARY) + " train " + world() + " --out " + run_dir + " --epochs 1,1,100000" + kTiny;
    execl("/bin/sh", "sh", "-c", ("exec " + args).c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  // Wait (a generous bound, never asserted on) until the first epoch has been reported.
  bool epoch_done = false;
  for (int k = 0; k < 6000 && !epoch_done; ++k) {
    usleep(50 * 1000);
    epoch_done = read_text(out).find("mode i   epoch   1:") != std::string::npos;
    int status = 0;
    if (waitpid(child, &status, WNOHANG) == child) FAIL() << "scout train ended early: " << read_text(err);
  }
  EXPECT_TRUE(epoch_done) << read_text(out) << read_text(err);
  kill(child, SIGINT);
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130) << read_text(err);
  const std::string said = read_text(err);
  EXPECT_NE(said.find("checkpoint saved"), std::string::npos) << said;
  EXPECT_NE(said.find(run_dir + "/checkpoint.pt"), std::string::npos) << said;
  ASSERT_TRUE(fs::is_regular_file(run_dir + "/checkpoint.pt"));

  // Epochs of mode (iii) finished before the interrupt; finish the one in progress.
  std::vector<std::string> rows = lines_of(read_text(run_dir + "/metrics.csv"));
  ASSERT_GE(rows.size(), 2u);
  const int done_iii = static_cast<int>(
      std::count_if(rows.begin(), rows.end(), [](const std::string& row) { return row.rfind("iii,", 0) == 0; }));
  const int last = done_iii + 1;
  const Result resumed = run("train --resume " + run_dir + " --epochs 1,1," + std::to_string(last));
  ASSERT_EQ(resumed.status, 0) << resumed.out << resumed.err;
  EXPECT_NE(resumed.out.find("resuming after"), std::string::npos) << resumed.out;

  rows = lines_of(read_text(run_dir + "/metrics.csv"));
  ASSERT_EQ(rows.size(), static_cast<std::size_t>(1 + 2 + last)) << read_text(run_dir + "/metrics.csv");
  EXPECT_EQ(rows[1].rfind("i,1,", 0), 0u) << rows[1];
  EXPECT_EQ(rows[2].rfind("ii,1,", 0), 0u) << rows[2];
  for (int e = 1; e <= last; ++e) EXPECT_EQ(rows[2 + e].rfind("iii," + std::to_string(e) + ",", 0), 0u) << rows[2 + e];
  // The manifest records the resumption.
  std::ifstream in(run_dir + "/manifest.json");
  const json m = json::parse(in);
  EXPECT_EQ(m["resumed"].size(), 1u) << m.dump(2);
  // Resuming a finished run trains nothing more.
  const Result again = run("train --resume " + run_dir);
  EXPECT_EQ(again.status, 0) << again.out << again.err;
  EXPECT_NE(again.out.find("nothing to do"), std::string::npos) << again.out;
  EXPECT_EQ(lines_of(read_text(run_dir + "/metrics.csv")).size(), rows.size());
  std::ifstream in_again(run_dir + "/manifest.json");
  EXPECT_EQ(json::parse(in_again)["resumed"].size(), 1u);  // nothing was resumed
}

TEST_F(TrainCli, BadCheckpointsAreRefusedWithOneLine) {
  // Garbage where the checkpoint should be.
  const std::string garbage = copy_of_base("garbage");
  std::ofstream(garbage + "/checkpoint.pt", std::ios::binary | std::ios::trunc) << "PK\x03\x04 not a checkpoint";
  expect_one_line_error(run("train --resume " + garbage), {garbage + "/checkpoint.pt"});
  // A real checkpoint cut short.
  const std::string truncated = copy_of_base("truncated");
  const std::string bytes = read_text(truncated + "/checkpoint.pt");
  std::ofstream(truncated + "/checkpoint.pt", std::ios::binary | std::ios::trunc) << bytes.substr(0, bytes.size() / 2);
  expect_one_line_error(run("train --resume " + truncated), {truncated + "/checkpoint.pt"});
  // A folder without one.
  fs::create_directories(path("empty"));
  expect_one_line_error(run("train --resume " + path("empty")), {"--resume", path("empty")});
  // Nothing was written into the refused folders.
  EXPECT_EQ(read_text(truncated + "/checkpoint.pt"), bytes.substr(0, bytes.size() / 2));
  EXPECT_TRUE(fs::is_empty(path("empty")));
}

TEST_F(TrainCli, AResumedRunKeepsItsConfig) {
  const std::string copy = copy_of_base("copy");
  const std::string checkpoint = read_text(copy + "/checkpoint.pt");
  expect_one_line_error(run("train --resume " + copy + " --planner-width 8"), {"--planner-width", copy, "4", "8"});
  const std::string other = (temp_->path() / "other.yaml").string();
  expect_one_line_error(run("train " + other + " --resume " + copy), {other});
  expect_one_line_error(run("train --resume " + copy + " --out " + path("elsewhere")), {"--out"});
  // The run was trained at the default, auto: what it resolved to on this CPU; the other is refused.
  const std::string trained = scout::agent::to_string(scout::agent::resolve_precision(scout::agent::Precision::Auto));
  const std::string other_precision = trained == "bf16" ? "fp32" : "bf16";
  expect_one_line_error(run("train --resume " + copy + " --precision " + other_precision),
                        {"--precision", trained, other_precision});
  EXPECT_EQ(read_text(copy + "/checkpoint.pt"), checkpoint);
  EXPECT_FALSE(fs::exists(path("elsewhere")));
  // The same world and the same options are accepted (and there is nothing left to train).
  const Result same = run("train " + world() + " --resume " + copy + " --planner-width 4");
  EXPECT_EQ(same.status, 0) << same.out << same.err;
  // The learning rate is the one option a resumed run may change (fine-tuning at a lower rate).
  const Result lower = run("train --resume " + copy + " --epochs 2,0,0 --lr 0.001");
  ASSERT_EQ(lower.status, 0) << lower.out << lower.err;
  EXPECT_NE(lower.out.find("learning rate 0.003 -> 0.001"), std::string::npos) << lower.out;
  const std::vector<std::string> rows = lines_of(read_text(copy + "/metrics.csv"));
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[1].substr(rows[1].rfind(',')), ",0.003");
  EXPECT_EQ(rows[2].substr(rows[2].rfind(',')), ",0.001");
}

// --epochs on --resume may extend a finished run's schedule (learn/training.hpp): the run
// continues right after its last epoch, first in the stage it was in.
TEST_F(TrainCli, ResumeExtendsAFinishedSchedule) {
  const std::string copy = copy_of_base("extend");
  const Result r = run("train --resume " + copy + " --epochs 2,1,0");
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  const std::vector<std::string> rows = lines_of(read_text(copy + "/metrics.csv"));
  ASSERT_EQ(rows.size(), 4u) << read_text(copy + "/metrics.csv") << r.out;
  EXPECT_EQ(rows[1], lines_of(read_text(base() + "/metrics.csv"))[1]);
  EXPECT_EQ(rows[2].rfind("i,2,", 0), 0u) << rows[2];
  EXPECT_EQ(rows[3].rfind("ii,1,", 0), 0u) << rows[3];
  // The manifest keeps the first command line and records the resumption's.
  std::ifstream in(copy + "/manifest.json");
  const json m = json::parse(in);
  EXPECT_EQ(m["command_line"][1], "train");
  ASSERT_EQ(m["resumed"].size(), 1u) << m.dump(2);
  const json& resumed = m["resumed"][0];
  EXPECT_EQ(resumed["command_line"][2], "--resume") << resumed.dump();
  EXPECT_EQ(resumed["epochs"], json::array({2, 1, 0}));
  EXPECT_EQ(resumed["learning_rate"], 0.003);
}

TEST_F(TrainCli, BadOptionsAreRefusedWithOneLine) {
  // An existing --out folder is never trained into.
  fs::create_directories(path("exists"));
  expect_one_line_error(run("train " + world() + " --out " + path("exists") + kTiny), {"--out", path("exists")});
  EXPECT_TRUE(fs::is_empty(path("exists")));
  // A schedule with no epoch at all.
  expect_one_line_error(run("train " + world() + " --out " + path("o") + " --epochs 0,0,0"), {"--epochs"});
  EXPECT_FALSE(fs::exists(path("o")));
  for (const char* epochs : {"1,2", "a,b,c", "1,2,3,4", "1,,2"}) {
    expect_one_line_error(run("train " + world() + " --out " + path("o") + " --epochs " + epochs), {"--epochs"}, 2);
    EXPECT_FALSE(fs::exists(path("o"))) << epochs;
  }
  expect_one_line_error(run("train " + world() + " --out " + path("o") + " --classifier foo"), {"--classifier", "foo"},
                        2);
  expect_one_line_error(run("train " + world() + " --out " + path("o") + " --freeze foo"), {"--freeze", "foo"}, 2);
  expect_one_line_error(run("train " + world() + " --out " + path("o") + " --precision fp16"),
                        {"--precision", "fp16"}, 2);
  EXPECT_FALSE(fs::exists(path("o")));
}

// A resumed run reads only the data it was trained on: changed files are refused by their SHA-256.
TEST_F(TrainCli, ResumeRefusesDataThatChanged) {
  write_train_idx(path("data"), 48);
  std::ofstream(path("world.yaml")) << world_text(path("data"), 3);
  ASSERT_EQ(run("train " + path("world.yaml") + " --out " + path("run") + " --epochs 1,0,0" + kTiny).status, 0);
  // The same data again: resumes.
  const Result same = run("train --resume " + path("run") + " --epochs 2,0,0");
  ASSERT_EQ(same.status, 0) << same.out << same.err;
  // Other digits under the same names: refused, and the run is untouched.
  write_train_idx(path("data"), 50);
  const std::string before = read_text(path("run") + "/checkpoint.pt");
  expect_one_line_error(run("train --resume " + path("run") + " --epochs 3,0,0"),
                        {"train-images-idx3-ubyte", "SHA-256"});
  EXPECT_EQ(read_text(path("run") + "/checkpoint.pt"), before);
}

// scout export: a model file (no optimizer state) that eval reads exactly as it reads the run.
TEST_F(TrainCli, ExportWritesASmallModelThatEvalReadsLikeTheRun) {
  const std::string model = path("model.pt");
  const Result r = run("export " + base() + " --out " + model);
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_NE(r.out.find(model), std::string::npos) << r.out;
  const auto run_size = fs::file_size(base() + "/checkpoint.pt"), model_size = fs::file_size(model);
  EXPECT_LT(model_size, run_size);  // Adam's two moments per weight are gone
  // The same figures from the model as from the run (same weights, history and config).
  const std::string data = (temp_->path() / "data").string();
  const std::string inputs =
      " --images " + data + "/train-images-idx3-ubyte --labels " + data + "/train-labels-idx1-ubyte --runs 2";
  ASSERT_EQ(run("eval --checkpoint " + base() + inputs + " --json " + path("a.json")).status, 0);
  ASSERT_EQ(run("eval --checkpoint " + model + inputs + " --json " + path("b.json")).status, 0);
  json a = json::parse(read_text(path("a.json"))), b = json::parse(read_text(path("b.json")));
  for (const char* key : {"accuracy", "top2", "confusion", "baselines", "full_image_accuracy", "precision"})
    EXPECT_EQ(a[key], b[key]) << key;
  EXPECT_EQ(a["precision"], scout::agent::to_string(scout::agent::resolve_precision(scout::agent::Precision::Auto)));

  // Refusals: an existing file (unless --overwrite), a missing folder, something not a checkpoint.
  const std::string before = read_text(model);
  expect_one_line_error(run("export " + base() + " --out " + model), {"--out", model, "--overwrite"});
  EXPECT_EQ(read_text(model), before);
  EXPECT_EQ(run("export " + base() + " --out " + model + " --overwrite").status, 0);
  expect_one_line_error(run("export " + base() + " --out " + path("no/such/m.pt")), {"--out", "no/such"});
  std::ofstream(path("junk.pt")) << "not a checkpoint";
  expect_one_line_error(run("export " + path("junk.pt") + " --out " + path("m2.pt")), {path("junk.pt")});
  EXPECT_FALSE(fs::exists(path("m2.pt")));
}

// scout bench train: every mode asked for, with its images/s and the shares of a step.
TEST_F(TrainCli, BenchTrainReportsEachModeAndWhereTheTimeGoes) {
  const std::string report = path("bench.json");
  const Result r = run("bench train --world " + world() +
                       " --modes i,iii --batch 4 --rollouts 2 --batches 2 --warmup 0 --threads 1 --planner-width 4 "
                       "--planner-depth 1 --classifier strided --classifier-width 8 --classifier-depth 2 --json " +
                       report);
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("planners 4 x 1"), std::string::npos) << r.out;
  const json j = json::parse(read_text(report));
  EXPECT_EQ(j["robots"], 8);
  EXPECT_EQ(j["precision"], scout::agent::to_string(scout::agent::resolve_precision(scout::agent::Precision::Auto)));
  EXPECT_EQ(j["network"]["classifier"], "strided");
  EXPECT_EQ(j["network"]["classifier_width"], 8);
  ASSERT_EQ(j["modes"].size(), 2u);
  EXPECT_EQ(j["modes"][0]["mode"], "i");
  EXPECT_EQ(j["modes"][1]["mode"], "iii");
  for (const json& m : j["modes"]) {
    EXPECT_GT(m["images_per_s"].get<double>(), 0) << m;
    double parts = 0;
    for (const char* part : {"physics", "render", "state", "forward", "backward", "optimizer"}) {
      const double share = m["share"][part].get<double>();
      EXPECT_GE(share, 0) << part;
      parts += share;
    }
    // The parts are disjoint pieces of the step and cover nearly all of it.
    EXPECT_LE(parts, 1.0 + 1e-9) << m;
    EXPECT_GT(parts, 0.8) << m;
    EXPECT_GT(m["share"]["physics"].get<double>(), 0) << m;
    EXPECT_GT(m["share"]["backward"].get<double>(), 0) << m;
  }
  // Mode (i) never consults the action planner; mode (iii) does, where the protocol chooses.
  EXPECT_EQ(j["modes"][0]["action_decisions_per_batch"].get<double>(), 0);
  EXPECT_GT(j["modes"][1]["action_decisions_per_batch"].get<double>(), 0);

  expect_one_line_error(run("bench train --world " + world() + " --modes i,iv"), {"--modes", "iv"}, 2);
  expect_one_line_error(run("bench train --world " + world() + " --modes ii,ii"), {"--modes"}, 2);
  expect_one_line_error(run("bench train --world " + world() + " --modes i,"), {"--modes"}, 2);
  // A report that cannot be written is refused before any timing.
  expect_one_line_error(run("bench train --world " + world() + " --json " + path("no/such/b.json")), {"--json"});
  fs::create_directories(path("folder"));
  expect_one_line_error(run("bench train --world " + world() + " --json " + path("folder")), {"--json", "folder"});
}

}  // namespace
