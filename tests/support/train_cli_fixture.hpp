#pragma once
// The TrainCli fixture of the `scout train`, `export` and `bench train` end-to-end tests: tiny
// runs on synthetic 12 x 12 IDX floors (real Box2D, real OSMesa, real LibTorch), with one
// finished one-epoch run shared by the suite.
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

namespace scout::testing::train_cli_support {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr int kSide = 12;

inline std::string read_text(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

inline std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// The cells of a metrics.csv row (no quoting: the file writes none).
inline std::vector<std::string> csv_cells(const std::string& line) {
  std::vector<std::string> cells;
  std::istringstream in(line);
  for (std::string cell; std::getline(in, cell, ',');) cells.push_back(cell);
  return cells;
}

// metrics.csv without its timing columns (images_per_s, seconds), which differ run to run.
inline std::vector<std::string> metrics_without_timing(const std::string& file) {
  std::vector<std::string> rows;
  for (const std::string& line : lines_of(read_text(file))) {
    std::vector<std::string> cells = csv_cells(line);
    if (cells.size() > 7) cells.erase(cells.begin() + 6, cells.begin() + 8);
    std::string row;
    for (const std::string& c : cells) row += c + ",";
    rows.push_back(row);
  }
  return rows;
}

// Raw IDX train-* files of `count` 12 x 12 floors of two classes, told apart only by the
// top-left 3 x 3 block (black or white) over noise in [64, 192).
inline void write_train_idx(const fs::path& folder, int count) {
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

// Runs `scout ARGS` with stdout and stderr captured apart; `environment`: "NAME=VALUE ..." for it.
inline Result scout(const std::string& args, const fs::path& scratch, const std::string& environment = "") {
  const fs::path out = scratch / "stdout.txt", err = scratch / "stderr.txt";
  const std::string command = (environment.empty() ? "" : "env " + environment + " ") + std::string(SCOUT_BINARY) +
                              " " + args + " > '" + out.string() + "' 2> '" + err.string() + "'";
  Result r;
  const int raw = std::system(command.c_str());
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  r.out = read_text(out);
  r.err = read_text(err);
  return r;
}

// Options of every run here: tiny networks, one LibTorch thread (with more, OpenMP's busy-waiting
// makes runs side by side, as under `ctest -j`, many times slower).
inline const char* const kTiny =
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
  Result run(const std::string& args, const std::string& environment = "") const {
    return scout(args, local_.path(), environment);
  }

  // A copy of the finished base run.
  std::string copy_of_base(const std::string& name) const {
    fs::copy(base(), path(name), fs::copy_options::recursive);
    return path(name);
  }

  static inline scout::testing::TempDir* temp_ = nullptr;
};

// Exit status 1, nothing on stdout, and exactly one line on stderr: "scout: error: ..." holding
// every one of `names`.
// status 1: "scout: error: ..." (bad input or files); status 2: "scout: usage error: ..." (a
// malformed command line).
inline void expect_one_line_error(const Result& r, const std::vector<std::string>& names, int status = 1) {
  EXPECT_EQ(r.status, status) << r.out << r.err;
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(r.err.rfind(status == 1 ? "scout: error: " : "scout: usage error: ", 0), 0u) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_EQ(r.err.back(), '\n') << r.err;
  for (const std::string& name : names) EXPECT_NE(r.err.find(name), std::string::npos) << name << " in " << r.err;
}

}  // namespace scout::testing::train_cli_support
