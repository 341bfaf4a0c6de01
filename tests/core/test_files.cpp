#include <gtest/gtest.h>

#include <fstream>
#include <iterator>

#include "core/error.hpp"
#include "core/files.hpp"
#include "tests/support/temp_dir.hpp"

namespace scout::core {
namespace {

namespace fs = std::filesystem;

std::string read(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

TEST(AtomicFile, WritesAndReplacesWholeFilesAndLeavesNoTemporary) {
  scout::testing::TempDir temp;
  const fs::path file = temp.path() / "report.json";
  // A user's file that happens to carry the name a naive writer would use as its temporary.
  std::ofstream(temp.path() / "report.json.tmp") << "mine";
  write_file_atomic(file, "first\n");
  write_file_atomic(file, std::string("second\0with a NUL\n", 18));
  EXPECT_EQ(read(file), std::string("second\0with a NUL\n", 18));
  EXPECT_EQ(read(temp.path() / "report.json.tmp"), "mine");
  int entries = 0;
  for (const auto& entry : fs::directory_iterator(temp.path())) {
    ++entries;
    EXPECT_EQ(entry.path().filename().string().find(".report.json.tmp-"), std::string::npos) << entry.path();
  }
  EXPECT_EQ(entries, 2);
}

TEST(AtomicFile, AFolderThatCannotBeWrittenIsOneLineNamingTheFile) {
  scout::testing::TempDir temp;
  const fs::path file = temp.path() / "missing" / "report.json";
  try {
    write_file_atomic(file, "x");
    ADD_FAILURE() << "wrote into a folder that does not exist";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(file.string() + ": cannot write", 0), 0u) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
  EXPECT_FALSE(fs::exists(temp.path() / "missing"));
}

TEST(AtomicFile, TemporaryNamesAreHiddenBesideTheFileAndFresh) {
  const fs::path a = temporary_path_beside("/some/dir/out.csv"), b = temporary_path_beside("/some/dir/out.csv");
  EXPECT_EQ(a.parent_path(), fs::path("/some/dir"));
  EXPECT_EQ(a.filename().string().rfind(".out.csv.tmp-", 0), 0u) << a;
  EXPECT_NE(a, b);
}

}  // namespace
}  // namespace scout::core
