// Hard kills: `scout train` killed with SIGKILL at random moments and at named points (inside a
// batch, in the middle of a checkpoint write, during validation), resumed each time, ends with
// the weights and metrics of an uninterrupted run.
#include <chrono>
#include <random>

#include "tests/support/train_cli_fixture.hpp"

namespace {

namespace fs = std::filesystem;
using scout::testing::train_cli_support::kTiny;
using scout::testing::train_cli_support::lines_of;
using scout::testing::train_cli_support::metrics_without_timing;
using scout::testing::train_cli_support::read_text;
using scout::testing::train_cli_support::Result;
using scout::testing::train_cli_support::TrainCli;

// How one attempt ends: a named point ("POINT:N", the process kills itself there) or a kill from
// outside after `delay_ms`.
struct Kill {
  std::string point;
  int delay_ms = 0;
};

// The line scout train prints once its run is open and the work begins ("training WORLD -> RUN
// (...)"): random kills are drawn after it, so that none is spent on start-up (~2.5 s under ASan).
constexpr const char* kReady = "training ";

// Runs `scout ARGS` to its end (stdout and stderr in DIR/ref.out, DIR/ref.err); returns the
// milliseconds from its readiness line to its end, or -1 if it failed.
double work_after_ready_ms(const std::string& args, const fs::path& dir) {
  std::vector<std::string> argv = {SCOUT_BINARY};
  std::istringstream words(args);
  for (std::string w; words >> w;) argv.push_back(w);
  const pid_t child = scout::testing::spawn(argv, dir / "ref.out", dir / "ref.err");
  int status = 0;
  if (!scout::testing::wait_for_text(child, dir / "ref.out", kReady, 300, &status)) return -1;
  const auto ready = std::chrono::steady_clock::now();
  if (waitpid(child, &status, 0) != child || !WIFEXITED(status) || WEXITSTATUS(status) != 0) return -1;
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - ready).count();
}

// Seven named fault points, and between them seven random moments, seeded (the same schedule
// every run), as shares of the uninterrupted run's work on this machine now; each is counted from
// the readiness line and scaled to the share of the schedule's epochs a resumed run still has
// ahead of it, so that it lands inside its work.
std::vector<Kill> kill_schedule(double work_ms) {
  std::vector<Kill> schedule = {{"batch:3"},      {"file-write:2"}, {"validation:1"}, {"batch:2"},
                                {"file-write:5"}, {"validation:2"}, {"file-write:1"}};
  std::mt19937 random(20261202);
  std::uniform_real_distribution<double> share(0.1, 0.5);
  for (int k = 0; k < 7; ++k)
    schedule.insert(schedule.begin() + 2 * k + 1, Kill{"", static_cast<int>(share(random) * work_ms)});
  return schedule;
}

// What killed writers left (hidden temporaries beside the checkpoint and metrics) is gone once a
// run has written to the folder again.
void expect_no_hidden_files(const std::string& folder) {
  for (const auto& entry : fs::directory_iterator(folder))
    EXPECT_NE(entry.path().filename().string()[0], '.') << entry.path() << " was left behind";
}

// The killed and resumed run ended as the uninterrupted one: the same metrics but for clocks, and
// the same weights bit for bit.
void expect_the_same_run(const std::string& reference, const std::string& killed) {
  EXPECT_EQ(metrics_without_timing(killed + "/metrics.csv"), metrics_without_timing(reference + "/metrics.csv"));
  const scout::testing::CliResult same = scout::testing::run_cli(
      COMPARE_WEIGHTS, "'" + reference + "/checkpoint.safetensors' '" + killed + "/checkpoint.safetensors'");
  ASSERT_EQ(same.status, 0) << same.output;
  EXPECT_EQ(same.output.substr(0, same.output.find(' ')), "0") << same.output;  // relative difference 0
  EXPECT_NE(same.output.find(" 1 "), std::string::npos) << same.output;         // bit for bit
}

