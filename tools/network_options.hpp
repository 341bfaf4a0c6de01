#pragma once
// The networks' options that `scout train` and `scout bench train` share: widths, depths, the
// classifier variant and the arithmetic, with one set of checks (their defaults are those of a
// default-constructed agent::NetworkConfig and learn::TrainConfig); and --precision for the
// commands that run a trained model (run, eval, report), with what each says about it.
#include <string>

#include "agent/config.hpp"

namespace CLI {
class App;
}

namespace scout::tools {

/// The library's defaults, read once (learn::TrainConfig holds a world, so it is not constexpr).
inline constexpr agent::NetworkConfig kDefaultNetwork{};

struct NetworkOptions {
  int planner_width = kDefaultNetwork.planner_width;
  int planner_depth = kDefaultNetwork.planner_depth;
  std::string classifier = agent::to_string(kDefaultNetwork.classifier);
  int classifier_width = kDefaultNetwork.classifier_width;
  int classifier_depth = kDefaultNetwork.classifier_depth;
  std::string precision = default_precision();

  /// The options' values as a config (classes and channels keep their defaults).
  agent::NetworkConfig network() const;
  /// The requested arithmetic, `auto` resolved for this CPU.
  agent::Precision arithmetic() const;
  /// With `auto`: prints what it chose and why, in one line on stderr; with bf16 where it is
  /// emulated, a warning. Called once the command's checks have passed, so that a refusal stays
  /// one line.
  void announce_precision() const;
  /// learn::TrainConfig's default precision, as --precision spells it.
  static std::string default_precision();
};

/// Adds --planner-width/-depth, --classifier, --classifier-width/-depth and --precision.
void add_network_options(CLI::App& cmd, NetworkOptions& o);

/// Prints agent::auto_precision_note() on stderr when `requested` is "auto", and a warning when bf16
/// is asked for on a CPU that would emulate it.
void announce_auto_precision(const std::string& requested);

/// --precision's choices, "auto, bf16, fp32" (its messages).
std::string precision_choices();

/// --precision for the commands that run a trained model (run, eval, report): default auto, this
/// CPU's best arithmetic, whatever the model was trained in.
void add_model_precision_option(CLI::App& cmd, std::string& precision);

/// One line on stderr saying what a model runs in here: with `auto`, what it chose and why (and
/// that the model was trained in the other one when it differs); with bf16 asked on a CPU without
/// native bf16, that it is emulated and several times slower than fp32. Nothing otherwise.
void announce_model_precision(const std::string& requested, agent::Precision trained);

}  // namespace scout::tools
