#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <csignal>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <string>

#include "core/error.hpp"
#include "core/process.hpp"
#include "tests/support/cli.hpp"
#include "tests/support/temp_dir.hpp"

namespace scout::core {
namespace {

namespace fs = std::filesystem;

using scout::testing::read_file;

// A signal set as /proc/PID/status prints it: "SigBlk:\t" and 16 hex digits, bit s - 1 for signal s.
std::string sigblk_line(const sigset_t& set) {
  std::uint64_t bits = 0;
  for (int s = 1; s <= 64; ++s)
    if (sigismember(&set, s) == 1) bits |= std::uint64_t{1} << (s - 1);
  return fmt::format("SigBlk:\t{:016x}\n", bits);
}

int wait_exit_code(pid_t pid) {
  int status = 0;
  EXPECT_EQ(waitpid(pid, &status, 0), pid);
  EXPECT_TRUE(WIFEXITED(status));
  return WEXITSTATUS(status);
}

// The child sees this process's environment with the spec's variables set on top (an inherited
// variable replaced, not doubled), runs in its folder, writes both streams to the log, and starts
// with the signal mask the spec gives, whatever the parent blocks.
TEST(SpawnChild, BuildsTheChildsEnvironmentFolderOutputAndSignalMaskBeforeItStarts) {
  scout::testing::TempDir temp;
  ::setenv("SCOUT_SPAWN_TEST_KEPT", "inherited", 1);
  ::setenv("SCOUT_SPAWN_TEST_REPLACED", "old", 1);
  sigset_t blocked, previous, child_mask;
  sigemptyset(&blocked);
  sigaddset(&blocked, SIGTERM);
  sigemptyset(&child_mask);
  sigaddset(&child_mask, SIGUSR1);
  ASSERT_EQ(sigprocmask(SIG_BLOCK, &blocked, &previous), 0);
  const fs::path log = temp.path() / "child.log";
  const pid_t pid =
      spawn_child({.args = {"sh", "-c",
                            "echo kept=$SCOUT_SPAWN_TEST_KEPT; env | grep -c '^SCOUT_SPAWN_TEST_REPLACED='; "
                            "echo replaced=$SCOUT_SPAWN_TEST_REPLACED; echo new=$SCOUT_SPAWN_TEST_NEW; pwd; "
                            "echo to-stderr >&2; exit 7"},
                   .environment = {{"SCOUT_SPAWN_TEST_REPLACED", "new value"}, {"SCOUT_SPAWN_TEST_NEW", "x=y"}},
                   .cwd = temp.path(),
                   .output_log = log});
  // grep itself, not under a shell (dash clears the mask it was started with).
  const pid_t masked = spawn_child({.args = {"grep", "^SigBlk", "/proc/self/status"},
                                    .output_log = temp.path() / "mask.log",
                                    .signal_mask = child_mask});
  const pid_t unmasked =
      spawn_child({.args = {"grep", "^SigBlk", "/proc/self/status"}, .output_log = temp.path() / "inherited.log"});
  sigset_t parents;  // what the parent blocked while it spawned: the runner's mask and SIGTERM
  sigprocmask(SIG_SETMASK, nullptr, &parents);
  sigprocmask(SIG_SETMASK, &previous, nullptr);
  ::unsetenv("SCOUT_SPAWN_TEST_KEPT");
  ::unsetenv("SCOUT_SPAWN_TEST_REPLACED");
  EXPECT_EQ(wait_exit_code(pid), 7);
  const std::string out = read_file(log);
  EXPECT_NE(out.find("kept=inherited\n1\nreplaced=new value\nnew=x=y\n"), std::string::npos) << out;
  EXPECT_NE(out.find(fs::canonical(temp.path()).string() + "\n"), std::string::npos) << out;
  EXPECT_NE(out.find("to-stderr\n"), std::string::npos) << out;
  // SIGUSR1 is signal 10: bit 9 of the mask; the parent's SIGTERM (15: bit 14) is not passed on,
  // unless no mask is given.
  EXPECT_EQ(wait_exit_code(masked), 0);
  EXPECT_EQ(read_file(temp.path() / "mask.log"), "SigBlk:\t0000000000000200\n");
  EXPECT_EQ(sigblk_line(child_mask), "SigBlk:\t0000000000000200\n");
  EXPECT_EQ(wait_exit_code(unmasked), 0);
  ASSERT_EQ(sigismember(&parents, SIGTERM), 1);
  EXPECT_EQ(read_file(temp.path() / "inherited.log"), sigblk_line(parents));
}

TEST(SpawnChild, AProgramThatCannotStartIsOneLineNamingIt) {
  try {
    spawn_child({.args = {"scout-no-such-program"}});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "cannot run scout-no-such-program: No such file or directory");
  }
  scout::testing::TempDir temp;
  const ProgramResult result = run_program({"scout-no-such-program", "x"}, temp.path(), temp.path() / "log");
  EXPECT_TRUE(result.failed());
  EXPECT_EQ(result.describe("scout-no-such-program"), "(cannot run scout-no-such-program: No such file or directory)");
}

TEST(RunProgram, QuotesTheLastLineOfAFailingProgramsLog) {
  scout::testing::TempDir temp;
  const ProgramResult result = run_program({"sh", "-c", "echo first; echo '  the \x1b[31mreason\x1b[0m  ' >&2; exit 3"},
                                           temp.path(), temp.path() / "log");
  EXPECT_TRUE(result.exited);
  EXPECT_EQ(result.code, 3);
  EXPECT_EQ(result.describe("sh"), "(exit 3): the reason");
  const ProgramResult ok = run_program({"true"}, temp.path(), temp.path() / "log2");
  EXPECT_FALSE(ok.failed());
}

}  // namespace
}  // namespace scout::core