TEST_F(TrainCli, HardKillsAtRandomAndNamedMomentsLoseNothing) {
  // A checkpoint after every batch (--checkpoint-every below a batch's time), as the default
  // 5 minutes is on a long run; fp32 so that nothing depends on the CPU's bf16.
  const std::string options = " --epochs 2,2,2 --baseline --precision fp32" + std::string(kTiny);
  constexpr double kEpochs = 6;                             // of the schedule above
  const std::string every = " --checkpoint-every 0.00002";  // 1 ms
  // The uninterrupted run, and how long its work takes from the readiness line to its end.
  const double work_ms =
      work_after_ready_ms("train " + world() + " --out " + path("reference") + options + every, local_.path());
  ASSERT_GT(work_ms, 0) << read_text(local_.path() / "ref.err");

  const std::vector<Kill> schedule = kill_schedule(work_ms);

  const std::string killed = path("killed");
  int kills = 0, fresh_starts = 0, random_mid_work = 0;
  for (const Kill& kill : schedule) {
    const bool checkpointed = fs::is_regular_file(killed + "/checkpoint.safetensors");
    const double epochs_done =
        checkpointed ? double(lines_of(read_text(killed + "/metrics.csv")).size() - 1) / kEpochs : 0.0;
    // Killed before its first checkpoint, or finished (a random moment after its end): the run
    // starts again, so that every attempt has work left for its kill to land in.
    const bool resume = checkpointed && epochs_done < 1.0;
    const double epochs_left = resume ? 1.0 - epochs_done : 1.0;
    if (!resume) {
      fs::remove_all(killed);
      ++fresh_starts;
    }
    std::vector<std::string> argv = {"/usr/bin/env", "SCOUT_FAULT_KILL_AT=" + kill.point, SCOUT_BINARY, "train"};
    const std::string args = (resume ? "--resume " + killed : world() + " --out " + killed + options) + every;
    std::istringstream words(args);
    for (std::string w; words >> w;) argv.push_back(w);
    const pid_t child = scout::testing::spawn(argv, local_.path() / "out.txt", local_.path() / "err.txt");
    ASSERT_GT(child, 0);
    int status = 0;
    bool reaped = false;
    if (kill.point.empty()) {
      if (scout::testing::wait_for_text(child, local_.path() / "out.txt", kReady, 300, &status)) {
        usleep(static_cast<useconds_t>(kill.delay_ms * std::max(epochs_left, 0.1) * 1000));
        // Mid-work: still running when the kill lands (it ends by the kill, not on its own).
        int raw = 0;
        if (waitpid(child, &raw, WNOHANG) == 0) {
          ::kill(child, SIGKILL);
          ++random_mid_work;
        } else {
          status = raw;
          reaped = true;
        }
      } else {
        reaped = true;  // it ended before its readiness line: an error, reported below
      }
    }
    if (!reaped) {
      ASSERT_EQ(waitpid(child, &status, 0), child);
    }
    if (WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) {
      ++kills;
    } else {
      // A point not reached before the run ended, or a random moment after it: it must have
      // ended well.
      ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
          << (kill.point.empty() ? std::to_string(kill.delay_ms) + " ms" : kill.point) << ": "
          << read_text(local_.path() / "err.txt");
    }
  }
  EXPECT_GE(kills, 10);
  // Most random moments land in the middle of the work: a resumed run's work is shorter than the
  // whole run's, so a late draw may find it finished, but not most of them.
  EXPECT_GE(random_mid_work, 5) << "of 7 random kills, only " << random_mid_work << " landed mid-work";
  // Finish: one more resume (a no-op when the last attempt finished).
  ASSERT_TRUE(fs::is_regular_file(killed + "/checkpoint.safetensors"));
  const Result last = run("train --resume " + killed);
  ASSERT_EQ(last.status, 0) << last.out << last.err;
  expect_no_hidden_files(killed);
  std::printf(
      "[ measured ] %d SIGKILLs (%d of 7 random ones mid-work, %d before a first checkpoint), then resumed to "
      "the end\n",
      kills, random_mid_work, fresh_starts - 1);

  expect_the_same_run(path("reference"), killed);
}

}  // namespace
