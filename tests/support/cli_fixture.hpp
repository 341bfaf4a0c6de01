#pragma once
// The Cli fixture of the `scout` end-to-end tests that need no trained model (run, data, bench
// sim, help): a fresh folder per test and the source tree's world files.
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

namespace scout::testing::cli_support {

namespace fs = std::filesystem;
using nlohmann::json;

using Result = scout::testing::CliResult;

inline Result scout(const std::string& args) { return scout::testing::run_cli(SCOUT_BINARY, args); }

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

}  // namespace scout::testing::cli_support
