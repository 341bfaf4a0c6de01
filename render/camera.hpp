#pragma once
/// The downward camera: an offscreen OpenGL (OSMesa, llvmpipe) renderer that produces the m x m
/// floor patches seen by a batch of robots in one draw and one read-back (METHOD.md § Camera
/// window). No display and no X are needed. GL stays behind this header.
#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "render/limits.hpp"

namespace scout::render {

/// A robot's grid pose, in floor pixels (x = column, y = row).
struct PixelPose {
  int x = 0;
  int y = 0;
};

/// Renders the camera patches of up to `max_robots` robots, each over its own floor.
class PatchCamera {
 public:
  /// Creates the GL context and buffers. Floors are width x height 8-bit images; the camera
  /// sees patch_px x patch_px windows. Throws std::runtime_error if no GL context can be made.
  PatchCamera(int floor_width_px, int floor_height_px, int patch_px, int max_robots);
  ~PatchCamera();
  PatchCamera(const PatchCamera&) = delete;
  PatchCamera& operator=(const PatchCamera&) = delete;

  /// Uploads the floors: `floors` holds `count` images of width x height bytes, robot i sees
  /// image i. One upload call for the whole batch.
  void load_floors(std::span<const std::uint8_t> floors, int count);

  /// Renders the patches of robots 0 .. poses.size()-1 at their grid poses and reads them back
  /// into `patches` (poses.size() * patch_px * patch_px bytes, robot after robot, row-major).
  /// Pixels of a window that fall off the floor are 0. The result equals the CPU crop exactly.
  void capture(std::span<const PixelPose> poses, std::span<std::uint8_t> patches);

  int patch_px() const;
  int max_robots() const;
  /// The GL renderer and version strings, e.g. "llvmpipe (LLVM 15.0.6, 256 bits); 4.5 (Core Profile) Mesa 22.3.6".
  std::string gl_description() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The CPU reference: the same window cropped from an image in memory (off-floor pixels 0).
void crop_patch(const std::uint8_t* floor, int floor_width_px, int floor_height_px, int patch_px, PixelPose pose,
                std::uint8_t* patch_out);

}  // namespace scout::render
