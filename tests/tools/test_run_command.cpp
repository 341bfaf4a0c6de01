// `scout run` (tools/run_command.cpp) end to end: real world files, real data, real Box2D and
// OSMesa; with a trained checkpoint (predictions, pictures, greedy) on tiny models made here.

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
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "tests/support/cli_fixture.hpp"
#include "tests/support/eval_run_fixture.hpp"

namespace scout::testing::run_command_cli_tests {

using namespace scout::testing::cli_support;

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

// Floors bigger than the view: the robot drives the real Box2D world over a 60 x 60 cluttered
// floor through the real camera; trajectory.json says where the digit and the clutter went, and
// what the camera saw there agrees with the floor rebuilt from the split.
TEST_F(Cli, ACompositeFloorRunsAndTellsWhereItsDigitLay) {
  std::ofstream(path("c.yaml"))
      << "floor: {dataset: mnist-10k, split: validation, size_px: [60, 50], layout: cluttered,"
         " clutter: 5}\ncamera: {patch_px: 8}\ntask: {episodes: 3, steps: 4, step_px: 4}\n";
  const Result r = scout("run " + path("c.yaml") + " --out " + path("out") + " --count 6");
  ASSERT_EQ(r.status, 0) << r.output;
  const json t = read_json(path("out") + "/trajectory.json");
  ASSERT_EQ(t["runs"].size(), 6u);
  std::set<std::pair<int, int>> places;
  for (const json& run : t["runs"]) {
    EXPECT_EQ(run["floor_px"], json::array({60, 50}));
    ASSERT_EQ(run["digits"].size(), 1u);
    const json& digit = run["digits"][0];
    EXPECT_EQ(digit["index"], run["index"]);
    EXPECT_EQ(digit["label"], run["label"]);
    const int x = digit["at"][0], y = digit["at"][1];
    EXPECT_TRUE(x >= 0 && x <= 32 && y >= 0 && y <= 22) << x << "," << y;
    places.insert({x, y});
    ASSERT_EQ(run["clutter"].size(), 5u);
    for (const json& piece : run["clutter"]) EXPECT_NE(piece["index"], run["index"]);
    ASSERT_EQ(run["steps"].size(), 12u);
    for (const json& s : run["steps"]) {
      const int gx = s["grid_pose"][0], gy = s["grid_pose"][1];
      EXPECT_TRUE(gx >= 0 && gx < 60 && gy >= 0 && gy < 50) << gx << "," << gy;
      EXPECT_LE(std::abs(s["command"][0].get<int>()) + std::abs(s["command"][1].get<int>()), 4);
    }
    EXPECT_GE(run["steps"].back()["revealed_px"].get<int>(), 64);
  }
  EXPECT_GE(places.size(), 5u) << "each run places its digit anew";
  // The pictures show the whole 60 x 50 floor.
  const cv::Mat png = cv::imread(path("out") + "/images/run000_final.png");
  EXPECT_EQ(png.rows, 500);
  EXPECT_GE(png.cols, 600);
}

TEST_F(Cli, AnInterruptedRunLeavesNothingBehind) {
  // A run far too long to finish, interrupted once it is writing: exit 130, no --out folder, no
  // staging folder.
  const std::string program = SCOUT_BINARY;
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    const std::string world_file = world("fashion.yaml"), out = path("out");
    std::freopen("/dev/null", "w", stderr);
    std::freopen("/dev/null", "w", stdout);
    execl(program.c_str(), program.c_str(), "run", world_file.c_str(), "--out", out.c_str(), "--count", "1000000",
          static_cast<char*>(nullptr));
    _exit(127);
  }
  // Wait until the staging folder has images in it (polling, with a generous bound that is never
  // a pass condition by itself), then interrupt.
  bool writing = false;
  for (int k = 0; k < 12000 && !writing; ++k) {  // up to 10 minutes
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

// Run k's seed and digit depend on k and the command's seed only: run 3 of --count 5 is run 3 of
// --count 8 (every field of trajectory.json), and so is run 4.
TEST_F(Cli, RunKIsTheSameWhateverTheCount) {
  ASSERT_EQ(scout("run " + world("fashion.yaml") + " --out " + path("five") + " --count 5 --seed 9 --no-images").status,
            0);
  ASSERT_EQ(
      scout("run " + world("fashion.yaml") + " --out " + path("eight") + " --count 8 --seed 9 --no-images").status, 0);
  const json five = read_json(path("five") + "/trajectory.json"), eight = read_json(path("eight") + "/trajectory.json");
  ASSERT_EQ(five["runs"].size(), 5u);
  ASSERT_EQ(eight["runs"].size(), 8u);
  EXPECT_EQ(five["runs"][3], eight["runs"][3]);
  EXPECT_EQ(five["runs"][4], eight["runs"][4]);
  EXPECT_NE(five["runs"][3]["steps"], five["runs"][2]["steps"]);  // the runs differ from each other
}

}  // namespace scout::testing::run_command_cli_tests

namespace scout::testing::run_command_eval_run_tests {

using namespace scout::testing::eval_run_support;

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
  const std::string text = temp_->write("notes.safetensors", "x").string();
  r = scout("run " + world() + " --out " + path("o4") + " --checkpoint " + text);
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(r.output.rfind("scout: error: " + text + ": not a valid safetensors file", 0), 0u) << r.output;
  for (const char* o : {"o1", "o2", "o3", "o4"}) EXPECT_FALSE(fs::exists(path(o))) << o;
}

}  // namespace scout::testing::run_command_eval_run_tests
