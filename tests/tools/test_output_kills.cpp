// Hard kills of the commands that write results: `scout run` and `scout eval` killed with
// SIGKILL at seeded random moments and at named points (half-way through a file, between the two
// renames that replace an output folder) leave either nothing or complete output, never a part
// that passes for the whole; the next run repairs what the killed one left (its hidden staging
// folders and temporary files) and finishes. `scout data` killed mid-install is repaired by the
// next run (needs the npm registry, as `scout data` does). `scout report`, `scout run --video` and
// `scout bench sim --json` killed at random moments of their work: the same.
#include <chrono>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <random>

#include "tests/support/data.hpp"
#include "tests/support/train_cli_fixture.hpp"

namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using scout::testing::train_cli_support::lines_of;
using scout::testing::train_cli_support::read_text;
using scout::testing::train_cli_support::Result;
using scout::testing::train_cli_support::TrainCli;

// How one attempt ends: a named point ("POINT:N": the process kills itself there), a kill from
// outside after `delay_ms`, or none (kNoKill: the attempt runs to its end).
struct Kill {
  std::string point;
  int delay_ms = -1;
  std::string describe() const { return point.empty() ? std::to_string(delay_ms) + " ms" : point; }
};

const Kill kNoKill{};

// What `scout run --checkpoint` and `scout eval` print on stderr once the model is open and the
// work begins (the precision line): random kills are drawn after it, so that none is spent on
// start-up (seconds under ASan).
constexpr const char* kModelOpened = "precision: ";

// How an attempt ended.
struct Ended {
  bool killed = false;    // by SIGKILL (a named point or a random moment)
  bool mid_work = false;  // a random kill that found the process still working
};

// Runs `scout ARGS` once with `kill` (otherwise it must finish well). A random moment counts from
// the line `ready` on stderr where one is given, else from the start.
Ended attempt(const fs::path& dir, const std::string& args, const Kill& kill, const std::string& ready = "") {
  std::vector<std::string> argv = {"/usr/bin/env", "SCOUT_FAULT_KILL_AT=" + kill.point, SCOUT_BINARY};
  std::istringstream words(args);
  for (std::string w; words >> w;) argv.push_back(w);
  const pid_t child = scout::testing::spawn(argv, dir / "out.txt", dir / "err.txt");
  EXPECT_GT(child, 0);
  Ended ended;
  int status = 0;
  bool reaped = false;
  if (kill.point.empty() && kill.delay_ms >= 0) {
    if (ready.empty() || scout::testing::wait_for_text(child, dir / "err.txt", ready, 300, &status)) {
      usleep(kill.delay_ms * 1000);
      reaped = waitpid(child, &status, WNOHANG) == child;
      if (!reaped) {
        ::kill(child, SIGKILL);
        ended.mid_work = true;
      }
    } else {
      reaped = true;  // ended before its readiness line: reported below
    }
  }
  if (!reaped) {
    EXPECT_EQ(waitpid(child, &status, 0), child);
  }
  ended.killed = WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL;
  if (!ended.killed) {
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << kill.describe() << ": " << read_text(dir / "err.txt");
  }
  return ended;
}

