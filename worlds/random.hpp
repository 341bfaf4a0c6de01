#pragma once
/// Seeds and random draws that are the same on every platform and standard library:
/// std::uniform_int_distribution and std::shuffle are implementation-defined, these are not.
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

namespace scout::worlds {

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

/// An unbiased integer in [0, n), n > 0: draws below 2^64 mod n are rejected, since they would
/// favour the smallest residues.
inline std::uint64_t uniform_below(std::mt19937_64& rng, std::uint64_t n) {
  const std::uint64_t reject_below = (0 - n) % n;
  std::uint64_t x;
  do x = rng();
  while (x < reject_below);
  return x % n;
}

/// Fisher-Yates shuffle, written out because std::shuffle's sequence is unspecified.
template <typename T>
void shuffle(std::vector<T>& v, std::mt19937_64& rng) {
  for (std::size_t i = v.size(); i > 1; --i) std::swap(v[i - 1], v[uniform_below(rng, i)]);
}

}  // namespace scout::worlds
