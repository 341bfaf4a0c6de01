// Output folders (tools/output.cpp) through `scout run`: an existing folder is refused unless
// --overwrite, which never destroys what is not Scout output; staging leaves nothing behind.

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

namespace scout::testing::output_cli_tests {

using namespace scout::testing::cli_support;

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

}  // namespace scout::testing::output_cli_tests
