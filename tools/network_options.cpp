#include "tools/network_options.hpp"

#include <CLI/CLI.hpp>
#include <cstdio>

#include "learn/train_config.hpp"
#include "tools/parsing.hpp"

namespace scout::tools {

namespace {

// "Classifier: paper: METHOD.md's dense blocks at full resolution | strided: ... | resnet18: ...".
std::string classifier_help() {
  std::string help = "Classifier: ";
  for (const agent::ClassifierVariant& variant : agent::kClassifierVariants) {
    if (&variant != &agent::kClassifierVariants[0]) help += " | ";
    help += std::string(variant.name) + ": " + variant.help;
  }
  return help;
}

}  // namespace

std::string NetworkOptions::default_precision() { return agent::to_string(learn::TrainConfig{}.precision); }

std::string precision_choices() { return "auto, bf16, fp32"; }

agent::NetworkConfig NetworkOptions::network() const {
  agent::NetworkConfig n;
  n.planner_width = planner_width;
  n.planner_depth = planner_depth;
  n.classifier = agent::parse_classifier_kind(classifier);  // checked by the option
  n.classifier_width = classifier_width;
  n.classifier_depth = classifier_depth;
  return n;
}

agent::Precision NetworkOptions::arithmetic() const {
  return agent::resolve_precision(agent::parse_precision(precision));  // checked by the option
}

void NetworkOptions::announce_precision() const { announce_auto_precision(precision); }

void announce_auto_precision(const std::string& requested) {
  if (agent::parse_precision(requested) == agent::Precision::Auto)
    std::fprintf(stderr, "%s\n", agent::auto_precision_note().c_str());
}

void add_network_options(CLI::App& cmd, NetworkOptions& o) {
  cmd.add_option("--planner-width", o.planner_width, "Channels each planner block adds (d)")
      ->capture_default_str()
      ->check(decimal_in(1, agent::kMaxWidth));
  cmd.add_option("--planner-depth", o.planner_depth, "Planner blocks (r)")
      ->capture_default_str()
      ->check(decimal_in(1, agent::kMaxPlannerDepth));
  cmd.add_option("--classifier", o.classifier, classifier_help())
      ->capture_default_str()
      ->check(one_of(agent::parse_classifier_kind, agent::classifier_choices(), "KIND"));
  cmd.add_option("--classifier-width", o.classifier_width, "Classifier's first block width (doubles each block)")
      ->capture_default_str()
      ->check(decimal_in(1, agent::kMaxWidth));
  cmd.add_option("--classifier-depth", o.classifier_depth, "Classifier blocks")
      ->capture_default_str()
      ->check(decimal_in(1, agent::kMaxClassifierDepth));
  cmd.add_option("--precision", o.precision,
                 "Networks' arithmetic: auto (bf16 where this CPU has native bf16, else fp32) | bf16 (bfloat16 "
                 "convolutions, fp32 weights and optimizer) | fp32")
      ->capture_default_str()
      ->check(one_of(agent::parse_precision, precision_choices(), "PRECISION"));
}

}  // namespace scout::tools
