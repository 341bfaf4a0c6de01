#pragma once
// The EvalRun fixture of the `scout eval` and `scout run --checkpoint` end-to-end tests: two tiny
// checkpoints that `scout train` makes from synthetic 12 x 12 IDX files (real Box2D, real
// OSMesa): through modes (i) - (iii) ("run"), and mode (i) only ("run_i").
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

#include "tests/support/cli.hpp"
#include "tests/support/temp_dir.hpp"

namespace scout::testing::eval_run_support {

namespace fs = std::filesystem;
using nlohmann::json;

using Result = scout::testing::CliResult;

inline Result scout(const std::string& args) { return scout::testing::run_cli(SCOUT_BINARY, args); }

constexpr int kSide = 12;
constexpr int kTestImages = 9;

// Raw IDX files (big-endian header) of `count` 12 x 12 images of three classes: a vertical bar,
// a horizontal bar, a square.
inline void write_idx(const fs::path& folder, const std::string& prefix, int count) {
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

inline json read_json(const fs::path& file) {
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
      ASSERT_TRUE(fs::exists(path(run) + "/checkpoint.safetensors")) << r.output;
    }
  }
  static void TearDownTestSuite() {
    delete temp_;
    temp_ = nullptr;
  }

  static std::string path(const std::string& name) { return (temp_->path() / name).string(); }
  static std::string world() { return path("world.yaml"); }
  static std::string checkpoint(const std::string& run = "run") { return path(run) + "/checkpoint.safetensors"; }
  static std::string test_data() {
    return " --images " + path("data/t10k-images-idx3-ubyte") + " --labels " + path("data/t10k-labels-idx1-ubyte");
  }

  static inline scout::testing::TempDir* temp_ = nullptr;
};

}  // namespace scout::testing::eval_run_support
