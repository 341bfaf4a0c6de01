// A deterministic fuzz loop over the IDX parsers: random bytes and mutations of valid raw and
// gzipped files. Each input must parse into a consistent set or throw InputError; any other
// outcome (another exception type, a crash, an inconsistent result) is a bug.
#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "worlds/idx.hpp"

namespace scout::worlds {
namespace {

using Bytes = std::vector<std::uint8_t>;

Bytes be32(std::uint32_t v) {
  return {static_cast<std::uint8_t>(v >> 24), static_cast<std::uint8_t>(v >> 16), static_cast<std::uint8_t>(v >> 8),
          static_cast<std::uint8_t>(v)};
}

Bytes images_file(std::uint32_t count, std::uint32_t rows, std::uint32_t cols, std::mt19937_64& rng) {
  Bytes b = {0, 0, 8, 3};
  for (std::uint32_t v : {count, rows, cols}) {
    const Bytes f = be32(v);
    b.insert(b.end(), f.begin(), f.end());
  }
  for (std::uint64_t i = 0; i < std::uint64_t{count} * rows * cols; ++i)
    b.push_back(static_cast<std::uint8_t>(rng() % 3 == 0 ? rng() : 0));  // mostly zeros, like digits
  return b;
}

Bytes labels_file(std::uint32_t count, std::mt19937_64& rng) {
  Bytes b = {0, 0, 8, 1};
  const Bytes f = be32(count);
  b.insert(b.end(), f.begin(), f.end());
  for (std::uint32_t i = 0; i < count; ++i) b.push_back(static_cast<std::uint8_t>(rng() % 10));
  return b;
}

// In-memory gzip (the format gzip writes), so that the loop stays fast.
Bytes gzip(const Bytes& in, int level) {
  z_stream zs{};
  if (deflateInit2(&zs, level, Z_DEFLATED, 16 + MAX_WBITS, 8, Z_DEFAULT_STRATEGY) != Z_OK) return {};
  Bytes out(deflateBound(&zs, static_cast<uLong>(in.size())) + 32);
  zs.next_in = const_cast<Bytef*>(in.data());
  zs.avail_in = static_cast<uInt>(in.size());
  zs.next_out = out.data();
  zs.avail_out = static_cast<uInt>(out.size());
  const int rc = deflate(&zs, Z_FINISH);
  out.resize(zs.total_out);
  deflateEnd(&zs);
  return rc == Z_STREAM_END ? out : Bytes{};
}

class Mutator {
 public:
  explicit Mutator(std::uint64_t seed) : rng_(seed) {}
  std::mt19937_64& rng() { return rng_; }
  std::size_t below(std::size_t n) { return n == 0 ? 0 : static_cast<std::size_t>(rng_() % n); }

  Bytes random_bytes() {
    Bytes b(below(80));
    for (auto& x : b) x = static_cast<std::uint8_t>(rng_());
    // Often start like a real file so that the later checks are reached too.
    switch (below(4)) {
      case 0:
        if (b.size() >= 4) b[0] = 0, b[1] = 0, b[2] = 8, b[3] = static_cast<std::uint8_t>(below(2) ? 3 : 1);
        break;
      case 1:
        if (b.size() >= 2) b[0] = 0x1f, b[1] = 0x8b;
        break;
      default:
        break;
    }
    return b;
  }

  void flip_bits(Bytes& b) {
    if (b.empty()) return;
    for (std::size_t n = 1 + below(8); n > 0; --n) b[below(b.size())] ^= static_cast<std::uint8_t>(1u << below(8));
  }
  void truncate(Bytes& b) { b.resize(below(b.size() + 1)); }
  void insert_bytes(Bytes& b) {
    for (std::size_t n = 1 + below(4); n > 0; --n)
      b.insert(b.begin() + static_cast<std::ptrdiff_t>(below(b.size() + 1)), static_cast<std::uint8_t>(rng_()));
  }
  // Overwrites a 32-bit header field (or any aligned word near the start) with an extreme value.
  void overwrite_field(Bytes& b) {
    static const std::uint32_t kExtreme[] = {0,          1,          2,          3,          255,
                                             4095,       4096,       4097,       65535,      65536,
                                             0x7FFFFFFF, 0x80000000, 0xFFFFFFFE, 0xFFFFFFFF, 0x00000803,
                                             0x00000801, 0x01000000, 0x00100000, 1u << 28,   1u << 31 | 1};
    if (b.size() < 4) return;
    const std::size_t at = std::min<std::size_t>(4 * below(4), b.size() - 4);
    const Bytes v = be32(kExtreme[below(std::size(kExtreme))]);
    std::copy(v.begin(), v.end(), b.begin() + static_cast<std::ptrdiff_t>(at));
  }
  void mutate(Bytes& b) {
    switch (below(4)) {
      case 0:
        flip_bits(b);
        break;
      case 1:
        truncate(b);
        break;
      case 2:
        insert_bytes(b);
        break;
      default:
        overwrite_field(b);
        break;
    }
  }

