#pragma once
// Starting other programs — npm, tar, the report's plotting script, the ranks of `--nproc` — through
// one spawner (posix_spawn: no shell, and nothing runs in the child between fork and exec, which
// matters once threads exist); output kept in a log file and quoted in one-line errors; a free
// local port for the processes of a group.
#include <signal.h>
#include <sys/types.h>

#include <filesystem>
#include <optional>
#include <string>
#include <utility>
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

/// What to start. Everything the child gets is built here, before the spawn.
struct ChildSpec {
  std::vector<std::string> args = {};  ///< the argument vector; args[0] is looked up on PATH unless `executable` is set
  std::filesystem::path executable = {};  ///< the file to run (e.g. /proc/self/exe); empty: args[0] on PATH
  /// Variables set (or replaced) on top of this process's environment.
  std::vector<std::pair<std::string, std::string>> environment = {};
  std::optional<std::filesystem::path> cwd = {};         ///< nullopt: this process's
  std::optional<std::filesystem::path> output_log = {};  ///< stdout and stderr both go here; nullopt: inherited
  std::optional<sigset_t> signal_mask = {};              ///< the child's blocked signals; nullopt: inherited
};

/// Starts a child as `spec` says and returns its pid without waiting. Throws InputError with
/// "cannot run <program>: <reason>" when it cannot be started (not found, not executable).
pid_t spawn_child(const ChildSpec& spec);

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
