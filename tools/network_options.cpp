#include "tools/network_options.hpp"

#include <CLI/CLI.hpp>
#include <stdexcept>

#include "tools/commands.hpp"
#include "core/error.hpp"

namespace scout::tools {

namespace {

// A CLI11 check that `parse` accepts the text (a usage error, exit 2, otherwise).
template <typename Parse>
CLI::Validator accepted_by(Parse parse, const char* choices, const char* name) {
  return CLI::Validator(
      [parse, choices](std::string& text) -> std::string {
        try {
          parse(text);
          return {};
        } catch (const std::invalid_argument&) {
          return std::string("expected one of ") + choices + ", got '" + one_line(text) + "'";
        }
      },
      name);
}

}  // namespace

agent::NetworkConfig NetworkOptions::network() const {
  agent::NetworkConfig n;
  n.planner_width = planner_width;
  n.planner_depth = planner_depth;
  n.classifier = agent::parse_classifier_kind(classifier);  // checked by the option
  n.classifier_width = classifier_width;
  n.classifier_depth = classifier_depth;
  return n;
}

agent::Precision NetworkOptions::arithmetic() const { return agent::parse_precision(precision); }

void add_network_options(CLI::App& cmd, NetworkOptions& o) {
  cmd.add_option("--planner-width", o.planner_width, "Channels each planner block adds (d)")
      ->capture_default_str()
      ->check(decimal_in(1, agent::kMaxWidth));
  cmd.add_option("--planner-depth", o.planner_depth, "Planner blocks (r)")
      ->capture_default_str()
      ->check(decimal_in(1, agent::kMaxPlannerDepth));
  cmd.add_option("--classifier", o.classifier, "Classifier: paper | strided | resnet18")
      ->capture_default_str()
      ->check(accepted_by(agent::parse_classifier_kind, "paper, strided, resnet18", "KIND"));
  cmd.add_option("--classifier-width", o.classifier_width, "Classifier's first block width (doubles each block)")
      ->capture_default_str()
      ->check(decimal_in(1, agent::kMaxWidth));
  cmd.add_option("--classifier-depth", o.classifier_depth, "Classifier blocks")
      ->capture_default_str()
      ->check(decimal_in(1, agent::kMaxClassifierDepth));
  cmd.add_option("--precision", o.precision,
                 "Networks' arithmetic: bf16 (bfloat16 convolutions, fp32 weights and optimizer) | fp32")
      ->capture_default_str()
      ->check(accepted_by(agent::parse_precision, "bf16, fp32", "PRECISION"));
}

}  // namespace scout::tools
