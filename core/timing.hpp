#pragma once
/// Wall-clock intervals for progress lines, metrics and benchmarks (steady clock: never jumps).
#include <chrono>

namespace scout::core {

using Clock = std::chrono::steady_clock;

/// Seconds from `start` until now.
inline double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace scout::core
