#pragma once
/// Seeds and random draws that are the same on every platform and standard library:
/// std::uniform_int_distribution and std::shuffle are implementation-defined, these are not.
#include <cstdint>
#include <random>

namespace scout::sim {

/// SplitMix64 finaliser: a well-mixed 64-bit value from any 64-bit input.
constexpr std::uint64_t mix_seed(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

/// The seed of stream `stream` derived from `seed` (e.g. run k of a command, or one use within a run).
constexpr std::uint64_t derive_seed(std::uint64_t seed, std::uint64_t stream) {
  return mix_seed(mix_seed(seed) ^ mix_seed(stream + 0x632BE59BD9B4E019ull));
}

/// An unbiased integer in [0, n), n > 0 (rejection sampling on the top bits).
inline std::uint64_t uniform_below(std::mt19937_64& rng, std::uint64_t n) {
  const std::uint64_t limit = ~std::uint64_t{0} - (~std::uint64_t{0} % n);
  std::uint64_t x;
  do x = rng(); while (x >= limit);
  return x % n;
}

}  // namespace scout::sim
