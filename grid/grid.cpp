#include "grid/grid.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace scout::grid {

Cell FloorFrame::grid_pose(const Eigen::Vector2d& px) const {
  const int x = static_cast<int>(std::floor(px.x()));
  const int y = static_cast<int>(std::floor(px.y()));
  return {std::clamp(x, 0, width_px - 1), std::clamp(y, 0, height_px - 1)};
}

Window camera_window(const Cell& pose, int patch_px, const FloorFrame& frame) {
  const int half = patch_px / 2;
  Window w;
  w.x0 = std::max(pose.x() - half, 0);
  w.y0 = std::max(pose.y() - half, 0);
  w.x1 = std::min(pose.x() - half + patch_px, frame.width_px);
  w.y1 = std::min(pose.y() - half + patch_px, frame.height_px);
  // A window wholly off the floor (only possible for a pose off the floor) is empty, not negative.
  w.x1 = std::max(w.x1, w.x0);
  w.y1 = std::max(w.y1, w.y0);
  return w;
}

const char* to_string(Axis axis) {
  switch (axis) {
    case Axis::Horizontal:
      return "h";
    case Axis::Vertical:
      return "v";
    case Axis::None:
      break;
  }
  return "none";
}

Decision decide(const Cell& p, const Cell& g) {
  if (p == g) return Decision::AtGoal;
  if (p.x() == g.x()) return Decision::Vertical;
  if (p.y() == g.y()) return Decision::Horizontal;
  return Decision::Choose;
}

namespace {

void check_blocked_size(std::span<const std::uint8_t> blocked, const FloorFrame& frame, const char* who) {
  if (blocked.size() != static_cast<std::size_t>(frame.area_px()))
    throw std::invalid_argument(std::string(who) + ": blocked must hold one byte per floor cell");
}

// The monotone routes from `from` into the rectangle spanned by `from` and `to`, as a DP over that
// rectangle in the direction of travel: a cell is reached when it is free and the cell before it
// along x or along y is reached. Writes the rectangle's cells (row-major, |dx| + 1 wide) to `out`.
void reach_rectangle(std::span<const std::uint8_t> blocked, int width, const Cell& from, const Cell& to,
                     std::uint8_t* out) {
  const int sx = to.x() >= from.x() ? 1 : -1, sy = to.y() >= from.y() ? 1 : -1;
  const int w = std::abs(to.x() - from.x()) + 1, h = std::abs(to.y() - from.y()) + 1;
  for (int j = 0; j < h; ++j) {
    const std::uint8_t* row = blocked.data() + static_cast<std::size_t>(from.y() + sy * j) * width;
    std::uint8_t* r = out + static_cast<std::size_t>(j) * w;
    for (int i = 0; i < w; ++i) {
      if (i == 0 && j == 0) {
        r[0] = 1;
        continue;
      }
      const bool before = (i > 0 && r[i - 1] != 0) || (j > 0 && r[i - w] != 0);
      r[i] = before && row[from.x() + sx * i] == 0 ? 1 : 0;
    }
  }
}

}  // namespace

void monotone_reach(std::span<const std::uint8_t> blocked, const FloorFrame& frame, const Cell& from,
                    std::span<std::uint8_t> reach) {
  check_blocked_size(blocked, frame, "monotone_reach");
  if (reach.size() != blocked.size()) throw std::invalid_argument("monotone_reach: reach must match blocked");
  if (!frame.contains(from)) throw std::invalid_argument("monotone_reach: from is off the floor");
  const int width = frame.width_px;
  // Each quadrant is the rectangle from `from` to a floor corner; cells on the axes through
  // `from` belong to two quadrants and get the same value from both.
  std::vector<std::uint8_t> quadrant;
  for (const Cell& corner :
       {Cell(0, 0), Cell(width - 1, 0), Cell(0, frame.height_px - 1), Cell(width - 1, frame.height_px - 1)}) {
    const int w = std::abs(corner.x() - from.x()) + 1, h = std::abs(corner.y() - from.y()) + 1;
    const int sx = corner.x() >= from.x() ? 1 : -1, sy = corner.y() >= from.y() ? 1 : -1;
    quadrant.resize(static_cast<std::size_t>(w) * h);
    reach_rectangle(blocked, width, from, corner, quadrant.data());
    for (int j = 0; j < h; ++j)
      for (int i = 0; i < w; ++i)
        reach[static_cast<std::size_t>(from.y() + sy * j) * width + (from.x() + sx * i)] =
            quadrant[static_cast<std::size_t>(j) * w + i];
  }
}

