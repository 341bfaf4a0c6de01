// The memory a request may take (core/memory.hpp): MemAvailable, cgroup v1 and v2 limits less
// their usage up the hierarchy, and SCOUT_MEMORY_LIMIT, the smallest winning and named; files as
// the kernel writes them, in a fake /proc and /sys/fs/cgroup.
#include <gtest/gtest.h>
#include <malloc.h>
#include <stdlib.h>

#include <fstream>
#include <optional>
#include <vector>

#include "core/error.hpp"
#include "core/memory.hpp"
#include "tests/support/temp_dir.hpp"

namespace scout::core {
namespace {

namespace fs = std::filesystem;

constexpr std::uint64_t kGiB = std::uint64_t{1} << 30;

class FakeMachine : public ::testing::Test {
 protected:
  void SetUp() override { ::unsetenv("SCOUT_MEMORY_LIMIT"); }
  void TearDown() override { ::unsetenv("SCOUT_MEMORY_LIMIT"); }
  // /proc/meminfo with MemAvailable of `kib`, and /proc/self/cgroup.
  void proc(std::uint64_t kib, const std::string& cgroup) {
    fs::create_directories(proc_ / "self");
    std::ofstream(proc_ / "meminfo") << "MemTotal:       24683548 kB\nMemFree:        20924800 kB\nMemAvailable:   "
                                     << kib << " kB\nBuffers:          123 kB\n";
    std::ofstream(proc_ / "self/cgroup") << cgroup;
  }
  void file(const fs::path& relative, const std::string& text) {
    fs::create_directories((cgroup_ / relative).parent_path());
    std::ofstream(cgroup_ / relative) << text;
  }
  std::optional<AvailableMemory> available() const { return available_memory(proc_, cgroup_); }

  scout::testing::TempDir temp_;
  fs::path proc_ = temp_.path() / "proc", cgroup_ = temp_.path() / "cgroup";
};

TEST_F(FakeMachine, MemAvailableAloneWithoutACgroupLimit) {
  proc(8 * 1024 * 1024, "0::/user.slice\n");
  file("user.slice/memory.max", "max\n");
  file("user.slice/memory.current", "123456\n");
  const auto a = available();
  ASSERT_TRUE(a);
  EXPECT_EQ(a->bytes, 8 * kGiB);
  EXPECT_EQ(a->bound, "MemAvailable");
}

TEST_F(FakeMachine, ACgroupV2LimitLessItsUsageUpTheHierarchy) {
  proc(20 * 1024 * 1024, "0::/a/b\n");
  file("a/b/memory.max", "max\n");  // no limit of its own
  file("a/b/memory.current", "1000\n");
  file("a/memory.max", std::to_string(4 * kGiB) + "\n");  // the parent's bounds it
  file("a/memory.current", std::to_string(1 * kGiB) + "\n");
  const auto a = available();
  ASSERT_TRUE(a);
  EXPECT_EQ(a->bytes, 3 * kGiB);
  EXPECT_EQ(a->bound, "the cgroup's memory limit");
}

TEST_F(FakeMachine, ACgroupV1MemoryControllerInsideAContainer) {
  // The host's path does not exist below the container's own controller root: its files count.
  proc(20 * 1024 * 1024, "4:memory:/process_api/17c7\n3:cpuset:/\n0::/\n");
  file("memory/memory.limit_in_bytes", std::to_string(2 * kGiB) + "\n");
  file("memory/memory.usage_in_bytes", std::to_string(kGiB / 2) + "\n");
  const auto a = available();
  ASSERT_TRUE(a);
  EXPECT_EQ(a->bytes, 3 * kGiB / 2);
  // "No limit" is written as a number near 2^63 in v1.
  file("memory/memory.limit_in_bytes", "9223372036854771712\n");
  EXPECT_EQ(available()->bound, "MemAvailable");
}

TEST_F(FakeMachine, ScoutMemoryLimitCapsAndABadValueIsOneLine) {
  proc(20 * 1024 * 1024, "0::/\n");
  ::setenv("SCOUT_MEMORY_LIMIT", "512M", 1);
  EXPECT_EQ(available()->bytes, 512u << 20);
  EXPECT_EQ(available()->bound, "SCOUT_MEMORY_LIMIT");
  ::setenv("SCOUT_MEMORY_LIMIT", "lots", 1);
  try {
    available();
    ADD_FAILURE() << "a bad SCOUT_MEMORY_LIMIT was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("SCOUT_MEMORY_LIMIT: expected bytes", 0), 0u) << e.what();
  }
}

TEST_F(FakeMachine, NothingReadableIsUnknown) { EXPECT_FALSE(available()); }

TEST(CheckMemory, RefusesAnEstimateBeyondWhatIsAvailableUnlessForced) {
  ::setenv("SCOUT_MEMORY_LIMIT", "1G", 1);
  try {
    check_memory(3 * kGiB, "training 4096 robots", false);
    ADD_FAILURE() << "3 GiB passed a 1 GiB limit";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              "training 4096 robots needs about 3.0 GiB of memory, 1.0 GiB is available (SCOUT_MEMORY_LIMIT); ask for "
              "less, or give --force to try anyway");
  }
  check_memory(3 * kGiB, "training", true);   // forced
  check_memory(kGiB / 2, "training", false);  // fits
  ::unsetenv("SCOUT_MEMORY_LIMIT");
}

TEST(PeakMemory, GrowsWithWhatThisProcessTouches) {
  const std::uint64_t before = peak_resident_bytes();
  ASSERT_GT(before, 0u);
  std::vector<char> block(256u << 20, 1);  // 256 MiB, written
  EXPECT_GE(peak_resident_bytes(), before + (200u << 20)) << format_bytes(peak_resident_bytes());
  EXPECT_EQ(block[block.size() / 2], 1);
}

TEST(FormatBytes, PicksAReadableUnit) {
  EXPECT_EQ(format_bytes(512), "512 bytes");
  EXPECT_EQ(format_bytes(3 * 1024 * 1024 + 300 * 1024), "3.3 MiB");
  EXPECT_EQ(format_bytes(41 * kGiB + kGiB / 4), "41.2 GiB");
}

// After keep_freed_memory_for_reuse(), a 64 MiB block (a training step's activations are blocks of
// this size) comes from the heap, not from a fresh mapping, and freeing it keeps it for the next:
// glibc's mallinfo2() counts mapped blocks in hblkhd and the heap's size in arena.
TEST(KeepFreedMemory, LargeBlocksComeFromTheHeapAndStayThereWhenFreed) {
#if defined(__GLIBC__) && !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
  keep_freed_memory_for_reuse();
  constexpr std::size_t kBlock = std::size_t{64} << 20;
  const struct mallinfo2 before = mallinfo2();
  void* block = std::malloc(kBlock);
  ASSERT_NE(block, nullptr);
  static_cast<volatile char*>(block)[kBlock - 1] = 1;
  const struct mallinfo2 holding = mallinfo2();
  EXPECT_EQ(holding.hblkhd, before.hblkhd) << "the block was mapped on its own";
  std::free(block);
  EXPECT_GE(mallinfo2().arena, holding.arena) << "the heap was trimmed when the block was freed";
#else
  GTEST_SKIP() << "glibc's allocator only (a sanitizer's allocator ignores mallopt)";
#endif
}

}  // namespace
}  // namespace scout::core
