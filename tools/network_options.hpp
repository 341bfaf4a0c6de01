#pragma once
// The networks' options that `scout train` and `scout bench train` share: widths, depths, the
// classifier variant and the arithmetic, with one set of checks and defaults.
#include <string>

#include "agent/config.hpp"

namespace CLI {
class App;
}

namespace scout::tools {

struct NetworkOptions {
  int planner_width = 16, planner_depth = 3;
  std::string classifier = "paper";
  int classifier_width = 16, classifier_depth = 3;
  std::string precision = "bf16";

  /// The options' values as a config (classes and channels keep their defaults).
  agent::NetworkConfig network() const;
  agent::Precision arithmetic() const;
};

/// Adds --planner-width/-depth, --classifier, --classifier-width/-depth and --precision.
void add_network_options(CLI::App& cmd, NetworkOptions& o);

}  // namespace scout::tools
