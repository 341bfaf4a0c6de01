// scout: the command-line program. Exit status: 0 success, 1 error (bad input, a file, the data),
// 2 bad command line, 3 internal error (a bug: please report it), 130 interrupted.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

#include "core/error.hpp"
#include "core/memory.hpp"
#include "render/camera.hpp"
#include "tools/commands.hpp"
#include "tools/group.hpp"
#include "tools/output.hpp"
#include "tools/parsing.hpp"

int main(int argc, char** argv) {
  scout::core::keep_freed_memory_for_reuse();  // before any tensor is allocated
  // Past a file-size limit (ulimit -f) a write then fails with EFBIG and takes the one-line error
  // path, instead of the default action of SIGXFSZ killing the process mid-write.
  std::signal(SIGXFSZ, SIG_IGN);
  scout::tools::Context context{.argv = scout::tools::command_line(argc, argv)};
  CLI::App app{
      "Scout: a robot that sees a small patch of the floor learns where to drive to tell what the floor shows.",
      "scout"};
  app.set_version_flag("--version", std::string("scout ") + SCOUT_VERSION);
  app.require_subcommand(1);
  // One line for a bad command line too (subcommands inherit this when they are added).
  app.failure_message([](const CLI::App* failed, const CLI::Error& e) {
    // Point at the help of the deepest subcommand given (`scout bench sim --help`).
    std::string path = failed->get_name();
    for (const CLI::App* a = failed; !a->get_subcommands().empty();) {
      a = a->get_subcommands().front();
      path += " " + a->get_name();
    }
    return "scout: usage error: " + scout::one_line(e.what()) + " (see " + path + " --help)\n";
  });
  app.footer(
      "Exit status: 0 success, 1 error in the input or a file, 2 bad command line, 3 internal error, 130 interrupted.");
  scout::tools::add_run_command(app, context);
  scout::tools::add_data_command(app, context);
  scout::tools::add_bench_command(app, context);
  scout::tools::add_train_command(app, context);
  scout::tools::add_eval_command(app, context);
  scout::tools::add_export_command(app, context);
  scout::tools::add_convert_command(app, context);
  scout::tools::add_report_command(app, context);
  scout::tools::install_interrupt_handler();
  if (const std::string unknown = scout::tools::unknown_command_message(app, argc, argv); !unknown.empty()) {
    std::fprintf(stderr, "%s\n", unknown.c_str());
    return 2;
  }
  // A member of a data-parallel group names its rank in every message.
  auto who = [] {
    const auto rank = scout::tools::current_rank();
    return rank ? fmt::format("rank {}: ", *rank) : std::string();
  };
  try {
    // A bad SCOUT_CAMERA_BACKEND is the user's input: one line, exit 1, before any work starts.
    if (const char* backend = std::getenv(scout::render::kCameraBackendVariable); backend != nullptr && *backend) try {
        scout::render::parse_camera_backend(backend);
      } catch (const std::invalid_argument& e) {
        throw scout::InputError(std::string(scout::render::kCameraBackendVariable) + ": " + e.what());
      }
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  } catch (const scout::tools::ExitStatus& e) {
    return e.code;
  } catch (const scout::core::Stopped& e) {
    // Rank 0 says where the run stopped for all of them.
    if (scout::tools::current_rank().value_or(0) == 0)
      std::fprintf(stderr, "scout: %s\n", scout::one_line(e.what()).c_str());
    return 130;
  } catch (const scout::InputError& e) {
    std::fprintf(stderr, "scout: %serror: %s\n", who().c_str(), scout::one_line(e.what()).c_str());
    return 1;
  } catch (const std::exception& e) {
    // The first line only: LibTorch appends a backtrace of dozens of lines.
    std::fprintf(stderr, "scout: %sinternal error: %s\n", who().c_str(), scout::first_line(e.what()).c_str());
    return 3;
  }
  return 0;
}