// Runs `scout ARGS` to its end; returns the milliseconds from the line `ready` to the end.
double work_ms(const fs::path& dir, const std::string& args, const std::string& ready) {
  std::vector<std::string> argv = {SCOUT_BINARY};
  std::istringstream words(args);
  for (std::string w; words >> w;) argv.push_back(w);
  const pid_t child = scout::testing::spawn(argv, dir / "out.txt", dir / "err.txt");
  EXPECT_TRUE(scout::testing::wait_for_text(child, dir / "err.txt", ready, 300)) << read_text(dir / "err.txt");
  const auto t0 = std::chrono::steady_clock::now();
  int status = 0;
  EXPECT_EQ(waitpid(child, &status, 0), child);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << read_text(dir / "err.txt");
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// Every regular file under `folder` but the manifest (which records times and command lines), by
// its path inside it.
std::map<std::string, std::string> files_under(const fs::path& folder) {
  std::map<std::string, std::string> files;
  for (const auto& entry : fs::recursive_directory_iterator(folder))
    if (entry.is_regular_file() && entry.path().filename() != "manifest.json")
      files[fs::relative(entry.path(), folder).string()] = read_text(entry.path());
  return files;
}

// The hidden entries beside `target` that a writer of it leaves while working.
std::vector<std::string> leftovers_beside(const fs::path& target) {
  std::vector<std::string> found;
  const std::string prefix = std::string(".").append(target.filename().string()).append(".");
  for (const auto& entry : fs::directory_iterator(target.parent_path()))
    if (entry.path().filename().string().rfind(prefix, 0) == 0) found.push_back(entry.path().filename().string());
  return found;
}

// A schedule of kills: the named points interleaved with seeded random moments in [lo, hi] ms.
std::vector<Kill> schedule(std::vector<std::string> points, int random_kills, double lo, double hi, unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_int_distribution<int> delay_ms(static_cast<int>(lo), static_cast<int>(hi));
  std::vector<Kill> out;
  for (int k = 0; k < random_kills || !points.empty(); ++k) {
    if (k < random_kills) out.push_back(Kill{"", delay_ms(random)});
    if (!points.empty()) {
      out.push_back(Kill{points.front()});
      points.erase(points.begin());
    }
  }
  return out;
}

constexpr int kRuns = 120;

// A complete `scout run` folder: its manifest and all of its runs.
void expect_complete_run_output(const fs::path& out, const std::string& when) {
  ASSERT_TRUE(fs::is_regular_file(out / "manifest.json")) << when;
  const json trajectory = json::parse(read_text(out / "trajectory.json"));
  EXPECT_EQ(trajectory["runs"].size(), static_cast<std::size_t>(kRuns)) << when;
}

TEST_F(TrainCli, RunKilledLeavesNoOutputThatPassesForComplete) {
  const fs::path out = path("out");
  const std::string common = "run " + world() + " --checkpoint " + base() + " --count " + std::to_string(kRuns);
  const std::string args = common + " --out " + out.string() + " --overwrite";
  // The uninterrupted run, the one every killed run's final output must equal, and how long its
  // work takes: the random moments are shares of it.
  const double work = work_ms(local_.path(), common + " --out " + path("reference"), kModelOpened);
  int kills = 0, mid_work = 0;
  for (const Kill& kill :
       schedule({"file-write:1", "output-commit:1", "file-write:1"}, 6, 0.05 * work, 0.9 * work, 20261202)) {
    const Ended ended = attempt(local_.path(), args, kill, kModelOpened);
    kills += ended.killed ? 1 : 0;
    mid_work += ended.mid_work ? 1 : 0;
    // After every attempt: the folder is absent, or whole (the previous run's or this one's).
    if (fs::exists(out)) expect_complete_run_output(out, kill.describe());
  }
  EXPECT_GE(kills, 5);
  EXPECT_GE(mid_work, 4) << "of 6 random kills, only " << mid_work << " landed mid-work";

  // Killed between the two renames of a replacement: the previous output is aside, none in place.
  ASSERT_FALSE(attempt(local_.path(), args, kNoKill).killed);  // a whole run first (the kill comes too late)
  ASSERT_TRUE(attempt(local_.path(), args, Kill{"output-commit:1"}).killed);
  EXPECT_FALSE(fs::exists(out));
  // The next run puts it back before anything else: without --overwrite it is refused, as for any
  // existing output, and the previous output is in place again.
  const Result refused = run("run " + world() + " --count 1 --out " + out.string());
  EXPECT_EQ(refused.status, 1) << refused.err;
  EXPECT_NE(refused.err.find("already exists"), std::string::npos) << refused.err;
  expect_complete_run_output(out, "restored");

  // Finally a run to the end: complete, the uninterrupted run's output byte for byte (trajectories
  // and pictures), and nothing hidden left beside it.
  ASSERT_FALSE(attempt(local_.path(), args, kNoKill).killed);
  expect_complete_run_output(out, "last");
  const std::map<std::string, std::string> reference = files_under(path("reference")), last = files_under(out);
  EXPECT_GT(reference.size(), 1u);
  EXPECT_EQ(last.size(), reference.size());
  for (const auto& [name, bytes] : reference) EXPECT_TRUE(last.count(name) && last.at(name) == bytes) << name;
  EXPECT_EQ(leftovers_beside(out), std::vector<std::string>{});
  std::printf("[ measured ] scout run: %d SIGKILLs (%d of 6 random ones mid-work), then the uninterrupted output\n",
              kills + 1, mid_work);
}

TEST_F(TrainCli, EvalKilledLeavesNoPartialReport) {
  const fs::path data = temp_->path() / "data";
  const fs::path report = path("eval.json"), predictions = path("predictions.csv");
  const std::string args = "eval --checkpoint " + base() + " --images " + (data / "train-images-idx3-ubyte").string() +
                           " --labels " + (data / "train-labels-idx1-ubyte").string() + " --runs 200 --json " +
                           report.string() + " --predictions " + predictions.string();
  const std::size_t images = 48;
  // The uninterrupted evaluation (its predictions are what every finished attempt must write).
  const fs::path reference = path("reference-predictions.csv");
  const double work = work_ms(
      local_.path(),
      "eval --checkpoint " + base() + " --images " + (data / "train-images-idx3-ubyte").string() + " --labels " +
          (data / "train-labels-idx1-ubyte").string() + " --runs 200 --predictions " + reference.string(),
      kModelOpened);
  int kills = 0, mid_work = 0;
  for (const Kill& kill : schedule({"file-write:1", "file-write:2", "file-write:1"}, 6, 0.05 * work, 0.9 * work, 7)) {
    const Ended ended = attempt(local_.path(), args, kill, kModelOpened);
    kills += ended.killed ? 1 : 0;
    mid_work += ended.mid_work ? 1 : 0;
    if (fs::exists(report)) {
      const json j = json::parse(read_text(report));  // parses: never half a file
      EXPECT_TRUE(j.contains("accuracy")) << kill.describe();
    }
    if (fs::exists(predictions)) {
      EXPECT_EQ(lines_of(read_text(predictions)).size(), images + 1) << kill.describe();
    }
  }
  EXPECT_GE(kills, 5);
  EXPECT_GE(mid_work, 4) << "of 6 random kills, only " << mid_work << " landed mid-work";
  ASSERT_FALSE(attempt(local_.path(), args, kNoKill).killed);
  EXPECT_TRUE(json::parse(read_text(report)).contains("accuracy"));
  EXPECT_EQ(lines_of(read_text(predictions)).size(), images + 1);
  EXPECT_EQ(read_text(predictions), read_text(reference)) << "not the uninterrupted evaluation's predictions";
  EXPECT_EQ(leftovers_beside(report), std::vector<std::string>{});
  EXPECT_EQ(leftovers_beside(predictions), std::vector<std::string>{});
  std::printf("[ measured ] scout eval: %d SIGKILLs (%d of 6 random ones mid-work), then a complete report\n", kills,
              mid_work);
}

TEST_F(TrainCli, DataKilledMidInstallIsRepairedByTheNextRun) {
  if (scout::testing::skip_network_tests()) GTEST_SKIP() << "SCOUT_SKIP_NETWORK_TESTS is set";
  const fs::path data = path("data");
  const std::string args = "data mnist-10k --data " + data.string();
  int kills = 0;
  for (const Kill& kill : schedule({"file-write:1"}, 4, 300, 4000, 11))
    kills += attempt(local_.path(), args, kill).killed ? 1 : 0;
  EXPECT_GE(kills, 3);
  ASSERT_FALSE(attempt(local_.path(), args, kNoKill).killed);
  // Installed and checked (the next call has nothing to do), and the killed installs' temporary
  // folders are gone.
  const Result again = run(args);
  ASSERT_EQ(again.status, 0) << again.err;
  EXPECT_NE(again.out.find("nothing to do"), std::string::npos) << again.out;
  for (const fs::path& folder : {data, data / "mnist-10k"})
    for (const auto& entry : fs::directory_iterator(folder))
      EXPECT_NE(entry.path().filename().string()[0], '.') << entry.path();  // no temporaries left
  std::printf("[ measured ] scout data: %d SIGKILLs, then installed\n", kills);
}

// Kills of the commands that write one whole output at the end (report, run --video, bench).

// What a schedule of kills came to.
struct Tally {
  int kills = 0;     // attempts that ended by SIGKILL
  int random = 0;    // random moments in the schedule
  int mid_work = 0;  // random moments that found the process still working
};

// Runs `scout ARGS` once per kill of `kills` (the random moments counted from the line `ready`),
// calling `before(k)` before the k-th attempt where given and `check(kill)` after each.
Tally kill_on_schedule(const fs::path& dir, const std::string& args, const std::vector<Kill>& kills,
                       const std::string& ready, const std::function<void(const Kill&)>& check,
                       const std::function<void(std::size_t)>& before = {}) {
  Tally tally;
  for (std::size_t k = 0; k < kills.size(); ++k) {
    const Kill& kill = kills[k];
    if (before) before(k);
    const Ended ended = attempt(dir, args, kill, ready);
    tally.kills += ended.killed ? 1 : 0;
    tally.random += kill.point.empty() ? 1 : 0;
    tally.mid_work += ended.mid_work ? 1 : 0;
    check(kill);
  }
  return tally;
}

// A JSON file's document without the members at `pointers` (times and dates, which differ run to
// run); a file that does not parse is a null document with "unparsable" in it.
json json_without(const fs::path& file, const std::vector<std::string>& pointers) {
  json j = json::parse(read_text(file), nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) return json{{"unparsable", file.string()}};
  for (const std::string& p : pointers) {
    const json::json_pointer at(p);
    if (j.contains(at)) j[at.parent_pointer()].erase(at.back());
  }
  return j;
}

// The hidden entries of `folder` (a writer's temporaries and staging folders).
std::vector<std::string> hidden_in(const fs::path& folder) {
  std::vector<std::string> found;
  for (const auto& entry : fs::directory_iterator(folder))
    if (entry.path().filename().string()[0] == '.') found.push_back(entry.path().filename().string());
  return found;
}

// REPORT.md's text with the time it took (" in 12 s") replaced by " in # s".
// (Not std::regex: GCC 12's <regex> trips -Wmaybe-uninitialized under the sanitizers' -O1, which
// CI builds with warnings as errors.)
std::string without_durations(const std::string& text) {
  std::string out;
  for (std::size_t i = 0; i < text.size();) {
    std::size_t end = i + 4;
    if (text.compare(i, 4, " in ") == 0) {
      while (end < text.size() && text[end] >= '0' && text[end] <= '9') ++end;
      if (end > i + 4 && text.compare(end, 2, " s") == 0) {
        out += " in #";
        i = end;
        continue;
      }
    }
    out += text[i++];
  }
  return out;
}

// The files of a `scout report` folder that differ from the uninterrupted report's (its files
// listed from it). Deterministic byte for byte: the figures (matplotlib's PNGs). Deterministic
// but for times: REPORT.md (the "in N s" it took), report-data.json ("seconds"), eval.json
// ("seconds", the manifest's "created_utc") and manifest.json ("created_utc").
std::vector<std::string> report_differences(const fs::path& out, const fs::path& reference) {
  static const std::map<std::string, std::vector<std::string>> kTimes = {
      {"report-data.json", {"/seconds"}},
      {"eval.json", {"/seconds", "/manifest/created_utc"}},
      {"manifest.json", {"/created_utc"}}};
  std::vector<std::string> differ;
  std::size_t files = 0;
  for (const auto& entry : fs::directory_iterator(reference)) {
    const std::string name = entry.path().filename().string();
    ++files;
    const fs::path mine = out / name;
    bool same = false;
    if (kTimes.count(name)) {
      same = json_without(mine, kTimes.at(name)) == json_without(entry.path(), kTimes.at(name));
    } else if (name == "REPORT.md") {
      same = without_durations(read_text(mine)) == without_durations(read_text(entry.path()));
    } else {
      same = fs::is_regular_file(mine) && read_text(mine) == read_text(entry.path());
    }
    if (!same) differ.push_back(name);
  }
  std::size_t mine = 0;
  for (const auto& entry : fs::directory_iterator(out)) mine += entry.is_regular_file() ? 1 : 0;
  if (mine != files) differ.push_back(std::to_string(mine) + " files, not " + std::to_string(files));
  return differ;
}

TEST_F(TrainCli, ReportKilledLeavesNoReportThatPassesForComplete) {
  const fs::path data = temp_->path() / "data";
  const fs::path out = local_.path() / "report", reference = local_.path() / "reference";
  // The base model has no evaluation beside it: the report evaluates it, then sweeps the budget,
  // drives the test episodes and draws the figures (matplotlib) into a staging folder.
  const std::string args = "report " + base() + " --out " + out.string() + " --overwrite --images " +
                           (data / "train-images-idx3-ubyte").string() + " --labels " +
                           (data / "train-labels-idx1-ubyte").string() +
                           " --runs 2 --sweep-digits 9 --sweep-runs 1 --episodes 4 --seed 4";
  // The uninterrupted report, with the very command line of the killed ones (the report quotes
  // it), set aside as the reference; its work's length scales the random moments.
  const double work = work_ms(local_.path(), args, kModelOpened);
  fs::copy(out, reference, fs::copy_options::recursive);
  ASSERT_EQ(report_differences(out, reference), std::vector<std::string>{});

  // The named point: half-way through report-data.json, before the figures are drawn (the kill
  // between the two renames of a replacement is scout run's above: the same OutputDir). The
  // random moments stop short of the reference's end, whose length varies with the load.
  auto whole = [&](const Kill& kill) {
    // Absent, or a whole report (the previous one or this one): never part of one.
    if (fs::exists(out)) {
      EXPECT_EQ(report_differences(out, reference), std::vector<std::string>{}) << kill.describe();
    }
  };
  // Every other attempt is a first report into a new folder (the previous one removed), the
  // others replace the previous one: a killed report must leave no folder, or the previous one.
  auto new_folder_every_other = [&](std::size_t k) {
    if (k % 2 == 0) fs::remove_all(out);
  };
  const Tally tally =
      kill_on_schedule(local_.path(), args, schedule({"file-write:2"}, 4, 0.05 * work, 0.7 * work, 20261204),
                       kModelOpened, whole, new_folder_every_other);
  EXPECT_EQ(tally.kills, 1 + tally.mid_work);  // the named point was reached
  EXPECT_GE(tally.mid_work, 3) << "of 4 random kills, only " << tally.mid_work << " landed mid-work";

  // A SIGKILL does not reach the plotting script a killed report had started: it finishes on its
  // own, writing into the dead report's hidden staging folder. The last run's clean-up is checked
  // once those have ended (a bound against hanging, never a pass condition).
  const std::string staging = (local_.path() / ".report.partial-").string();
  const int orphans = scout::testing::processes_naming(staging);
  for (int k = 0; k < 3000 && scout::testing::processes_naming(staging) > 0; ++k) usleep(20 * 1000);
  // A run to the end: the uninterrupted report, and nothing hidden left beside it or in it.
  ASSERT_FALSE(attempt(local_.path(), args, kNoKill).killed);
  EXPECT_EQ(report_differences(out, reference), std::vector<std::string>{});
  EXPECT_EQ(leftovers_beside(out), std::vector<std::string>{});
  EXPECT_EQ(hidden_in(out), std::vector<std::string>{});
  std::printf(
      "[ measured ] scout report: %d SIGKILLs (%d of 4 random ones mid-work in %.0f ms of work, %d plotting "
      "script(s) still running after its report was killed), then the uninterrupted report\n",
      tally.kills, tally.mid_work, work, orphans);
}

TEST_F(TrainCli, RunVideoKilledLeavesNoPartialVideo) {
  const fs::path out = local_.path() / "out", video = local_.path() / "video" / "runs.gif";
  fs::create_directories(video.parent_path());
  // GIF (giflib): the same frames give the same bytes.
  const std::string args = "run " + world() + " --checkpoint " + base() + " --count 80 --no-images --scale 4 " +
                           "--fps 10 --video " + video.string() + " --out " + out.string() + " --overwrite";
  const double work = work_ms(local_.path(), args, kModelOpened);
  const std::string reference_video = read_text(video), reference_trajectory = read_text(out / "trajectory.json");
  ASSERT_GT(reference_video.size(), 1000u);

  // The named point: half-way through the manifest, after the video is in place and before the
  // output folder is.
  auto whole = [&](const Kill& kill) {
    // Under its name, a video is the whole video (the previous one or this one), never part.
    if (fs::exists(video)) {
      EXPECT_TRUE(read_text(video) == reference_video) << kill.describe();
    }
    if (fs::exists(out)) {
      EXPECT_EQ(read_text(out / "trajectory.json"), reference_trajectory) << kill.describe();
    }
  };
  const Tally tally = kill_on_schedule(local_.path(), args, schedule({"file-write:1"}, 4, 0.05 * work, 0.9 * work, 5),
                                       kModelOpened, whole);
  EXPECT_EQ(tally.kills, 1 + tally.mid_work);  // the named point was reached
  EXPECT_GE(tally.mid_work, 3) << "of 4 random kills, only " << tally.mid_work << " landed mid-work";

  // A run to the end: the uninterrupted run's video and trajectories byte for byte (the
  // manifests differ by their dates), and no temporary video or staging folder left.
  ASSERT_FALSE(attempt(local_.path(), args, kNoKill).killed);
  EXPECT_TRUE(read_text(video) == reference_video) << "not the uninterrupted run's video";
  EXPECT_EQ(read_text(out / "trajectory.json"), reference_trajectory);
  EXPECT_EQ(hidden_in(video.parent_path()), std::vector<std::string>{});
  EXPECT_EQ(leftovers_beside(out), std::vector<std::string>{});
  std::printf(
      "[ measured ] scout run --video: %d SIGKILLs (%d of 4 random ones mid-work in %.0f ms of work), then the same "
      "video\n",
      tally.kills, tally.mid_work, work);
}

TEST_F(TrainCli, BenchKilledLeavesNoPartialReport) {
  const fs::path report = local_.path() / "bench.json";
  const std::string args = "bench sim --world " + world() + " --robots 8 --repeats 5000 --json " + report.string();
  // What bench sim prints on stderr once its timing has begun.
  const std::string timing = "scout bench sim: timing ";
  // The figures that do not depend on time: the batch and what its moves did (the seeded
  // recorded batch), and the manifest but its date. The medians and peak memory differ run to run.
  // (and each camera back end's camera-alone figures, which the report keys by back end).
  const std::vector<std::string> times = {"/median_ms",
                                          "/agent_steps_per_s",
                                          "/patches_per_s",
                                          "/peak_resident_bytes",
                                          "/manifest/created_utc",
                                          "/camera_backends/osmesa/median_ms",
                                          "/camera_backends/osmesa/patches_per_s",
                                          "/camera_backends/egl/median_ms",
                                          "/camera_backends/egl/patches_per_s"};
  const double work = work_ms(local_.path(), args, timing);
  const json reference = json_without(report, times);
  ASSERT_EQ(reference["robots"], 8);
  ASSERT_TRUE(reference.contains("ticks_per_move"));

  auto whole = [&](const Kill& kill) {
    // The previous report or this one, whole (it parses, with the same figures).
    if (fs::exists(report)) {
      EXPECT_EQ(json_without(report, times), reference) << kill.describe();
    }
  };
  const Tally tally =
      kill_on_schedule(local_.path(), args, schedule({"file-write:1"}, 4, 0.05 * work, 0.9 * work, 9), timing, whole);
  EXPECT_EQ(tally.kills, 1 + tally.mid_work);  // the named point was reached
  EXPECT_GE(tally.mid_work, 3) << "of 4 random kills, only " << tally.mid_work << " landed mid-work";
  ASSERT_FALSE(attempt(local_.path(), args, kNoKill).killed);
  EXPECT_EQ(json_without(report, times), reference);
  EXPECT_EQ(leftovers_beside(report), std::vector<std::string>{});
  std::printf(
      "[ measured ] scout bench sim: %d SIGKILLs (%d of 4 random ones mid-work in %.0f ms of work), then a whole "
      "report\n",
      tally.kills, tally.mid_work, work);
}

}  // namespace
