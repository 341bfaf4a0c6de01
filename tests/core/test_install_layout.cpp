// Where a build finds Scout's own files: the source tree (an installed package, its share/ folder:
// tests/python/test_pip_install.py installs one and runs it with the source tree hidden).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/install_layout.hpp"

namespace scout::core {
namespace {

namespace fs = std::filesystem;

TEST(InstallLayout, ABuildReadsTheSourceTree) {
  // This test program lies in build/tests/core/, which has no share/worlds/.
  EXPECT_FALSE(installed_files().has_value());
  EXPECT_EQ(files_root(), fs::path(SCOUT_SOURCE_DIR));
  EXPECT_TRUE(fs::is_regular_file(files_root() / "worlds" / "mnist.yaml"));
  EXPECT_TRUE(fs::is_regular_file(files_root() / "tools" / "report" / "scout_report.py"));
}

// The variables the user data folder follows, restored after each test.
class UserDataFolder : public ::testing::Test {
 protected:
  void SetUp() override {
    for (const char* name : {"XDG_DATA_HOME", "HOME"})
      if (const char* value = std::getenv(name)) saved_.emplace_back(name, value);
  }
  void TearDown() override {
    ::unsetenv("XDG_DATA_HOME");
    for (const auto& [name, value] : saved_) ::setenv(name.c_str(), value.c_str(), 1);
  }
  std::vector<std::pair<std::string, std::string>> saved_;
};

TEST_F(UserDataFolder, IsXdgDataHomeElseTheHomeFoldersLocalShare) {
  ::setenv("XDG_DATA_HOME", "/data/home", 1);
  EXPECT_EQ(user_data_folder(), fs::path("/data/home/scout"));
  ::unsetenv("XDG_DATA_HOME");
  ::setenv("HOME", "/home/someone", 1);
  EXPECT_EQ(user_data_folder(), fs::path("/home/someone/.local/share/scout"));
  ::setenv("XDG_DATA_HOME", "", 1);  // empty: as if unset
  EXPECT_EQ(user_data_folder(), fs::path("/home/someone/.local/share/scout"));
}

}  // namespace
}  // namespace scout::core
