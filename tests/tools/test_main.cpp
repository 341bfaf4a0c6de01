// The `scout` program (tools/main.cpp): --version, every command's --help, and usage errors as
// one line pointing at the right help.

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

namespace scout::testing::main_cli_tests {

using namespace scout::testing::cli_support;

TEST_F(Cli, HelpVersionAndUsageErrors) {
  const Result version = scout("--version");
  EXPECT_EQ(version.status, 0);
  EXPECT_EQ(version.output.rfind("scout ", 0), 0u) << version.output;
  for (const char* cmd : {"--help", "run --help", "data --help", "bench --help", "bench sim --help",
                          "bench train --help", "train --help", "eval --help", "export --help"}) {
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

}  // namespace scout::testing::main_cli_tests
