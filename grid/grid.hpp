#pragma once
/// Frames, grid poses, camera windows, the action protocol and the exact grid model
/// (METHOD.md § Frames and coordinates, § One rollout). Pure pixel arithmetic, no physics:
/// the reference that the Box2D world is tested against.
#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

namespace scout::grid {

/// A floor pixel / grid pose: x = column, y = row (y down), in pixels.
using Cell = Eigen::Vector2i;

/// The floor frame: pixel units, origin at the image's top-left corner, y down; metres are the
/// same frame times pixel_size_m.
struct FloorFrame {
  int width_px = 28;          ///< floor width, pixels
  int height_px = 28;         ///< floor height, pixels
  double pixel_size_m = 0.1;  ///< metres per pixel

  /// Centre of a cell, pixels.
  Eigen::Vector2d cell_centre_px(const Cell& cell) const { return cell.cast<double>().array() + 0.5; }
  Eigen::Vector2d px_to_m(const Eigen::Vector2d& px) const { return px * pixel_size_m; }
  Eigen::Vector2d m_to_px(const Eigen::Vector2d& m) const { return m / pixel_size_m; }
  /// The grid pose of a continuous position (pixels): the cell its point is in, clamped to the floor.
  Cell grid_pose(const Eigen::Vector2d& px) const;
  bool contains(const Cell& cell) const {
    return cell.x() >= 0 && cell.y() >= 0 && cell.x() < width_px && cell.y() < height_px;
  }
  int area_px() const { return width_px * height_px; }
};

/// A pixel-aligned rectangle [x0, x1) x [y0, y1), pixels.
struct Window {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  int area() const { return (x1 - x0) * (y1 - y0); }
};

/// The m x m window the camera sees at grid pose `pose` (columns x - m/2 .. x - m/2 + m - 1,
/// same rows), clipped to the floor. For even m its centre is the corner at (x, y).
Window camera_window(const Cell& pose, int patch_px, const FloorFrame& frame);

/// The wider view's coarse grid over a floor (worlds' camera.wide_scale, METHOD.md's wider view):
/// blocks of scale x scale floor pixels laid from the floor's top-left corner, the last column and
/// row of blocks cut by the floor's edge. A coarse map holds one byte per block, row-major.
struct BlockGrid {
  int columns = 0;  ///< ceil(width / scale)
  int rows = 0;     ///< ceil(height / scale)
  int scale = 1;    ///< floor pixels per block, per side

  /// The grid over `frame` (scale >= 1).
  static BlockGrid over(const FloorFrame& frame, int scale);
  int area() const { return columns * rows; }
  /// The block that holds floor coordinate v (either axis; floor division, so negative v too).
  int block_of(int v) const { return v >= 0 ? v / scale : (v + 1) / scale - 1; }
};

/// A coarse map (grid.area() bytes) written out at floor resolution: every pixel of `frame` takes
/// its block's byte (frame.area_px() bytes out), for pictures and observations that are per pixel.
void expand_blocks(const BlockGrid& grid, const FloorFrame& frame, const std::uint8_t* blocks, std::uint8_t* pixels);

/// Which axis a move takes.
enum class Axis : std::uint8_t { None, Horizontal, Vertical };
const char* to_string(Axis axis);  ///< "none", "h", "v"

/// The action protocol's verdict at pose p with goal g, before any sampling.
enum class Decision : std::uint8_t {
  AtGoal,      ///< p = g: no move, nothing sampled
  Vertical,    ///< same column: vertical move
  Horizontal,  ///< same row: horizontal move
  Choose,      ///< both axes move toward g: the action layer samples (chi = 1)
};
Decision decide(const Cell& p, const Cell& g);

/// The move command toward g along `axis`: min(step_px, remaining distance on that axis), signed.
/// (0, 0) for Axis::None.
Cell move_command(const Cell& p, const Cell& g, Axis axis, int step_px);

/// Free routes among obstacles (METHOD.md § Obstacles, the route rule). A monotone route from a to
/// b is a staircase of one-pixel steps, each along x or y and each towards b, so that every cell
/// on it lies in the rectangle spanned by a and b: the routes the action protocol drives. `blocked`
/// holds one byte per floor cell (row-major, non-zero: the robot cannot stand there).
///
/// reach[c] = 1 for every cell c that a monotone route of free cells joins to `from` (`from`
/// itself counts as free). reach must hold frame.area_px() bytes. O(area).
void monotone_reach(std::span<const std::uint8_t> blocked, const FloorFrame& frame, const Cell& from,
                    std::span<std::uint8_t> reach);
/// Whether a monotone route of free cells joins `from` to `to` (`from` counts as free). O(area of
/// their rectangle); `scratch` is resized to it.
bool monotone_route_free(std::span<const std::uint8_t> blocked, const FloorFrame& frame, const Cell& from,
                         const Cell& to, std::vector<std::uint8_t>& scratch);

/// Pixels seen so far by one robot, and their count.
class RevealMask {
 public:
  explicit RevealMask(const FloorFrame& frame);
  /// Marks the window as seen; returns how many pixels were new.
  int reveal(const Window& window);
  void clear();
  /// Replaces what is seen with `seen` (one byte per floor pixel, row-major, non-zero = seen),
  /// e.g. from an observation. Throws std::invalid_argument for the wrong size.
  void assign(std::span<const std::uint8_t> seen);
  bool seen(int x, int y) const { return seen_[static_cast<std::size_t>(y) * width_ + x] != 0; }
  int count() const { return count_; }
  const std::vector<std::uint8_t>& data() const { return seen_; }  ///< row-major, 1 = seen
  /// The smallest window that holds every pixel seen since the last clear() (empty, x0 == x1, if
  /// none): clear() zeroes only it, and a caller that writes where it reveals can do the same.
  const Window& bounds() const { return bounds_; }

 private:
  int width_;
  std::vector<std::uint8_t> seen_;
  int count_ = 0;
  Window bounds_{};
};

/// The exact grid model of one robot: a move lands exactly on pose + command, clamped to the
/// floor as the walls would stop it; the camera reveals its window after every move.
class GridModel {
 public:
  GridModel(const FloorFrame& frame, int patch_px, const Cell& start);
  /// Applies a move command (pixels) and reveals the new window.
  void move(const Cell& command);
  const Cell& pose() const { return pose_; }
  const RevealMask& revealed() const { return revealed_; }

 private:
  FloorFrame frame_;
  int patch_px_;
  Cell pose_;
  RevealMask revealed_;
};

}  // namespace scout::grid
