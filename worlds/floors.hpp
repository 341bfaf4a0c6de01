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

/// The largest floor, in pixels per side: render::PatchCamera's limit (its constructor refuses
/// floors wider or taller than 512 px; kMaxFloorPx in render/camera.cpp, keep the two equal).
/// load_floors refuses larger floors with a world-file message instead.
inline constexpr int kMaxFloorPx = 512;

/// Candidate floor images, all the same size.
struct FloorSet {
  ImageSet images;                           ///< the floors, row 0 = top of the floor
  std::vector<int> labels;                   ///< class per image; -1 where unknown (a PNG)
  std::string source;                        ///< data set name or folder, or the PNG path
  std::optional<Split> split;                ///< the split, for a data set
  std::vector<std::filesystem::path> files;  ///< files read (for the manifest's hashes)

  int width_px() const { return images.cols; }
  int height_px() const { return images.rows; }
  int size() const { return images.count; }
};

/// Loads the world's floors: its data set's split (from `data_root` for "mnist"), or its PNG
/// read as grayscale (the file's bytes must start with the PNG signature; libpng and OpenCV
/// print nothing while it is decoded). Refuses floors larger than kMaxFloorPx on a side, checks
/// the floor-dependent fields (patch size, start, index) and throws InputError with one line
/// naming the world file's line and field ("w.yaml:3: floor.image: expected ...",
/// "w.yaml:2: floor.dataset: <the data set's own message>").
FloorSet load_floors(const World& world, const std::filesystem::path& data_root);

}  // namespace scout::worlds
