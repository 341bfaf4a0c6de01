#include "agent/config.hpp"

#include <stdexcept>
#include <string>

namespace scout::agent {
namespace {

// One message format for every field, so that a bad value reads the same wherever it comes from
// (a command line or a checkpoint's config).
void check_range(const char* field, int value, int lo, int hi) {
  if (value < lo || value > hi) {
    throw std::invalid_argument(std::string(field) + ": expected an integer in " + std::to_string(lo) + ".." +
                                std::to_string(hi) + ", got " + std::to_string(value));
  }
}

}  // namespace

const char* to_string(Precision precision) {
  return precision == Precision::BFloat16 ? "bf16" : "fp32";
}

Precision parse_precision(const std::string& text) {
  if (text == "fp32") return Precision::Float32;
  if (text == "bf16") return Precision::BFloat16;
  throw std::invalid_argument("precision: expected one of fp32, bf16, got \"" + text + "\"");
}

const char* to_string(ClassifierKind kind) {
  switch (kind) {
    case ClassifierKind::Paper:
      return "paper";
    case ClassifierKind::Strided:
      return "strided";
    case ClassifierKind::ResNet18:
      return "resnet18";
  }
  return "?";
}

ClassifierKind parse_classifier_kind(const std::string& text) {
  for (const ClassifierKind kind : {ClassifierKind::Paper, ClassifierKind::Strided, ClassifierKind::ResNet18}) {
    if (text == to_string(kind)) return kind;
  }
  throw std::invalid_argument("classifier: expected one of paper, strided, resnet18, got \"" + text + "\"");
}

void NetworkConfig::validate() const {
  check_range("image_channels", image_channels, 1, 4);
  check_range("classes", classes, 2, 1000);
  check_range("planner_width", planner_width, 1, kMaxWidth);
  check_range("planner_depth", planner_depth, 1, kMaxPlannerDepth);
  check_range("classifier_width", classifier_width, 1, kMaxWidth);
  check_range("classifier_depth", classifier_depth, 1, kMaxClassifierDepth);
  // The paper and strided classifiers double their width each block: bound the widest block,
  // so that a typo fails here and not as an out-of-memory an hour later.
  if (classifier != ClassifierKind::ResNet18) {
    const long widest = static_cast<long>(classifier_width) << (classifier_depth - 1);
    if (widest > kMaxClassifierBlockWidth)
      throw std::invalid_argument("classifier_width: expected classifier_width x 2^(classifier_depth - 1) <= " +
                                  std::to_string(kMaxClassifierBlockWidth) + ", got " + std::to_string(widest));
  }
  // An enum cast from an out-of-range integer would otherwise reach make_classifier.
  if (classifier != ClassifierKind::Paper && classifier != ClassifierKind::Strided &&
      classifier != ClassifierKind::ResNet18) {
    throw std::invalid_argument("classifier: expected one of paper, strided, resnet18, got " +
                                std::to_string(static_cast<int>(classifier)));
  }
}

}  // namespace scout::agent
