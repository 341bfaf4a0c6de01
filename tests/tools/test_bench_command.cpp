// `scout bench sim` and `scout bench train` (tools/bench_command.cpp) end to end.

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
#include "render/camera.hpp"
#include "tests/support/cli_fixture.hpp"
#include "tests/support/train_cli_fixture.hpp"

namespace scout::testing::bench_command_cli_tests {

using namespace scout::testing::cli_support;

// SIGTERM once the timing has begun (bench sim says so on stderr): exit 130 and no report.
TEST_F(Cli, AnInterruptedBenchWritesNoReport) {
  const std::string out = path("stdout.txt"), err = path("stderr.txt");
  const pid_t child = scout::testing::spawn(
      {SCOUT_BINARY, "bench", "sim", "--world", world("fashion.yaml"), "--repeats", "10000", "--json", path("b.json")},
      out, err);
  ASSERT_GT(child, 0);
  int early = 0;
  const bool timing = scout::testing::wait_for_text(child, err, "scout bench sim: timing 10000 repeats", 600, &early);
  if (!timing) kill(child, SIGKILL);
  ASSERT_TRUE(timing) << "bench sim never began timing (status " << early << "): " << scout::testing::read_file(err);
  kill(child, SIGTERM);
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130) << scout::testing::read_file(err);
  EXPECT_FALSE(fs::exists(path("b.json")));
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
  // The peak resident size: at least the 12 x 12 floors' robots and LibTorch's libraries (tens of
  // MiB), far below a gigabyte for 8 robots.
  EXPECT_NE(r.output.find("memory: peak resident"), std::string::npos) << r.output;
  EXPECT_GT(b["peak_resident_bytes"].get<double>(), 20e6);
  EXPECT_LT(b["peak_resident_bytes"].get<double>(), 1e9);
}

// The camera alone under every back end this build has, the one --camera-backend names first,
// side by side, with their patches equal; a back end that is not one is a usage error.
TEST_F(Cli, BenchSimTimesTheCameraUnderEachBackEndSideBySide) {
  const std::vector<render::CameraBackend> built = render::built_camera_backends();
  const std::string first = render::camera_backend_name(built.back());
  const Result r = scout("bench sim --world " + world("fashion.yaml") + " --robots 8 --repeats 2 --camera-backend " +
                         first + " --json " + path("b.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  const json b = read_json(path("b.json"));
  ASSERT_EQ(b["camera_backends"].size(), built.size()) << b["camera_backends"].dump();
  EXPECT_EQ(b["camera_backends"].begin().key(), first);  // the chosen one, first
  for (render::CameraBackend backend : built) {
    const json& figure = b["camera_backends"][render::camera_backend_name(backend)];
    EXPECT_GT(figure["patches_per_s"].get<double>(), 0.0) << figure.dump();
    EXPECT_TRUE(figure["patches_equal_to_chosen"].get<bool>()) << figure.dump();
    EXPECT_NE(r.output.find(std::string("camera alone, ") + render::camera_backend_name(backend)), std::string::npos)
        << r.output;
  }
  EXPECT_EQ(b["manifest"]["libraries"]["gl"].get<std::string>().rfind(first == "egl" ? "EGL: " : "OSMesa: ", 0), 0u)
      << b["manifest"]["libraries"].dump();
  const Result bad = scout("bench sim --world " + world("fashion.yaml") + " --camera-backend vulkan");
  EXPECT_EQ(bad.status, 2);
  EXPECT_NE(bad.output.find("--camera-backend: expected one of auto, osmesa, egl, got 'vulkan'"), std::string::npos)
      << bad.output;
}

// --floor-sizes: the same task on larger floors in one process, a row each beside the first; a
// floor smaller than the images is one line naming the field before anything is timed.
TEST_F(Cli, BenchSimComparesFloorSizesInOneRun) {
  const Result r = scout("bench sim --world " + world("fashion.yaml") + " --robots 8 --repeats 2 --floor-sizes 28,45");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("\n  28 x 28 "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\n  45 x 45 "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(" 100% "), std::string::npos) << r.output;
  const Result small = scout("bench sim --world " + world("fashion.yaml") + " --robots 8 --floor-sizes 28,20");
  EXPECT_EQ(small.status, 1);
  EXPECT_NE(small.output.find("floor.size_px: expected a floor at least the images' 28 x 28 pixels, got [20, 20]"),
            std::string::npos)
      << small.output;
}

}  // namespace scout::testing::bench_command_cli_tests

namespace scout::testing::bench_command_train_cli_tests {

using namespace scout::testing::train_cli_support;

// scout bench train: every mode asked for, with its images/s and the shares of a step.
TEST_F(TrainCli, BenchTrainReportsEachModeAndWhereTheTimeGoes) {
  const std::string report = path("bench.json");
  const Result r = run("bench train --world " + world() +
                       " --modes i,iii --batch 4 --rollouts 2 --batches 2 --warmup 0 --threads 1 --planner-width 4 "
                       "--planner-depth 1 --classifier strided --classifier-width 8 --classifier-depth 2 --json " +
                       report);
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("planners 4x1 (width x depth)"), std::string::npos) << r.out;
  const json j = json::parse(read_text(report));
  EXPECT_EQ(j["robots"], 8);
  EXPECT_EQ(j["precision"], scout::agent::to_string(scout::learn::resolve_precision(scout::agent::Precision::Auto)));
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
  // Peak and estimate: the estimate bounds the measured peak from above, within a few times.
  EXPECT_NE(r.out.find("memory: peak resident"), std::string::npos) << r.out;
  const double peak = j["peak_resident_bytes"].get<double>(), estimate = j["estimated_bytes"].get<double>();
  EXPECT_GT(peak, 20e6);
  EXPECT_GE(estimate, peak) << "the estimate should not be below what a run takes";
  EXPECT_LT(estimate, 8 * peak);
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

}  // namespace scout::testing::bench_command_train_cli_tests
