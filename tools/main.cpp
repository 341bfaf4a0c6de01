// scout: the command-line program. Exit status: 0 success, 1 error (bad input, a file, the data),
// 2 bad command line, 3 internal error (a bug: please report it), 130 interrupted.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <charconv>
#include <csignal>
#include <cstdio>
#include <exception>
#include <string>

#include "tools/commands.hpp"
#include "tools/output.hpp"
#include "core/error.hpp"

namespace {

volatile std::sig_atomic_t interrupted = 0;

extern "C" void on_signal(int) { interrupted = 1; }

}  // namespace

std::uint64_t scout::tools::parse_seed(const std::string& text) {
  std::uint64_t value = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  if (text.empty() || ec != std::errc() || ptr != end)
    throw scout::InputError("--seed: expected an integer in [0, 18446744073709551615], got '" + text + "'");
  return value;
}

CLI::Validator scout::tools::seed_validator() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        try {
          parse_seed(text);
          return {};
        } catch (const scout::InputError&) {
          return "expected an integer in [0, 18446744073709551615], got '" + text + "'";
        }
      },
      "UINT64");
}

CLI::Validator scout::tools::decimal_in(long long lo, long long hi) {
  const std::string expected = "expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
  return CLI::Validator(
      [lo, hi, expected](std::string& text) -> std::string {
        long long value = 0;
        const char* end = text.data() + text.size();
        const auto [ptr, ec] = std::from_chars(text.data(), end, value);
        const bool plain = !text.empty() && ptr == end && ec == std::errc() && (text.size() == 1 || text[0] != '0');
        if (!plain || value < lo || value > hi) return expected + ", got '" + text + "'";
        return {};
      },
      "INT in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
}

void scout::tools::install_interrupt_handler() {
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
}

const scout::core::StopToken& scout::tools::interrupt_token() {
  static const scout::core::StopToken token([] { return interrupted != 0; });
  return token;
}

namespace {

// CLI11 reports a mistyped command as "A subcommand is required"; name the word instead.
// Returns the one-line message for a word that is not a command, or "" when all are.
std::string check_command_words(const CLI::App& app, int argc, char** argv) {
  const CLI::App* at = &app;
  std::string path = app.get_name();
  for (int i = 1; i < argc && argv[i][0] != '-'; ++i) {
    const std::string word = argv[i];
    auto named = const_cast<CLI::App*>(at)->get_subcommands([&](const CLI::App* sub) { return sub->check_name(word); });
    if (!named.empty()) {
      at = named.front();
      path += " " + at->get_name();
      continue;
    }
    auto all = const_cast<CLI::App*>(at)->get_subcommands([](const CLI::App*) { return true; });
    if (all.empty()) return {};  // a positional argument, e.g. the world file
    std::string names;
    for (const CLI::App* sub : all) names += (names.empty() ? "" : ", ") + sub->get_name();
    return "scout: usage error: unknown command '" + scout::one_line(word) + "' (commands: " + names + "; see " + path +
           " --help)";
  }
  return {};
}

}  // namespace

int main(int argc, char** argv) {
  scout::tools::Context context{scout::tools::command_line(argc, argv)};
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
  scout::tools::install_interrupt_handler();
  if (const std::string unknown = check_command_words(app, argc, argv); !unknown.empty()) {
    std::fprintf(stderr, "%s\n", unknown.c_str());
    return 2;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  } catch (const scout::core::Stopped& e) {
    std::fprintf(stderr, "scout: %s\n", scout::one_line(e.what()).c_str());
    return 130;
  } catch (const scout::InputError& e) {
    std::fprintf(stderr, "scout: error: %s\n", scout::one_line(e.what()).c_str());
    return 1;
  } catch (const std::exception& e) {
    // The first line only: LibTorch appends a backtrace of dozens of lines.
    const std::string what = e.what();
    std::fprintf(stderr, "scout: internal error: %s\n", scout::one_line(what.substr(0, what.find('\n'))).c_str());
    return 3;
  }
  return 0;
}
