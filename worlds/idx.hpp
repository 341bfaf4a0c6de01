#pragma once
/// IDX files (the MNIST format), raw or gzip-compressed, read and written.
#include <cstdint>
#include <filesystem>
#include <vector>

#include "core/error.hpp"

namespace scout::worlds {

/// A stack of 8-bit grayscale images, row-major, image after image.
struct ImageSet {
  static constexpr int channels = 1;  ///< grayscale: one byte per pixel
  int count = 0;                      ///< number of images
  int rows = 0;                       ///< image height, pixels
  int cols = 0;                       ///< image width, pixels
  std::vector<std::uint8_t> pixels;   ///< count * rows * cols bytes

  const std::uint8_t* image(int i) const { return pixels.data() + static_cast<std::size_t>(i) * rows * cols; }
};

/// Reads an idx3-ubyte image file (".gz" or raw, detected by content). Throws InputError naming
/// the file for a missing file, bad magic, bad dimensions or truncated data.
ImageSet read_idx_images(const std::filesystem::path& file);

/// Reads an idx1-ubyte label file (".gz" or raw). Throws InputError as read_idx_images.
std::vector<std::uint8_t> read_idx_labels(const std::filesystem::path& file);

/// Parses IDX bytes already in memory (gzip or raw); `origin` names them in errors.
ImageSet parse_idx_images(const std::vector<std::uint8_t>& bytes, const std::filesystem::path& origin);
std::vector<std::uint8_t> parse_idx_labels(const std::vector<std::uint8_t>& bytes, const std::filesystem::path& origin);

/// Writes raw (uncompressed) IDX files atomically (temporary file, then rename).
void write_idx_images(const std::filesystem::path& file, const ImageSet& images);
void write_idx_labels(const std::filesystem::path& file, const std::vector<std::uint8_t>& labels);

}  // namespace scout::worlds
