#pragma once
// Runs a piece of a test in a forked child and measures the child's peak resident memory above
// what it held when it started, the way tests/learn/test_hostile_checkpoints.cpp measures its
// refusals: the kernel's high-water mark (VmHWM) is reset to the current resident size through
// /proc/self/clear_refs, so only what `body` itself touches counts, not the parent's history.
// A crash or a hang (60 s alarm) ends only the child.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <exception>
#include <fstream>
#include <functional>
#include <string>

#include "core/error.hpp"

namespace scout::testing {

// AddressSanitizer's redzones, its shadow memory and its quarantine of freed blocks keep several
// times the memory resident that a Release build does (the CI's ASan pass runs these tests too):
// a bound on a child's peak is multiplied by this.
#if defined(__SANITIZE_ADDRESS__)
inline constexpr long kSanitizerMemoryFactor = 4;
#else
inline constexpr long kSanitizerMemoryFactor = 1;
#endif

struct ChildOutcome {
  int status = -1;      ///< the child's: 0 body returned, 1 InputError, 2 another exception; -1 killed
  int signal = 0;       ///< the signal that ended it, if one did
  std::string message;  ///< the InputError's or the exception's text ("returned" if none)
  long peak_kib = -1;   ///< peak resident size above the child's own at the start; -1 if unmeasured
};

namespace child_peak_detail {

inline long status_kib(const char* field) {
  std::ifstream in("/proc/self/status");
  const std::string prefix(field);
  for (std::string line; std::getline(in, line);)
    if (line.rfind(prefix, 0) == 0) return std::stol(line.substr(prefix.size()));
  return -1;
}

}  // namespace child_peak_detail

/// Runs `body` in a forked child; its outcome and its peak resident memory (KiB) above its start.
inline ChildOutcome run_in_child_measuring_peak(const std::function<void()>& body) {
  using child_peak_detail::status_kib;
  int fds[2];
  if (::pipe(fds) != 0) return {};
  const pid_t child = ::fork();
  if (child < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    return {};
  }
  if (child == 0) {
    ::close(fds[0]);
    ::alarm(60);
    std::ofstream("/proc/self/clear_refs") << "5";  // VmHWM := VmRSS
    const long base = status_kib("VmRSS:");
    // A reset that did not take (no /proc, an old kernel) would measure the parent's history:
    // the peak is then reported as unmeasured rather than as a number. (Reading the status
    // itself faults in a few hundred KiB of code and buffers, hence the MiB of tolerance.)
    const bool reset = base >= 0 && status_kib("VmHWM:") <= base + 1024;
    int status = 0;
    std::string message = "returned";
    try {
      body();
    } catch (const InputError& e) {
      status = 1;
      message = e.what();
    } catch (const std::exception& e) {
      status = 2;
      message = e.what();
    }
    const long peak = reset ? status_kib("VmHWM:") - base : -1;
    message = std::to_string(peak) + " " + message;
    for (std::size_t at = 0; at < message.size();) {
      const ssize_t n = ::write(fds[1], message.data() + at, message.size() - at);
      if (n <= 0) break;
      at += static_cast<std::size_t>(n);
    }
    ::_exit(status);
  }
  ::close(fds[1]);
  std::string text;
  char buffer[4096];
  for (ssize_t n; (n = ::read(fds[0], buffer, sizeof buffer)) > 0;) text.append(buffer, static_cast<std::size_t>(n));
  ::close(fds[0]);
  int raw = 0;
  ::waitpid(child, &raw, 0);
  ChildOutcome o;
  o.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  o.signal = WIFSIGNALED(raw) ? WTERMSIG(raw) : 0;
  const std::size_t space = text.find(' ');
  if (space != std::string::npos) {
    o.peak_kib = std::stol(text.substr(0, space));
    o.message = text.substr(space + 1);
  }
  return o;
}

}  // namespace scout::testing
