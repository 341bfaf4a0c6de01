// Floors: PNG files (folders, missing files, wrong formats, truncated and corrupt images, the
// camera's size limit, a huge header refused within a measured memory bound, pixels read back)
// and data set floors (errors named by the world file's floor.dataset line, labels outside
// 0..9). Every refusal is one line, and libpng / OpenCV print nothing to stderr on the way.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/core.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "tests/support/child_peak.hpp"
#include "tests/support/temp_dir.hpp"
#include "worlds/floors.hpp"
#include "worlds/idx.hpp"
#include "worlds/world.hpp"

namespace scout::worlds {
namespace {

namespace fs = std::filesystem;
using Bytes = std::vector<std::uint8_t>;

using scout::testing::TempDir;

void write_bytes(const fs::path& file, const Bytes& bytes) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  ASSERT_TRUE(out.good()) << file;
}

/// Everything written to fd 2 while it lives goes to a file; text() stops the capture.
class StderrCapture {
 public:
  explicit StderrCapture(const fs::path& file) : file_(file) {
    std::fflush(stderr);
    saved_ = ::dup(STDERR_FILENO);
    const int fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    EXPECT_GE(saved_, 0);
    EXPECT_GE(fd, 0);
    ::dup2(fd, STDERR_FILENO);
    ::close(fd);
  }
  ~StderrCapture() { stop(); }
  StderrCapture(const StderrCapture&) = delete;
  StderrCapture& operator=(const StderrCapture&) = delete;

