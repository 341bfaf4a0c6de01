#pragma once
// Synthetic "corner" data sets for tests of training and data splits (torch-free): two classes of
// floors told apart only by one small block, written as IDX files.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "core/random.hpp"
#include "worlds/idx.hpp"

namespace scout::testing {

namespace fs = std::filesystem;

constexpr int kCornerSide = 12;
constexpr int kCornerBlock = 3;  // the class is the 3 x 3 block at the top-left corner

// Two classes of 12 x 12 floors that differ only in their top-left 3 x 3 block: black (class 0)
// or white (class 1). Every other pixel is noise in [64, 192), the same for both classes, so
// the class can only be read where the block is; a robot that never sees the corner can only
// guess. `flip` writes the other class's label (a folder whose labels lie).
struct CornerSet {
  scout::worlds::ImageSet images;
  std::vector<std::uint8_t> labels;
};

inline CornerSet corner_set(int count, std::uint64_t seed, bool flip = false) {
  CornerSet set;
  set.images.count = count;
  set.images.rows = set.images.cols = kCornerSide;
  set.images.pixels.resize(static_cast<std::size_t>(count) * kCornerSide * kCornerSide);
  set.labels.resize(count);
  scout::core::Rng rng(seed);
  for (int i = 0; i < count; ++i) {
    const int label = static_cast<int>(scout::core::uniform_below(rng, 2));
    std::uint8_t* img = set.images.pixels.data() + static_cast<std::size_t>(i) * kCornerSide * kCornerSide;
    for (int k = 0; k < kCornerSide * kCornerSide; ++k)
      img[k] = static_cast<std::uint8_t>(64 + scout::core::uniform_below(rng, 128));
    for (int y = 0; y < kCornerBlock; ++y)
      for (int x = 0; x < kCornerBlock; ++x) img[y * kCornerSide + x] = label == 1 ? 255 : 0;
    set.labels[i] = static_cast<std::uint8_t>(flip ? 1 - label : label);
  }
  return set;
}

inline void write_set(const fs::path& folder, const std::string& prefix, const CornerSet& set) {
  fs::create_directories(folder);
  scout::worlds::write_idx_images(folder / (prefix + "-images-idx3-ubyte"), set.images);
  scout::worlds::write_idx_labels(folder / (prefix + "-labels-idx1-ubyte"), set.labels);
}

}  // namespace scout::testing
