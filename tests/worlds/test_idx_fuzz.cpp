// A deterministic fuzz loop over the IDX parsers: random bytes and mutations of valid raw and
// gzipped files. Every input is also read by a reference reader written here (zlib for the gzip
// layer, then the header by hand), and the parsers must agree with it: a file it reads is
// accepted with exactly its counts, dimensions, pixels and labels, byte for byte; a file it
// refuses is refused with one InputError line naming the input. Any other outcome (another
// exception type, a crash, a set that differs from what the bytes say) is a bug.
#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <climits>
#include <cstdint>
#include <cstdio>
#include <iterator>
#include <optional>
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

// --- The reference reader: what a file's bytes say, worked out without worlds/idx.cpp ------------

// The fuzz inputs are a few KiB and deflate expands at most about 1032:1, so a few MiB at most;
// the reference stops (and fails the test) far beyond that rather than guess.
constexpr std::size_t kReferenceMaxBytes = std::size_t{64} << 20;

std::uint32_t be32_at(const Bytes& b, std::size_t at) {
  return (std::uint32_t{b[at]} << 24) | (std::uint32_t{b[at + 1]} << 16) | (std::uint32_t{b[at + 2]} << 8) |
         std::uint32_t{b[at + 3]};
}

bool starts_gzip(const Bytes& b, std::size_t at) { return b.size() - at >= 2 && b[at] == 0x1f && b[at + 1] == 0x8b; }

// The gzip members inflated one after another (as gunzip reads `cat a.gz b.gz`); nullopt for a
// corrupt or truncated member, or for bytes after a member that do not start another one.
std::optional<Bytes> reference_gunzip(const Bytes& in) {
  Bytes out;
  std::size_t at = 0;
  while (at < in.size()) {
    if (!starts_gzip(in, at)) return std::nullopt;  // junk after a member
    z_stream zs{};
    if (inflateInit2(&zs, 16 + MAX_WBITS) != Z_OK) return std::nullopt;
    zs.next_in = const_cast<Bytef*>(in.data() + at);  // zlib's API is not const-correct
    zs.avail_in = static_cast<uInt>(in.size() - at);
    std::uint8_t chunk[4096];
    int rc = Z_OK;
    while (rc == Z_OK && out.size() <= kReferenceMaxBytes) {
      zs.next_out = chunk;
      zs.avail_out = sizeof chunk;
      rc = inflate(&zs, Z_NO_FLUSH);  // Z_BUF_ERROR once the input ends before the member does
      out.insert(out.end(), chunk, chunk + (sizeof chunk - zs.avail_out));
    }
    at = in.size() - zs.avail_in;
    inflateEnd(&zs);
    if (out.size() > kReferenceMaxBytes) {
      ADD_FAILURE() << "the reference reader's limit: the input inflates to more than " << kReferenceMaxBytes;
      return std::nullopt;
    }
    if (rc != Z_STREAM_END) return std::nullopt;
  }
  return out;
}

// The IDX bytes of a file: inflated if it starts with gzip's magic, else the file itself.
std::optional<Bytes> reference_content(const Bytes& file) {
  return starts_gzip(file, 0) ? reference_gunzip(file) : std::optional<Bytes>(file);
}

// The images a file holds by the IDX format (magic 0x00000803, then count, rows and columns as
// big-endian 32-bit words, then exactly count * rows * cols pixel bytes) within the parser's
// documented limits (at least one image, sides of 1 to 4096, a payload of at most INT_MAX
// bytes); nullopt where the bytes do not hold such a set.
std::optional<ImageSet> reference_images(const Bytes& file) {
  const std::optional<Bytes> b = reference_content(file);
  if (!b || b->size() < 16 || be32_at(*b, 0) != 0x00000803) return std::nullopt;
  const std::uint32_t count = be32_at(*b, 4), rows = be32_at(*b, 8), cols = be32_at(*b, 12);
  if (count < 1 || rows < 1 || rows > 4096 || cols < 1 || cols > 4096) return std::nullopt;
  const std::uint64_t pixels = std::uint64_t{count} * rows * cols;
  if (pixels > INT_MAX || b->size() - 16 != pixels) return std::nullopt;
  ImageSet set;
  set.count = static_cast<int>(count);
  set.rows = static_cast<int>(rows);
  set.cols = static_cast<int>(cols);
  set.pixels.assign(b->begin() + 16, b->end());
  return set;
}

// The labels a file holds by the IDX format (magic 0x00000801, a big-endian count, then exactly
// that many bytes; at least one, at most INT_MAX); nullopt where the bytes do not hold them.
std::optional<Bytes> reference_labels(const Bytes& file) {
  const std::optional<Bytes> b = reference_content(file);
  if (!b || b->size() < 8 || be32_at(*b, 0) != 0x00000801) return std::nullopt;
  const std::uint32_t count = be32_at(*b, 4);
  if (count < 1 || count > INT_MAX || b->size() - 8 != count) return std::nullopt;
  return Bytes(b->begin() + 8, b->end());
}

