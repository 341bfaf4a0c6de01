// The `scout` program end to end: real world files, real data, real Box2D and OSMesa.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <set>
#include <string>

#include "tests/support/cli.hpp"
#include "tests/support/temp_dir.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

using Result = scout::testing::CliResult;

Result scout(const std::string& args) { return scout::testing::run_cli(SCOUT_BINARY, args); }

class Cli : public ::testing::Test {
 protected:
  scout::testing::TempDir temp_{"scout_cli"};
  const fs::path dir_ = temp_.path();

  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::string world(const std::string& name) const { return std::string(SCOUT_SOURCE_DIR) + "/worlds/" + name; }

  // A copy of the Fashion-MNIST preset with some lines replaced (the data needs no download).
  std::string write_world(const std::string& name, const std::string& from, const std::string& to) {
    std::ifstream in(world("fashion.yaml"));
    std::string text((std::istreambuf_iterator<char>(in)), {});
    if (!from.empty()) {
      const auto at = text.find(from);
      EXPECT_NE(at, std::string::npos) << from;
      if (at != std::string::npos) text.replace(at, from.size(), to);
    }
    std::ofstream(path(name)) << text;
    return path(name);
  }

  static json read_json(const fs::path& file) {
    std::ifstream in(file);
    return json::parse(in);
  }
};

TEST_F(Cli, RunWritesTrajectoryImagesAndManifest) {
  const Result r = scout("run " + world("fashion.yaml") + " --out " + path("out") + " --count 3");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find(path("out") + "/images"), std::string::npos) << r.output;

  const json t = read_json(path("out") + "/trajectory.json");
  EXPECT_EQ(t["seed"], 1);
  ASSERT_EQ(t["runs"].size(), 3u);
  for (const json& run : t["runs"]) {
    EXPECT_EQ(run["dataset"], "fashion-mnist");
    EXPECT_EQ(run["split"], "test");
    EXPECT_GE(run["label"].get<int>(), 0);
    EXPECT_LE(run["label"].get<int>(), 9);
    ASSERT_EQ(run["steps"].size(), 20u);  // E x T, no-op moves included
    int revealed = 0;
    std::array<int, 2> pose = {run["start"][0].get<int>(), run["start"][1].get<int>()};
    for (const json& s : run["steps"]) {
      const std::string axis = s["axis"];
      ASSERT_TRUE(axis == "h" || axis == "v" || axis == "none") << axis;
      const int dx = s["command"][0], dy = s["command"][1];
      if (axis == "none") {
        EXPECT_TRUE(dx == 0 && dy == 0);
      }
      if (axis == "h") {
        EXPECT_TRUE(dy == 0 && dx != 0 && std::abs(dx) <= 2);
      }
      if (axis == "v") {
        EXPECT_TRUE(dx == 0 && dy != 0 && std::abs(dy) <= 2);
      }
      if (s["sampled"].get<bool>()) {
        EXPECT_NE(axis, "none");
      }
      // The grid pose is the actual position's cell, and the robot went where it was told.
      const double x_m = s["pose_m"][0], y_m = s["pose_m"][1];
      EXPECT_EQ(s["grid_pose"][0].get<int>(), static_cast<int>(std::floor(x_m / 0.1)));
      EXPECT_EQ(s["grid_pose"][1].get<int>(), static_cast<int>(std::floor(y_m / 0.1)));
      EXPECT_EQ(s["grid_pose"][0].get<int>(), pose[0] + dx);
      EXPECT_EQ(s["grid_pose"][1].get<int>(), pose[1] + dy);
      pose = {s["grid_pose"][0].get<int>(), s["grid_pose"][1].get<int>()};
      EXPECT_GE(s["revealed_px"].get<int>(), revealed);
      revealed = s["revealed_px"];
      if (dx != 0 || dy != 0) {
        EXPECT_GE(s["ticks"].get<int>(), 3);  // driven at 1/3 px per tick
      }
    }
  }
  // E + 1 snapshots per run, readable PNGs at 10x.
  int images = 0;
  for (const auto& entry : fs::directory_iterator(path("out") + "/images")) {
    const cv::Mat png = cv::imread(entry.path().string());
    ASSERT_FALSE(png.empty()) << entry.path();
    EXPECT_EQ(png.rows, 280);
    ++images;
  }
  EXPECT_EQ(images, 3 * 5);

  const json m = read_json(path("out") + "/manifest.json");
  EXPECT_EQ(m["command_line"][1], "run");
  EXPECT_FALSE(m["git_commit"].get<std::string>().empty());
  EXPECT_TRUE(m["libraries"].contains("box2d"));
  EXPECT_TRUE(m["libraries"].contains("gl"));
  EXPECT_NE(m["world"].get<std::string>().find("patch_px: 6"), std::string::npos);
  ASSERT_EQ(m["data_sha256"].size(), 2u);  // t10k images and labels
  for (const auto& [file, hash] : m["data_sha256"].items()) EXPECT_EQ(hash.get<std::string>().size(), 64u) << file;
  // Nothing half-written is left beside the output.
  for (const auto& entry : fs::directory_iterator(dir_))
    EXPECT_EQ(entry.path().filename().string().find(".out.partial"), std::string::npos) << entry.path();
}

