// --precision auto (learn/auto_precision.hpp): bf16 only where it is native and measured faster,
// the measurement cached per CPU and LibTorch and shared by concurrent processes, the probe
// invisible to a seeded run, and one line saying which and why. These hold on every CPU: the
// choice itself is this machine's, so the tests check how it is made, not what it is.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "agent/config.hpp"
#include "learn/auto_precision.hpp"
#include "learn/internal/auto_precision.hpp"
#include "tests/support/temp_dir.hpp"

namespace scout::learn {
namespace {

nlohmann::json read_json(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return nlohmann::json::parse(text.str());
}

std::string cache_with(const std::string& key, double fp32_ms, double bf16_ms) {
  nlohmann::json cache;
  cache["choices"][key] = {{"fp32_ms", fp32_ms}, {"bf16_ms", bf16_ms}};
  return cache.dump();
}

TEST(AutoPrecision, ResolvesToAStoredPrecisionAndSaysWhichInOneLine) {
  EXPECT_EQ(resolve_precision(agent::Precision::Float32), agent::Precision::Float32);
  EXPECT_EQ(resolve_precision(agent::Precision::BFloat16), agent::Precision::BFloat16);
  const PrecisionChoice choice = auto_precision();
  ASSERT_NE(choice.precision, agent::Precision::Auto);
  EXPECT_EQ(resolve_precision(agent::Precision::Auto), choice.precision);
  EXPECT_EQ(choice.note.rfind(std::string("precision: ") + agent::to_string(choice.precision) + " (", 0), 0u)
      << choice.note;
  EXPECT_EQ(choice.note.find('\n'), std::string::npos) << choice.note;
  if (!agent::native_bf16().any()) {
    EXPECT_EQ(choice.precision, agent::Precision::Float32) << "never emulated bf16";
  } else {
    EXPECT_NE(choice.note.find(" ms in bf16, "), std::string::npos) << "a measured choice quotes its figures";
  }
}

// A oneDNN cap below AVX512_CORE_BF16 (CI's stand-in for a CPU without native bf16): fp32, and
// nothing measured or written.
TEST(AutoPrecision, WithoutNativeBf16ItIsFp32AndNothingIsMeasured) {
  const testing::TempDir cache("scout_auto_precision");
  ASSERT_EQ(::setenv("SCOUT_CACHE_DIR", cache.path().c_str(), 1), 0);
  ASSERT_EQ(::setenv("ONEDNN_MAX_CPU_ISA", "AVX2", 1), 0);
  const PrecisionChoice choice = auto_precision();
  const std::string fp32_note = agent::fp32_without_native_bf16_note();
  ::unsetenv("ONEDNN_MAX_CPU_ISA");
  ::unsetenv("SCOUT_CACHE_DIR");
  EXPECT_EQ(choice.precision, agent::Precision::Float32);
  EXPECT_EQ(choice.note, fp32_note);
  EXPECT_FALSE(std::filesystem::exists(cache.path() / "precision.json"));
}

TEST(AutoPrecision, Bf16OnlyWhereItsStepTakesAtMostNinetyPercentOfFp32s) {
  EXPECT_EQ(choose_precision({.fp32_ms = 100, .bf16_ms = 40}), agent::Precision::BFloat16);
  EXPECT_EQ(choose_precision({.fp32_ms = 100, .bf16_ms = 90}), agent::Precision::BFloat16);
  EXPECT_EQ(choose_precision({.fp32_ms = 100, .bf16_ms = 91}), agent::Precision::Float32);
  EXPECT_EQ(choose_precision({.fp32_ms = 100, .bf16_ms = 127}), agent::Precision::Float32);
}

// A cached entry is the answer, without measuring: a cache saying bf16 is 2.5x faster gives bf16
// and one saying it is 27 % slower gives fp32, whatever this CPU would measure.
TEST(AutoPrecision, ACachedMeasurementIsUsedAsItIs) {
  const testing::TempDir dir("scout_auto_precision");
  const std::string key = precision_cache_key();
  const auto file = dir.write("precision.json", cache_with(key, 100, 40));
  PrecisionChoice choice = cached_or_measured_precision(file, key);
  EXPECT_EQ(choice.precision, agent::Precision::BFloat16);
  EXPECT_NE(choice.note.find("40 ms in bf16, 100 ms in fp32"), std::string::npos) << choice.note;
  EXPECT_NE(choice.note.find("cached in " + file.string()), std::string::npos) << choice.note;

  dir.write("precision.json", cache_with(key, 100, 127));
  choice = cached_or_measured_precision(file, key);
  EXPECT_EQ(choice.precision, agent::Precision::Float32);
  EXPECT_NE(choice.note.find("not 10 % faster"), std::string::npos) << choice.note;
}

// What the key holds: the CPU's model, LibTorch's version, and a cap in force.
TEST(AutoPrecision, TheKeyNamesTheCpuTheLibraryAndTheCaps) {
  const std::string plain = precision_cache_key();
  EXPECT_NE(plain.find("LibTorch "), std::string::npos) << plain;
  ASSERT_EQ(::setenv("ONEDNN_MAX_CPU_ISA", "AVX512_CORE_BF16", 1), 0);
  const std::string capped = precision_cache_key();
  ::unsetenv("ONEDNN_MAX_CPU_ISA");
  EXPECT_NE(capped, plain);
  EXPECT_NE(capped.find("ONEDNN_MAX_CPU_ISA=AVX512_CORE_BF16"), std::string::npos) << capped;
}

// A damaged or foreign cache, or one without this key, is measured and rewritten: the other keys stay.
// Two processes started together on an empty cache measure once between them and agree.
TEST(AutoPrecision, AMissingEntryIsMeasuredOnceAndWrittenForTheNextProcess) {
  if (!agent::native_bf16().any())
    GTEST_SKIP() << "the probe runs only where bf16 is native: " << agent::fp32_without_native_bf16_note();
  const testing::TempDir dir("scout_auto_precision");
  const std::string key = precision_cache_key();
  const auto file = dir.write("precision.json", "{\"choices\": {\"another CPU | LibTorch 0\": {\"fp32_ms\": 1, ");
  const PrecisionChoice first = cached_or_measured_precision(file, key);  // damaged: measured
  nlohmann::json cache = read_json(file);
  ASSERT_TRUE(cache["choices"].contains(key)) << cache.dump();
  EXPECT_GT(cache["choices"][key]["fp32_ms"].get<double>(), 0);
  EXPECT_GT(cache["choices"][key]["bf16_ms"].get<double>(), 0);
  EXPECT_EQ(cache["choices"][key]["precision"], agent::to_string(first.precision));

  // Another program's file of that name: measured again and made Scout's.
  dir.write("precision.json", "{\"choices\": 5}");
  EXPECT_EQ(cached_or_measured_precision(file, key).note.find("not cached"), std::string::npos);
  EXPECT_TRUE(read_json(file)["choices"].contains(key));

  // Another key is kept when this one is added, and a second process started at the same time
  // (this test program again, not a fork: LibTorch's OpenMP runtime does not survive a fork after
  // it has run) waits for this one's measurement and agrees with it.
  std::filesystem::remove(file);
  dir.write("precision.json", cache_with("another CPU | LibTorch 0", 1, 2));
  // Without gtest's sharding variables: under a sharded run the child's one test would fall in
  // another shard and not run.
  const std::string command =
      "env -u GTEST_SHARD_INDEX -u GTEST_TOTAL_SHARDS -u GTEST_SHARD_STATUS_FILE -u "
      "GTEST_OUTPUT SCOUT_AUTO_PRECISION_CHILD='" +
      file.string() + "' '" + std::filesystem::read_symlink("/proc/self/exe").string() +
      "' --gtest_filter=AutoPrecision.ChildOfTheConcurrencyTest 2>&1";
  FILE* child = ::popen(command.c_str(), "r");
  ASSERT_NE(child, nullptr);
  const PrecisionChoice in_parent = cached_or_measured_precision(file, key);
  std::string output;
  char buffer[4096];
  while (std::fgets(buffer, sizeof buffer, child) != nullptr) output += buffer;
  ASSERT_EQ(::pclose(child), 0) << output;
  EXPECT_NE(output.find(std::string("child's choice: ") + agent::to_string(in_parent.precision) + "\n"),
            std::string::npos)
      << "the two processes disagree: " << output;
  cache = read_json(file);
  EXPECT_TRUE(cache["choices"].contains("another CPU | LibTorch 0")) << cache.dump();
  EXPECT_TRUE(cache["choices"].contains(key)) << cache.dump();
}

// The second process of the test above (skipped when run on its own).
TEST(AutoPrecision, ChildOfTheConcurrencyTest) {
  const char* file = std::getenv("SCOUT_AUTO_PRECISION_CHILD");
  if (file == nullptr) GTEST_SKIP() << "started by AMissingEntryIsMeasuredOnceAndWrittenForTheNextProcess";
  const PrecisionChoice choice = cached_or_measured_precision(file, precision_cache_key());
  std::printf("child's choice: %s\n", agent::to_string(choice.precision));
}

// The probe builds and runs networks: a seeded run draws the same numbers with or without it, and
// keeps its thread count.
TEST(AutoPrecision, TheProbeLeavesTheGeneratorAndTheThreadCountAlone) {
  if (!agent::native_bf16().any())
    GTEST_SKIP() << "the probe runs only where bf16 is native: " << agent::fp32_without_native_bf16_note();
  torch::manual_seed(11);
  const torch::Tensor expected = torch::rand({8});
  torch::manual_seed(11);
  const int threads = torch::get_num_threads();
  const PrecisionMeasurement m = measure_precisions();
  EXPECT_GT(m.fp32_ms, 0);
  EXPECT_GT(m.bf16_ms, 0);
  EXPECT_TRUE(torch::equal(torch::rand({8}), expected));
  EXPECT_EQ(torch::get_num_threads(), threads);
}

}  // namespace
}  // namespace scout::learn
