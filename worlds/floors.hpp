#pragma once
/// The floors a world drives over: the images of its data set split, or its one PNG image.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "worlds/idx.hpp"
#include "worlds/world.hpp"

namespace scout::worlds {

/// Candidate floor images, all the same size.
struct FloorSet {
  ImageSet images;                             ///< the floors, row 0 = top of the floor
  std::vector<int> labels;                     ///< class per image; -1 where unknown (a PNG)
  std::string source;                          ///< data set name or folder, or the PNG path
  std::optional<Split> split;                  ///< the split, for a data set
  std::vector<std::filesystem::path> files;    ///< files read (for the manifest's hashes)

  int width_px() const { return images.cols; }
  int height_px() const { return images.rows; }
  int size() const { return images.count; }
};

/// Loads the world's floors: its data set's split (from `data_root` for "mnist"), or its PNG
/// read as grayscale. Checks the floor-dependent fields (patch size, start, index) and throws
/// InputError naming the world file's line.
FloorSet load_floors(const World& world, const std::filesystem::path& data_root);

}  // namespace scout::worlds
