#pragma once
/// The downward camera: an offscreen OpenGL renderer (OSMesa or EGL; llvmpipe, or a GPU through
/// EGL) that produces the m x m floor patches seen by a batch of robots in one draw and one
/// read-back (METHOD.md § Camera window). No display and no X are needed. GL stays behind this
/// header.
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "render/limits.hpp"

namespace scout::core {
class WorkerPool;
}  // namespace scout::core

namespace scout::render {

/// A robot's grid pose, in floor pixels (x = column, y = row).
struct PixelPose {
  int x = 0;
  int y = 0;
};

/// A robot's centre in continuous floor pixels (pixel (x, y) spans [x, x+1) x [y, y+1); a cell's
/// centre is (x + 0.5, y + 0.5)).
struct FloorPoint {
  float x = 0.5f;
  float y = 0.5f;
};

/// The largest wider-view scale (floor pixels per wide pixel, per side).
inline constexpr int kMaxWideScale = 16;

/// The wider view (worlds' camera.wide_px, camera.wide_scale): a second, coarser window per
/// robot of px x px pixels, each the mean of a block of scale x scale floor pixels. The blocks are
/// those of the floor's block grid (grid::BlockGrid, laid from the floor's corner), and the window
/// is the px x px blocks around the block that holds the robot's cell: from that block less
/// floor(px / 2) on each axis. It covers (px * scale)^2 floor pixels at px^2 pixels' cost, the
/// robot within a block of its centre. px 0: none.
struct WideView {
  int px = 0;
  int scale = 1;
};

/// Which library makes the camera's GL context (render/README.md § Back ends). `automatic` takes
/// the back end named by the environment variable SCOUT_CAMERA_BACKEND (auto, osmesa or egl) and,
/// where that is unset or auto, OSMesa where this build has it and it works, else EGL.
enum class CameraBackend { automatic, osmesa, egl };

/// The environment variable `automatic` reads (the CLI's --camera-backend sets it, so that the
/// processes a run starts choose the same).
inline constexpr const char* kCameraBackendVariable = "SCOUT_CAMERA_BACKEND";

/// "auto", "osmesa" or "egl".
const char* camera_backend_name(CameraBackend backend);
/// The inverse of camera_backend_name; std::invalid_argument naming the three otherwise.
CameraBackend parse_camera_backend(std::string_view name);
/// The back ends this build has (its libraries were found when it was configured), in
/// `automatic`'s order of preference.
std::vector<CameraBackend> built_camera_backends();

/// Renders the camera patches of up to `max_robots` robots, each over its own floor.
class PatchCamera {
 public:
  /// Creates the GL context and buffers. Floors are width x height 8-bit images; the camera
  /// sees patch_px x patch_px windows, and with `wide` a wider view as well (px 0..64, scale
  /// 1..kMaxWideScale). `backend` makes the GL context (automatic: see CameraBackend). Throws
  /// std::runtime_error saying why if the back end cannot make a context, std::invalid_argument
  /// for bad sizes or a bad SCOUT_CAMERA_BACKEND.
  PatchCamera(int floor_width_px, int floor_height_px, int patch_px, int max_robots, WideView wide = {},
              CameraBackend backend = CameraBackend::automatic);
  ~PatchCamera();
  PatchCamera(const PatchCamera&) = delete;
  PatchCamera& operator=(const PatchCamera&) = delete;

  /// Uploads the floors: `floors` holds `count` images of width x height bytes, robot i sees
  /// image i. One upload call for the whole batch. With a wider view, each floor's block means are
  /// made on the CPU first, spread over `pool`'s threads where one is given (the caller's; the
  /// camera starts none).
  void load_floors(std::span<const std::uint8_t> floors, int count, core::WorkerPool* pool = nullptr);

  /// Replaces some of the loaded floors: robot slots[k] sees floors' image k from now on (width x
  /// height bytes each, in the order of `slots`), the others keep theirs. One upload call a floor,
  /// so a few robots starting again cost their own floors' bytes, not the batch's. Each slot must
  /// be one of the floors loaded, named once (std::invalid_argument otherwise).
  void replace_floors(std::span<const int> slots, std::span<const std::uint8_t> floors,
                      core::WorkerPool* pool = nullptr);

  /// Renders the patches of robots 0 .. poses.size()-1 at their grid poses and reads them back
  /// into `patches` (poses.size() * patch_px * patch_px bytes, robot after robot, row-major).
  /// Pixels of a window that fall off the floor are 0. The result equals the CPU crop exactly.
  /// With `wide_patches` (poses.size() * wide.px^2 bytes; a camera with a wider view), the wider
  /// view of each robot too, drawn before the same one read-back: equal to wide_patch exactly.
  void capture(std::span<const PixelPose> poses, std::span<std::uint8_t> patches,
               std::span<std::uint8_t> wide_patches = {});

  /// Renders the patches of robots 0 .. centres.size()-1 at their continuous centres, sub-pixel,
  /// into `patches` (the same layout as capture()). What filtering: patch pixel (column i, row j)
  /// is the floor sampled bilinearly over texel centres at (cx + i - floor(m/2), cy + j - floor(m/2)),
  /// with texels off the floor counting as 0, computed in float and rounded to nearest (halves up);
  /// see sample_patch_bilinear. At a cell centre (x + 0.5, y + 0.5) the result equals capture() at
  /// PixelPose{x, y} bit for bit. Centres may lie anywhere, on or off the floor, but must be finite
  /// (std::invalid_argument otherwise). One draw and one read-back for the batch, like capture().
  /// `wide_patches`: the wider view at the cell that holds each centre (its floor), as capture()
  /// takes it there: its pixels are 4 or more floor pixels wide, so a sub-pixel offset is left out.
  void capture_at(std::span<const FloorPoint> centres, std::span<std::uint8_t> patches,
                  std::span<std::uint8_t> wide_patches = {});

  int patch_px() const;
  WideView wide_view() const;
  int max_robots() const;
  /// The back end, the GL renderer and the version, e.g.
  /// "OSMesa: llvmpipe (LLVM 15.0.6, 256 bits); 4.5 (Core Profile) Mesa 22.3.6".
  std::string gl_description() const;
  /// The back end that made the context (never `automatic`).
  CameraBackend backend() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The CPU reference: the same window cropped from an image in memory (off-floor pixels 0).
void crop_patch(const std::uint8_t* floor, int floor_width_px, int floor_height_px, int patch_px, PixelPose pose,
                std::uint8_t* patch_out);

/// The CPU reference of the wider view at `cell`: pixel (i, j) is the mean of the floor pixels
/// [(u + i) s, (u + i + 1) s) x [(v + j) s, (v + j + 1) s) with u = floor(cell.x / s) - floor(px / 2)
/// (v the same for y), pixels off the floor 0, rounded to nearest (halves up). wide.px^2 bytes out.
void wide_patch(const std::uint8_t* floor, int floor_width_px, int floor_height_px, WideView wide, PixelPose cell,
                std::uint8_t* wide_out);

/// The CPU reference of PatchCamera::capture_at, in double precision: patch pixel (i, j) is
/// round-half-up of the bilinear blend of the four texels around the point
/// (centre.x + i - floor(m/2), centre.y + j - floor(m/2)), with texel (x, y)'s centre at
/// (x + 0.5, y + 0.5) and texels off the floor 0. The GL camera computes the same blend in float,
/// so it may differ from this by one grey level where the blend lies within float error of a half.
void sample_patch_bilinear(const std::uint8_t* floor, int floor_width_px, int floor_height_px, int patch_px,
                           FloorPoint centre, std::uint8_t* patch_out);

}  // namespace scout::render
