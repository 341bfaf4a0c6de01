#pragma once
// The command line's value checks, shared by the subcommands: a value that does not parse is a
// usage error (exit 2) whose one line says what was expected.
#include <CLI/Error.hpp>  // before Validators.hpp, which uses it without including it
#include <CLI/Validators.hpp>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "core/error.hpp"

namespace CLI {
class App;
}

namespace scout::tools {

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

/// CLI11 check from a parser of a name that throws std::invalid_argument (agent::parse_*): a usage
/// error "expected one of CHOICES, got 'TEXT'" otherwise.
template <typename Parse>
CLI::Validator one_of(Parse parse, const std::string& choices, const std::string& name) {
  return CLI::Validator(
      [parse, choices](std::string& text) -> std::string {
        try {
          parse(text);
          return {};
        } catch (const std::invalid_argument&) {
          return "expected one of " + choices + ", got '" + one_line(text) + "'";
        }
      },
      name);
}

/// --camera-backend auto|osmesa|egl on a command that renders: sets SCOUT_CAMERA_BACKEND for this
/// process and the ones it starts (the ranks of --nproc), which every camera then reads.
void add_camera_backend_option(CLI::App& command);

/// CLI11 reports a mistyped command as "A subcommand is required"; this names the word instead.
/// Returns the one-line message for a word of the command line that is not a command, or "" when
/// all are.
std::string unknown_command_message(const CLI::App& app, int argc, char** argv);

}  // namespace scout::tools
