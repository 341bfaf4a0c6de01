#include "tools/network_options.hpp"

#include <fmt/format.h>

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

namespace {

// --precision's check: one of the names, and bf16 only where it can run at all.
CLI::Validator precision_validator() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        agent::Precision precision;
        try {
          precision = agent::parse_precision(text);
        } catch (const std::invalid_argument&) {
          return "expected one of " + precision_choices() + ", got '" + one_line(text) + "'";
        }
        if (precision == agent::Precision::BFloat16) {
          const std::string why = agent::bf16_unavailable();
          if (!why.empty()) return "bf16: " + why;
        }
        return {};
      },
      "PRECISION");
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

agent::Precision NetworkOptions::arithmetic() const {
  return agent::resolve_precision(agent::parse_precision(precision));  // checked by the option
}

void NetworkOptions::announce_precision() const { announce_auto_precision(precision); }

void announce_auto_precision(const std::string& requested) {
  // Training has no model yet: what it trains in is what it runs in.
  announce_model_precision(requested, agent::resolve_precision(agent::parse_precision(requested)));
}

void add_model_precision_option(CLI::App& cmd, std::string& precision) {
  precision = "auto";
  cmd.add_option("--precision", precision,
                 "Networks' arithmetic: auto (bf16 where this CPU has native bf16, else fp32, whatever the model was "
                 "trained in) | bf16 | fp32")
      ->capture_default_str()
      ->check(precision_validator());
}

void announce_model_precision(const std::string& requested, agent::Precision trained) {
  const agent::Precision asked = agent::parse_precision(requested);  // checked by the option
  const agent::Precision used = agent::resolve_precision(asked);
  if (asked == agent::Precision::Auto) {
    std::string line = agent::auto_precision_note();
    if (used != trained) line += fmt::format("; the model was trained in {}", agent::to_string(trained));
    std::fprintf(stderr, "%s\n", line.c_str());
  } else if (used == agent::Precision::BFloat16 && !agent::native_bf16().any()) {
    std::fprintf(stderr,
                 "precision: bf16 as asked, emulated: this CPU has no native bf16, so the networks run several "
                 "times slower than in fp32 (--precision auto picks fp32 here)\n");
  }
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
      ->check(precision_validator());
}

}  // namespace scout::tools
