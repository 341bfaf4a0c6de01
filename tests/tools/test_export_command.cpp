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
#include <iterator>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "agent/config.hpp"
#include "tests/support/train_cli_fixture.hpp"

namespace scout::testing::export_command_train_cli_tests {

using namespace scout::testing::train_cli_support;

// scout export: a model file (no optimizer state) that eval reads exactly as it reads the run.
TEST_F(TrainCli, ExportWritesASmallModelThatEvalReadsLikeTheRun) {
  const std::string model = path("model.pt");
  const Result r = run("export " + base() + " --out " + model);
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_NE(r.out.find(model), std::string::npos) << r.out;
  const auto run_size = fs::file_size(base() + "/checkpoint.pt"), model_size = fs::file_size(model);
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
  EXPECT_EQ(a["precision"], scout::agent::to_string(scout::agent::resolve_precision(scout::agent::Precision::Auto)));

  // Refusals: an existing file (unless --overwrite), a missing folder, something not a checkpoint.
  const std::string before = read_text(model);
  expect_one_line_error(run("export " + base() + " --out " + model), {"--out", model, "--overwrite"});
  EXPECT_EQ(read_text(model), before);
  EXPECT_EQ(run("export " + base() + " --out " + model + " --overwrite").status, 0);
  expect_one_line_error(run("export " + base() + " --out " + path("no/such/m.pt")), {"--out", "no/such"});
  std::ofstream(path("junk.pt")) << "not a checkpoint";
  expect_one_line_error(run("export " + path("junk.pt") + " --out " + path("m2.pt")), {path("junk.pt")});
  EXPECT_FALSE(fs::exists(path("m2.pt")));
}

}  // namespace scout::testing::export_command_train_cli_tests
