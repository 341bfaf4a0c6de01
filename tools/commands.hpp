#pragma once
// The subcommands of `scout`. Each adds itself to the CLI and runs when chosen; errors are
// thrown (InputError for what the user can fix) and reported once by main().
#include <string>
#include <vector>

namespace CLI { class App; }

namespace scout::tools {

/// Process-wide context the commands share.
struct Context {
  std::vector<std::string> argv;   ///< the command line, for manifests
};

void add_run_command(CLI::App& app, const Context& context);
void add_data_command(CLI::App& app, const Context& context);
void add_bench_command(CLI::App& app, const Context& context);

}  // namespace scout::tools