TEST_F(Cli, AnExistingOutputFolderIsRefusedUnlessOverwriting) {
  ASSERT_EQ(scout("run " + world("fashion.yaml") + " --no-images --out " + path("out")).status, 0);
  std::ofstream(path("out") + "/keep.txt") << "mine";
  const Result refused = scout("run " + world("fashion.yaml") + " --out " + path("out"));
  EXPECT_EQ(refused.status, 1);
  EXPECT_NE(refused.output.find("already exists"), std::string::npos) << refused.output;
  EXPECT_TRUE(fs::exists(path("out") + "/keep.txt"));
  const Result replaced = scout("run " + world("fashion.yaml") + " --out " + path("out") + " --overwrite");
  ASSERT_EQ(replaced.status, 0) << replaced.output;
  EXPECT_FALSE(fs::exists(path("out") + "/keep.txt"));
  EXPECT_TRUE(fs::exists(path("out") + "/trajectory.json"));
}

TEST_F(Cli, OverwriteNeverDestroysWhatIsNotScoutOutput) {
  // The current folder, its parents, the root and a folder of someone else's files are refused,
  // even with --overwrite, and keep their contents.
  fs::create_directories(path("work/sub"));
  std::ofstream(path("work/sub/keep.txt")) << "mine";
  const std::string in_sub = "cd " + path("work/sub") + " && " + SCOUT_BINARY + " run " + world("fashion.yaml");
  for (const std::string out : {".", "..", "./", "/"}) {
    Result r;
    FILE* pipe = popen((in_sub + " --overwrite --out " + out + " 2>&1").c_str(), "r");
    ASSERT_NE(pipe, nullptr);
    std::array<char, 4096> buffer{};
    while (std::fgets(buffer.data(), buffer.size(), pipe)) r.output += buffer.data();
    r.status = WEXITSTATUS(pclose(pipe));
    EXPECT_EQ(r.status, 1) << out;
    EXPECT_NE(r.output.find("refusing to write the output over"), std::string::npos) << r.output;
    EXPECT_TRUE(fs::exists(path("work/sub/keep.txt"))) << out;
  }
  const Result foreign = scout("run " + world("fashion.yaml") + " --overwrite --out " + path("work"));
  EXPECT_EQ(foreign.status, 1);
  EXPECT_NE(foreign.output.find("not a Scout output folder"), std::string::npos) << foreign.output;
  EXPECT_TRUE(fs::exists(path("work/sub/keep.txt")));
}

TEST_F(Cli, ATrailingSlashNamesTheSameFolder) {
  ASSERT_EQ(scout("run " + world("fashion.yaml") + " --no-images --out " + path("out") + "/").status, 0);
  ASSERT_TRUE(fs::exists(path("out") + "/trajectory.json"));
  const Result again =
      scout("run " + world("fashion.yaml") + " --no-images --seed 3 --overwrite --out " + path("out") + "/");
  ASSERT_EQ(again.status, 0) << again.output;
  EXPECT_EQ(read_json(path("out") + "/trajectory.json")["seed"], 3);
  // Only the output folder is left: no staging or old copies beside it.
  int entries = 0;
  for (const auto& entry : fs::directory_iterator(dir_)) entries += entry.path().filename() != "out";
  EXPECT_EQ(entries, 0);
}

