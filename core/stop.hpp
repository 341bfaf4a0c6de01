#pragma once
/// Stopping long work early (Ctrl-C): the one cancellation path of every layer. Long operations
/// take a StopToken, poll it between units of work (a batch, a run, a benchmark repeat), leave
/// their outputs consistent (saved or not written, as each documents) and throw Stopped; the CLI
/// catches Stopped once and exits with status 130.
#include <functional>
#include <stdexcept>
#include <string>
#include <utility>

namespace scout::core {

/// Thrown when work stopped because a stop was requested. `what()` is one line for the user
/// saying what was kept ("checkpoint saved: RUN/checkpoint.safetensors") or that nothing was written.
class Stopped : public std::runtime_error {
 public:
  explicit Stopped(const std::string& message = "interrupted; nothing was written") : std::runtime_error(message) {}
};

/// Whether to stop, asked between units of work. Copyable and cheap; a default token never stops.
class StopToken {
 public:
  StopToken() = default;
  /// `requested` is polled from the working thread; it must be cheap and must not throw.
  explicit StopToken(std::function<bool()> requested) : requested_(std::move(requested)) {}

  bool requested() const { return requested_ && requested_(); }
  /// Throws Stopped(message) if a stop has been requested.
  void throw_if_requested(const std::string& message = "interrupted; nothing was written") const {
    if (requested()) throw Stopped(message);
  }

 private:
  std::function<bool()> requested_;
};

}  // namespace scout::core
