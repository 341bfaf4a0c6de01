// IDX reading and writing against real files: round trips (raw and gzip) and every kind of bad
// file, each of which must give one InputError line naming the file and the problem.
#include <gtest/gtest.h>
#include <zlib.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "tests/support/temp_dir.hpp"
#include "worlds/dataset.hpp"
#include "worlds/idx.hpp"

namespace scout::worlds {
namespace {

namespace fs = std::filesystem;
using Bytes = std::vector<std::uint8_t>;

// A fresh folder per test under the system's temporary directory, removed afterwards.
class IdxFiles : public ::testing::Test {
 protected:
  scout::testing::TempDir temp_{"scout_idx"};
  const fs::path dir_ = temp_.path();
};

ImageSet sample_images(int count, int rows, int cols, unsigned seed) {
  ImageSet s;
  s.count = count;
  s.rows = rows;
  s.cols = cols;
  std::mt19937 rng(seed);
  s.pixels.resize(static_cast<std::size_t>(count) * rows * cols);
  for (auto& p : s.pixels) p = static_cast<std::uint8_t>(rng());
  return s;
}

Bytes read_bytes(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const fs::path& file, const Bytes& bytes) {
  std::ofstream out(file, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

// Gzip as the gzip tool writes it, through zlib's file interface.
void write_gzip(const fs::path& file, const Bytes& bytes) {
  gzFile gz = gzopen(file.c_str(), "wb");
  ASSERT_NE(gz, nullptr);
  ASSERT_EQ(gzwrite(gz, bytes.data(), static_cast<unsigned>(bytes.size())), static_cast<int>(bytes.size()));
  ASSERT_EQ(gzclose(gz), Z_OK);
}

void put_be32(Bytes& b, std::size_t at, std::uint32_t v) {
  b[at] = static_cast<std::uint8_t>(v >> 24);
  b[at + 1] = static_cast<std::uint8_t>(v >> 16);
  b[at + 2] = static_cast<std::uint8_t>(v >> 8);
  b[at + 3] = static_cast<std::uint8_t>(v);
}

// Runs `f`, which must throw InputError with a one-line message that names `file` and contains
// every one of `parts`.
void expect_input_error(const std::function<void()>& f, const fs::path& file, const std::vector<std::string>& parts) {
  try {
    f();
    ADD_FAILURE() << "no InputError for " << file;
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    EXPECT_NE(msg.find(file.string()), std::string::npos) << "message does not name the file: " << msg;
    for (const auto& p : parts) EXPECT_NE(msg.find(p), std::string::npos) << "missing \"" << p << "\" in: " << msg;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "wrong exception type: " << e.what();
  }
}

TEST_F(IdxFiles, ImagesRoundTripRaw) {
  const ImageSet in = sample_images(7, 5, 4, 1);
  const fs::path file = dir_ / "x-images-idx3-ubyte";
  write_idx_images(file, in);
  const Bytes raw = read_bytes(file);
  ASSERT_EQ(raw.size(), 16u + 7 * 5 * 4);
  // The standard header: magic 0x00000803, then count, rows, cols, all big-endian.
  EXPECT_EQ(Bytes(raw.begin(), raw.begin() + 16), (Bytes{0, 0, 8, 3, 0, 0, 0, 7, 0, 0, 0, 5, 0, 0, 0, 4}));
  EXPECT_FALSE(fs::exists(dir_ / "x-images-idx3-ubyte.tmp"));

  const ImageSet out = read_idx_images(file);
  EXPECT_EQ(out.count, 7);
  EXPECT_EQ(out.rows, 5);
  EXPECT_EQ(out.cols, 4);
  EXPECT_EQ(out.pixels, in.pixels);
  EXPECT_EQ(out.image(3)[2], in.pixels[3 * 20 + 2]);
}

TEST_F(IdxFiles, LabelsRoundTripRaw) {
  const Bytes labels = {3, 1, 4, 1, 5, 9, 2, 6};
  const fs::path file = dir_ / "x-labels-idx1-ubyte";
  write_idx_labels(file, labels);
  const Bytes raw = read_bytes(file);
  EXPECT_EQ(Bytes(raw.begin(), raw.begin() + 8), (Bytes{0, 0, 8, 1, 0, 0, 0, 8}));
  EXPECT_EQ(read_idx_labels(file), labels);
}

TEST_F(IdxFiles, RoundTripGzipDetectedByContent) {
  const ImageSet images = sample_images(9, 28, 28, 2);
  const Bytes labels = {0, 1, 2, 3, 4, 5, 6, 7, 8};
  write_idx_images(dir_ / "raw-images", images);
  write_idx_labels(dir_ / "raw-labels", labels);
  write_gzip(dir_ / "a-images-idx3-ubyte.gz", read_bytes(dir_ / "raw-images"));
  write_gzip(dir_ / "a-labels-idx1-ubyte.gz", read_bytes(dir_ / "raw-labels"));
  // The same gzip content without the suffix: detection is by the 1f 8b magic, not the name.
  write_gzip(dir_ / "no-suffix", read_bytes(dir_ / "raw-images"));

  const ImageSet out = read_idx_images(dir_ / "a-images-idx3-ubyte.gz");
  EXPECT_EQ(out.count, 9);
  EXPECT_EQ(out.rows, 28);
  EXPECT_EQ(out.cols, 28);
  EXPECT_EQ(out.pixels, images.pixels);
  EXPECT_EQ(read_idx_labels(dir_ / "a-labels-idx1-ubyte.gz"), labels);
  EXPECT_EQ(read_idx_images(dir_ / "no-suffix").pixels, images.pixels);
}

TEST_F(IdxFiles, ConcatenatedGzipMembersReadAsOneFile) {
  // `cat a.gz b.gz` is a valid gzip file whose content is a's then b's, as gunzip reads it.
  const ImageSet images = sample_images(4, 3, 3, 3);
  write_idx_images(dir_ / "raw", images);
  const Bytes raw = read_bytes(dir_ / "raw");
  const Bytes first(raw.begin(), raw.begin() + 20), second(raw.begin() + 20, raw.end());
  write_gzip(dir_ / "a.gz", first);
  write_gzip(dir_ / "b.gz", second);
  Bytes joined = read_bytes(dir_ / "a.gz");
  const Bytes b = read_bytes(dir_ / "b.gz");
  joined.insert(joined.end(), b.begin(), b.end());
  write_bytes(dir_ / "joined.gz", joined);
  EXPECT_EQ(read_idx_images(dir_ / "joined.gz").pixels, images.pixels);
}

TEST_F(IdxFiles, WriterCreatesParentFoldersAndReplacesFiles) {
  const fs::path file = dir_ / "deep" / "er" / "labels";
  write_idx_labels(file, {1, 2, 3});
  write_idx_labels(file, {4, 5});
  EXPECT_EQ(read_idx_labels(file), (Bytes{4, 5}));
  EXPECT_FALSE(fs::exists(dir_ / "deep" / "er" / "labels.tmp"));
}

TEST_F(IdxFiles, WriterRefusesInconsistentSets) {
  ImageSet bad = sample_images(2, 3, 3, 4);
  bad.pixels.pop_back();
  EXPECT_THROW(write_idx_images(dir_ / "bad", bad), std::invalid_argument);
  EXPECT_THROW(write_idx_labels(dir_ / "bad", {}), std::invalid_argument);
  EXPECT_FALSE(fs::exists(dir_ / "bad"));
}

TEST_F(IdxFiles, MissingFile) {
  const fs::path file = dir_ / "nope-images-idx3-ubyte";
  expect_input_error([&] { read_idx_images(file); }, file, {"no such file"});
  expect_input_error([&] { read_idx_labels(file); }, file, {"no such file"});
}

TEST_F(IdxFiles, FolderInsteadOfFile) {
  expect_input_error([&] { read_idx_images(dir_); }, dir_, {"is a folder"});
}

TEST_F(IdxFiles, BadMagic) {
  write_idx_labels(dir_ / "labels", {1, 2, 3});
  expect_input_error([&] { read_idx_images(dir_ / "labels"); }, dir_ / "labels",
                     {"bad magic 0x00000801, expected 0x00000803 (idx3-ubyte images)"});
  write_idx_images(dir_ / "images", sample_images(2, 2, 2, 5));
  expect_input_error([&] { read_idx_labels(dir_ / "images"); }, dir_ / "images",
                     {"bad magic 0x00000803, expected 0x00000801 (idx1-ubyte labels)"});
  write_bytes(dir_ / "text", Bytes{'h', 'e', 'l', 'l', 'o', ' ', 'w', 'o', 'r', 'l', 'd', '!', '!', '!', '!', '!'});
  expect_input_error([&] { read_idx_images(dir_ / "text"); }, dir_ / "text", {"bad magic 0x68656c6c"});
}

TEST_F(IdxFiles, TruncatedHeader) {
  write_bytes(dir_ / "short", Bytes{0, 0, 8, 3, 0, 0, 0, 1, 0, 0});
  expect_input_error([&] { read_idx_images(dir_ / "short"); }, dir_ / "short", {"truncated header", "10 bytes"});
  write_bytes(dir_ / "empty", Bytes{});
  expect_input_error([&] { read_idx_labels(dir_ / "empty"); }, dir_ / "empty", {"truncated header", "0 bytes"});
}

TEST_F(IdxFiles, TruncatedData) {
  write_idx_images(dir_ / "images", sample_images(7, 5, 4, 6));
  Bytes b = read_bytes(dir_ / "images");
  b.pop_back();
  write_bytes(dir_ / "images", b);
  expect_input_error([&] { read_idx_images(dir_ / "images"); }, dir_ / "images",
                     {"truncated: header says 7 images of 5x4 = 140 bytes, file has 139"});

  write_idx_labels(dir_ / "labels", {1, 2, 3, 4});
  b = read_bytes(dir_ / "labels");
  b.resize(b.size() - 2);
  write_bytes(dir_ / "labels", b);
  expect_input_error([&] { read_idx_labels(dir_ / "labels"); }, dir_ / "labels",
                     {"truncated: header says 4 labels = 4 bytes, file has 2"});
}

TEST_F(IdxFiles, TrailingBytes) {
  write_idx_images(dir_ / "images", sample_images(2, 3, 3, 7));
  Bytes b = read_bytes(dir_ / "images");
  b.push_back(42);
  write_bytes(dir_ / "images", b);
  expect_input_error([&] { read_idx_images(dir_ / "images"); }, dir_ / "images",
                     {"trailing garbage", "18 bytes, file has 19"});
  write_idx_labels(dir_ / "labels", {1, 2});
  b = read_bytes(dir_ / "labels");
  b.insert(b.end(), {0, 0, 0});
  write_bytes(dir_ / "labels", b);
  expect_input_error([&] { read_idx_labels(dir_ / "labels"); }, dir_ / "labels", {"trailing garbage", "3 extra bytes"});
}

TEST_F(IdxFiles, ZeroAndAbsurdDimensions) {
  write_idx_images(dir_ / "images", sample_images(2, 3, 3, 8));
  const Bytes good = read_bytes(dir_ / "images");
  struct Case {
    std::size_t offset;
    std::uint32_t value;
    std::string expect;
  };
  const std::vector<Case> cases = {
      {8, 0, "bad dimensions 0x3: rows and columns must be 1..4096"},
      {12, 0, "bad dimensions 3x0"},
      {8, 4097, "bad dimensions 4097x3"},
      {12, 0xFFFFFFFFu, "bad dimensions 3x4294967295"},
      {4, 0, "header says 0 images"},
      {4, 0xFFFFFFFFu, "more than the 2 GiB limit"},
      {4, 1000, "truncated: header says 1000 images of 3x3 = 9000 bytes, file has 18"},
  };
  for (const Case& c : cases) {
    Bytes b = good;
    put_be32(b, c.offset, c.value);
    write_bytes(dir_ / "images", b);
    expect_input_error([&] { read_idx_images(dir_ / "images"); }, dir_ / "images", {c.expect});
  }
  // 4096 x 4096 images, 2^32 - 1 of them: the byte count overflows 32 bits; it must not wrap.
  Bytes huge = good;
  put_be32(huge, 4, 0xFFFFFFFFu);
  put_be32(huge, 8, 4096);
  put_be32(huge, 12, 4096);
  write_bytes(dir_ / "images", huge);
  expect_input_error(
      [&] { read_idx_images(dir_ / "images"); }, dir_ / "images",
      {"header says 4294967295 images of 4096x4096 = 72057594021150720 bytes, more than the 2 GiB limit"});

  write_bytes(dir_ / "labels", Bytes{0, 0, 8, 1, 0, 0, 0, 0});
  expect_input_error([&] { read_idx_labels(dir_ / "labels"); }, dir_ / "labels", {"header says 0 labels"});
  write_bytes(dir_ / "labels", Bytes{0, 0, 8, 1, 0xFF, 0xFF, 0xFF, 0xFF, 1});
  expect_input_error([&] { read_idx_labels(dir_ / "labels"); }, dir_ / "labels", {"more than the 2 GiB limit"});
}

TEST_F(IdxFiles, CorruptGzip) {
  write_idx_images(dir_ / "raw", sample_images(20, 28, 28, 9));
  write_gzip(dir_ / "good.gz", read_bytes(dir_ / "raw"));
  const Bytes gz = read_bytes(dir_ / "good.gz");

  // A damaged byte in the middle of the deflate data, and one in the CRC trailer.
  Bytes damaged = gz;
  damaged[gz.size() / 2] ^= 0x55;
  damaged[gz.size() / 2 + 1] ^= 0xAA;
  write_bytes(dir_ / "damaged.gz", damaged);
  expect_input_error([&] { read_idx_images(dir_ / "damaged.gz"); }, dir_ / "damaged.gz", {"corrupt gzip data"});
  Bytes bad_crc = gz;
  bad_crc[gz.size() - 6] ^= 0x01;
  write_bytes(dir_ / "crc.gz", bad_crc);
  expect_input_error([&] { read_idx_images(dir_ / "crc.gz"); }, dir_ / "crc.gz", {"corrupt gzip data"});

  // Cut short: the stream never ends.
  write_bytes(dir_ / "cut.gz", Bytes(gz.begin(), gz.begin() + static_cast<std::ptrdiff_t>(gz.size() / 3)));
  expect_input_error([&] { read_idx_images(dir_ / "cut.gz"); }, dir_ / "cut.gz", {"truncated gzip data"});
  write_bytes(dir_ / "magic-only.gz", Bytes{0x1f, 0x8b});
  expect_input_error([&] { read_idx_labels(dir_ / "magic-only.gz"); }, dir_ / "magic-only.gz", {"truncated gzip data"});

  // Junk after a complete gzip member.
  Bytes junk = gz;
  junk.insert(junk.end(), {'j', 'u', 'n', 'k'});
  write_bytes(dir_ / "junk.gz", junk);
  expect_input_error([&] { read_idx_images(dir_ / "junk.gz"); }, dir_ / "junk.gz",
                     {"4 bytes of trailing garbage after the gzip data"});
}

TEST_F(IdxFiles, GzipContentErrorsNameTheFile) {
  // The checks on the decompressed content are the same as on raw files.
  write_idx_images(dir_ / "raw", sample_images(3, 4, 4, 10));
  Bytes raw = read_bytes(dir_ / "raw");
  raw.resize(raw.size() - 5);
  write_gzip(dir_ / "short.gz", raw);
  expect_input_error([&] { read_idx_images(dir_ / "short.gz"); }, dir_ / "short.gz",
                     {"truncated: header says 3 images of 4x4 = 48 bytes, file has 43"});
}

TEST_F(IdxFiles, LoadSplitCountMismatchNamesBothFilesAndCounts) {
  write_idx_images(dir_ / "train-images-idx3-ubyte", sample_images(10, 2, 2, 11));
  write_idx_labels(dir_ / "train-labels-idx1-ubyte", Bytes(9, 1));
  write_idx_images(dir_ / "t10k-images-idx3-ubyte", sample_images(3, 2, 2, 12));
  write_idx_labels(dir_ / "t10k-labels-idx1-ubyte", Bytes(3, 1));
  const fs::path images = dir_ / "train-images-idx3-ubyte";
  expect_input_error([&] { load_split(dir_, Split::Train); }, images,
                     {"count mismatch", "has 10 images", (dir_ / "train-labels-idx1-ubyte").string(), "has 9 labels"});
  EXPECT_EQ(load_split(dir_, Split::Test).images.count, 3);
}

}  // namespace
}  // namespace scout::worlds
