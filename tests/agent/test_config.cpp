// The agent's network configuration: names of the classifier kinds and range checks that name
// the field.
#include <gtest/gtest.h>

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
  for (const ClassifierKind kind : {ClassifierKind::Paper, ClassifierKind::Strided, ClassifierKind::ResNet18}) {
    EXPECT_EQ(parse_classifier_kind(to_string(kind)), kind);
  }
  EXPECT_STREQ(to_string(ClassifierKind::Paper), "paper");
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

}  // namespace scout::agent