TEST_F(Cli, ARunIsTheSameAloneAndInsideABatchOf240) {
  ASSERT_EQ(scout("run " + world("fashion.yaml") + " --out " + path("one") + " --count 1 --seed 42").status, 0);
  ASSERT_EQ(
      scout("run " + world("fashion.yaml") + " --out " + path("many") + " --count 240 --seed 42 --no-images").status,
      0);
  const json one = read_json(path("one") + "/trajectory.json");
  const json many = read_json(path("many") + "/trajectory.json");
  ASSERT_EQ(many["runs"].size(), 240u);
  EXPECT_EQ(one["runs"][0], many["runs"][0]);  // every field, poses bit for bit (JSON keeps 17 digits)
  EXPECT_NE(many["runs"][0]["steps"], many["runs"][1]["steps"]);
  // With `index: random` each run has its own digit.
  std::set<int> digits;
  for (const json& run : many["runs"]) digits.insert(run["index"].get<int>());
  EXPECT_EQ(digits.size(), 240u);
}

TEST_F(Cli, TheSeedDecidesTheRun) {
  ASSERT_EQ(scout("run " + world("fashion.yaml") + " --out " + path("a") + " --seed 7 --no-images").status, 0);
  ASSERT_EQ(scout("run " + world("fashion.yaml") + " --out " + path("b") + " --seed 7 --no-images").status, 0);
  ASSERT_EQ(scout("run " + world("fashion.yaml") + " --out " + path("c") + " --seed 8 --no-images").status, 0);
  const json a = read_json(path("a") + "/trajectory.json"), b = read_json(path("b") + "/trajectory.json"),
             c = read_json(path("c") + "/trajectory.json");
  EXPECT_EQ(a["runs"], b["runs"]);
  EXPECT_NE(a["runs"], c["runs"]);
  EXPECT_EQ(c["seed"], 8);
  // The largest seed is a seed; anything else that is not a 64-bit unsigned integer is a usage error.
  EXPECT_EQ(
      scout("run " + world("fashion.yaml") + " --out " + path("d") + " --seed 18446744073709551615 --no-images").status,
      0);
  for (const char* bad : {"-1", "18446744073709551616", "1e3", "0x10", "seven"}) {
    const Result r = scout("run " + world("fashion.yaml") + " --out " + path("e") + " --seed " + bad);
    EXPECT_EQ(r.status, 2) << bad;
    EXPECT_EQ(r.output.rfind("scout: usage error: --seed: expected an integer in [0, 18446744073709551615]", 0), 0u)
        << r.output;
    EXPECT_FALSE(fs::exists(path("e")));
  }
}

// One line on stderr, exit status 1, naming the file, the line and the field.
void expect_one_line_error(const Result& r, const std::string& prefix) {
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_EQ(r.output.rfind("scout: error: " + prefix, 0), 0u) << r.output;
  EXPECT_EQ(r.output.find('\n'), r.output.size() - 1) << r.output;
}

TEST_F(Cli, BadWorldsGiveOneClearLine) {
  const std::string big = write_world("big.yaml", "patch_px: 6", "patch_px: 40");
  expect_one_line_error(scout("run " + big + " --out " + path("o1")), big + ":16: camera.patch_px: expected");
  const std::string off = write_world("off.yaml", "start: random", "start: [3, 28]");
  expect_one_line_error(scout("run " + off + " --out " + path("o2")), off + ":11: robot.start: expected");
  const std::string index = write_world("index.yaml", "index: random", "index: 10000");
  expect_one_line_error(scout("run " + index + " --out " + path("o3")), index + ":5: floor.index: expected");
  const std::string typo = write_world("typo.yaml", "episodes: 4", "episode: 4");
  expect_one_line_error(scout("run " + typo + " --out " + path("o4")), typo + ":18: task.episode");
  expect_one_line_error(scout("run " + path("missing.yaml") + " --out " + path("o5")), path("missing.yaml"));
  const std::string nodata = write_world("nodata.yaml", "dataset: fashion-mnist", "dataset: " + path("nowhere"));
  const Result r = scout("run " + nodata + " --out " + path("o6"));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find(path("nowhere")), std::string::npos) << r.output;
  // No output folder is created for a refused run.
  for (const char* o : {"o1", "o2", "o3", "o4", "o5", "o6"}) EXPECT_FALSE(fs::exists(path(o))) << o;
}