 private:
  std::mt19937_64 rng_;
};

struct Tally {
  int parsed = 0;
  int rejected = 0;
};

// Runs one parser on one input: either it accepts and `accepted` checks the result, or it refuses
// with one InputError line naming the input; any other outcome fails the test.
template <typename Parse, typename Check>
void parse_or_refuse(const char* parser, Parse&& parse, Check&& accepted, const std::filesystem::path& origin,
                     int case_no, Tally& tally) {
  try {
    accepted(parse());
    ++tally.parsed;
  } catch (const InputError& e) {
    const std::string msg = e.what();
    ASSERT_EQ(msg.rfind(origin.string() + ": ", 0), 0u) << "case " << case_no << ": " << msg;
    ASSERT_EQ(msg.find('\n'), std::string::npos) << "case " << case_no << ": " << msg;
    ++tally.rejected;
  } catch (const std::exception& e) {
    FAIL() << "case " << case_no << ": " << parser << " parser threw a non-InputError: " << e.what();
  } catch (...) {
    FAIL() << "case " << case_no << ": " << parser << " parser threw a non-exception";
  }
}

// Feeds `input` to both parsers and checks the outcome.
void check(const Bytes& input, int case_no, Tally& tally) {
  const std::filesystem::path origin = "fuzz-" + std::to_string(case_no);
  parse_or_refuse(
      "images", [&] { return parse_idx_images(input, origin); },
      [&](const ImageSet& s) {
        ASSERT_GE(s.count, 1) << "case " << case_no;
        ASSERT_GE(s.rows, 1) << "case " << case_no;
        ASSERT_GE(s.cols, 1) << "case " << case_no;
        ASSERT_LE(s.rows, 4096) << "case " << case_no;
        ASSERT_LE(s.cols, 4096) << "case " << case_no;
        ASSERT_EQ(s.pixels.size(), static_cast<std::size_t>(s.count) * s.rows * s.cols) << "case " << case_no;
      },
      origin, case_no, tally);
  if (::testing::Test::HasFatalFailure()) return;
  parse_or_refuse(
      "labels", [&] { return parse_idx_labels(input, origin); },
      [&](const Bytes& labels) {
        ASSERT_GE(labels.size(), 1u) << "case " << case_no;
        ASSERT_LE(labels.size(), input.size() * 1100 + 64) << "case " << case_no;  // bounded by deflate's ratio
      },
      origin, case_no, tally);
}

TEST(IdxFuzz, TwentyThousandCasesParseConsistentlyOrThrowInputError) {
  Mutator m(0x5C0u);  // fixed seed: a failure is reproducible by its case number

  // Valid seeds of several shapes, raw and gzipped at different levels (0 gives stored blocks).
  std::vector<Bytes> seeds = {images_file(1, 1, 1, m.rng()), images_file(3, 4, 5, m.rng()),
                              images_file(2, 28, 28, m.rng()), labels_file(1, m.rng()), labels_file(37, m.rng())};
  const std::size_t raw_seeds = seeds.size();
  for (std::size_t i = 0; i < raw_seeds; ++i)
    for (int level : {0, 1, 9}) seeds.push_back(gzip(seeds[i], level));
  for (const Bytes& s : seeds) ASSERT_FALSE(s.empty());

  constexpr int kCases = 20000;
  Tally tally;
  for (int n = 0; n < kCases; ++n) {
    Bytes input;
    switch (m.below(6)) {
      case 0:
        input = m.random_bytes();
        break;
      case 1:  // mutate a raw or gzipped file's bytes
      case 2:
        input = seeds[m.below(seeds.size())];
        for (std::size_t k = 1 + m.below(3); k > 0; --k) m.mutate(input);
        break;
      case 3: {  // mutate the content, then gzip it: header overwrites reach the parser through zlib
        input = seeds[m.below(raw_seeds)];
        for (std::size_t k = 1 + m.below(2); k > 0; --k) m.mutate(input);
        input = gzip(input, static_cast<int>(m.below(10)));
        break;
      }
      case 4: {  // two gzip members, or a member followed by junk
        input = seeds[raw_seeds + m.below(seeds.size() - raw_seeds)];
        const Bytes tail = m.below(2) ? seeds[raw_seeds + m.below(seeds.size() - raw_seeds)] : m.random_bytes();
        input.insert(input.end(), tail.begin(), tail.end());
        if (m.below(2)) m.mutate(input);
        break;
      }
      default:  // header field overwrites only, several at once
        input = seeds[m.below(raw_seeds)];
        for (std::size_t k = 1 + m.below(3); k > 0; --k) m.overwrite_field(input);
        break;
    }
    check(input, n, tally);
    if (HasFatalFailure()) return;
  }
  // Both outcomes must be common, or the loop is not exercising the parsers.
  EXPECT_GT(tally.parsed, kCases / 50);
  EXPECT_GT(tally.rejected, kCases / 2);
  RecordProperty("parsed", tally.parsed);
  RecordProperty("rejected", tally.rejected);
}

}  // namespace
}  // namespace scout::worlds
