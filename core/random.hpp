#pragma once
/// Seeds and random draws that are the same on every platform and standard library:
/// std::uniform_int_distribution and std::shuffle are implementation-defined, these are not.
#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

namespace scout::core {

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

/// A small, fast generator (xoshiro256**, 32 bytes of state) for the many per-robot streams:
/// constructing one is four SplitMix64 steps, where an mt19937_64 fills 2.5 KB.
///
/// Seeding: word i of the state is mix_seed(seed + (i + 1) * 0x9E3779B97F4A7C15), and mix_seed
/// adds that constant once more, so Rng(s) holds the state that the reference SplitMix64 seeding
/// gives for s + 0x9E3779B97F4A7C15 (not for s). It stays so: every pinned result depends on it.
class Rng {
 public:
  using result_type = std::uint64_t;
  explicit Rng(std::uint64_t seed) {
    for (std::uint64_t& word : state_) {
      seed += 0x9E3779B97F4A7C15ull;
      word = mix_seed(seed);
    }
  }
  /// A generator in exactly this state (not all zero), e.g. to compare with reference outputs.
  static Rng from_state(const std::array<std::uint64_t, 4>& state) {
    Rng rng(0);
    for (int i = 0; i < 4; ++i) rng.state_[i] = state[i];
    return rng;
  }
  static constexpr result_type min() { return 0; }
  static constexpr result_type max() { return ~result_type{0}; }
  result_type operator()() {
    const std::uint64_t result = rotl(state_[1] * 5, 7) * 9;
    const std::uint64_t t = state_[1] << 17;
    state_[2] ^= state_[0];
    state_[3] ^= state_[1];
    state_[1] ^= state_[2];
    state_[0] ^= state_[3];
    state_[2] ^= t;
    state_[3] = rotl(state_[3], 45);
    return result;
  }

 private:
  static constexpr std::uint64_t rotl(std::uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  std::uint64_t state_[4];
};

/// An unbiased integer in [0, n), n > 0, from a generator of uniform 64-bit words (Rng or
/// std::mt19937_64): draws below 2^64 mod n are rejected, since they would favour the smallest
/// residues.
template <typename Generator>
std::uint64_t uniform_below(Generator& rng, std::uint64_t n) {
  const std::uint64_t reject_below = (0 - n) % n;
  std::uint64_t x;
  do x = rng();
  while (x < reject_below);
  return x % n;
}

/// A uniform double in [0, 1) from the top 53 bits of one draw.
template <typename Generator>
double uniform01(Generator& rng) {
  return static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

/// A standard normal draw (Box-Muller from two uniform01 draws, the cosine branch): written out
/// because std::normal_distribution's sequence is unspecified.
template <typename Generator>
double standard_normal(Generator& rng) {
  const double u1 = 1.0 - uniform01(rng);  // (0, 1]: the logarithm stays finite
  const double u2 = uniform01(rng);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * 3.14159265358979323846 * u2);
}

/// Fisher-Yates shuffle, written out because std::shuffle's sequence is unspecified.
template <typename T, typename Generator>
void shuffle(std::vector<T>& v, Generator& rng) {
  for (std::size_t i = v.size(); i > 1; --i) std::swap(v[i - 1], v[uniform_below(rng, i)]);
}

}  // namespace scout::core