TEST_F(Cli, APngFloorWorks) {
  cv::Mat floor(20, 32, CV_8UC1, cv::Scalar(0));
  cv::rectangle(floor, {4, 4}, {12, 10}, cv::Scalar(255), cv::FILLED);
  ASSERT_TRUE(cv::imwrite(path("floor.png"), floor));
  std::ofstream(path("png.yaml"))
      << "floor: {image: floor.png}\nrobot: {start: [8, 7]}\ntask: {episodes: 2, steps: 3}\n";
  const Result r = scout("run " + path("png.yaml") + " --out " + path("out"));
  ASSERT_EQ(r.status, 0) << r.output;
  const json t = read_json(path("out") + "/trajectory.json");
  EXPECT_TRUE(t["runs"][0]["label"].is_null());
  EXPECT_EQ(t["runs"][0]["steps"].size(), 6u);
  EXPECT_EQ(t["runs"][0]["start"], json::array({8, 7}));
  EXPECT_EQ(t["runs"][0]["steps"][0]["revealed_px"].get<int>() >= 36, true);
  const cv::Mat png = cv::imread(path("out") + "/images/run000_final.png");
  EXPECT_EQ(png.cols, 320);
  EXPECT_EQ(png.rows, 200);
  // Pictures are at most 16384 px a side: a scale beyond that is refused before any work.
  cv::Mat wide(20, 300, CV_8UC1, cv::Scalar(0));
  ASSERT_TRUE(cv::imwrite(path("floor.png"), wide));
  const Result big = scout("run " + path("png.yaml") + " --out " + path("big") + " --scale 64");
  EXPECT_EQ(big.status, 1);
  EXPECT_EQ(big.output.rfind("scout: error: --scale: expected at most 54 for a 300 x 20 floor", 0), 0u) << big.output;
  EXPECT_FALSE(fs::exists(path("big")));
}

TEST_F(Cli, DataInstallsMnistWithAManifestThenDoesNothing) {
  // Needs the npm registry (as `scout data` does); an offline machine can opt out explicitly.
  if (std::getenv("SCOUT_SKIP_NETWORK_TESTS") != nullptr) GTEST_SKIP() << "SCOUT_SKIP_NETWORK_TESTS is set";
  const Result first = scout("data --data " + path("data"));
  ASSERT_EQ(first.status, 0) << first.output;
  EXPECT_NE(first.output.find("8000 train, 1000 validation, 1000 test"), std::string::npos) << first.output;
  const json m = read_json(path("data") + "/mnist/manifest.json");
  EXPECT_EQ(m["data_sha256"].size(), 6u);
  const auto stamp = fs::last_write_time(path("data") + "/mnist/train-images-idx3-ubyte");
  const Result again = scout("data --data " + path("data"));
  ASSERT_EQ(again.status, 0) << again.output;
  EXPECT_NE(again.output.find("nothing to do"), std::string::npos) << again.output;
  EXPECT_EQ(fs::last_write_time(path("data") + "/mnist/train-images-idx3-ubyte"), stamp);
  // The installed data drives a run: the mnist world with this data folder.
  const Result run = scout("run " + world("mnist.yaml") + " --data " + path("data") + " --out " + path("out"));
  ASSERT_EQ(run.status, 0) << run.output;
  EXPECT_EQ(read_json(path("out") + "/trajectory.json")["runs"][0]["dataset"], "mnist");
  // So does a folder that holds the IDX files itself (as a user's MNIST download would).
  const Result direct =
      scout("run " + world("mnist.yaml") + " --data " + path("data") + "/mnist --out " + path("out2"));
  ASSERT_EQ(direct.status, 0) << direct.output;
  EXPECT_EQ(read_json(path("out2") + "/trajectory.json")["runs"], read_json(path("out") + "/trajectory.json")["runs"]);
}

TEST_F(Cli, AnInterruptedBenchWritesNoReport) {
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    const std::string world_file = world("fashion.yaml"), report = path("b.json");
    std::freopen("/dev/null", "w", stderr);
    std::freopen("/dev/null", "w", stdout);
    execl(SCOUT_BINARY, SCOUT_BINARY, "bench", "sim", "--world", world_file.c_str(), "--repeats", "10000", "--json",
          report.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  usleep(1500 * 1000);  // well into the timing loops (10,000 repeats take minutes)
  kill(child, SIGTERM);
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130);
  EXPECT_FALSE(fs::exists(path("b.json")));
}

