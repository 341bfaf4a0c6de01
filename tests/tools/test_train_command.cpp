// `scout train` (tools/train_command.cpp) end to end: a tiny run on synthetic 12 x 12 IDX floors writes its checkpoint,
// metrics and manifest; Ctrl-C saves a checkpoint that --resume finishes; bad checkpoints and
// conflicting options are refused with one line (real Box2D, real OSMesa, real LibTorch).

#include <fcntl.h>
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
#include "tests/support/train_cli_fixture.hpp"

namespace scout::testing::train_command_train_cli_tests {

using namespace scout::testing::train_cli_support;

TEST_F(TrainCli, ATinyRunWritesCheckpointMetricsAndManifest) {
  const Result r = run("train " + world() + " --out " + path("run") + " --epochs 1,1,1 --seed 7" + kTiny);
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  // auto: the faster precision on this CPU, as measured and cached (fp32 where bf16 would be emulated).
  const std::string resolved = scout::agent::to_string(scout::learn::resolve_precision(scout::agent::Precision::Auto));
  EXPECT_NE(r.out.find("(1 LibTorch threads, " + resolved + ";"), std::string::npos) << r.out;
  for (const char* mode : {"mode i   epoch   1:", "mode ii  epoch   1:", "mode iii epoch   1:"})
    EXPECT_NE(r.out.find(mode), std::string::npos) << mode << " in " << r.out;
  EXPECT_TRUE(fs::is_regular_file(path("run") + "/checkpoint.safetensors"));
  EXPECT_GT(fs::file_size(path("run") + "/checkpoint.safetensors"), 1000u);

  const std::vector<std::string> rows = lines_of(read_text(path("run") + "/metrics.csv"));
  ASSERT_EQ(rows.size(), 4u);
  EXPECT_EQ(rows[0],
            "mode,epoch,reward,loss,train_accuracy,validation_accuracy,images_per_s,seconds,learning_rate,"
            "validation_iid,validation_goals_only,validation_full_image,gradient_norm");
  const char* modes[] = {"i", "ii", "iii"};
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(rows[k + 1].rfind(std::string(modes[k]) + ",1,", 0), 0u) << rows[k + 1];
    EXPECT_EQ(std::count(rows[k + 1].begin(), rows[k + 1].end(), ','), 12) << rows[k + 1];
    // Accuracies are fractions.
    std::vector<double> fields;
    std::istringstream in(rows[k + 1].substr(rows[k + 1].find(',', rows[k + 1].find(',') + 1) + 1));
    // An empty field (NaN here) is a figure not measured: goals only, before mode (ii).
    for (std::string f; std::getline(in, f, ',');) fields.push_back(f.empty() ? std::nan("") : std::stod(f));
    if (rows[k + 1].back() == ',') fields.push_back(std::nan(""));
    ASSERT_EQ(fields.size(), 11u);
    EXPECT_LE(fields[0], 0.0);  // reward = log pi_c[label]
    EXPECT_EQ(std::isnan(fields[8]), k == 0) << rows[k + 1];
    for (int a : {2, 3, 7, 8, 9}) {  // train, validation, and validation's baselines and full images
      if (a == 8 && k == 0) continue;
      EXPECT_GE(fields[a], 0.0);
      EXPECT_LE(fields[a], 1.0);
    }
    EXPECT_GT(fields[4], 0.0);    // images per second
    EXPECT_EQ(fields[6], 0.003);  // the epoch's learning rate (--lr)
    EXPECT_GT(fields[10], 0.0);   // the mean norm of the steps' gradients
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

// --init-from starts a new run from a model's weights: with every layer frozen, the new run's
// checkpoint holds exactly the model's weights; the manifest names the model by path and SHA-256;
// a network option that contradicts the model is refused, except --occupancy, which adds the
// channel; and a resumed run cannot take it.
TEST_F(TrainCli, InitFromStartsANewRunFromAModelsWeights) {
  const std::string frozen = " --epochs 1,0,0 --freeze goal,action,classifier --seed 3";
  const Result r = run("train " + world() + " --out " + path("init") + " --init-from " + base() + frozen + kTiny);
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  const scout::testing::CliResult same = scout::testing::run_cli(
      COMPARE_WEIGHTS, "'" + base() + "/checkpoint.safetensors' '" + path("init") + "/checkpoint.safetensors'");
  ASSERT_EQ(same.status, 0) << same.output;
  EXPECT_NE(same.output.find(" 1 "), std::string::npos) << "expected identical weights: " << same.output;
  // Without --init-from the same command starts from the seed's initialisation instead.
  ASSERT_EQ(run("train " + world() + " --out " + path("fresh") + frozen + kTiny).status, 0);
  const scout::testing::CliResult fresh = scout::testing::run_cli(
      COMPARE_WEIGHTS, "'" + base() + "/checkpoint.safetensors' '" + path("fresh") + "/checkpoint.safetensors'");
  EXPECT_NE(fresh.output.find(" 0 "), std::string::npos) << fresh.output;

  std::ifstream in(path("init") + "/manifest.json");
  const json m = json::parse(in);
  ASSERT_TRUE(m.contains("init_from")) << m.dump(2);
  EXPECT_EQ(fs::path(m["init_from"]["file"].get<std::string>()),
            fs::absolute(fs::path(base()) / "checkpoint.safetensors"));
  EXPECT_EQ(m["init_from"]["sha256"].get<std::string>().size(), 64u);

  expect_one_line_error(run("train " + world() + " --out " + path("wider") + " --init-from " + base() + frozen + kTiny +
                            " --classifier strided"),
                        {"--classifier: --init-from " + base() + " has paper, the command line asks for strided"});
  EXPECT_FALSE(fs::exists(path("wider")));

  const Result occupancy = run("train " + world() + " --out " + path("occupancy") + " --init-from " + base() + frozen +
                               kTiny + " --occupancy");
  ASSERT_EQ(occupancy.status, 0) << occupancy.out << occupancy.err;
  std::ifstream occupancy_manifest(path("occupancy") + "/manifest.json");
  EXPECT_EQ(json::parse(occupancy_manifest)["config"]["network"]["occupancy"], true);

  expect_one_line_error(run("train --resume " + path("init") + " --init-from " + base()),
                        {"--init-from: a resumed run continues from its own checkpoint"});
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
  EXPECT_NE(said.find(run_dir + "/checkpoint.safetensors"), std::string::npos) << said;
  ASSERT_TRUE(fs::is_regular_file(run_dir + "/checkpoint.safetensors"));

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
  std::ofstream(garbage + "/checkpoint.safetensors", std::ios::binary | std::ios::trunc)
      << "PK\x03\x04 not a checkpoint";
  expect_one_line_error(run("train --resume " + garbage), {garbage + "/checkpoint.safetensors"});
  // A real checkpoint cut short.
  const std::string truncated = copy_of_base("truncated");
  const std::string bytes = read_text(truncated + "/checkpoint.safetensors");
  std::ofstream(truncated + "/checkpoint.safetensors", std::ios::binary | std::ios::trunc)
      << bytes.substr(0, bytes.size() / 2);
  expect_one_line_error(run("train --resume " + truncated), {truncated + "/checkpoint.safetensors"});
  // A folder without one.
  fs::create_directories(path("empty"));
  expect_one_line_error(run("train --resume " + path("empty")), {"--resume", path("empty")});
  // Nothing was written into the refused folders.
  EXPECT_EQ(read_text(truncated + "/checkpoint.safetensors"), bytes.substr(0, bytes.size() / 2));
  EXPECT_TRUE(fs::is_empty(path("empty")));
}

TEST_F(TrainCli, AResumedRunKeepsItsConfig) {
  const std::string copy = copy_of_base("copy");
  const std::string checkpoint = read_text(copy + "/checkpoint.safetensors");
  expect_one_line_error(run("train --resume " + copy + " --planner-width 8"), {"--planner-width", copy, "4", "8"});
  // A frozen layer is part of the run's config too (the schema table's resume column).
  expect_one_line_error(run("train --resume " + copy + " --freeze goal"), {"--freeze", copy, "goal"});
  const std::string other = (temp_->path() / "other.yaml").string();
  expect_one_line_error(run("train " + other + " --resume " + copy), {other});
  expect_one_line_error(run("train --resume " + copy + " --out " + path("elsewhere")), {"--out"});
  EXPECT_EQ(read_text(copy + "/checkpoint.safetensors"), checkpoint);
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
  // learning_rate is the ninth column.
  auto rate = [](const std::string& row) {
    std::size_t at = 0;
    for (int comma = 0; comma < 8; ++comma) at = row.find(',', at) + 1;
    return row.substr(at, row.find(',', at) - at);
  };
  EXPECT_EQ(rate(rows[0]), "learning_rate");
  EXPECT_EQ(rate(rows[1]), "0.003");
  EXPECT_EQ(rate(rows[2]), "0.001");
}

// --epochs on --resume may extend a finished run's schedule (learn/trainer.hpp): the run
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

// A bf16 run resumed where bf16 is not native (here: oneDNN capped to AVX2, the stand-in for such a
// CPU) does not silently continue emulated: without --precision it is refused with one line naming
// the flag; --precision fp32 continues it in fp32 and says so; the manifest records it.
TEST_F(TrainCli, ABf16RunResumedWithoutNativeBf16NeedsPrecision) {
  if (const std::string why = scout::agent::bf16_unavailable(); !why.empty())
    GTEST_SKIP() << "bf16 cannot run here: " << why;
  const char* const no_native_bf16 = "ONEDNN_MAX_CPU_ISA=AVX2 ATEN_CPU_CAPABILITY=avx2";
  const Result trained =
      run("train " + world() + " --out " + path("bf16") + " --epochs 1,0,0 --precision bf16" + kTiny);
  ASSERT_EQ(trained.status, 0) << trained.out << trained.err;
  const std::string checkpoint = read_text(path("bf16") + "/checkpoint.safetensors");
  expect_one_line_error(run("train --resume " + path("bf16") + " --epochs 2,0,0", no_native_bf16),
                        {"--precision fp32", "bf16", path("bf16")});
  EXPECT_EQ(read_text(path("bf16") + "/checkpoint.safetensors"), checkpoint);
  const Result fp32 = run("train --resume " + path("bf16") + " --epochs 2,0,0 --precision fp32", no_native_bf16);
  ASSERT_EQ(fp32.status, 0) << fp32.out << fp32.err;
  EXPECT_NE(fp32.out.find("precision bf16 -> fp32 from the next batch on"), std::string::npos) << fp32.out;
  std::ifstream in(path("bf16") + "/manifest.json");
  const json m = json::parse(in);
  EXPECT_EQ(m["config"]["precision"], "bf16");
  ASSERT_EQ(m["resumed"].size(), 1u) << m.dump(2);
  EXPECT_EQ(m["resumed"][0]["precision"], "fp32");
  EXPECT_EQ(lines_of(read_text(path("bf16") + "/metrics.csv")).size(), 3u);
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
  expect_one_line_error(run("train " + world() + " --out " + path("o") + " --precision fp16"), {"--precision", "fp16"},
                        2);
  // Numbers are checked against the settings' table as the command line reads them.
  expect_one_line_error(run("train " + world() + " --out " + path("o") + " --lr 0"), {"--lr", "(0, 10)"}, 2);
  expect_one_line_error(run("train " + world() + " --out " + path("o") + " --entropy-bonus 100"),
                        {"--entropy-bonus", "[0, 100)"}, 2);
  // Settings that disagree name the options: the leave-one-out baseline needs two rollouts.
  expect_one_line_error(run("train " + world() + " --out " + path("o") + " --baseline --rollouts 1"),
                        {"--baseline: the leave-one-out baseline needs --rollouts >= 2"});
  // Planners that read the wider view need a world that has one.
  expect_one_line_error(
      run("train " + world() + " --out " + path("o") + " --wide-view" + kTiny),
      {"camera.wide_px: expected a wider view (wide_px > 0) for planners that read it (--wide-view)"});
  EXPECT_FALSE(fs::exists(path("o")));
}

// A batch of more robots than one camera draws (render::kMaxCameraRobots) is refused before
// anything is read or made, with one line naming both options; so is the training bench's.
TEST_F(TrainCli, ABatchTheCameraCannotDrawIsRefusedUpFront) {
  expect_one_line_error(run("train " + world() + " --out " + path("o") + " --batch 128 --rollouts 64"),
                        {"--batch x --rollouts: expected at most 4096 robots (what one camera draws), got 128 x 64"});
  EXPECT_FALSE(fs::exists(path("o")));
  expect_one_line_error(run("bench train --world " + world() + " --batch 4096 --rollouts 2"),
                        {"--batch x --rollouts", "4096 robots"});
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
  const std::string before = read_text(path("run") + "/checkpoint.safetensors");
  expect_one_line_error(run("train --resume " + path("run") + " --epochs 3,0,0"),
                        {"train-images-idx3-ubyte", "SHA-256"});
  EXPECT_EQ(read_text(path("run") + "/checkpoint.safetensors"), before);
}

// --entropy-bonus end to end: the same tiny run through mode (ii) with and without it trains
// other weights (the mode (ii) epoch's loss differs; mode (i) has no learned layer to reward, so
// its row is the same), and the run's config records it.
TEST_F(TrainCli, TheEntropyBonusChangesTrainingAndIsRecorded) {
  const std::string args = "train " + world() + " --epochs 1,1,0" + kTiny + " --precision fp32 --out ";
  const Result plain = run(args + path("plain"));
  ASSERT_EQ(plain.status, 0) << plain.out << plain.err;
  const Result bonus = run(args + path("bonus") + " --entropy-bonus 2");
  ASSERT_EQ(bonus.status, 0) << bonus.out << bonus.err;
  const std::vector<std::string> a = lines_of(read_text(path("plain") + "/metrics.csv")),
                                 b = lines_of(read_text(path("bonus") + "/metrics.csv"));
  ASSERT_EQ(a.size(), 3u);
  ASSERT_EQ(b.size(), 3u);
  auto fields = [](const std::string& row, int first, int last) {  // columns [first, last)
    std::vector<std::string> out;
    std::stringstream in(row);
    std::string f;
    for (int k = 0; std::getline(in, f, ','); ++k)
      if (k >= first && k < last) out.push_back(f);
    return out;
  };
  // mode,epoch,reward,loss,train_accuracy,validation_accuracy: the same in mode (i), not in (ii).
  EXPECT_EQ(fields(a[1], 0, 6), fields(b[1], 0, 6)) << a[1] << "\n" << b[1];
  EXPECT_NE(fields(a[2], 3, 4), fields(b[2], 3, 4)) << a[2] << "\n" << b[2];
  std::ifstream pm(path("plain") + "/manifest.json"), bm(path("bonus") + "/manifest.json");
  EXPECT_EQ(json::parse(pm)["config"]["entropy_bonus"], 0.0);
  EXPECT_EQ(json::parse(bm)["config"]["entropy_bonus"], 2.0);
  // A resumed run keeps it and refuses another.
  const std::string copy = path("bonus");
  expect_one_line_error(run("train --resume " + copy + " --entropy-bonus 1"), {"--entropy-bonus", "2", "1"});
}

// The same data moved to another folder: --resume with --data takes it (the files' SHA-256 match
// what the run recorded); without --data the run's old folder is gone and the resume is refused.
// The world names its data set (`dataset: mnist`), so the data folder comes from --data.
TEST_F(TrainCli, ResumeReadsTheSameDataMovedWithData) {
  write_train_idx(path("data") + "/mnist", 48);
  std::ofstream(path("world.yaml")) << "floor: {dataset: mnist, split: train, index: random}\ncamera: {patch_px: 3}\n"
                                       "task: {episodes: 1, steps: 3, step_px: 2}\nseed: 5\n";
  const Result first = run("train " + path("world.yaml") + " --data " + path("data") + " --out " + path("run") +
                           " --epochs 1,0,0" + kTiny);
  ASSERT_EQ(first.status, 0) << first.out << first.err;
  fs::rename(path("data"), path("moved"));
  const Result lost = run("train --resume " + path("run") + " --epochs 2,0,0");
  EXPECT_EQ(lost.status, 1) << lost.out << lost.err;
  EXPECT_NE(lost.err.find(path("data")), std::string::npos) << lost.err;
  const Result moved = run("train --resume " + path("run") + " --epochs 2,0,0 --data " + path("moved"));
  ASSERT_EQ(moved.status, 0) << moved.out << moved.err;
  const std::vector<std::string> rows = lines_of(read_text(path("run") + "/metrics.csv"));
  ASSERT_EQ(rows.size(), 3u) << read_text(path("run") + "/metrics.csv");
  EXPECT_EQ(rows[2].rfind("i,2,", 0), 0u) << rows[2];
}

// A NaN or infinite loss at the command line: exit status 1 with one line naming the loss, the
// last good checkpoint and metrics.csv kept as they were. The NaN comes from a classifier weight
// set to NaN in a finished run's checkpoint (by a helper program; LibTorch stays out of this test).
TEST_F(TrainCli, ANonFiniteLossExitsWithStatusOneAndKeepsTheCheckpoint) {
  const std::string copy = copy_of_base("nan");
  const std::string checkpoint = copy + "/checkpoint.safetensors";
  const CliResult poisoned = run_cli(POISON_CHECKPOINT, checkpoint);
  ASSERT_EQ(poisoned.status, 0) << poisoned.output;
  const std::string before = read_text(checkpoint), metrics = read_text(copy + "/metrics.csv");
  const Result r = run("train --resume " + copy + " --epochs 2,0,0");
  EXPECT_EQ(r.status, 1) << r.out << r.err;
  // The error is stderr's last line (progress lines may come before it).
  const std::size_t at = r.err.find("scout: error: ");
  ASSERT_NE(at, std::string::npos) << r.err;
  const std::string line = r.err.substr(at);
  EXPECT_EQ(std::count(line.begin(), line.end(), '\n'), 1) << r.err;
  EXPECT_NE(line.find("loss"), std::string::npos) << line;
  EXPECT_NE(line.find("nan"), std::string::npos) << line;
  EXPECT_NE(line.find(checkpoint), std::string::npos) << line;
  EXPECT_TRUE(read_text(checkpoint) == before) << "the last good checkpoint was overwritten";
  EXPECT_EQ(read_text(copy + "/metrics.csv"), metrics);
}

TEST_F(TrainCli, CheckpointsInsideAnEpochSoThatAKillLosesMinutesNotAnEpoch) {
  const std::string run_dir = path("run");
  const fs::path out = local_.path() / "kill.out", err = local_.path() / "kill.err";
  // Epochs of 44 batches of one image, a checkpoint after every batch (--checkpoint-every below
  // a batch's time): killed with SIGKILL, the run resumes inside an epoch.
  std::vector<std::string> argv = {SCOUT_BINARY,         "train",  world(), "--out", run_dir, "--epochs", "100000,0,0",
                                   "--checkpoint-every", "0.00002"};
  std::istringstream tiny(kTiny);
  for (std::string w; tiny >> w;) argv.push_back(argv.back() == "--batch" ? "1" : w);
  // The kill may land just after an epoch's last checkpoint (its cursor then starts the next
  // epoch): try again then, a few times at most.
  int batch = 0;
  for (int attempt = 0; attempt < 5 && batch == 0; ++attempt) {
    const pid_t child = scout::testing::spawn(argv, out, err);
    ASSERT_TRUE(scout::testing::wait_for_text(child, out, "mode i   epoch", 300)) << read_text(err);
    usleep(150 * 1000);
    kill(child, SIGKILL);
    int status = 0;
    waitpid(child, &status, 0);
    // Finish the epoch in progress: "resuming after E epoch(s) (stage 1, epoch E, batch B)".
    const std::size_t rows = lines_of(read_text(run_dir + "/metrics.csv")).size();
    const Result resumed = run("train --resume " + run_dir + " --epochs " + std::to_string(rows) + ",0,0");
    ASSERT_EQ(resumed.status, 0) << resumed.out << resumed.err;
    const auto at = resumed.out.find(", batch ");
    ASSERT_NE(at, std::string::npos) << resumed.out;
    batch = std::stoi(resumed.out.substr(at + 8));
    // Such a checkpoint is a whole one: the epoch it was in is finished from it.
    EXPECT_EQ(lines_of(read_text(run_dir + "/metrics.csv")).size(), rows + 1);
    argv = {SCOUT_BINARY, "train", "--resume", run_dir, "--epochs", "100000,0,0", "--checkpoint-every", "0.00002"};
  }
  EXPECT_GT(batch, 0);
}

// Requests that cannot fit are refused before they allocate, with the estimate; a user's cap
// (SCOUT_MEMORY_LIMIT) counts as the machine's, and --force runs anyway.
// Two writers of one run folder would overwrite each other's checkpoints: while one scout train
// runs on a folder, a second (a resume, or a new run of the same name) is refused with one line,
// and the first goes on to a checkpoint that a later resume continues.
TEST_F(TrainCli, ASecondTrainOnARunFolderInUseIsRefused) {
  const std::string run_dir = path("run");
  ASSERT_EQ(run("train " + world() + " --out " + run_dir + " --epochs 1,0,0" + kTiny).status, 0);
  const fs::path out = local_.path() / "first.out", err = local_.path() / "first.err";
  const pid_t first =
      scout::testing::spawn({SCOUT_BINARY, "train", "--resume", run_dir, "--epochs", "100000,0,0"}, out, err);
  ASSERT_TRUE(scout::testing::wait_for_text(first, out, "mode i   epoch", 300)) << read_text(err);  // training
  const std::string checkpoint_before = read_text(run_dir + "/checkpoint.safetensors");
  const Result second = run("train --resume " + run_dir + " --epochs 100000,0,0");
  EXPECT_EQ(second.status, 1) << second.out << second.err;
  EXPECT_EQ(std::count(second.err.begin(), second.err.end(), '\n'), 1) << second.err;
  EXPECT_NE(second.err.find("--resume: " + run_dir + ": another scout train is writing this run"), std::string::npos)
      << second.err;
  const Result renewed = run("train " + world() + " --out " + run_dir + " --epochs 1,0,0" + kTiny);
  EXPECT_EQ(renewed.status, 1) << renewed.err;
  EXPECT_NE(renewed.err.find(run_dir + " exists"), std::string::npos) << renewed.err;
  kill(first, SIGINT);
  int status = 0;
  ASSERT_EQ(waitpid(first, &status, 0), first);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130) << read_text(err);
  // The first run's checkpoint is its own (it trained on from the one it resumed), and a resume
  // after it continues from there.
  EXPECT_NE(read_text(run_dir + "/checkpoint.safetensors"), checkpoint_before);
  const std::size_t rows = lines_of(read_text(run_dir + "/metrics.csv")).size();
  const Result after = run("train --resume " + run_dir + " --epochs " + std::to_string(rows) + ",0,0");
  EXPECT_EQ(after.status, 0) << after.out << after.err;
  EXPECT_NE(after.out.find("resuming after"), std::string::npos) << after.out;
}

TEST_F(TrainCli, AnEstimateBeyondTheAvailableMemoryIsRefusedUnlessForced) {
  // 64 x 64 robots (the most one camera draws) with 16 planner blocks 512 wide: hundreds of GiB of
  // activations on these 12 x 12 floors, beyond a 64 GiB cap on any host (without the cap a host
  // with more memory than the estimate would start training; the message names whichever bound is
  // the smallest).
  ::setenv("SCOUT_MEMORY_LIMIT", "64G", 1);
  const Result huge =
      run("train " + world() + " --out " + path("huge") +
          " --epochs 1,0,0 --batch 64 --rollouts 64 --planner-width 512 --planner-depth 16 --threads 1");
  EXPECT_EQ(huge.status, 1) << huge.err;
  EXPECT_EQ(std::count(huge.err.begin(), huge.err.end(), '\n'), 1) << huge.err;
  for (const char* part :
       {"scout: error: training B x N = 64 x 64 robots", "needs about", "GiB of memory", "is available", "--force"})
    EXPECT_NE(huge.err.find(part), std::string::npos) << part << " in " << huge.err;
  EXPECT_FALSE(fs::exists(path("huge")));  // nothing left behind

  ::setenv("SCOUT_MEMORY_LIMIT", "1M", 1);
  const Result capped = run("train " + world() + " --out " + path("capped") + " --epochs 1,0,0" + kTiny);
  EXPECT_EQ(capped.status, 1) << capped.err;
  EXPECT_NE(capped.err.find("1.0 MiB is available (SCOUT_MEMORY_LIMIT)"), std::string::npos) << capped.err;
  const Result forced = run("train " + world() + " --out " + path("forced") + " --epochs 1,0,0 --force" + kTiny);
  ::unsetenv("SCOUT_MEMORY_LIMIT");
  EXPECT_EQ(forced.status, 0) << forced.err;
  EXPECT_TRUE(fs::is_regular_file(path("forced") + "/checkpoint.safetensors"));
}

}  // namespace scout::testing::train_command_train_cli_tests
