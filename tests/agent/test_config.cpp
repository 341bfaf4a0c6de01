// The agent's network configuration: names of the classifier kinds and range checks that name
// the field.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>

#include "agent/config.hpp"

namespace scout::agent {
namespace {

// The message of the std::invalid_argument that validate() throws ("" if it throws none).
std::string validation_error(const NetworkConfig& config) {
  try {
    config.validate();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(ClassifierKind, NamesRoundTrip) {
  for (const ClassifierVariant& variant : kClassifierVariants) {
    EXPECT_EQ(parse_classifier_kind(to_string(variant.kind)), variant.kind);
  }
  EXPECT_STREQ(to_string(ClassifierKind::Paper), "paper");
  EXPECT_STREQ(to_string(ClassifierKind::PaperStrided), "paper-strided");
  EXPECT_STREQ(to_string(ClassifierKind::PaperStridedNorm), "paper-strided-gn");
  EXPECT_STREQ(to_string(ClassifierKind::Strided), "strided");
  EXPECT_STREQ(to_string(ClassifierKind::ResNet18), "resnet18");
}

TEST(ClassifierKind, UnknownNameIsRefusedListingTheChoices) {
  try {
    parse_classifier_kind("foo");
    FAIL() << "\"foo\" was accepted";
  } catch (const std::invalid_argument& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("foo"), std::string::npos) << message;
    EXPECT_NE(message.find("paper"), std::string::npos) << message;
    EXPECT_NE(message.find("strided"), std::string::npos) << message;
    EXPECT_NE(message.find("resnet18"), std::string::npos) << message;
  }
  EXPECT_THROW(parse_classifier_kind("Paper"), std::invalid_argument);  // names are case-sensitive
  EXPECT_THROW(parse_classifier_kind(""), std::invalid_argument);
}

TEST(NetworkConfig, DefaultsArePlanner16x3AndPaperClassifier16x3) {
  const NetworkConfig config;
  EXPECT_EQ(config.image_channels, 1);
  EXPECT_EQ(config.classes, 10);
  EXPECT_EQ(config.planner_width, 16);
  EXPECT_EQ(config.planner_depth, 3);
  EXPECT_EQ(config.classifier, ClassifierKind::Paper);
  EXPECT_EQ(config.classifier_width, 16);
  EXPECT_EQ(config.classifier_depth, 3);
  EXPECT_NO_THROW(config.validate());
}

TEST(NetworkConfig, DescriptionsGiveTheDepthOnlyWhereTheClassifierHasOne) {
  NetworkConfig config;
  config.classifier_width = 24;
  config.classifier_depth = 5;
  EXPECT_EQ(describe_classifier(config), "paper 24x5");
  config.classifier = ClassifierKind::Strided;
  EXPECT_EQ(describe_classifier(config), "strided 24x5");
  config.classifier = ClassifierKind::ResNet18;  // four fixed stages: classifier_depth is ignored
  EXPECT_EQ(describe_classifier(config), "resnet18 width 24");
}

TEST(NetworkConfig, OutOfRangeValueNamesTheFieldAndTheRange) {
  NetworkConfig config;
  config.planner_width = 0;
  EXPECT_EQ(validation_error(config), "planner_width: expected an integer in 1..512, got 0");
}

TEST(NetworkConfig, EveryFieldIsCheckedAtBothEnds) {
  struct Case {
    const char* field;
    int NetworkConfig::*member;
    int lo, hi;
  };
  const Case cases[] = {
      {"image_channels", &NetworkConfig::image_channels, 1, 4},
      {"classes", &NetworkConfig::classes, 2, 1000},
      {"planner_width", &NetworkConfig::planner_width, 1, kMaxWidth},
      {"planner_depth", &NetworkConfig::planner_depth, 1, kMaxPlannerDepth},
      {"classifier_width", &NetworkConfig::classifier_width, 1, kMaxWidth},
      {"classifier_depth", &NetworkConfig::classifier_depth, 1, kMaxClassifierDepth},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.field);
    for (const int good : {c.lo, c.hi}) {
      NetworkConfig config;
      config.*c.member = good;
      EXPECT_EQ(validation_error(config), "");
    }
    for (const int bad : {c.lo - 1, c.hi + 1, -7}) {
      NetworkConfig config;
      config.*c.member = bad;
      const std::string expected = std::string(c.field) + ": expected an integer in " + std::to_string(c.lo) + ".." +
                                   std::to_string(c.hi) + ", got " + std::to_string(bad);
      EXPECT_EQ(validation_error(config), expected);
    }
  }
}

TEST(NetworkConfig, UnknownClassifierEnumValueIsRefused) {
  NetworkConfig config;
  config.classifier = static_cast<ClassifierKind>(17);
  EXPECT_NE(validation_error(config).find("classifier"), std::string::npos);
}

}  // namespace
TEST(NetworkConfig, TheWidestClassifierBlockIsBounded) {
  NetworkConfig config;
  config.classifier_width = kMaxWidth;
  config.classifier_depth = kMaxClassifierDepth;  // 512 x 2^7 channels in the last block
  EXPECT_EQ(validation_error(config), "classifier_width: expected classifier_width x 2^(classifier_depth - 1) <= " +
                                          std::to_string(kMaxClassifierBlockWidth) + ", got 65536");
  config.classifier = ClassifierKind::ResNet18;  // its stages are fixed: 8 x width at most
  EXPECT_EQ(validation_error(config), "");
}

namespace {

TEST(ClassifierKind, ChoicesListEveryRegisteredNameOnce) {
  std::set<std::string> names;
  for (const ClassifierVariant& variant : kClassifierVariants) {
    EXPECT_TRUE(names.insert(variant.name).second) << variant.name << " is registered twice";
    EXPECT_NE(classifier_choices().find(variant.name), std::string::npos) << classifier_choices();
  }
  EXPECT_EQ(classifier_choices(), "paper, paper-strided, paper-strided-gn, strided, resnet18");
  EXPECT_EQ(kClassifierVariants[0].kind, NetworkConfig{}.classifier) << "the first row is the default";
}

TEST(Precision, NamesRoundTrip) {
  for (const Precision p : {Precision::Float32, Precision::BFloat16, Precision::Auto})
    EXPECT_EQ(parse_precision(to_string(p)), p);
  EXPECT_THROW(parse_precision("fp16"), std::invalid_argument);
}

// The /proc/cpuinfo flags of the first processor (none where there is no such file).
std::set<std::string> cpuinfo_flags() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("flags", 0) != 0) continue;
    std::istringstream words(line.substr(line.find(':') + 1));
    std::set<std::string> flags;
    for (std::string word; words >> word;) flags.insert(word);
    return flags;
  }
  return {};
}

