// Writes that fail: a file-size limit (RLIMIT_FSIZE; scout ignores SIGXFSZ itself, so write()
// returns EFBIG), a full disk (a small tmpfs) and a read-only folder, each in a private mount namespace.
// Every case is one line naming the file, exit status 1, and the previous checkpoint intact.
#include <fmt/format.h>
#include <sys/resource.h>

#include "tests/support/train_cli_fixture.hpp"

namespace {

namespace fs = std::filesystem;
using scout::testing::train_cli_support::lines_of;
using scout::testing::train_cli_support::read_text;
using scout::testing::train_cli_support::Result;
using scout::testing::train_cli_support::TrainCli;

// Runs `argv` with files limited to `max_bytes`, as `ulimit -f` would (SIGXFSZ keeps its default
// action, which kills: the program must ignore it itself); stdout and stderr captured.
Result run_limited(const std::vector<std::string>& argv, rlim_t max_bytes, const fs::path& scratch) {
  const fs::path out = scratch / "limited.out", err = scratch / "limited.err";
  const pid_t child = scout::testing::spawn(argv, out, err, [max_bytes] {
    const rlimit limit{max_bytes, max_bytes};
    setrlimit(RLIMIT_FSIZE, &limit);
    signal(SIGXFSZ, SIG_DFL);  // whatever the test runner set
  });
  int raw = 0;
  waitpid(child, &raw, 0);
  return {WIFEXITED(raw) ? WEXITSTATUS(raw) : -1, read_text(out), read_text(err)};
}

// Files in `folder` whose names start with '.' (temporaries left behind).
int hidden_files(const fs::path& folder) {
  int n = 0;
  for (const fs::directory_entry& e : fs::directory_iterator(folder))
    if (e.path().filename().string().front() == '.') ++n;
  return n;
}

// Exit status 1 and one error line (after any progress lines): "scout: error: FILE: cannot write (REASON)".
void expect_write_error(const Result& r, const std::string& file, const std::string& reason) {
  EXPECT_EQ(r.status, 1) << r.out << r.err;
  std::vector<std::string> lines;
  for (const std::string& line : lines_of(r.err))
    if (line.rfind("mode ", 0) != 0) lines.push_back(line);
  ASSERT_EQ(lines.size(), 1u) << r.err;
  EXPECT_EQ(lines[0], "scout: error: " + file + ": cannot write (" + reason + ")") << r.err;
}

TEST_F(TrainCli, AFileSizeLimitStopsTrainingWithOneLineAndKeepsTheCheckpoint) {
  const std::string run_dir = copy_of_base("limited");
  const std::string checkpoint_before = read_text(run_dir + "/checkpoint.safetensors");
  // Room for the manifest and metrics.csv, not for the checkpoint.
  const auto small_files = std::max(fs::file_size(run_dir + "/manifest.json"), fs::file_size(run_dir + "/metrics.csv"));
  const rlim_t limit = small_files * 2 + 4096;
  ASSERT_LT(limit, checkpoint_before.size());
  const Result r = run_limited({SCOUT_BINARY, "train", "--resume", run_dir, "--epochs", "2,0,0"}, limit, local_.path());
  expect_write_error(r, run_dir + "/checkpoint.safetensors", "File too large");
  EXPECT_EQ(read_text(run_dir + "/checkpoint.safetensors"), checkpoint_before);
  EXPECT_EQ(hidden_files(run_dir), 0);
  // With room again, the run goes on from the kept checkpoint.
  const Result resumed = run("train --resume " + run_dir + " --epochs 2,0,0");
  ASSERT_EQ(resumed.status, 0) << resumed.out << resumed.err;
  EXPECT_EQ(lines_of(read_text(run_dir + "/metrics.csv")).size(), 3u);
}

// The same in a private mount namespace on a tmpfs that is full, then read-only.
TEST_F(TrainCli, AFullDiskAndAReadOnlyFolderStopTrainingWithOneLineAndKeepTheCheckpoint) {
  const fs::path mount = local_.path() / "disk";
  fs::create_directories(mount);
  const std::string run_dir = (mount / "run").string();
  const std::string checkpoint = base() + "/checkpoint.safetensors";
  const auto room = fs::file_size(checkpoint) + fs::file_size(base() + "/manifest.json") + 64 * 1024;
  // A tmpfs just big enough for the run's files plus a filler that leaves too little for a
  // second checkpoint beside the first; then remounted read-only.
  const std::string script = fmt::format(
      "set -e; mount -t tmpfs -o size={room} tmpfs '{m}'; cp -r '{base}' '{run}'; "
      "fill=$(( $(stat -f -c '%a*%S' '{m}') - {keep} )); head -c $fill /dev/zero > '{m}/filler' || true; "
      "'{scout}' train --resume '{run}' --epochs 2,0,0 > '{m}/../full.out' 2> '{m}/../full.err' || echo $? > "
      "'{m}/../full.status'; "
      "cmp '{run}/checkpoint.safetensors' '{ckpt}' && echo intact > '{m}/../full.intact'; "
      "ls -A '{run}' | grep -c '^[.]' > '{m}/../full.hidden' || true; "
      "rm '{m}/filler'; mount -o remount,ro '{m}'; "
      "'{scout}' train --resume '{run}' --epochs 2,0,0 > '{m}/../ro.out' 2> '{m}/../ro.err' || echo $? > "
      "'{m}/../ro.status'",
      fmt::arg("room", room), fmt::arg("m", mount.string()), fmt::arg("base", base()), fmt::arg("run", run_dir),
      fmt::arg("keep", fs::file_size(checkpoint) / 2), fmt::arg("scout", SCOUT_BINARY), fmt::arg("ckpt", checkpoint));
  std::ofstream(local_.path() / "disk.sh") << script << "\n";
  const scout::testing::CliResult r =
      scout::testing::run_cli("unshare", "-m sh '" + (local_.path() / "disk.sh").string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  const fs::path dir = local_.path();
  EXPECT_EQ(read_text(dir / "full.status"), "1\n") << read_text(dir / "full.err");
  expect_write_error({1, "", read_text(dir / "full.err")}, run_dir + "/checkpoint.safetensors",
                     "No space left on device");
  EXPECT_EQ(read_text(dir / "full.intact"), "intact\n");
  EXPECT_EQ(read_text(dir / "full.hidden"), "0\n") << "the failed write left a temporary in the run folder";
  EXPECT_EQ(read_text(dir / "ro.status"), "1\n") << read_text(dir / "ro.err");
  const std::string ro = read_text(dir / "ro.err");
  EXPECT_EQ(std::count(ro.begin(), ro.end(), '\n'), 1) << ro;
  EXPECT_EQ(ro.rfind("scout: error: " + run_dir + "/", 0), 0u) << ro;
  EXPECT_NE(ro.find(": cannot write (Read-only file system)"), std::string::npos) << ro;
}

}  // namespace
