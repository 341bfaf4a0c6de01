// Data-parallel `scout train` and `scout eval` end to end: real processes on 127.0.0.1 over
// c10d/Gloo with free ports, the real physics, camera and networks (tiny ones, fp32).

#include <chrono>
#include <map>
#include <thread>
#include <tuple>

#include "core/process.hpp"
#include "tests/support/network_namespaces.hpp"
#include "tests/support/train_cli_fixture.hpp"

namespace {

namespace fs = std::filesystem;
using scout::testing::train_cli_support::csv_cells;
using scout::testing::train_cli_support::json;
using scout::testing::train_cli_support::lines_of;
using scout::testing::train_cli_support::metrics_without_timing;
using scout::testing::train_cli_support::read_text;
using scout::testing::train_cli_support::Result;
using scout::testing::train_cli_support::TrainCli;
using Clock = std::chrono::steady_clock;

// fp32, so that two runs differ only in the order of sums; BatchNorm-free networks (GroupNorm).
const std::string kExact = " --precision fp32";

// The suite's tiny options with one of them changed.
std::string tiny_with(const std::string& option, const std::string& value) {
  std::string tiny = scout::testing::train_cli_support::kTiny;
  const auto at = tiny.find(option + " ");
  const auto end = tiny.find(' ', at + option.size() + 1);
  return tiny.substr(0, at) + option + " " + value + (end == std::string::npos ? "" : tiny.substr(end));
}

struct Weights {
  double relative = -1;        // |A - B| / |A| over all weights as one vector (L2)
  double max_difference = -1;  // largest elementwise |A - B|
  bool identical = false;
  std::string worst;  // the tensor that differs most
};

Weights compare_weights(const std::string& a, const std::string& b) {
  const scout::testing::CliResult r =
      scout::testing::run_cli(COMPARE_WEIGHTS, "'" + a + "/checkpoint.safetensors' '" + b + "/checkpoint.safetensors'");
  Weights w;
  int identical = 0;
  char worst[256] = {};
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(std::sscanf(r.output.c_str(), "%lf %lf %d %255s", &w.relative, &w.max_difference, &identical, worst), 4)
      << r.output;
  w.identical = identical == 1;
  w.worst = worst;
  return w;
}

// Exit status 1, nothing on stdout, and one line on stderr: "scout: rank R: error: ..." holding
// every one of `names`.
void expect_rank_error(const Result& r, int rank, const std::vector<std::string>& names) {
  EXPECT_EQ(r.status, 1) << r.out << r.err;
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(r.err.rfind("scout: rank " + std::to_string(rank) + ": error: ", 0), 0u) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  for (const std::string& name : names) EXPECT_NE(r.err.find(name), std::string::npos) << name << " in " << r.err;
}

// A port nothing listens on now.
int free_port() { return scout::core::free_loopback_port(); }

using scout::testing::processes_naming;

// One rank of a group started by hand, as a launcher on another machine would start it.
struct Rank {
  pid_t pid = -1;
  fs::path out, err;
};

Rank start_rank(int rank, int world_size, int port, const std::string& args, const fs::path& dir) {
  Rank r;
  r.out = dir / ("rank" + std::to_string(rank) + ".out");
  r.err = dir / ("rank" + std::to_string(rank) + ".err");
  std::vector<std::string> argv = {
      "/usr/bin/env",          "RANK=" + std::to_string(rank),        "WORLD_SIZE=" + std::to_string(world_size),
      "MASTER_ADDR=127.0.0.1", "MASTER_PORT=" + std::to_string(port), SCOUT_BINARY};
  std::istringstream words(args);
  for (std::string w; words >> w;) argv.push_back(w);
  r.pid = scout::testing::spawn(argv, r.out, r.err);
  return r;
}

// One rank started inside network namespace `ns` (ip netns exec), as on a host of its own: rank 0's
// store at `master`, and Gloo bound to the namespace's interface.
Rank start_rank_in(const scout::testing::NetworkNamespaces& hosts, int rank, int port, const std::string& args,
                   const fs::path& dir) {
  Rank r;
  r.out = dir / ("rank" + std::to_string(rank) + ".out");
  r.err = dir / ("rank" + std::to_string(rank) + ".err");
  std::vector<std::string> argv = {"/usr/bin/env",
                                   "PATH=/usr/sbin:/usr/bin:/sbin:/bin",
                                   "ip",
                                   "netns",
                                   "exec",
                                   hosts.name(rank),
                                   "/usr/bin/env",
                                   "RANK=" + std::to_string(rank),
                                   "WORLD_SIZE=2",
                                   "MASTER_ADDR=" + hosts.address(0),
                                   "MASTER_PORT=" + std::to_string(port),
                                   "GLOO_SOCKET_IFNAME=" + hosts.link(rank),
                                   SCOUT_BINARY};
  std::istringstream words(args);
  for (std::string w; words >> w;) argv.push_back(w);
  r.pid = scout::testing::spawn(argv, r.out, r.err);
  return r;
}

// A run of 40 tiny mode (iii) epochs with the timeout 5 s, one rank in each namespace: long enough
// to lose a rank in the middle of it.
std::pair<Rank, Rank> start_long_run_across(const scout::testing::NetworkNamespaces& hosts, const std::string& world,
                                            const std::string& run_dir, const fs::path& dir) {
  const std::string args = "train " + world + " --out " + run_dir + " --epochs 0,0,40 --timeout 5" +
                           scout::testing::train_cli_support::kTiny;
  const int port = free_port();
  return {start_rank_in(hosts, 0, port, args, dir), start_rank_in(hosts, 1, port, args, dir)};
}

// The namespaces, or the test skips with their one-line reason; CI (CI=true) runs every test, so
// there it fails instead (as the Gymnasium tests do).
#define REQUIRE_NAMESPACES(hosts)                                                                            \
  do {                                                                                                       \
    if (!(hosts).available()) {                                                                              \
      const char* ci = std::getenv("CI");                                                                    \
      if (ci != nullptr && std::string(ci) == "true") FAIL() << (hosts).why() << ", and CI runs every test"; \
      GTEST_SKIP() << (hosts).why();                                                                         \
    }                                                                                                        \
  } while (false)

// The lines a rank wrote that begin with "scout: " (its errors; progress lines begin otherwise).
std::vector<std::string> error_lines(const std::string& said) {
  std::vector<std::string> out;
  for (const std::string& line : lines_of(said))
    if (line.rfind("scout: ", 0) == 0) out.push_back(line);
  return out;
}

// Waits for a rank to exit (a generous bound against hanging forever); returns its exit status
// (-1: killed or still running) and the seconds it took.
std::pair<int, double> wait_rank(const Rank& r, double limit_s = 300) {
  const auto t0 = Clock::now();
  int raw = 0;
  while (std::chrono::duration<double>(Clock::now() - t0).count() < limit_s) {
    if (waitpid(r.pid, &raw, WNOHANG) == r.pid)
      return {WIFEXITED(raw) ? WEXITSTATUS(raw) : -1, std::chrono::duration<double>(Clock::now() - t0).count()};
    usleep(20 * 1000);
  }
  kill(r.pid, SIGKILL);
  waitpid(r.pid, &raw, 0);
  return {-1, limit_s};
}

// Two runs' metrics.csv, one process against two: the same validation figures (each validation
// digit's rollout depends on its index alone), and the same training figures and gradient norms
// up to the order of the sums.
void expect_the_same_metrics(const std::string& one_csv, const std::string& two_csv) {
  const std::vector<std::string> a = lines_of(read_text(one_csv));
  const std::vector<std::string> b = lines_of(read_text(two_csv));
  ASSERT_EQ(a.size(), 4u);
  ASSERT_EQ(b.size(), a.size());
  for (std::size_t i = 1; i < a.size(); ++i) {
    const std::vector<std::string> x = csv_cells(a[i]), y = csv_cells(b[i]);
    ASSERT_EQ(x.size(), y.size()) << a[i] << "\n" << b[i];
    // mode, epoch, then validation_accuracy (6th) and validation_iid, goals_only, full_image
    // (10th-12th): the same digits, the same draws.
    for (const int column : {0, 1, 5, 9, 10, 11}) EXPECT_EQ(x.at(column), y.at(column)) << a[i] << "\n" << b[i];
    // The training figures are sums over both processes' rollouts: the same reward, loss and
    // training accuracy (the count of right guesses), up to the order of the sums.
    for (const int column : {2, 3, 4})
      EXPECT_NEAR(std::stod(x.at(column)), std::stod(y.at(column)), 1e-5) << "column " << column << "\n"
                                                                          << a[i] << "\n"
                                                                          << b[i];
    EXPECT_EQ(x.at(8), y.at(8)) << "learning rate";
    // The gradient each step applied (13th): the processes' shares must add up to the one
    // process's gradient, which Adam's scale-free steps alone would not show (a share weighted
    // twice, or a mean taken where a sum belongs, changes the norm by a factor, not the weights).
    const double norm_one = std::stod(x.at(12)), norm_two = std::stod(y.at(12));
    EXPECT_GT(norm_one, 0) << a[i];
    EXPECT_NEAR(norm_two / norm_one, 1.0, 1e-4) << "gradient norm\n" << a[i] << "\n" << b[i];
  }
}

// The multi-process tests under their own name (scripts/sanitize.sh runs them under ThreadSanitizer).
class TrainDistributed : public TrainCli {};

TEST_F(TrainDistributed, TwoProcessesTrainTheSameWeightsAsOne) {
  // One batch in each of modes (i), (ii), (iii) with the leave-one-out baseline: every layer
  // learns, and a batch's 10 images split 5 + 5 over the two processes, their rollouts together.
  // Only the order of the gradient sums differs (each process sums its share, then the all-reduce
  // adds the shares), so:
  //   - the gradient each step applied agrees to about sqrt(n) u relative (u = 2^-24 = 6.0e-8;
  //     n, the terms of the longest sum, 10 images x 2 rollouts x 28 x 28 positions = 15,680:
  //     7.5e-6), checked on its norm below within 1e-4;
  //   - the weights: Adam's steps are lr g / |g| while its moments hold one or two gradients, so a
  //     relative error of a gradient hardly moves them, except for a component within its rounding
  //     of zero (REINFORCE's advantages cancel over an image's rollouts), whose step's sign the
  //     rounding decides: up to 2 lr apart per step (docs/DISTRIBUTED.md). Allowing F = 4 such
  //     components in each planner, each flipping at every one of the planner's steps (S = 2 for
  //     the goal planner, modes ii and iii; 1 for the action planner), the weights lie within
  //     2 lr sqrt(F (2^2 + 1^2)) = 2 x 3e-3 x sqrt(20) = 2.7e-2 in L2, against the trained weights'
  //     L2 norm of 3.94: kWeightTolerance = 6.8e-3 relative (the allowance of the trainer's
  //     reference test, tests/learn/test_trainer.cpp).
  // Measured 1e-6 to 1.15e-5 on two Intel Xeons (AVX-512, and capped to AVX2 and SSE4.1 kernels);
  // training itself moves the weights by 6.4e-2 from their initial values (checked below), and a
  // share dropped or counted twice shows in the gradient's norm.
  const std::string schedule =
      " --epochs 1,1,1 --train-limit 10 --baseline" + kExact + scout::testing::train_cli_support::kTiny;
  const Result one = run("train " + world() + " --out " + path("one") + schedule);
  ASSERT_EQ(one.status, 0) << one.out << one.err;
  const Result two = run("train " + world() + " --out " + path("two") + schedule + " --nproc 2");
  ASSERT_EQ(two.status, 0) << two.out << two.err;
  EXPECT_NE(two.out.find("2 processes x 1 LibTorch threads"), std::string::npos) << two.out;
  // Only rank 0 prints, and nothing goes to stderr but progress lines.
  EXPECT_EQ(two.err.find("rank 1"), std::string::npos) << two.err;
  EXPECT_EQ(std::count(two.out.begin(), two.out.end(), '\n'), std::count(one.out.begin(), one.out.end(), '\n'))
      << one.out << two.out;

  const Weights w = compare_weights(path("one"), path("two"));
  std::printf("[ measured ] 2 processes vs 1: relative L2 difference %.3g, largest %.3g (%s)\n", w.relative,
              w.max_difference, w.worst.c_str());
  constexpr double kWeightTolerance = 6.8e-3;  // 2 lr sqrt(F (2^2 + 1^2)) / |w| (above)
  EXPECT_LE(w.relative, kWeightTolerance) << w.worst << " differs by up to " << w.max_difference;
  // Both did train: their weights are far from the initial ones (the same seed with every layer
  // frozen trains nothing).
  const Result initial =
      run("train " + world() + " --out " + path("initial") + schedule + " --freeze goal,action,classifier");
  ASSERT_EQ(initial.status, 0) << initial.out << initial.err;
  const Weights trained = compare_weights(path("one"), path("initial"));
  std::printf("[ measured ] 1 process vs its initial weights: relative L2 difference %.3g, largest %.3g\n",
              trained.relative, trained.max_difference);
  EXPECT_GT(trained.relative, 1e-3);
  EXPECT_GT(compare_weights(path("two"), path("initial")).relative, 1e-3);

  expect_the_same_metrics(path("one") + "/metrics.csv", path("two") + "/metrics.csv");
  std::ifstream in(path("two") + "/manifest.json");
  EXPECT_EQ(json::parse(in)["world_size"], 2);
}

TEST_F(TrainDistributed, TheSameProcessCountTwiceGivesBitIdenticalWeights) {
  const std::string schedule = " --epochs 1,1,1" + std::string(kExact) + scout::testing::train_cli_support::kTiny;
  for (const char* name : {"a", "b"}) {
    const Result r = run("train " + world() + " --out " + path(name) + schedule + " --nproc 2");
    ASSERT_EQ(r.status, 0) << r.out << r.err;
  }
  const Weights w = compare_weights(path("a"), path("b"));
  EXPECT_TRUE(w.identical) << w.worst << " differs by up to " << w.max_difference;
  EXPECT_EQ(w.relative, 0);
}

TEST_F(TrainDistributed, ALostRankStopsTheOthersWithinTheTimeoutAndResumeFinishes) {
  const int port = free_port();
  const std::string run_dir = path("run");
  const std::string args = "train " + world() + " --out " + run_dir + " --epochs 0,0,40 --timeout 10" +
                           scout::testing::train_cli_support::kTiny;
  const Rank r0 = start_rank(0, 2, port, args, local_.path());
  const Rank r1 = start_rank(1, 2, port, args, local_.path());
  // Kill rank 1 once the first epoch is done (a generous bound, never asserted on).
  ASSERT_TRUE(scout::testing::wait_for_text(r0.pid, r0.out, "mode iii epoch   1:", 300)) << read_text(r0.err);
  const std::string checkpoint_before = read_text(run_dir + "/checkpoint.safetensors");
  kill(r1.pid, SIGKILL);
  const auto [status, seconds] = wait_rank(r0);
  wait_rank(r1, 5);
  std::printf("[ measured ] rank 0 stopped %.1f s after rank 1 was killed\n", seconds);
  const std::string said = read_text(r0.err);
  EXPECT_EQ(status, 1) << said;
  // Stopped within the timeout (10 s) plus the time to notice and finish a batch.
  EXPECT_LT(seconds, 10 + 20) << said;
  const std::vector<std::string> error_lines = [&] {
    std::vector<std::string> out;
    for (const std::string& line : lines_of(said))
      if (line.rfind("scout: ", 0) == 0) out.push_back(line);
    return out;
  }();
  ASSERT_EQ(error_lines.size(), 1u) << said;
  EXPECT_NE(error_lines[0].find("rank 0: error: rank 1 was lost"), std::string::npos) << said;
  // The last checkpoint is intact: resuming with two processes finishes the schedule.
  ASSERT_TRUE(fs::is_regular_file(run_dir + "/checkpoint.safetensors"));
  EXPECT_FALSE(checkpoint_before.empty());
  const Result resumed = run("train --resume " + run_dir + " --nproc 2");
  ASSERT_EQ(resumed.status, 0) << resumed.out << resumed.err;
  EXPECT_NE(resumed.out.find("resuming after"), std::string::npos) << resumed.out;
  const std::vector<std::string> rows = lines_of(read_text(run_dir + "/metrics.csv"));
  ASSERT_EQ(rows.size(), 1u + 40u) << read_text(run_dir + "/metrics.csv");
  EXPECT_EQ(rows.back().rfind("iii,40,", 0), 0u) << rows.back();
}

TEST_F(TrainDistributed, LosingRankZeroStopsTheOthersWithOneLine) {
  const int port = free_port();
  const std::string args = "train " + world() + " --out " + path("run0") + " --epochs 0,0,40 --timeout 10" +
                           scout::testing::train_cli_support::kTiny;
  const Rank r0 = start_rank(0, 2, port, args, local_.path());
  const Rank r1 = start_rank(1, 2, port, args, local_.path());
  ASSERT_TRUE(scout::testing::wait_for_text(r0.pid, r0.out, "mode iii epoch   1:", 300)) << read_text(r0.err);
  kill(r0.pid, SIGKILL);
  const auto [status, seconds] = wait_rank(r1);
  wait_rank(r0, 5);
  std::printf("[ measured ] rank 1 stopped %.1f s after rank 0 was killed\n", seconds);
  const std::string said = read_text(r1.err);
  EXPECT_EQ(status, 1) << said;
  EXPECT_LT(seconds, 10 + 20) << said;
  EXPECT_EQ(std::count(said.begin(), said.end(), '\n'), 1) << said;
  EXPECT_EQ(said.rfind("scout: rank 1: error: rank 0 was lost", 0), 0u) << said;
  EXPECT_EQ(read_text(r1.out), "");  // rank 1 never prints progress
}

TEST_F(TrainDistributed, ControlCStopsEveryProcessAfterRankZeroSavesACheckpoint) {
  const std::string run_dir = path("run");
  const fs::path out = local_.path() / "launcher.out", err = local_.path() / "launcher.err";
  std::vector<std::string> argv = {SCOUT_BINARY, "train",   world(), "--out",     run_dir, "--epochs",
                                   "1,1,100000", "--nproc", "2",     "--timeout", "20"};
  std::istringstream tiny(scout::testing::train_cli_support::kTiny);
  for (std::string w; tiny >> w;) argv.push_back(w);
  const pid_t launcher = scout::testing::spawn(argv, out, err);
  ASSERT_TRUE(scout::testing::wait_for_text(launcher, out, "mode iii epoch   1:", 300)) << read_text(err);
  // Ctrl-C reaches the launcher, which passes it on to both ranks.
  kill(launcher, SIGINT);
  const auto [status, seconds] = wait_rank({launcher, out, err});
  const std::string said = read_text(err);
  EXPECT_EQ(status, 130) << said;
  EXPECT_LT(seconds, 60) << said;
  // One line, from rank 0, naming the checkpoint it saved; rank 1 stops quietly.
  std::vector<std::string> lines;
  for (const std::string& line : lines_of(said))
    if (line.rfind("scout: ", 0) == 0) lines.push_back(line);
  ASSERT_EQ(lines.size(), 1u) << said;
  EXPECT_NE(lines[0].find("checkpoint saved: " + run_dir + "/checkpoint.safetensors"), std::string::npos) << said;
  // No rank outlives the launcher: nothing is left holding the run's port or files.
  EXPECT_EQ(processes_naming(run_dir), 0);
  const std::vector<std::string> rows = lines_of(read_text(run_dir + "/metrics.csv"));
  ASSERT_GE(rows.size(), 4u);
  const int done = static_cast<int>(rows.size()) - 1;
  // The run continues from where it stopped, with two processes again.
  const Result resumed =
      run("train --resume " + run_dir + " --epochs 1,1," + std::to_string(done - 2 + 1) + " --nproc 2 --timeout 20");
  ASSERT_EQ(resumed.status, 0) << resumed.out << resumed.err;
  EXPECT_NE(resumed.out.find("resuming after " + std::to_string(done) + " epoch(s)"), std::string::npos) << resumed.out;
  EXPECT_EQ(lines_of(read_text(run_dir + "/metrics.csv")).size(), rows.size() + 1);
}

TEST_F(TrainDistributed, ARankThatNeverArrivesIsOneLineWithinTheTimeout) {
  const Rank r0 = start_rank(
      0, 2, free_port(),
      "train " + world() + " --out " + path("never") + " --timeout 3" + scout::testing::train_cli_support::kTiny,
      local_.path());
  const auto [status, seconds] = wait_rank(r0);
  std::printf("[ measured ] a rank that never arrived: rank 0 stopped after %.1f s (--timeout 3)\n", seconds);
  const Result r{status, read_text(r0.out), read_text(r0.err)};
  expect_rank_error(r, 0, {"the 2 processes did not all arrive at 127.0.0.1:", "within 3 s"});
  EXPECT_LT(seconds, 3 + 20);
  EXPECT_FALSE(fs::exists(path("never")));  // nothing left behind
}

TEST_F(TrainDistributed, AWrongPortIsOneLineOnEveryRankWithinTheTimeout) {
  const std::string args =
      "train " + world() + " --out " + path("wrong") + " --timeout 3" + scout::testing::train_cli_support::kTiny;
  const int port = free_port();
  int other = free_port();
  while (other == port) other = free_port();
  const Rank r0 = start_rank(0, 2, port, args, local_.path());
  const Rank r1 = start_rank(1, 2, other, args, local_.path());
  const auto [status0, seconds0] = wait_rank(r0);
  const auto [status1, seconds1] = wait_rank(r1);
  std::printf("[ measured ] wrong port: rank 0 stopped after %.1f s, rank 1 after %.1f s (--timeout 3)\n", seconds0,
              seconds1);
  EXPECT_LT(seconds0, 3 + 20);
  EXPECT_LT(seconds1, 3 + 20);
  expect_rank_error({status0, read_text(r0.out), read_text(r0.err)}, 0, {"the 2 processes did not all arrive"});
  const std::string said1 = read_text(r1.err);
  EXPECT_EQ(status1, 1);
  EXPECT_EQ(std::count(said1.begin(), said1.end(), '\n'), 1) << said1;
  EXPECT_EQ(said1.rfind("scout: rank 1: error: cannot reach rank 0's store at 127.0.0.1:" + std::to_string(other), 0),
            0u)
      << said1;
}

TEST_F(TrainDistributed, RanksThatDisagreeAreRefusedWithOneLineNamingWhat) {
  const std::string common = "train " + world() + " --out " + path("differ") + " --timeout 20 --epochs 1,0,0";
  const int port = free_port();
  const Rank r0 = start_rank(0, 2, port, common + scout::testing::train_cli_support::kTiny, local_.path());
  const Rank r1 = start_rank(1, 2, port, common + tiny_with("--classifier-width", "6"), local_.path());
  const auto [status0, seconds0] = wait_rank(r0);
  const auto [status1, seconds1] = wait_rank(r1);
  expect_rank_error({status0, read_text(r0.out), read_text(r0.err)}, 0, {"rank 1 asks for other networks"});
  EXPECT_EQ(status1, 1);
  EXPECT_NE(read_text(r1.err).find("rank 1: error: rank 1 asks for other networks"), std::string::npos)
      << read_text(r1.err);
  EXPECT_FALSE(fs::exists(path("differ")));  // the new run never started: no folder left
}

TEST_F(TrainDistributed, ResumingWithAnotherProcessCountIsRefusedUnlessAllowed) {
  const std::string run_dir = copy_of_base("base_copy");
  const Result refused = run("train --resume " + run_dir + " --epochs 1,1,0 --nproc 2 --timeout 20");
  expect_rank_error(refused, 0, {"--nproc", "trained with 1 process(es), this resume has 2", "--allow-nproc-change"});
  const Result allowed =
      run("train --resume " + run_dir + " --epochs 1,1,0 --nproc 2 --timeout 20 --allow-nproc-change");
  ASSERT_EQ(allowed.status, 0) << allowed.out << allowed.err;
  EXPECT_EQ(lines_of(read_text(run_dir + "/metrics.csv")).size(), 3u);
  // An odd batch does not split over two processes.
  const Result odd =
      run("train " + world() + " --out " + path("odd") + tiny_with("--batch", "7") + " --nproc 2 --timeout 20");
  expect_rank_error(odd, 0, {"--batch: B = 7 images do not divide evenly over 2 processes"});
}

TEST_F(TrainDistributed, EvalOverTwoProcessesGivesTheSameReport) {
  const std::string data = (temp_->path() / "data").string();
  const std::string common = "eval --checkpoint " + base() + " --images " + data +
                             "/train-images-idx3-ubyte --labels " + data + "/train-labels-idx1-ubyte --runs 3";
  const Result one = run(common + " --json " + path("one.json"));
  ASSERT_EQ(one.status, 0) << one.out << one.err;
  // Over the loopback interface by name (what GLOO_SOCKET_IFNAME or --interface choose).
  const Result two = run(common + " --json " + path("two.json") + " --nproc 2 --interface lo");
  ASSERT_EQ(two.status, 0) << two.out << two.err;
  json a = json::parse(read_text(path("one.json"))), b = json::parse(read_text(path("two.json")));
  EXPECT_EQ(b["manifest"]["world_size"], 2);
  for (const char* key : {"accuracy", "top2", "confusion", "baselines", "full_image_accuracy", "greedy_accuracy",
                          "revealed_fraction", "images", "runs"})
    EXPECT_EQ(a[key], b[key]) << key;
  // An interface this machine does not have: one line from each rank, naming it.
  const Result bad = run(common + " --nproc 2 --timeout 5 --interface nosuch0");
  EXPECT_EQ(bad.status, 1) << bad.out << bad.err;
  EXPECT_NE(bad.err.find("scout: rank 0: error: "), std::string::npos) << bad.err;
  EXPECT_NE(bad.err.find("nosuch0"), std::string::npos) << bad.err;
  for (const std::string& line : lines_of(bad.err)) EXPECT_EQ(line.rfind("scout: rank ", 0), 0u) << bad.err;
}

// The hidden temporaries a writer of a run's checkpoint leaves beside it when killed
// (".checkpoint.safetensors.tmp-PID-XXXXXXXX"), with their sizes.
std::map<std::string, std::uintmax_t> checkpoint_temporaries(const std::string& run_dir) {
  std::map<std::string, std::uintmax_t> found;
  std::error_code ec;
  for (fs::directory_iterator it(run_dir, ec), end; !ec && it != end; it.increment(ec))
    if (it->path().filename().string().rfind(".checkpoint.safetensors.tmp-", 0) == 0)
      found[it->path().filename().string()] = fs::file_size(it->path(), ec);
  return found;
}

TEST_F(TrainDistributed, AKillInsideACheckpointWriteLeavesARunThatResumesToTheSameWeights) {
  // A checkpoint after every batch (--checkpoint-every below a batch's time; rank 0 writes it
  // while rank 1 goes on to the next batch's all-reduce), fp32: two processes give the same
  // weights every time (TheSameProcessCountTwiceGivesBitIdenticalWeights).
  const std::string every = " --checkpoint-every 0.00002 --nproc 2 --timeout 20";
  const std::string options = " --epochs 1,1,1" + kExact + scout::testing::train_cli_support::kTiny + every;
  const Result reference = run("train " + world() + " --out " + path("reference") + options);
  ASSERT_EQ(reference.status, 0) << reference.out << reference.err;

  // Rank 0 kills itself half-way through the N-th file it writes (SCOUT_FAULT_KILL_AT reaches both
  // ranks through the launcher; rank 0 alone writes): the kill lands inside that write by
  // construction, whatever the timing. Rank 0 writes manifest.json, then a checkpoint after each
  // of an epoch's 5 batches; a resumed run first manifest.json and metrics.csv. So the points are
  // all checkpoints: after batch 2 of the first epoch (a new run), after batch 3 (resumed after
  // batch 1), and at the first epoch's end (resumed after batch 2), before its metrics.csv row.
  // Each resume must start from the checkpoint before the one being written: whole, not torn.
  const std::vector<std::pair<std::string, std::string>> kills = {{"file-write:3", "(stage i, epoch 0, batch 1)"},
                                                                  {"file-write:4", "(stage i, epoch 0, batch 2)"},
                                                                  {"file-write:5", "(stage i, epoch 0, batch 4)"}};
  const std::string killed = path("killed");
  int inside = 0;
  for (std::size_t k = 0; k < kills.size(); ++k) {
    const auto before = checkpoint_temporaries(killed);
    const std::string args =
        k == 0 ? "train " + world() + " --out " + killed + options : "train --resume " + killed + every;
    const Result r = run(args, "SCOUT_FAULT_KILL_AT=" + kills[k].first);
    // Rank 0 was killed (the launcher passes its status on: 128 + 9); rank 1 stopped on its own,
    // with one line; no rank is left.
    EXPECT_EQ(r.status, 128 + SIGKILL) << kills[k].first << "\n" << r.out << r.err;
    EXPECT_NE(r.err.find("scout: rank 0 was killed by signal 9"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("scout: rank 1: error: rank 0 was lost"), std::string::npos) << r.err;
    EXPECT_EQ(processes_naming(killed), 0);
    if (k > 0) {
      EXPECT_NE(r.out.find("resuming after 0 epoch(s) " + kills[k - 1].second), std::string::npos)
          << "after the kill at " << kills[k - 1].first << ":\n"
          << r.out;
    }
    // Inside a checkpoint write: its half-written temporary is beside the checkpoint, not in place.
    auto after = checkpoint_temporaries(killed);
    for (const auto& [name, size] : before) after.erase(name);
    if (after.size() == 1 && after.begin()->second > 0) ++inside;
    // The checkpoint in place opens whole (scout_test_compare_weights reads every tensor of it).
    EXPECT_TRUE(compare_weights(killed, killed).identical) << kills[k].first;
  }
  EXPECT_EQ(inside, static_cast<int>(kills.size()))
      << "of " << kills.size() << " kills, " << inside << " landed inside a checkpoint write";

  const Result last = run("train --resume " + killed + every);
  ASSERT_EQ(last.status, 0) << last.out << last.err;
  EXPECT_NE(last.out.find("resuming after 0 epoch(s) " + kills.back().second), std::string::npos) << last.out;
  // The killed writers' temporaries are gone once rank 0 has written there again.
  for (const auto& entry : fs::directory_iterator(killed))
    EXPECT_NE(entry.path().filename().string()[0], '.') << entry.path() << " was left behind";
  std::printf("[ measured ] %zu SIGKILLs of rank 0 (%d inside a checkpoint write), then resumed to the end\n",
              kills.size(), inside);
  // The uninterrupted run's weights, bit for bit, and its metrics.
  const Weights w = compare_weights(path("reference"), killed);
  EXPECT_TRUE(w.identical) << w.worst << " differs by up to " << w.max_difference;
  EXPECT_EQ(metrics_without_timing(killed + "/metrics.csv"),
            metrics_without_timing(path("reference") + "/metrics.csv"));
}

TEST_F(TrainDistributed, TrainingOverANamedInterfaceTrainsTheSameWeights) {
  const std::string schedule =
      " --epochs 1,1,1 --train-limit 10 --nproc 2" + kExact + scout::testing::train_cli_support::kTiny;
  const Result two = run("train " + world() + " --out " + path("two") + schedule + " --timeout 20");
  ASSERT_EQ(two.status, 0) << two.out << two.err;
  // Over the loopback interface by name (what GLOO_SOCKET_IFNAME or --interface choose): the same
  // training, so the same weights bit for bit.
  const Result lo = run("train " + world() + " --out " + path("lo") + schedule + " --timeout 20 --interface lo");
  ASSERT_EQ(lo.status, 0) << lo.out << lo.err;
  EXPECT_NE(lo.out.find("2 processes x 1 LibTorch threads"), std::string::npos) << lo.out;
  EXPECT_EQ(json::parse(read_text(path("lo") + "/manifest.json"))["world_size"], 2);
  const Weights w = compare_weights(path("two"), path("lo"));
  EXPECT_TRUE(w.identical) << w.worst << " differs by up to " << w.max_difference;
  EXPECT_EQ(metrics_without_timing(path("lo") + "/metrics.csv"), metrics_without_timing(path("two") + "/metrics.csv"));
  // An interface this machine does not have: one line from each rank, naming it, and no run
  // folder left.
  const Result bad = run("train " + world() + " --out " + path("bad") + schedule + " --timeout 5 --interface nosuch0");
  EXPECT_EQ(bad.status, 1) << bad.out << bad.err;
  EXPECT_EQ(lines_of(bad.err).size(), 2u) << bad.err;
  for (const int rank : {0, 1})
    EXPECT_NE(bad.err.find("scout: rank " + std::to_string(rank) + ": error: "), std::string::npos) << bad.err;
  for (const std::string& line : lines_of(bad.err)) {
    EXPECT_EQ(line.rfind("scout: rank ", 0), 0u) << bad.err;
    EXPECT_NE(line.find("nosuch0"), std::string::npos) << line;
  }
  EXPECT_FALSE(fs::exists(path("bad")));
}

// Across hosts, as a cluster sees the run: one rank in each of two network namespaces joined by a
// veth pair, each with its own address, MASTER_ADDR on the first, Gloo bound to each namespace's
// interface. The same training as two processes on one host, bit for bit (the all-reduce adds
// the same shares in the same order; TrainingOverANamedInterfaceTrainsTheSameWeights shows the
// interface does not enter the sums), over the pair: its counters grew by the run's traffic.
TEST_F(TrainDistributed, RanksInTwoNetworkNamespacesTrainTheSameWeightsAsOneHost) {
  scout::testing::NetworkNamespaces hosts;
  REQUIRE_NAMESPACES(hosts);
  const std::string schedule =
      " --epochs 1,1,1 --train-limit 10 --timeout 20" + kExact + scout::testing::train_cli_support::kTiny;
  const Result one_host = run("train " + world() + " --out " + path("one-host") + schedule + " --nproc 2");
  ASSERT_EQ(one_host.status, 0) << one_host.out << one_host.err;
  const long long sent_before = hosts.sent_bytes(1);
  const int port = free_port();
  const std::string args = "train " + world() + " --out " + path("hosts") + schedule;
  const Rank r0 = start_rank_in(hosts, 0, port, args, local_.path());
  const Rank r1 = start_rank_in(hosts, 1, port, args, local_.path());
  const auto [status0, seconds0] = wait_rank(r0);
  const auto [status1, seconds1] = wait_rank(r1, 60);
  ASSERT_EQ(status0, 0) << read_text(r0.out) << read_text(r0.err);
  ASSERT_EQ(status1, 0) << read_text(r1.err);
  std::printf("[ measured ] two namespaces: rank 0 took %.1f s; rank 1 sent %lld bytes over the veth pair\n", seconds0,
              hosts.sent_bytes(1) - sent_before);
  EXPECT_NE(read_text(r0.out).find("2 processes x 1 LibTorch threads"), std::string::npos) << read_text(r0.out);
  // Rank 1's gradients crossed the pair: at least its share of every all-reduce.
  EXPECT_GT(hosts.sent_bytes(1) - sent_before, 10'000);
  const Weights w = compare_weights(path("one-host"), path("hosts"));
  EXPECT_TRUE(w.identical) << w.worst << " differs by up to " << w.max_difference;
  EXPECT_EQ(metrics_without_timing(path("hosts") + "/metrics.csv"),
            metrics_without_timing(path("one-host") + "/metrics.csv"));
  EXPECT_EQ(json::parse(read_text(path("hosts") + "/manifest.json"))["world_size"], 2);
}

// A host that drops off the network: its link goes down in the middle of mode (iii). With the
// timeout 5 s, every rank stops within 15 s, each with one line naming the rank it lost (rank 0
// loses rank 1; rank 1 loses rank 0, whose store it can no longer reach), and the checkpoint on
// disk is a whole one that scout reads.
TEST_F(TrainDistributed, ANamespaceWhoseLinkGoesDownStopsEveryRankWithinFifteenSeconds) {
  scout::testing::NetworkNamespaces hosts;
  REQUIRE_NAMESPACES(hosts);
  const std::string run_dir = path("run");
  const auto [r0, r1] = start_long_run_across(hosts, world(), run_dir, local_.path());
  ASSERT_TRUE(scout::testing::wait_for_text(r0.pid, r0.out, "mode iii epoch   1:", 300)) << read_text(r0.err);
  ASSERT_TRUE(hosts.set_link(1, false));
  const auto t0 = Clock::now();
  const auto [status0, seconds0] = wait_rank(r0, 60);
  const int status1 = wait_rank(r1, 60 - seconds0).first;
  const double stopped1 = std::chrono::duration<double>(Clock::now() - t0).count();
  std::printf("[ measured ] link down: rank 0 stopped after %.1f s, rank 1 after %.1f s\n", seconds0,
              std::max(seconds0, stopped1));
  for (const auto& [rank, status, seconds, lost] :
       {std::tuple{0, status0, seconds0, 1}, std::tuple{1, status1, std::max(seconds0, stopped1), 0}}) {
    const std::string said = read_text(rank == 0 ? r0.err : r1.err);
    EXPECT_EQ(status, 1) << "rank " << rank << ": " << said;
    EXPECT_LT(seconds, 15.0) << "rank " << rank << ": " << said;
    const std::vector<std::string> errors = error_lines(said);
    ASSERT_EQ(errors.size(), 1u) << said;
    EXPECT_NE(
        errors[0].find("scout: rank " + std::to_string(rank) + ": error: rank " + std::to_string(lost) + " was lost"),
        std::string::npos)
        << said;
  }
  // The last good checkpoint: whole, and read back by scout.
  const Result exported = run("export " + run_dir + " --out " + path("last.safetensors"));
  EXPECT_EQ(exported.status, 0) << exported.out << exported.err;
}

// A host whose rank is killed: the other rank, in its own namespace, stops within 15 s with one
// line naming it.
TEST_F(TrainDistributed, ARankKilledInItsNamespaceStopsTheOtherWithinFifteenSeconds) {
  scout::testing::NetworkNamespaces hosts;
  REQUIRE_NAMESPACES(hosts);
  const std::string run_dir = path("run");
  const auto [r0, r1] = start_long_run_across(hosts, world(), run_dir, local_.path());
  ASSERT_TRUE(scout::testing::wait_for_text(r0.pid, r0.out, "mode iii epoch   1:", 300)) << read_text(r0.err);
  kill(r1.pid, SIGKILL);
  const auto [status, seconds] = wait_rank(r0, 60);
  wait_rank(r1, 5);
  std::printf("[ measured ] rank 0 stopped %.1f s after rank 1 was killed in its namespace\n", seconds);
  const std::string said = read_text(r0.err);
  EXPECT_EQ(status, 1) << said;
  EXPECT_LT(seconds, 15.0) << said;
  const std::vector<std::string> errors = error_lines(said);
  ASSERT_EQ(errors.size(), 1u) << said;
  EXPECT_NE(errors[0].find("scout: rank 0: error: rank 1 was lost"), std::string::npos) << said;
  const Result exported = run("export " + run_dir + " --out " + path("last.safetensors"));
  EXPECT_EQ(exported.status, 0) << exported.out << exported.err;
}

}  // namespace
