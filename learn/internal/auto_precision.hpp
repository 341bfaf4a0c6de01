#pragma once
/// The parts of `--precision auto` (learn/auto_precision.hpp) that its tests drive one by one.
#include "learn/internal/private.hpp"
// (private.hpp first: it refuses to compile outside scout_learn and its tests)
#include <filesystem>
#include <string>

#include "learn/auto_precision.hpp"

namespace scout::learn {

/// Median milliseconds of one training step of the default networks in each precision.
struct PrecisionMeasurement {
  double fp32_ms = 0;
  double bf16_ms = 0;
};

/// The probe: the default networks on 24 robots over a 28 x 28 floor, the planners under no_grad
/// (a rollout's move) then all three forward and backward (the update), one warm-up and three
/// timed steps per precision, interleaved, on every core. Leaves LibTorch's global generator and
/// thread count as it found them.
PrecisionMeasurement measure_precisions();

/// bf16 where its step takes at most 90 % of fp32's, else fp32.
agent::Precision choose_precision(const PrecisionMeasurement& measurement);

/// What the choice depends on, as the cache names it: "MODEL | avx512-bf16 | LibTorch 2.15.0"
/// (with the instruction-set caps in force).
std::string precision_cache_key();

/// The choice for `key` from `cache_file`, or measured and written there (atomically, under an
/// exclusive lock on `cache_file`.lock, so concurrent processes measure once and agree). A
/// damaged or foreign cache file is measured again and rewritten; an unwritable one is measured
/// every time, and the note says so.
PrecisionChoice cached_or_measured_precision(const std::filesystem::path& cache_file, const std::string& key);

}  // namespace scout::learn
