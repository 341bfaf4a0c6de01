// scout eval (tools/eval_command.cpp): the pinned report. A fixed model (the 8,000-digit model of
// December 2026, kept in tests/data so that retraining the shipped model does not move the pin),
// 64 fixed test digits, seed 5, three runs, fp32: the report and the per-image probabilities
// must be exactly those this file pins (tests/tools/golden/, written by the build before the
// "house" refactor). A change that is meant to change them updates the golden files in the same
// commit and says why.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/support/cli.hpp"
#include "tests/support/temp_dir.hpp"

namespace scout::testing {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

std::string read_text(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(EvalCommand, ThePinnedReportIsReproducedExactly) {
  TempDir temp("eval-pin");
  const fs::path source = SCOUT_SOURCE_DIR;
  const fs::path subset = source / "tests/data/mnist-subset";
  const fs::path report = temp.path() / "report.json";
  const fs::path predictions = temp.path() / "predictions.csv";
  const CliResult r = run_cli(SCOUT_BINARY, "eval --checkpoint " + (source / "tests/data/mnist-8k-v1.pt").string() +
                                                " --images " + (subset / "t10k-images-idx3-ubyte").string() +
                                                " --labels " + (subset / "t10k-labels-idx1-ubyte").string() +
                                                " --runs 3 --seed 5 --precision fp32 --json " + report.string() +
                                                " --predictions " + predictions.string());
  ASSERT_EQ(r.status, 0) << r.output;
  json got = json::parse(read_text(report));
  // What depends on the machine, the clock or the paths is not pinned.
  for (const char* volatile_key : {"seconds", "manifest", "checkpoint"}) got.erase(volatile_key);
  const json want = json::parse(read_text(source / "tests/tools/golden/eval-fp32.json"));
  EXPECT_EQ(got, want) << "got " << got.dump(1);
  EXPECT_EQ(read_text(predictions), read_text(source / "tests/tools/golden/eval-fp32-predictions.csv"));
}

}  // namespace
}  // namespace scout::testing
