#pragma once
/// Trajectory images in the paper's style, drawn and written with OpenCV.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "render/camera.hpp"

namespace scout::render {

/// The largest picture side draw_snapshot makes (floor side x scale), pixels.
inline constexpr int kMaxPictureSidePx = 16384;

/// Everything one snapshot shows.
struct Snapshot {
  const std::uint8_t* floor = nullptr;  ///< floor image, width * height bytes
  int width_px = 0;
  int height_px = 0;
  const std::uint8_t* revealed = nullptr;  ///< width * height, non-zero where seen so far
  /// Unseen pixels show a quarter of the floor's grey through their shade (floors larger than the
  /// digit, where the picture should show where the digits and the clutter lie); off: flat shade.
  bool faint_unseen_floor = false;
  int patch_px = 6;  ///< m: size of the robot's and the goal's squares
  /// The wider view (worlds with camera.wide_px): the coarse map (width * height, each floor
  /// pixel its block's grey where `wide_seen` is non-zero), shown in the pixels not seen at full
  /// resolution, and the robot's wider window outlined thinly, `wide` as the camera has it (px x
  /// scale floor pixels a side), placed as the camera places it. Null / px 0: none.
  const std::uint8_t* wide_revealed = nullptr;
  const std::uint8_t* wide_seen = nullptr;
  WideView wide{};
  PixelPose robot;                ///< current grid pose (blue square: the camera window)
  std::optional<PixelPose> goal;  ///< current goal (green square), if any
  std::vector<PixelPose> path;    ///< grid poses visited so far, in order (drawn as a line)
  /// Where the robot's centre really went (continuous floor pixels, e.g. every physics tick), in
  /// worlds where it differs from `path`: imperfect motion, pushes. Drawn as a thin cyan line
  /// under the path; empty: none.
  std::vector<FloorPoint> true_path;
  /// Floor pixels covered by obstacles (width * height, non-zero: an obstacle), drawn in brick
  /// red whether seen or not; null: none.
  const std::uint8_t* obstacles = nullptr;
  /// Floor pixels of slip zones (width * height, non-zero: on a zone), tinted ice blue whether
  /// seen or not; null: none.
  const std::uint8_t* slip = nullptr;
  std::span<const float> class_probabilities;  ///< optional prediction bars (empty: none)
  std::span<const float> goal_probabilities;   ///< optional goal distribution pi_g over the floor's pixels
                                               ///< (width*height, row-major); drawn as a heat map
  int scale = 10;                              ///< output pixels per floor pixel
  /// The robot's body between grid poses (animations): its centre in continuous floor pixels
  /// (pixel (x, y) spans [x, x + 1) x [y, y + 1)) and its radius. Drawn as a disc, and the camera
  /// window follows it instead of sitting on `robot`. Unset: the window at `robot`, no disc.
  struct Body {
    double x_px = 0, y_px = 0;
    double radius_px = 0;
  };
  std::optional<Body> body;
  /// With class_probabilities: draw the panel's labels but no bars yet (the classifier is asked
  /// only after the last move), so that every frame of a video has the same size.
  bool prediction_pending = false;
  /// The other robots of a team (docs/SCENARIOS.md § Several robots), each drawn like the first
  /// (its path, window, goal and disc) in a colour of its own (teammate_colour); `revealed` is
  /// the team's. Empty: one robot.
  struct Teammate {
    PixelPose robot;
    std::optional<PixelPose> goal;
    std::vector<PixelPose> path;
    std::vector<FloorPoint> true_path;
    std::optional<Body> body;
  };
  std::vector<Teammate> teammates;
};

/// The colour team robot `k` (1 .. 7) is drawn in, as 0xRRGGBB: its path, window, goal and disc
/// (robot 0 keeps the one-robot colours: an orange path and a blue window).
std::uint32_t teammate_colour(int k);

/// A BGR image as bytes (rows * cols * 3) with its size.
struct Picture {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> bgr;
};

/// Draws the snapshot: revealed pixels as the image, unseen pixels shaded, the path, the robot's
/// window as a blue square and the goal's as a green one, enlarged `scale` times.
///
/// With `goal_probabilities`, every floor pixel (seen or not) is first blended half and half with
/// the colour of OpenCV's COLORMAP_INFERNO at level round(255 * p / max p): per channel
/// (floor colour + colormap colour + 1) / 2. Negative and non-finite p count as 0; if no p is
/// positive every pixel takes level 0. The path and the windows are drawn on top, and a colour
/// scale (level 255 at the top, 0 at the bottom, labelled with max p where it fits) is appended
/// right of the floor, before the class panel. An empty span changes nothing.
/// Throws std::invalid_argument if `goal_probabilities` is neither empty nor width * height long,
/// or if the floor, sizes, scale or patch are invalid.
Picture draw_snapshot(const Snapshot& snapshot);

/// Writes a picture as PNG atomically (temporary file, then rename). Throws std::runtime_error.
void write_png(const std::filesystem::path& file, const Picture& picture);

}  // namespace scout::render
