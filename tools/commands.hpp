#pragma once
// The subcommands of `scout`. Each adds itself to the CLI and runs when chosen; errors are
// thrown (InputError for what the user can fix) and reported once by main().
#include <cstdint>
#include <string>

#include <CLI/Validators.hpp>
#include <vector>

namespace CLI { class App; }

namespace scout::tools {

/// Process-wide context the commands share.
struct Context {
  std::vector<std::string> argv;   ///< the command line, for manifests
};

/// Thrown between units of work after SIGINT or SIGTERM, so that output folders are cleaned up
/// by unwinding; main() exits with status 130.
struct Interrupted {};
/// Installs the SIGINT / SIGTERM handler (once, from main).
void install_interrupt_handler();
/// Throws Interrupted if a signal has arrived.
void throw_if_interrupted();

/// A --seed value: a decimal integer in [0, 2^64 - 1], nothing else (no sign, no wrap-around).
std::uint64_t parse_seed(const std::string& text);
/// CLI11 check for --seed, so that a bad seed is a usage error (exit 2).
CLI::Validator seed_validator();

void add_run_command(CLI::App& app, const Context& context);
void add_data_command(CLI::App& app, const Context& context);
void add_bench_command(CLI::App& app, const Context& context);

}  // namespace scout::tools