  std::string text() {
    stop();
    std::ifstream in(file_, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }

 private:
  void stop() {
    if (saved_ < 0) return;
    std::fflush(stderr);
    ::dup2(saved_, STDERR_FILENO);
    ::close(saved_);
    saved_ = -1;
  }
  fs::path file_;
  int saved_ = -1;
};

/// A world file "w.yaml" in the temporary folder with `yaml` as its text (parsed in memory).
World world_in(const TempDir& dir, const std::string& yaml) { return parse_world(yaml, dir.path() / "w.yaml"); }

struct Refusal {
  std::string message;
  std::string stderr_text;  ///< what reached fd 2 during the call: must stay empty
};

/// load_floors' message for `world` (fails the test if it accepts it), and what reached stderr.
Refusal refusal_of(const TempDir& dir, const World& world, const fs::path& data_root = "/nonexistent") {
  Refusal out;
  StderrCapture capture(dir.path() / "stderr.txt");
  try {
    load_floors(world, data_root);
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    out.message = e.what();
  }
  out.stderr_text = capture.text();
  return out;
}

void expect_one_line_with_prefix(const Refusal& r, const std::string& prefix) {
  EXPECT_EQ(r.message.substr(0, prefix.size()), prefix) << "full message: " << r.message;
  EXPECT_EQ(r.message.find('\n'), std::string::npos) << r.message;
  EXPECT_EQ(r.message.find('\r'), std::string::npos) << r.message;
  EXPECT_EQ(r.stderr_text, "") << "written to stderr during load_floors";
}

/// A w x h grayscale image with distinct-looking pixels.
cv::Mat pattern(int w, int h) {
  cv::Mat img(h, w, CV_8UC1);
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) img.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>((r * 7 + c * 3) % 256);
  return img;
}

Bytes png_bytes(const cv::Mat& img) {
  Bytes out;
  EXPECT_TRUE(cv::imencode(".png", img, out));
  return out;
}

const std::string kPngWorld = "floor:\n  image: x.png\n";

std::string png_prefix(const TempDir& dir) { return (dir.path() / "w.yaml").string() + ":2: floor.image: "; }
std::string quoted_png(const TempDir& dir) { return "'" + (dir.path() / "x.png").string() + "'"; }

TEST(PngFloor, FolderNamedPngIsRefused) {
  TempDir dir;
  fs::create_directories(dir.path() / "x.png");
  const Refusal r = refusal_of(dir, world_in(dir, kPngWorld));
  expect_one_line_with_prefix(r, png_prefix(dir) + "expected");
  EXPECT_EQ(r.message, png_prefix(dir) + "expected a PNG file, got " + quoted_png(dir) + " (a folder)");
}

TEST(PngFloor, MissingPngIsRefused) {
  TempDir dir;
  const Refusal r = refusal_of(dir, world_in(dir, kPngWorld));
  expect_one_line_with_prefix(r, png_prefix(dir) + "expected");
  EXPECT_EQ(r.message, png_prefix(dir) + "expected a PNG file, got " + quoted_png(dir) + " (no such file)");
}

TEST(PngFloor, JpegBytesNamedPngAreRefusedBySignature) {
  TempDir dir;
  const std::string jpeg = "\xFF\xD8\xFF\xE0 junk that is not a PNG";
  write_bytes(dir.path() / "x.png", Bytes(jpeg.begin(), jpeg.end()));
  const Refusal r = refusal_of(dir, world_in(dir, kPngWorld));
  expect_one_line_with_prefix(r, png_prefix(dir) + "expected");
  EXPECT_EQ(r.message, png_prefix(dir) + "expected a PNG file, got " + quoted_png(dir) + " (not a PNG: bad signature)");

  // A real JPEG says the same, and so does an empty file (its own reason).
  Bytes real_jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", pattern(16, 16), real_jpeg));
  write_bytes(dir.path() / "x.png", real_jpeg);
  EXPECT_EQ(refusal_of(dir, world_in(dir, kPngWorld)).message,
            png_prefix(dir) + "expected a PNG file, got " + quoted_png(dir) + " (not a PNG: bad signature)");
  write_bytes(dir.path() / "x.png", {});
  const Refusal empty = refusal_of(dir, world_in(dir, kPngWorld));
  expect_one_line_with_prefix(empty, png_prefix(dir) + "expected a PNG file, got " + quoted_png(dir) + " (not a PNG");
}

TEST(PngFloor, TruncatedPngIsOneLineAndNothingReachesStderr) {
  TempDir dir;
  const Bytes full = png_bytes(pattern(64, 64));
  const std::string expected =
      png_prefix(dir) + "expected a readable PNG image, got " + quoted_png(dir) + " (corrupt or truncated)";
  const auto level = cv::utils::logging::getLogLevel();

  // Cut in half: libpng reports "Read Error" on stderr unless load_floors silences it.
  write_bytes(dir.path() / "x.png", Bytes(full.begin(), full.begin() + static_cast<std::ptrdiff_t>(full.size() / 2)));
  Refusal r = refusal_of(dir, world_in(dir, kPngWorld));
  expect_one_line_with_prefix(r, png_prefix(dir) + "expected");
  EXPECT_EQ(r.message, expected);

  // Only the signature and part of IHDR; then the whole header but no image data.
  write_bytes(dir.path() / "x.png", Bytes(full.begin(), full.begin() + 20));
  r = refusal_of(dir, world_in(dir, kPngWorld));
  expect_one_line_with_prefix(r, png_prefix(dir) + "expected");
  EXPECT_EQ(r.message, expected);
  write_bytes(dir.path() / "x.png", Bytes(full.begin(), full.begin() + 33));
  r = refusal_of(dir, world_in(dir, kPngWorld));
  expect_one_line_with_prefix(r, png_prefix(dir) + "expected");
  EXPECT_EQ(r.message, expected);

  // Full length, but the image data overwritten (its CRC no longer matches).
  Bytes corrupt = full;
  for (std::size_t i = 40; i < corrupt.size() - 12; ++i) corrupt[i] = static_cast<std::uint8_t>(corrupt[i] ^ 0x5a);
  write_bytes(dir.path() / "x.png", corrupt);
  r = refusal_of(dir, world_in(dir, kPngWorld));
  expect_one_line_with_prefix(r, png_prefix(dir) + "expected");
  EXPECT_EQ(r.message, expected);

  // stderr and OpenCV's log level are back as they were.
  EXPECT_EQ(cv::utils::logging::getLogLevel(), level);
  StderrCapture capture(dir.path() / "after.txt");
  std::fputs("still here\n", stderr);
  EXPECT_EQ(capture.text(), "still here\n");
}

TEST(PngFloor, LargerThanTheCameraLimitIsRefused) {
  TempDir dir;
  write_bytes(dir.path() / "x.png", png_bytes(pattern(600, 600)));
  Refusal r = refusal_of(dir, world_in(dir, kPngWorld));
  expect_one_line_with_prefix(r, png_prefix(dir) + "expected");
  EXPECT_EQ(r.message,
            png_prefix(dir) + "expected a floor of at most 512 x 512 pixels (the camera's limit), got 600 x 600");
  // One side is enough.
  write_bytes(dir.path() / "x.png", png_bytes(pattern(513, 40)));
  r = refusal_of(dir, world_in(dir, kPngWorld));
  EXPECT_EQ(r.message,
            png_prefix(dir) + "expected a floor of at most 512 x 512 pixels (the camera's limit), got 513 x 40");
  static_assert(kMaxFloorPx == 512);
}

// --- A huge header over a small file -------------------------------------------------------------

void put_be32(Bytes& out, std::uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out.push_back(static_cast<std::uint8_t>(v >> shift));
}

void put_chunk(Bytes& png, const char* type, const Bytes& data) {
  put_be32(png, static_cast<std::uint32_t>(data.size()));
  const std::size_t start = png.size();
  png.insert(png.end(), type, type + 4);
  png.insert(png.end(), data.begin(), data.end());
  uLong crc = crc32(0L, Z_NULL, 0);
  crc = crc32(crc, png.data() + start, static_cast<uInt>(png.size() - start));
  put_be32(png, static_cast<std::uint32_t>(crc));
}

// An 8-bit grayscale PNG of `side` x `side` black pixels, every row present, in a small file: the
// zlib stream is one block of `kRowsPerBlock` rows (filter byte 0, then zeros), compressed once
// and repeated (after a full flush deflate starts afresh, so each repeat is the same bytes), then
// an empty final block and the Adler-32 of the zeros ((1, N mod 65521): every byte adds a = 1 to
// b). A decoder that goes ahead reads it to the end and fills the whole image.
Bytes black_png(std::uint32_t side) {
  constexpr std::uint32_t kRowsPerBlock = 64;
  Bytes png = {0x89, 0x50, 0x4E, 0x47, 0x0D, 0x0A, 0x1A, 0x0A};
  Bytes ihdr;
  put_be32(ihdr, side);
  put_be32(ihdr, side);
  ihdr.insert(ihdr.end(), {8, 0, 0, 0, 0});  // 8 bits, grayscale, deflate, adaptive filters, no interlace
  put_chunk(png, "IHDR", ihdr);

  EXPECT_EQ(side % kRowsPerBlock, 0u);
  const Bytes rows(static_cast<std::size_t>(side + 1) * kRowsPerBlock, 0);
  z_stream zs{};
  EXPECT_EQ(deflateInit(&zs, Z_BEST_COMPRESSION), Z_OK);
  const auto compress_block = [&zs, &rows] {
    Bytes out(deflateBound(&zs, static_cast<uLong>(rows.size())) + 64);
    zs.next_in = const_cast<Bytef*>(rows.data());  // zlib's API is not const-correct
    zs.avail_in = static_cast<uInt>(rows.size());
    zs.next_out = out.data();
    zs.avail_out = static_cast<uInt>(out.size());
    EXPECT_EQ(deflate(&zs, Z_FULL_FLUSH), Z_OK);
    EXPECT_EQ(zs.avail_in, 0u);
    out.resize(out.size() - zs.avail_out);
    return out;
  };
  Bytes idat = compress_block();  // the zlib header, then the first block
  const Bytes block = compress_block();
  deflateEnd(&zs);
  for (std::uint32_t n = 1; n < side / kRowsPerBlock; ++n) idat.insert(idat.end(), block.begin(), block.end());
  idat.insert(idat.end(), {0x01, 0x00, 0x00, 0xFF, 0xFF});  // final stored block of 0 bytes
  const std::uint64_t zeros = std::uint64_t{side + 1} * side;
  put_be32(idat, static_cast<std::uint32_t>(((zeros % 65521) << 16) | 1));
  put_chunk(png, "IDAT", idat);
  put_chunk(png, "IEND", {});
  return png;
}

// "Refused before the decoder allocates", measured: the PNG declares 16384 x 16384 pixels (256 MiB
// of image) in a file of about 260 KiB, and load_floors runs in a forked child whose peak resident
// memory above its start must stay within kRefusalBoundKiB, a small fraction of the image. The
// same bytes handed to the decoder directly (OpenCV's imdecode, which load_floors calls) show that
// the bound means something: the decoder reads them as the whole black image and its peak is at
// least the image's size, so a loader that let the decoder start would fail the bound.
TEST(PngFloor, AHugeHeaderIsRefusedBeforeTheDecoderAllocatesTheImage) {
  constexpr std::uint32_t kSide = 16384;
  constexpr long kImageKiB = long{kSide} * kSide / 1024;
  // Reading a file of this size and refusing it: well under a MiB in a Release build.
  constexpr long kRefusalBoundKiB = 8 * 1024 * scout::testing::kSanitizerMemoryFactor;
  static_assert(2 * kRefusalBoundKiB <= kImageKiB, "the bound must be far below the decoded image");

  TempDir dir;
  const Bytes png = black_png(kSide);
  ASSERT_LT(png.size(), std::size_t{512} << 10);
  write_bytes(dir.path() / "x.png", png);
  const World world = world_in(dir, kPngWorld);

  const scout::testing::ChildOutcome refused =
      scout::testing::run_in_child_measuring_peak([&world] { load_floors(world, "/nonexistent"); });
  std::printf("[ measured ] %zu-byte PNG declaring %u x %u: load_floors' peak %ld KiB (bound %ld KiB)\n", png.size(),
              kSide, kSide, refused.peak_kib, kRefusalBoundKiB);
  EXPECT_EQ(refused.signal, 0);
  EXPECT_EQ(refused.status, 1) << refused.message;
  EXPECT_EQ(refused.message,
            png_prefix(dir) + "expected a floor of at most 512 x 512 pixels (the camera's limit), got 16384 x 16384");
  EXPECT_GE(refused.peak_kib, 0) << "the child's peak memory could not be measured";
  EXPECT_LE(refused.peak_kib, kRefusalBoundKiB);

  // The control: the decoder itself, on the same bytes, in a child of its own. (No OpenCV call
  // that might start its thread pool runs in the child: the pixels are checked by hand.)
  const scout::testing::ChildOutcome decoded = scout::testing::run_in_child_measuring_peak([&png] {
    const cv::Mat encoded(1, static_cast<int>(png.size()), CV_8UC1, const_cast<std::uint8_t*>(png.data()));
    const cv::Mat gray = cv::imdecode(encoded, cv::IMREAD_GRAYSCALE);
    if (gray.rows != static_cast<int>(kSide) || gray.cols != static_cast<int>(kSide) || gray.type() != CV_8UC1)
      throw std::runtime_error("decoded as " + std::to_string(gray.cols) + " x " + std::to_string(gray.rows));
    for (int r = 0; r < gray.rows; ++r) {
      const std::uint8_t* row = gray.ptr<std::uint8_t>(r);
      if (std::any_of(row, row + gray.cols, [](std::uint8_t p) { return p != 0; }))
        throw std::runtime_error("a pixel that is not black in row " + std::to_string(r));
    }
  });
  std::printf("[ measured ] the same PNG decoded by cv::imdecode: peak %ld KiB (the image: %ld KiB)\n",
              decoded.peak_kib, kImageKiB);
  EXPECT_EQ(decoded.signal, 0);
  EXPECT_EQ(decoded.status, 0) << decoded.message;
  EXPECT_GE(decoded.peak_kib, kImageKiB * 9 / 10);  // the whole image, give or take the kernel's approximate count
}

TEST(PngFloor, ValidPngIsReadAsGrayscale) {
  TempDir dir;
  const cv::Mat img = pattern(40, 30);
  write_bytes(dir.path() / "x.png", png_bytes(img));
  StderrCapture capture(dir.path() / "stderr.txt");
  const FloorSet set = load_floors(world_in(dir, kPngWorld), "/nonexistent");
  EXPECT_EQ(capture.text(), "");
  EXPECT_EQ(set.size(), 1);
  EXPECT_EQ(set.width_px(), 40);
  EXPECT_EQ(set.height_px(), 30);
  ASSERT_EQ(set.images.pixels.size(), 40u * 30u);
  for (int r = 0; r < 30; ++r)
    for (int c = 0; c < 40; ++c)
      ASSERT_EQ(set.images.pixels[static_cast<std::size_t>(r) * 40 + c], img.at<std::uint8_t>(r, c)) << r << "," << c;
  EXPECT_EQ(set.labels, std::vector<int>{-1});
  EXPECT_EQ(set.source, (dir.path() / "x.png").string());
  EXPECT_EQ(set.files, std::vector<fs::path>{dir.path() / "x.png"});
  EXPECT_FALSE(set.split.has_value());

  // The limit itself is fine; a colour PNG is read as gray.
  write_bytes(dir.path() / "x.png", png_bytes(pattern(512, 512)));
  EXPECT_EQ(load_floors(world_in(dir, kPngWorld), "/nonexistent").width_px(), 512);
  write_bytes(dir.path() / "x.png", png_bytes(cv::Mat(8, 9, CV_8UC3, cv::Scalar(100, 100, 100))));
  const FloorSet colour = load_floors(world_in(dir, kPngWorld), "/nonexistent");
  EXPECT_EQ(colour.width_px(), 9);
  EXPECT_EQ(colour.height_px(), 8);
  for (std::uint8_t p : colour.images.pixels) EXPECT_EQ(p, 100);
}

// PNG chunks carry a CRC-32 over type and data: a mutation that should reach libpng's decoder
// (rather than its CRC check) has it recomputed.
void fix_chunk_crcs(Bytes& png) {
  std::size_t at = 8;
  while (at + 12 <= png.size()) {
    const std::uint32_t length = (std::uint32_t{png[at]} << 24) | (std::uint32_t{png[at + 1]} << 16) |
                                 (std::uint32_t{png[at + 2]} << 8) | std::uint32_t{png[at + 3]};
    if (length > png.size() - at - 12) return;
    std::uint32_t crc = 0xffffffffu;  // CRC-32 (ISO 3309), as PNG specifies
    for (std::size_t i = at + 4; i < at + 8 + length; ++i) {
      crc ^= png[i];
      for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
    }
    crc ^= 0xffffffffu;
    for (int k = 0; k < 4; ++k) png[at + 8 + length + k] = static_cast<std::uint8_t>(crc >> (24 - 8 * k));
    at += 12 + length;
  }
}

// A seeded fuzz loop over PNG floors: random bytes behind a PNG signature, and valid floors with
// flipped bytes (CRCs kept or fixed), truncations, and headers declaring huge sizes. Each is
// refused in one line with nothing on stderr, or read with the size its header declares; none
// crashes. (That a huge header is refused before the decoder allocates its image is measured by
// AHugeHeaderIsRefusedBeforeTheDecoderAllocatesTheImage above.)
TEST(PngFloor, FuzzedFilesAreRefusedInOneLineOrRead) {
  TempDir dir;
  const World world = world_in(dir, kPngWorld);
  std::uint64_t state = 20261202;
  const auto next = [&state] {  // SplitMix64
    std::uint64_t z = (state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  };
  const Bytes valid = png_bytes(pattern(28, 28));
  int refused = 0, read = 0;
  for (int i = 0; i < 2000; ++i) {
    Bytes bytes = valid;
    switch (i % 5) {
      case 0:  // random bytes behind the signature
        bytes.resize(8 + next() % 512);
        for (std::size_t k = 8; k < bytes.size(); ++k) bytes[k] = static_cast<std::uint8_t>(next());
        break;
      case 1:  // flipped bytes, CRCs left as they were (the decoder's CRC check meets them)
        for (int k = 1 + next() % 4; k > 0; --k) bytes[8 + next() % (bytes.size() - 8)] ^= 1 + next() % 255;
        break;
      case 2:  // flipped bytes with the CRCs fixed (the decoder itself meets them)
        for (int k = 1 + next() % 4; k > 0; --k) bytes[8 + next() % (bytes.size() - 8)] ^= 1 + next() % 255;
        fix_chunk_crcs(bytes);
        break;
      case 3:  // truncated
        bytes.resize(8 + next() % (bytes.size() - 8));
        break;
      case 4: {  // a header declaring up to 2^31 - 1 pixels a side, with a valid CRC
        for (int k = 16; k < 24; ++k) bytes[k] = static_cast<std::uint8_t>(next());
        bytes[16] &= 0x7f;
        bytes[20] &= 0x7f;
        fix_chunk_crcs(bytes);
        break;
      }
    }
    write_bytes(dir.path() / "x.png", bytes);
    StderrCapture capture(dir.path() / "stderr.txt");
    try {
      const FloorSet set = load_floors(world, "/nonexistent");
      ASSERT_LE(set.width_px(), kMaxFloorPx);
      ASSERT_LE(set.height_px(), kMaxFloorPx);
      ASSERT_EQ(set.images.pixels.size(), static_cast<std::size_t>(set.width_px()) * set.height_px());
      ++read;
    } catch (const InputError& e) {
      const std::string message = e.what();
      ASSERT_EQ(message.rfind(png_prefix(dir), 0), 0u) << message;
      ASSERT_EQ(message.find('\n'), std::string::npos) << message;
      ++refused;
    }
    ASSERT_EQ(capture.text(), "") << "case " << i;
  }
  std::printf("[ measured ] 2000 fuzzed PNG floors: %d refused, %d read\n", refused, read);
  EXPECT_GT(refused, 1000);
  EXPECT_GT(read, 0);  // flips in pixel data behind a fixed CRC still decode
}

// An IDX folder: train and t10k pairs of `count` w x h images with labels `labels`.
void write_idx_folder(const fs::path& folder, int count, int w, int h, const Bytes& labels) {
  fs::create_directories(folder);
  ImageSet images;
  images.count = count;
  images.rows = h;
  images.cols = w;
  images.pixels.assign(static_cast<std::size_t>(count) * w * h, 128);
  for (const char* prefix : {"train", "t10k"}) {
    write_idx_images(folder / (std::string(prefix) + "-images-idx3-ubyte"), images);
    write_idx_labels(folder / (std::string(prefix) + "-labels-idx1-ubyte"), labels);
  }
}

std::string dataset_prefix(const TempDir& dir) { return (dir.path() / "w.yaml").string() + ":2: floor.dataset: "; }

TEST(DatasetFloor, MissingFolderIsNamedByTheWorldFileLine) {
  TempDir dir;
  const Refusal r = refusal_of(dir, world_in(dir, "floor:\n  dataset: nowhere\n  split: test\n"));
  expect_one_line_with_prefix(r, dataset_prefix(dir));
  // Then the data set's own message, naming the folder.
  EXPECT_EQ(
      r.message.substr(dataset_prefix(dir).size()).rfind((dir.path() / "nowhere").string() + ": no such folder", 0), 0u)
      << r.message;

  // The default "mnist" (no floor section): the field has no line, the file is still named.
  const Refusal mnist = refusal_of(dir, world_in(dir, "camera:\n  patch_px: 4\n"), dir.path() / "no-data");
  expect_one_line_with_prefix(mnist, (dir.path() / "w.yaml").string() + ": floor.dataset: ");
  // ... and it says how to install MNIST into that data folder.
  EXPECT_NE(
      mnist.message.find("(run `scout data --data " + (dir.path() / "no-data").string() + "` to install MNIST there)"),
      std::string::npos)
      << mnist.message;
  // A folder of the user's own gets no such advice, even one named mnist.
  const Refusal own = refusal_of(dir, world_in(dir, "floor:\n  dataset: own/mnist\n"));
  EXPECT_EQ(own.message.find("scout data"), std::string::npos) << own.message;
  // With a floor section but no dataset key, the section's line.
  const Refusal section =
      refusal_of(dir, world_in(dir, "camera:\n  patch_px: 4\nfloor:\n  split: test\n"), dir.path() / "no-data");
  expect_one_line_with_prefix(section, (dir.path() / "w.yaml").string() + ":3: floor.dataset: ");
}

TEST(DatasetFloor, LabelsBeyondNineAreRefused) {
  TempDir dir;
  Bytes labels = {0, 1, 2, 3, 4, 11, 6, 7};
  write_idx_folder(dir.path() / "idx", 8, 28, 28, labels);
  const Refusal r = refusal_of(dir, world_in(dir, "floor:\n  dataset: idx\n  split: test\n"));
  expect_one_line_with_prefix(r, dataset_prefix(dir));
  EXPECT_EQ(r.message, dataset_prefix(dir) + (dir.path() / "idx" / "t10k-labels-idx1-ubyte").string() +
                           ": label 11 at index 5 is not a class 0..9");

  labels[5] = 9;
  write_idx_folder(dir.path() / "idx", 8, 28, 28, labels);
  const FloorSet set = load_floors(world_in(dir, "floor:\n  dataset: idx\n  split: test\n"), "/nonexistent");
  EXPECT_EQ(set.size(), 8);
  EXPECT_EQ(set.labels[5], 9);
}

TEST(DatasetFloor, LargerThanTheCameraLimitIsRefused) {
  TempDir dir;
  write_idx_folder(dir.path() / "big", 1, 600, 520, {3});
  const Refusal r = refusal_of(dir, world_in(dir, "floor:\n  dataset: big\n  split: test\n"));
  expect_one_line_with_prefix(r, dataset_prefix(dir));
  EXPECT_EQ(r.message,
            dataset_prefix(dir) + "expected a floor of at most 512 x 512 pixels (the camera's limit), got 600 x 520");
}

}  // namespace
}  // namespace scout::worlds