TEST_F(Cli, AnInterruptedRunLeavesNothingBehind) {
  // A run far too long to finish, interrupted once it is writing: exit 130, no --out folder, no
  // staging folder.
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    const std::string world_file = world("fashion.yaml"), out = path("out");
    std::freopen("/dev/null", "w", stderr);
    std::freopen("/dev/null", "w", stdout);
    execl(SCOUT_BINARY, SCOUT_BINARY, "run", world_file.c_str(), "--out", out.c_str(), "--count", "1000000",
          static_cast<char*>(nullptr));
    _exit(127);
  }
  // Wait until the staging folder has images in it, then interrupt.
  bool writing = false;
  for (int k = 0; k < 200 && !writing; ++k) {
    usleep(50 * 1000);
    for (const auto& entry : fs::directory_iterator(dir_))
      if (entry.path().filename().string().find(".out.partial") == 0 && fs::exists(entry.path() / "images"))
        writing = !fs::is_empty(entry.path() / "images");
  }
  EXPECT_TRUE(writing);
  kill(child, SIGINT);
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130);
  EXPECT_FALSE(fs::exists(path("out")));
  EXPECT_TRUE(fs::is_empty(dir_)) << "a staging folder was left behind";
}

TEST_F(Cli, BenchReportsItsFiguresAsJson) {
  const Result r =
      scout("bench sim --world " + world("fashion.yaml") + " --robots 8 --repeats 3 --json " + path("b.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("physics + camera"), std::string::npos) << r.output;
  const json b = read_json(path("b.json"));
  EXPECT_EQ(b["robots"], 8);
  EXPECT_EQ(b["moves_per_rollout"], 20);
  for (const char* part : {"physics_and_camera", "physics", "camera", "cpu_crop"}) {
    EXPECT_GT(b["median_ms"][part].get<double>(), 0.0) << part;
  }
  // Driven, not teleported: a 1- or 2-px move at 1/3 px per tick takes 3 to 6 ticks.
  EXPECT_GE(b["ticks_per_driving_move"].get<double>(), 3.0);
  EXPECT_LE(b["ticks_per_driving_move"].get<double>(), 6.5);
  EXPECT_GT(b["peak_speed_mps"].get<double>(), 1.9);
  EXPECT_LE(b["peak_speed_mps"].get<double>(), 2.0 + 1e-4);
  EXPECT_FALSE(b["manifest"]["git_commit"].get<std::string>().empty());
}

TEST_F(Cli, HelpVersionAndUsageErrors) {
  const Result version = scout("--version");
  EXPECT_EQ(version.status, 0);
  EXPECT_EQ(version.output.rfind("scout ", 0), 0u) << version.output;
  for (const char* cmd : {"--help", "run --help", "data --help", "bench --help", "bench sim --help", "bench train --help",
                          "train --help", "eval --help", "export --help"}) {
    const Result help = scout(cmd);
    EXPECT_EQ(help.status, 0) << cmd;
    EXPECT_NE(help.output.find("Usage"), std::string::npos) << cmd;
  }
  // A bad command line is one line too, pointing at the right help.
  const Result missing = scout("run");
  EXPECT_EQ(missing.status, 2);
  EXPECT_EQ(missing.output, "scout: usage error: world is required (see scout run --help)\n");
  const Result unknown = scout("bench frobnicate");
  EXPECT_EQ(unknown.status, 2);
  EXPECT_EQ(unknown.output,
            "scout: usage error: unknown command 'frobnicate' (commands: sim, train; see scout bench --help)\n");
  const Result zero = scout("run " + world("fashion.yaml") + " --out " + path("x") + " --count 0");
  EXPECT_EQ(zero.status, 2);
  EXPECT_EQ(zero.output.rfind("scout: usage error: --count", 0), 0u) << zero.output;
  EXPECT_EQ(zero.output.find('\n'), zero.output.size() - 1) << zero.output;
  EXPECT_FALSE(fs::exists(path("x")));
}

}  // namespace
