// `scout export` (tools/export_command.cpp): a model file without the optimizer state that eval
// reads exactly as it reads the run; refusals.

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
#include <functional>
#include <iterator>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "agent/config.hpp"
#include "learn/auto_precision.hpp"
#include "tests/support/train_cli_fixture.hpp"

namespace scout::testing::export_command_train_cli_tests {

using namespace scout::testing::train_cli_support;

// scout export: a model file (no optimizer state) that eval reads exactly as it reads the run.
TEST_F(TrainCli, ExportWritesASmallModelThatEvalReadsLikeTheRun) {
  const std::string model = path("model.safetensors");
  const Result r = run("export " + base() + " --out " + model);
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_NE(r.out.find(model), std::string::npos) << r.out;
  const auto run_size = fs::file_size(base() + "/checkpoint.safetensors"), model_size = fs::file_size(model);
  EXPECT_LT(model_size, run_size);  // Adam's two moments per weight are gone
  // The same figures from the model as from the run (same weights, history and config).
  const std::string data = (temp_->path() / "data").string();
  const std::string inputs =
      " --images " + data + "/train-images-idx3-ubyte --labels " + data + "/train-labels-idx1-ubyte --runs 2";
  ASSERT_EQ(run("eval --checkpoint " + base() + inputs + " --json " + path("a.json")).status, 0);
  ASSERT_EQ(run("eval --checkpoint " + model + inputs + " --json " + path("b.json")).status, 0);
  json a = json::parse(read_text(path("a.json"))), b = json::parse(read_text(path("b.json")));
  for (const char* key : {"accuracy", "top2", "confusion", "baselines", "full_image_accuracy", "precision"})
    EXPECT_EQ(a[key], b[key]) << key;
  EXPECT_EQ(a["precision"], scout::agent::to_string(scout::learn::resolve_precision(scout::agent::Precision::Auto)));

  // Refusals: an existing file (unless --overwrite), a missing folder, something not a checkpoint.
  const std::string before = read_text(model);
  expect_one_line_error(run("export " + base() + " --out " + model), {"--out", model, "--overwrite"});
  EXPECT_EQ(read_text(model), before);
  EXPECT_EQ(run("export " + base() + " --out " + model + " --overwrite").status, 0);
  expect_one_line_error(run("export " + base() + " --out " + path("no/such/m.safetensors")), {"--out", "no/such"});
  std::ofstream(path("junk.safetensors")) << "not a checkpoint";
  expect_one_line_error(run("export " + path("junk.safetensors") + " --out " + path("m2.safetensors")),
                        {path("junk.safetensors")});
  EXPECT_FALSE(fs::exists(path("m2.safetensors")));
}

// A durable write, seen from the kernel's side (strace -f -y): the temporary file's data is synced
// before it is renamed over the model, and the folder is synced after the rename, so that a power
// cut leaves the old file or the whole new one (core/files.hpp). strace is one of the packages
// scripts/setup.sh installs; where the kernel forbids tracing, the test says so and skips.
TEST_F(TrainCli, ExportSyncsTheFileRenamesItThenSyncsTheFolder) {
  const std::string model = path("model.safetensors"), trace = path("trace.txt");
  const scout::testing::CliResult traced =
      scout::testing::run_cli("strace", "-f -y -qq -e trace=fsync,fdatasync,rename,renameat,renameat2 -o " + trace +
                                            " " + SCOUT_BINARY + " export " + base() + " --out " + model);
  if (traced.status != 0 && traced.output.find("ptrace") != std::string::npos)
    GTEST_SKIP() << "strace cannot trace here: " << traced.output;
  ASSERT_EQ(traced.status, 0) << traced.output;
  // The lines that name the model: "fsync(5</tmp/.../.model.safetensors.tmp-...>) = 0",
  // "rename(\"/tmp/.../.model.safetensors.tmp-...\", \"/tmp/.../model.safetensors\") = 0", "fsync(6</tmp/...>) = 0".
  std::vector<std::string> calls;
  std::istringstream lines(read_text(trace));
  for (std::string line; std::getline(lines, line);) {
    const std::size_t call = line.find_first_not_of(' ', line.find(' '));  // after "PID  "
    if (call != std::string::npos) calls.push_back(line.substr(call));
  }
  const auto index_of = [&](const std::function<bool(const std::string&)>& matches) {
    for (std::size_t i = 0; i < calls.size(); ++i)
      if (matches(calls[i])) return static_cast<long>(i);
    return -1L;
  };
  const std::string name = fs::path(model).filename().string(), folder = fs::path(model).parent_path().string();
  const long renamed = index_of([&](const std::string& c) {
    return c.rfind("rename", 0) == 0 && c.find("/." + name + ".tmp-") != std::string::npos &&
           c.find(", \"" + model + "\"") != std::string::npos && c.find(") = 0") != std::string::npos;
  });
  ASSERT_GE(renamed, 0) << "no rename of a temporary over " << model << " in:\n" << read_text(trace);
  // The temporary's name as renamed, then its sync before the rename.
  const std::string& rename_call = calls[renamed];
  const std::size_t from = rename_call.find('"') + 1;
  const std::string temporary = rename_call.substr(from, rename_call.find('"', from) - from);
  const long file_synced = index_of([&](const std::string& c) {
    return (c.rfind("fsync(", 0) == 0 || c.rfind("fdatasync(", 0) == 0) &&
           c.find("<" + temporary + ">") != std::string::npos;
  });
  EXPECT_GE(file_synced, 0) << temporary << " was never synced:\n" << read_text(trace);
  EXPECT_LT(file_synced, renamed) << "synced after the rename:\n" << read_text(trace);
  long folder_synced = -1;
  for (long i = renamed + 1; i < static_cast<long>(calls.size()) && folder_synced < 0; ++i)
    if (calls[i].rfind("fsync(", 0) == 0 && calls[i].find("<" + folder + ">") != std::string::npos) folder_synced = i;
  EXPECT_GT(folder_synced, renamed) << "the folder " << folder << " was not synced after the rename:\n"
                                    << read_text(trace);
  EXPECT_TRUE(fs::is_regular_file(model));
}

}  // namespace scout::testing::export_command_train_cli_tests