// Sets an environment variable for one scope, restoring what was there.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const char* value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    if (value)
      ::setenv(name, value, 1);
    else
      ::unsetenv(name);
  }
  ~ScopedEnv() {
    if (old_)
      ::setenv(name_, old_->c_str(), 1);
    else
      ::unsetenv(name_);
  }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  const char* name_;
  std::optional<std::string> old_;
};

TEST(Precision, NativeBf16AgreesWithProcCpuinfo) {
  const std::set<std::string> flags = cpuinfo_flags();
  if (flags.empty()) GTEST_SKIP() << "no flags in /proc/cpuinfo (not an x86 Linux machine)";
  // Without a oneDNN cap, what the CPU has is what this process may use.
  const ScopedEnv no_cap("ONEDNN_MAX_CPU_ISA", nullptr), no_old_cap("DNNL_MAX_CPU_ISA", nullptr);
  const NativeBf16 cpu = native_bf16();
  EXPECT_EQ(cpu.avx512_bf16, flags.count("avx512_bf16") == 1);
  EXPECT_EQ(cpu.amx_bf16, flags.count("amx_bf16") == 1);
  EXPECT_EQ(cpu.capped_by, "");
}

// A oneDNN cap below AVX512_CORE_BF16 (the stand-in for a CPU without native bf16) leaves no
// native bf16, whatever this CPU has, and the fp32 note names the cap; a cap at AVX512_CORE_BF16
// keeps AVX-512 BF16 but not AMX; ALL changes nothing. (That auto then picks fp32 without
// measuring: tests/learn/test_auto_precision.cpp.)
TEST(Precision, NoNativeBf16WhereOneDnnMayNotUseIt) {
  const NativeBf16 uncapped = [] {
    const ScopedEnv no_cap("ONEDNN_MAX_CPU_ISA", nullptr), no_old_cap("DNNL_MAX_CPU_ISA", nullptr);
    return native_bf16();
  }();
  for (const char* variable : {"ONEDNN_MAX_CPU_ISA", "DNNL_MAX_CPU_ISA"}) {
    const ScopedEnv no_cap("ONEDNN_MAX_CPU_ISA", nullptr), no_old_cap("DNNL_MAX_CPU_ISA", nullptr);
    for (const char* cap : {"AVX2", "avx2", "SSE41", "AVX512_CORE", "AVX512_CORE_VNNI"}) {
      const ScopedEnv capped(variable, cap);
      EXPECT_FALSE(native_bf16().any()) << variable << "=" << cap;
      const std::string note = fp32_without_native_bf16_note();
      EXPECT_EQ(note.rfind("precision: fp32 (", 0), 0u) << note;
      if (uncapped.any()) {
        EXPECT_NE(note.find(std::string(variable) + "=" + cap), std::string::npos) << note;
      }
    }
    const ScopedEnv bf16_cap(variable, "AVX512_CORE_BF16");
    EXPECT_EQ(native_bf16().avx512_bf16, uncapped.avx512_bf16);
    EXPECT_FALSE(native_bf16().amx_bf16);
    const ScopedEnv all(variable, "ALL");
    EXPECT_EQ(native_bf16().any(), uncapped.any());
    // oneDNN ignores a value it does not know, and so does auto.
    const ScopedEnv typo(variable, "AVX3");
    EXPECT_EQ(native_bf16().any(), uncapped.any());
    EXPECT_EQ(native_bf16().capped_by, "");
  }
}

}  // namespace

}  // namespace scout::agent