// Fails unless `loaded` holds exactly the bytes `expected` does, naming the first that differs.
void expect_same_bytes(const char* what, const Bytes& loaded, const Bytes& expected, int case_no) {
  ASSERT_EQ(loaded.size(), expected.size()) << "case " << case_no << ": " << what;
  const auto [l, e] = std::mismatch(loaded.begin(), loaded.end(), expected.begin());
  ASSERT_TRUE(l == loaded.end()) << "case " << case_no << ": " << what << " byte " << (l - loaded.begin())
                                 << " loaded as " << int{*l} << ", the file says " << int{*e};
}

// --- The loop ------------------------------------------------------------------------------------

struct Tally {
  int parsed = 0;
  int rejected = 0;
  int parsed_gzip = 0;               // accepted gzip inputs: the inflated bytes were compared
  std::uint64_t bytes_compared = 0;  // pixels and labels compared with the reference's
};

// Runs one parser on one input: either it accepts and `accepted` compares the result with what
// the reference reader found, or it refuses with one InputError line naming the input; a
// refusal of a file the reference reads, or any other outcome, fails the test.
template <typename Parse, typename Check>
void parse_or_refuse(const char* parser, Parse&& parse, Check&& accepted, bool reference_reads,
                     const std::filesystem::path& origin, int case_no, Tally& tally) {
  try {
    accepted(parse());
    ++tally.parsed;
  } catch (const InputError& e) {
    const std::string msg = e.what();
    ASSERT_FALSE(reference_reads) << "case " << case_no << ": the " << parser
                                  << " parser refused a valid file: " << msg;
    ASSERT_EQ(msg.rfind(origin.string() + ": ", 0), 0u) << "case " << case_no << ": " << msg;
    ASSERT_EQ(msg.find('\n'), std::string::npos) << "case " << case_no << ": " << msg;
    ++tally.rejected;
  } catch (const std::exception& e) {
    FAIL() << "case " << case_no << ": " << parser << " parser threw a non-InputError: " << e.what();
  } catch (...) {
    FAIL() << "case " << case_no << ": " << parser << " parser threw a non-exception";
  }
}

// Feeds `input` to both parsers and compares each outcome with the reference reader's.
void check(const Bytes& input, int case_no, Tally& tally) {
  const std::filesystem::path origin = "fuzz-" + std::to_string(case_no);
  const bool gzipped = starts_gzip(input, 0);
  const std::optional<ImageSet> images = reference_images(input);
  parse_or_refuse(
      "images", [&] { return parse_idx_images(input, origin); },
      [&](const ImageSet& s) {
        ASSERT_TRUE(images.has_value()) << "case " << case_no << ": accepted as " << s.count << " images of " << s.rows
                                        << "x" << s.cols << ", but the bytes hold no valid image set";
        ASSERT_EQ(s.count, images->count) << "case " << case_no;
        ASSERT_EQ(s.rows, images->rows) << "case " << case_no;
        ASSERT_EQ(s.cols, images->cols) << "case " << case_no;
        expect_same_bytes("pixel", s.pixels, images->pixels, case_no);
        tally.bytes_compared += s.pixels.size();
        tally.parsed_gzip += gzipped ? 1 : 0;
      },
      images.has_value(), origin, case_no, tally);
  if (::testing::Test::HasFatalFailure()) return;
  const std::optional<Bytes> labels = reference_labels(input);
  parse_or_refuse(
      "labels", [&] { return parse_idx_labels(input, origin); },
      [&](const Bytes& l) {
        ASSERT_TRUE(labels.has_value()) << "case " << case_no << ": accepted as " << l.size()
                                        << " labels, but the bytes hold no valid label set";
        expect_same_bytes("label", l, *labels, case_no);
        tally.bytes_compared += l.size();
        tally.parsed_gzip += gzipped ? 1 : 0;
      },
      labels.has_value(), origin, case_no, tally);
}

TEST(IdxFuzz, TwentyThousandCasesGiveWhatTheirBytesSayOrThrowInputError) {
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
  // Both outcomes must be common, or the loop is not exercising the parsers; and accepted gzip
  // inputs too, so that inflated content is compared as well as raw.
  EXPECT_GT(tally.parsed, kCases / 50);
  EXPECT_GT(tally.rejected, kCases / 2);
  EXPECT_GT(tally.parsed_gzip, kCases / 200);
  std::printf("[ measured ] %d IDX inputs: %d parses accepted (%d gzip, %llu bytes compared), %d refused\n", kCases,
              tally.parsed, tally.parsed_gzip, static_cast<unsigned long long>(tally.bytes_compared), tally.rejected);
  RecordProperty("parsed", tally.parsed);
  RecordProperty("parsed_gzip", tally.parsed_gzip);
  RecordProperty("rejected", tally.rejected);
}

}  // namespace
}  // namespace scout::worlds
