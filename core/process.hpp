#pragma once
// Running another program (npm, tar, the report's plotting script) without a shell, its output
// kept in a log file and quoted in one-line errors; a free local port for the processes of a group.
#include <filesystem>
#include <string>
#include <vector>

namespace scout::core {

/// How a program run went.
struct ProgramResult {
  bool exited = false;    ///< false: killed by a signal, or not run (run_error says why)
  int code = 0;           ///< exit status, or the signal number
  std::string run_error;  ///< why it could not be started or waited for, else empty
  std::string last_line;  ///< on failure: the last non-empty line it printed, cleaned and clipped

  bool failed() const { return !run_error.empty() || !exited || code != 0; }
  /// "(exit 1): <its last line>", "(killed by signal 9)", "(cannot run npm: No such file or directory)".
  std::string describe(const std::string& program) const;
};

/// Runs args[0] (found on PATH) with the argument vector `args` (no shell, so nothing is
/// re-parsed) in `cwd`. Its stdout and stderr both go to `log`, never to the user's terminal.
ProgramResult run_program(const std::vector<std::string>& args, const std::filesystem::path& cwd,
                          const std::filesystem::path& log);

/// The last non-empty line of a log, fit for a one-line message: trimmed, terminal escape
/// sequences dropped, other control characters turned into spaces, clipped to 200 bytes (at a
/// UTF-8 character boundary) with "..." appended. Empty if the file cannot be read.
std::string last_output_line(const std::filesystem::path& log);

/// A TCP port on 127.0.0.1 that nothing listens on now (the kernel's choice), for a process group
/// started moments later. Throws InputError naming why none could be found.
int free_loopback_port();

}  // namespace scout::core
