#pragma once
// The subcommands of `scout`. Each adds itself to the CLI and runs when chosen; errors are
// thrown (InputError for what the user can fix) and reported once by main().
#include <CLI/Error.hpp>
#include <CLI/Validators.hpp>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "learn/rollout.hpp"
#include "core/error.hpp"
#include "core/stop.hpp"

namespace CLI {
class App;
}

namespace scout::tools {

/// Process-wide context the commands share.
struct Context {
  std::vector<std::string> argv;  ///< the command line, for manifests
};

/// Installs the SIGINT / SIGTERM handler, for commands that poll interrupt_token() between units
/// of work; other commands keep the default (the process ends at once).
void install_interrupt_handler();
/// The stop token of the process: requested once SIGINT or SIGTERM has arrived. Work that sees it
/// throws core::Stopped (output folders are cleaned up by unwinding); main() exits with 130.
const core::StopToken& interrupt_token();

/// A --seed value: a decimal integer in [0, 2^64 - 1], nothing else (no sign, no wrap-around).
std::uint64_t parse_seed(const std::string& text);
/// CLI11 check for --seed, so that a bad seed is a usage error (exit 2).
CLI::Validator seed_validator();
/// CLI11 check for an integer option: plain decimal digits (CLI11 itself would read 010 as
/// octal and 0x2 as hexadecimal) in [lo, hi].
CLI::Validator decimal_in(long long lo, long long hi);
/// CLI11 check from a parser that throws InputError, so that a malformed value is a usage error
/// (exit 2) with the parser's message.
template <typename Parse>
CLI::Validator parsed_by(Parse parse, const std::string& name) {
  return CLI::Validator(
      [parse](std::string& text) -> std::string {
        try {
          parse(text);
          return {};
        } catch (const InputError& e) {
          return e.what();
        }
      },
      name);
}

/// The rollout engine for a world, with a camera failure (no OSMesa context: an environment
/// problem, not a bug) reported as an error of exit status 1.
std::unique_ptr<learn::RolloutEngine> make_engine(const worlds::World& world, const grid::FloorFrame& frame, int robots);

void add_run_command(CLI::App& app, const Context& context);
void add_data_command(CLI::App& app, const Context& context);
void add_bench_command(CLI::App& app, const Context& context);
void add_train_command(CLI::App& app, const Context& context);
void add_eval_command(CLI::App& app, const Context& context);
void add_export_command(CLI::App& app, const Context& context);

}  // namespace scout::tools
