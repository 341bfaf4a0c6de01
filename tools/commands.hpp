#pragma once
// The subcommands of `scout`. Each adds itself to the CLI and runs when chosen; errors are
// thrown (InputError for what the user can fix) and reported once by main().
#include <memory>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/stop.hpp"
#include "learn/rollout.hpp"
#include "tools/parsing.hpp"

namespace CLI {
class App;
}

namespace scout::tools {

/// Process-wide context the commands share.
struct Context {
  std::vector<std::string> argv;  ///< the command line, for manifests
};

/// Thrown by a command that ran other processes (the --nproc launcher): main() exits with their
/// status and prints nothing more (they printed their own errors).
struct ExitStatus {
  int code = 0;
};

/// Installs the SIGINT / SIGTERM handler (main does, before any command runs): commands poll
/// interrupt_token() between units of work; a command that never polls runs to its end.
void install_interrupt_handler();
/// The stop token of the process: requested once SIGINT or SIGTERM has arrived. Work that sees it
/// throws core::Stopped (output folders are cleaned up by unwinding); main() exits with 130.
const core::StopToken& interrupt_token();

/// The rollout engine for a world, with a camera failure (no OSMesa context: an environment
/// problem, not a bug) reported as an error of exit status 1.
std::unique_ptr<learn::RolloutEngine> make_engine(const worlds::World& world, const grid::FloorFrame& frame,
                                                  int robots);

void add_run_command(CLI::App& app, const Context& context);
void add_data_command(CLI::App& app, const Context& context);
void add_bench_command(CLI::App& app, const Context& context);
void add_train_command(CLI::App& app, const Context& context);
void add_eval_command(CLI::App& app, const Context& context);
void add_export_command(CLI::App& app, const Context& context);
void add_convert_command(CLI::App& app, const Context& context);
void add_report_command(CLI::App& app, const Context& context);

}  // namespace scout::tools
