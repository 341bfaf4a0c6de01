#pragma once
// Helpers for end-to-end tests of the `scout` program and for writing raw IDX files.
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <system_error>
#include <vector>

namespace scout::testing {

#ifdef SCOUT_BUILT_PROGRAM
/// The `scout` program the tools tests run (SCOUT_BINARY in them): this build's, or the one
/// SCOUT_TEST_PROGRAM names. The sanitizer pass runs the Release build's test programs against its
/// instrumented `scout` that way, instead of building the test programs a second time.
inline std::string scout_program() {
  const char* program = std::getenv("SCOUT_TEST_PROGRAM");
  return program != nullptr && *program != '\0' ? program : SCOUT_BUILT_PROGRAM;
}
#endif

/// What a command did: its exit status (-1 if it did not exit normally) and its output.
struct CliResult {
  int status = -1;
  std::string output;  ///< stdout and stderr together
};

/// Runs `program ARGS` through the shell with stderr folded into stdout.
inline CliResult run_cli(const std::string& program, const std::string& args) {
  const std::string command = program + " " + args + " 2>&1";
  CliResult r;
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) return r;
  std::array<char, 4096> buffer{};
  while (std::fgets(buffer.data(), buffer.size(), pipe)) r.output += buffer.data();
  const int raw = pclose(pipe);
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  return r;
}

/// The whole of a file ("" if there is none).
inline std::string read_file(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// Starts `argv` (argv[0] the program) in a child process with stdout and stderr written to the
/// two files; returns its pid (or -1). `before_exec` runs in the child first (limits, signal
/// dispositions the program inherits).
inline pid_t spawn(const std::vector<std::string>& argv, const std::filesystem::path& out,
                   const std::filesystem::path& err, const std::function<void()>& before_exec = {}) {
  const pid_t child = fork();
  if (child != 0) return child;
  if (before_exec) before_exec();
  const int out_fd = open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  const int err_fd = open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  dup2(out_fd, 1);
  dup2(err_fd, 2);
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  execv(args[0], args.data());
  _exit(127);
}

/// Whether `text` appeared in `file` while the child `child` ran: polls until it does, or the
/// child has exited (then false; the child is reaped into `*status` when given), or `limit_s`
/// seconds have passed (a generous bound against hanging forever, never a pass condition).
inline bool wait_for_text(pid_t child, const std::filesystem::path& file, const std::string& text, int limit_s = 600,
                          int* status = nullptr) {
  for (int k = 0; k < limit_s * 50; ++k) {
    std::ifstream in(file, std::ios::binary);
    const std::string now{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    if (now.find(text) != std::string::npos) return true;
    int raw = 0;
    if (waitpid(child, &raw, WNOHANG) == child) {
      if (status) *status = raw;
      return false;
    }
    usleep(20 * 1000);
  }
  return false;
}

/// How many processes now running have `text` in their command line (read from /proc): a child
/// that outlived the process that started it (a rank, a plotting script) still names its files.
inline int processes_naming(const std::string& text) {
  int count = 0;
  std::error_code ec;
  for (std::filesystem::directory_iterator it("/proc", ec), end; !ec && it != end; it.increment(ec)) {
    std::string cmdline = read_file(it->path() / "cmdline");
    for (char& c : cmdline)
      if (c == '\0') c = ' ';
    if (cmdline.find(text) != std::string::npos) ++count;
  }
  return count;
}

/// Appends a 32-bit big-endian integer (IDX headers).
inline void put_u32_be(std::string& out, std::uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out.push_back(static_cast<char>((v >> shift) & 0xFF));
}

/// Starts raw IDX image and label files of `count` rows x cols images (their headers).
inline void put_idx_headers(std::string& images, std::string& labels, int count, int rows, int cols) {
  put_u32_be(images, 0x803);
  put_u32_be(images, static_cast<std::uint32_t>(count));
  put_u32_be(images, static_cast<std::uint32_t>(rows));
  put_u32_be(images, static_cast<std::uint32_t>(cols));
  put_u32_be(labels, 0x801);
  put_u32_be(labels, static_cast<std::uint32_t>(count));
}

}  // namespace scout::testing
