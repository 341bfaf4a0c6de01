// Running another program without a shell: posix_spawnp, output to a log file.
#include "core/process.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <fmt/format.h>
#include <netinet/in.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "core/error.hpp"

extern char** environ;

namespace scout::core {

namespace fs = std::filesystem;

namespace {

constexpr std::size_t kMaxQuotedOutput = 200;

}  // namespace

std::string last_output_line(const fs::path& log) {
  std::ifstream in(log, std::ios::binary | std::ios::ate);
  if (!in) return {};
  // The tail is enough: npm's last line is its summary or the path of its debug log.
  constexpr std::streamoff kTail = 64 * 1024;
  const std::streamoff size = in.tellg();
  in.seekg(size > kTail ? size - kTail : 0);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());

  std::string line;
  std::size_t end = text.size();
  while (end > 0) {
    const std::size_t newline = text.find_last_of("\r\n", end - 1);
    const std::size_t begin = newline == std::string::npos ? 0 : newline + 1;
    std::string clean;
    for (std::size_t i = begin; i < end; ++i) {
      const auto u = static_cast<unsigned char>(text[i]);
      if (u == 0x1b) {  // ESC [ parameters final-byte (colours), or ESC and one more byte
        ++i;
        if (i < end && text[i] == '[') {
          while (i + 1 < end && !(text[i + 1] >= '@' && text[i + 1] <= '~')) ++i;
          ++i;
        }
        continue;
      }
      clean += (u < 0x20 || u == 0x7f) ? ' ' : text[i];
    }
    const std::size_t first = clean.find_first_not_of(' ');
    if (first != std::string::npos) {
      line = clean.substr(first, clean.find_last_not_of(' ') - first + 1);
      break;
    }
    if (newline == std::string::npos) break;
    end = newline;
  }
  if (line.size() > kMaxQuotedOutput) {
    std::size_t cut = kMaxQuotedOutput;
    while (cut > 0 && (static_cast<unsigned char>(line[cut]) & 0xC0) == 0x80) --cut;  // not inside a character
    line = line.substr(0, cut) + "...";
  }
  return line;
}

namespace {

// "KEY=VALUE" strings: this process's environment with `overrides` set on top.
std::vector<std::string> child_environment(const std::vector<std::pair<std::string, std::string>>& overrides) {
  std::vector<std::string> out;
  for (char** e = environ; e != nullptr && *e != nullptr; ++e) {
    const std::string_view entry(*e);
    const std::string_view key = entry.substr(0, entry.find('='));
    bool replaced = false;
    for (const auto& [name, value] : overrides) replaced = replaced || key == name;
    if (!replaced) out.emplace_back(entry);
  }
  for (const auto& [name, value] : overrides) out.push_back(name + "=" + value);
  return out;
}

std::vector<char*> pointers(std::vector<std::string>& strings) {
  std::vector<char*> out;
  for (std::string& s : strings) out.push_back(s.data());
  out.push_back(nullptr);
  return out;
}

// posix_spawn's result: 0, or the errno why the child could not be started.
int start_child(const ChildSpec& spec, pid_t& pid) {
  if (spec.args.empty()) throw std::invalid_argument("spawn_child: an empty argument vector");
  std::vector<std::string> args = spec.args, environment = child_environment(spec.environment);
  std::vector<char*> argv = pointers(args), envp = pointers(environment);
  // Absolute, since the child changes to `cwd` before the open would otherwise be resolved.
  std::optional<std::string> log;
  if (spec.output_log) {
    std::error_code ec;
    const fs::path absolute = fs::absolute(*spec.output_log, ec);
    log = (ec ? *spec.output_log : absolute).string();
  }

  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (log) {
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log->c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  }
  if (spec.cwd) posix_spawn_file_actions_addchdir_np(&actions, spec.cwd->c_str());
  posix_spawnattr_t attributes;
  posix_spawnattr_init(&attributes);
  if (spec.signal_mask) {
    posix_spawnattr_setsigmask(&attributes, &*spec.signal_mask);
    posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETSIGMASK);
  }
  const int rc = spec.executable.empty()
                     ? posix_spawnp(&pid, argv[0], &actions, &attributes, argv.data(), envp.data())
                     : posix_spawn(&pid, spec.executable.c_str(), &actions, &attributes, argv.data(), envp.data());
  posix_spawnattr_destroy(&attributes);
  posix_spawn_file_actions_destroy(&actions);
  return rc;
}

}  // namespace

pid_t spawn_child(const ChildSpec& spec) {
  pid_t pid = 0;
  if (const int rc = start_child(spec, pid); rc != 0)
    throw InputError(fmt::format("cannot run {}: {}", spec.args[0], std::strerror(rc)));
  return pid;
}

// (process.hpp) Runs a program found on PATH with an argument vector (no shell, so nothing is re-parsed) in
// `cwd`. Its stdout and stderr both go to `log` (npm prints the tarball name on stdout and its
// "npm ERR!" lines on stderr), never to the user's terminal: a failure is reported as one line
// that quotes the last line of the log.
ProgramResult run_program(const std::vector<std::string>& args, const fs::path& cwd, const fs::path& log) {
  ProgramResult result;
  pid_t pid = 0;
  if (const int rc = start_child({.args = args, .cwd = cwd, .output_log = log}, pid); rc != 0) {
    result.run_error = std::strerror(rc);
    return result;
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) {
      result.run_error = std::string("waitpid: ") + std::strerror(errno);
      return result;
    }
  }
  if (WIFEXITED(status)) {
    result.exited = true;
    result.code = WEXITSTATUS(status);
  } else {
    result.code = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
  }
  if (!result.exited || result.code != 0) result.last_line = last_output_line(log);
  return result;
}

std::string ProgramResult::describe(const std::string& program) const {
  std::string what;
  if (!run_error.empty())
    what = fmt::format("(cannot run {}: {})", program, run_error);
  else
    what = exited ? fmt::format("(exit {})", code) : fmt::format("(killed by signal {})", code);
  return last_line.empty() ? what : what + ": " + last_line;
}

int free_loopback_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t length = sizeof(address);
  const bool ok = fd >= 0 && ::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)) == 0 &&
                  ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) == 0;
  const int error = errno;
  if (fd >= 0) ::close(fd);
  if (!ok) throw InputError(std::string("cannot find a free port on 127.0.0.1: ") + std::strerror(error));
  return ntohs(address.sin_port);
}

}  // namespace scout::core
