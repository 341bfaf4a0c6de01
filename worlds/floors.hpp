#pragma once
/// The floors a world drives over: the images of its data set split, or its one PNG image.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "worlds/floor_layout.hpp"
#include "worlds/idx.hpp"
#include "worlds/world.hpp"

namespace scout::worlds {

/// The largest floor, in pixels per side: render::PatchCamera's limit (its constructor refuses
/// floors wider or taller than 512 px; kMaxFloorPx in render/camera.cpp, keep the two equal).
/// load_floors refuses larger floors with a world-file message instead.
inline constexpr int kMaxFloorPx = 512;

/// A world's floors: the images of its data set split (or its PNG), and how a floor is made from
/// them (the world's floor layout; today's floors are the images themselves).
struct FloorSet {
  ImageSet images;                           ///< the images, row 0 = top
  std::vector<int> labels;                   ///< class per image; -1 where unknown (a PNG)
  std::string source;                        ///< data set name or folder, or the PNG path
  std::optional<Split> split;                ///< the split, for a data set
  std::vector<std::filesystem::path> files;  ///< files read (for the manifest's hashes)
  FloorComposer composer{0, 0};              ///< the world's layout over these images

  int width_px() const { return composer.width_px(); }
  int height_px() const { return composer.height_px(); }
  /// Floors to choose from: one per image (its digit; other digits and clutter come with it).
  int size() const { return images.count; }
  /// Floor `index` under `key` (a run's floor key) into `out` (width * height bytes); its label.
  int floor(int index, std::uint64_t key, std::span<std::uint8_t> out) const {
    return composer.compose(images, labels, index, key, out);
  }
  /// Its label alone.
  int label(int index, std::uint64_t key) const { return composer.label(labels, index, key); }
};

/// Loads the world's floors: its data set's split (from `data_root` for "mnist"), or its PNG
/// read as grayscale (the file's bytes must start with the PNG signature; libpng and OpenCV
/// print nothing while it is decoded). Refuses floors larger than kMaxFloorPx on a side, checks
/// the floor-dependent fields (patch size, start, index) and throws InputError with one line
/// naming the world file's line and field ("w.yaml:3: floor.image: expected ...",
/// "w.yaml:2: floor.dataset: <the data set's own message>").
FloorSet load_floors(const World& world, const std::filesystem::path& data_root);

}  // namespace scout::worlds
