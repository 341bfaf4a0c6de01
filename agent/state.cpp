#include "agent/state.hpp"

#include <algorithm>
#include <cstddef>
#include <stdexcept>

namespace scout::agent {
namespace {

// Sets the window's pixels of one H x W plane to `value`, row by row.
void fill_window(const grid::Window& w, int width_px, float value, float* plane) {
  for (int y = w.y0; y < w.y1; ++y) {
    float* row = plane + static_cast<std::size_t>(y) * width_px;
    std::fill(row + w.x0, row + w.x1, value);
  }
}

}  // namespace

void write_revealed_image(const grid::FloorFrame& frame, const RobotView& view, float* dst) {
  const std::size_t n = static_cast<std::size_t>(frame.area_px());
  // Unseen bytes may be anything (the caller need not clear them), so they must not be read into y.
  for (std::size_t i = 0; i < n; ++i) dst[i] = view.seen[i] != 0 ? pixel_value(view.revealed[i]) : 0.0f;
}

void write_planner_input(const grid::FloorFrame& frame, int patch_px, const RobotView& view, float* dst, bool occupancy,
                         bool team, bool wide) {
  const std::size_t n = static_cast<std::size_t>(frame.area_px());
  float* y = dst;
  float* l = dst + n;
  float* h = dst + 2 * n;
  float* g = dst + 3 * n;

  write_revealed_image(frame, view, y);

  std::fill(l, l + n, 1.0f);
  fill_window(grid::camera_window(view.pose, patch_px, frame), frame.width_px, 0.0f, l);

  for (std::size_t i = 0; i < n; ++i) h[i] = view.seen[i] != 0 ? 0.0f : 1.0f;

  // The goal's window follows the camera's rule (same offset, same clipping): it is the patch the
  // robot would see standing on the goal.
  std::fill(g, g + n, 1.0f);
  if (view.goal != nullptr) fill_window(grid::camera_window(*view.goal, patch_px, frame), frame.width_px, 0.0f, g);

  if (occupancy) {
    float* o = dst + 4 * n;
    if (view.occupied == nullptr) {
      std::fill(o, o + n, 0.0f);
    } else {
      for (std::size_t i = 0; i < n; ++i) o[i] = view.occupied[i] != 0 ? 1.0f : 0.0f;
    }
  }
  if (team) {
    float* tp = dst + (occupancy ? 5 : 4) * n;
    float* tg = tp + n;
    std::fill(tp, tp + 2 * n, 1.0f);
    for (const grid::Cell& pose : view.teammate_poses)
      fill_window(grid::camera_window(pose, patch_px, frame), frame.width_px, 0.0f, tp);
    for (const grid::Cell& goal : view.teammate_goals)
      fill_window(grid::camera_window(goal, patch_px, frame), frame.width_px, 0.0f, tg);
  }
  if (!wide) return;
  float* yw = dst + (4 + (occupancy ? 1 : 0) + (team ? 2 : 0)) * n;
  float* hw = yw + n;
  if (view.wide_seen == nullptr) {
    std::fill(yw, yw + n, 0.0f);
    std::fill(hw, hw + n, 1.0f);
    return;
  }
  // Each block's two values, then its floor pixels (a block row's floor rows are alike).
  const grid::BlockGrid& blocks = view.wide_grid;
  if (blocks.columns * blocks.scale < frame.width_px || blocks.rows * blocks.scale < frame.height_px)
    throw std::invalid_argument("write_planner_input: the coarse map's wide_grid does not cover the floor");
  const int width = frame.width_px;
  for (int v = 0; v < blocks.rows; ++v) {
    const std::size_t first = static_cast<std::size_t>(v) * blocks.columns;
    float* yw_row = yw + static_cast<std::size_t>(v) * blocks.scale * width;
    float* hw_row = hw + static_cast<std::size_t>(v) * blocks.scale * width;
    for (int x = 0; x < width; ++x) {
      const std::size_t b = first + static_cast<std::size_t>(x / blocks.scale);
      const bool seen = view.wide_seen[b] != 0;
      yw_row[x] = seen ? pixel_value(view.wide_revealed[b]) : 0.0f;
      hw_row[x] = seen ? 0.0f : 1.0f;
    }
    const int rows = std::min(blocks.scale, frame.height_px - v * blocks.scale);
    for (int r = 1; r < rows; ++r) {
      std::copy_n(yw_row, width, yw_row + static_cast<std::size_t>(r) * width);
      std::copy_n(hw_row, width, hw_row + static_cast<std::size_t>(r) * width);
    }
  }
}

}  // namespace scout::agent