bool monotone_route_free(std::span<const std::uint8_t> blocked, const FloorFrame& frame, const Cell& from,
                         const Cell& to, std::vector<std::uint8_t>& scratch) {
  check_blocked_size(blocked, frame, "monotone_route_free");
  if (!frame.contains(from) || !frame.contains(to))
    throw std::invalid_argument("monotone_route_free: a cell is off the floor");
  const int w = std::abs(to.x() - from.x()) + 1, h = std::abs(to.y() - from.y()) + 1;
  scratch.resize(static_cast<std::size_t>(w) * h);
  reach_rectangle(blocked, frame.width_px, from, to, scratch.data());
  return scratch.back() != 0;
}

Cell move_command(const Cell& p, const Cell& g, Axis axis, int step_px) {
  const auto toward = [step_px](int from, int to) {
    const int d = to - from;
    return d >= 0 ? std::min(d, step_px) : -std::min(-d, step_px);
  };
  switch (axis) {
    case Axis::Horizontal:
      return {toward(p.x(), g.x()), 0};
    case Axis::Vertical:
      return {0, toward(p.y(), g.y())};
    case Axis::None:
      break;
  }
  return {0, 0};
}

RevealMask::RevealMask(const FloorFrame& frame)
    : width_(frame.width_px), seen_(static_cast<std::size_t>(frame.area_px()), 0) {}

int RevealMask::reveal(const Window& window) {
  if (window.x0 >= window.x1 || window.y0 >= window.y1) return 0;
  bounds_ = bounds_.x0 == bounds_.x1 ? window
                                     : Window{std::min(bounds_.x0, window.x0), std::min(bounds_.y0, window.y0),
                                              std::max(bounds_.x1, window.x1), std::max(bounds_.y1, window.y1)};
  int fresh = 0;
  for (int y = window.y0; y < window.y1; ++y) {
    std::uint8_t* row = seen_.data() + static_cast<std::size_t>(y) * width_;
    for (int x = window.x0; x < window.x1; ++x) {
      fresh += row[x] == 0;
      row[x] = 1;
    }
  }
  count_ += fresh;
  return fresh;
}

void RevealMask::assign(std::span<const std::uint8_t> seen) {
  if (seen.size() != seen_.size())
    throw std::invalid_argument("RevealMask::assign: " + std::to_string(seen.size()) + " bytes for a floor of " +
                                std::to_string(seen_.size()) + " pixels");
  count_ = 0;
  for (std::size_t k = 0; k < seen.size(); ++k) {
    seen_[k] = seen[k] != 0 ? 1 : 0;
    count_ += seen_[k];
  }
  const int height = width_ > 0 ? static_cast<int>(seen_.size()) / width_ : 0;
  bounds_ = count_ > 0 ? Window{0, 0, width_, height} : Window{};
}

// Only the rows and columns anything was seen in: a run of a few dozen moves sees a small part of
// a large floor, and clearing all of it at every start was most of a reset's memory traffic.
void RevealMask::clear() {
  for (int y = bounds_.y0; y < bounds_.y1; ++y)
    std::fill_n(seen_.begin() + static_cast<std::ptrdiff_t>(y) * width_ + bounds_.x0, bounds_.x1 - bounds_.x0, 0);
  bounds_ = {};
  count_ = 0;
}

GridModel::GridModel(const FloorFrame& frame, int patch_px, const Cell& start)
    : frame_(frame), patch_px_(patch_px), pose_(start), revealed_(frame) {
  revealed_.reveal(camera_window(pose_, patch_px_, frame_));
}

void GridModel::move(const Cell& command) {
  const Cell target = pose_ + command;
  pose_ = {std::clamp(target.x(), 0, frame_.width_px - 1), std::clamp(target.y(), 0, frame_.height_px - 1)};
  revealed_.reveal(camera_window(pose_, patch_px_, frame_));
}

BlockGrid BlockGrid::over(const FloorFrame& frame, int scale) {
  if (scale < 1) throw std::invalid_argument("BlockGrid: scale must be at least 1, got " + std::to_string(scale));
  return {
      .columns = (frame.width_px + scale - 1) / scale, .rows = (frame.height_px + scale - 1) / scale, .scale = scale};
}

void expand_blocks(const BlockGrid& grid, const FloorFrame& frame, const std::uint8_t* blocks, std::uint8_t* pixels) {
  for (int y = 0; y < frame.height_px; ++y) {
    const std::uint8_t* block_row = blocks + static_cast<std::size_t>(y / grid.scale) * grid.columns;
    std::uint8_t* row = pixels + static_cast<std::size_t>(y) * frame.width_px;
    for (int x = 0; x < frame.width_px; ++x) row[x] = block_row[x / grid.scale];
  }
}

}  // namespace scout::grid
