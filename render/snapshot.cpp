// Trajectory pictures: the floor enlarged, the unseen part shaded, optionally the goal
// distribution as a heat map with its colour scale, the path, the camera window and the goal
// window, and optionally the classifier's bars. Drawn with OpenCV, in BGR.
#include "render/snapshot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <system_error>

#include "grid/grid.hpp"

namespace scout::render {
namespace {

// Colours, BGR.
const cv::Scalar kRobotColour(255, 0, 0);       // blue: the camera window
const cv::Scalar kRimColour(255, 160, 90);      // light blue: the robot's disc in videos
const cv::Scalar kGoalColour(0, 200, 0);        // green: the goal window
const cv::Scalar kPathColour(0, 140, 255);      // orange: the path and its poses
const cv::Scalar kTruePathColour(255, 220, 0);  // cyan: where the robot really went
const cv::Vec3b kObstacleColour(40, 50, 170);   // brick red: an obstacle
const cv::Vec3b kSlipTint(255, 200, 120);       // ice blue: a slip zone, blended over the floor
const cv::Scalar kPanelBackground(32, 32, 32);
const cv::Scalar kBarColour(150, 150, 150);
const cv::Scalar kBestBarColour(0, 140, 255);  // the argmax, in the path's orange
const cv::Scalar kTextColour(230, 230, 230);

// Team robots 1 .. 7, BGR: magenta, yellow, pink, red, violet, teal, white; distinct from the
// first robot's orange and blue, the goal's green and the true path's cyan.
const cv::Scalar kTeammateColours[] = {{220, 60, 230},  {0, 230, 255}, {190, 150, 255}, {40, 40, 230},
                                       {230, 120, 150}, {170, 170, 0}, {245, 245, 245}};

constexpr int kMaxScale = 64;
constexpr int kMaxSidePx = kMaxPictureSidePx;

// Unseen pixels are one flat blue-grey: the picture shows what the robot knows and nothing
// more. Blue exceeds red, so an unseen pixel never looks like a seen (gray) one, black included.
// With `faint`, a quarter of the floor's grey shows through (floors larger than the digit, where
// the reader wants to see where the digit was): blue still exceeds red by 25.
cv::Vec3b unseen_colour(std::uint8_t gray, bool faint) {
  const auto add = static_cast<std::uint8_t>(faint ? gray / 4 : 0);
  return {static_cast<std::uint8_t>(70 + add), static_cast<std::uint8_t>(52 + add),
          static_cast<std::uint8_t>(45 + add)};
}

// A pixel seen only by the wider view: its coarse grey at 60 % over a shade a little lighter than
// the unseen one (so that a coarse black is told from the unseen floor), blue exceeding red by 32:
// it never looks like a pixel seen at full resolution.
cv::Vec3b coarse_colour(std::uint8_t coarse) {
  const int add = coarse * 6 / 10;
  return {static_cast<std::uint8_t>(82 + add), static_cast<std::uint8_t>(62 + add),
          static_cast<std::uint8_t>(50 + add)};
}

// Draws the outline of a floor window (columns x - floor(side/2) .. + side - 1, same rows; side:
// the patch's m unless given), clipped to the floor, as bands `thickness` output pixels wide lying
// inside the window, so that the outline covers exactly the window's border pixels and nothing
// outside.
void draw_window(cv::Mat& image, const Snapshot& snapshot, PixelPose centre, int thickness, const cv::Scalar& colour,
                 int side = 0) {
  if (side == 0) side = snapshot.patch_px;
  const long long half = side / 2;
  const long long x0 = std::max<long long>(0, centre.x - half);
  const long long y0 = std::max<long long>(0, centre.y - half);
  const long long x1 = std::min<long long>(snapshot.width_px - 1, centre.x - half + side - 1);
  const long long y1 = std::min<long long>(snapshot.height_px - 1, centre.y - half + side - 1);
  if (x0 > x1 || y0 > y1) return;  // the window is wholly off the floor
  const int s = snapshot.scale;
  const int left = static_cast<int>(x0) * s;
  const int top = static_cast<int>(y0) * s;
  const int right = static_cast<int>(x1 + 1) * s;  // one past the last output column
  const int bottom = static_cast<int>(y1 + 1) * s;
  const int t = std::min({thickness, right - left, bottom - top});
  cv::rectangle(image, cv::Rect(left, top, right - left, t), colour, cv::FILLED);
  cv::rectangle(image, cv::Rect(left, bottom - t, right - left, t), colour, cv::FILLED);
  cv::rectangle(image, cv::Rect(left, top, t, bottom - top), colour, cv::FILLED);
  cv::rectangle(image, cv::Rect(right - t, top, t, bottom - top), colour, cv::FILLED);
}

cv::Point pixel_centre(PixelPose pose, int scale) { return {pose.x * scale + scale / 2, pose.y * scale + scale / 2}; }

// The outline of an m x m window centred on a continuous position (pixels), clipped to the
// floor, drawn with sub-pixel precision: the camera window of a robot between grid poses. At a
// cell centre (x + 0.5, y + 0.5) it covers exactly the cells draw_window does.
void draw_moving_window(cv::Mat& image, const Snapshot& snapshot, const Snapshot::Body& body, int thickness,
                        const cv::Scalar& colour) {
  const double s = snapshot.scale;
  const double left = std::max(0.0, body.x_px - 0.5 - snapshot.patch_px / 2);
  const double top = std::max(0.0, body.y_px - 0.5 - snapshot.patch_px / 2);
  const double right = std::min<double>(snapshot.width_px, body.x_px - 0.5 - snapshot.patch_px / 2 + snapshot.patch_px);
  const double bottom =
      std::min<double>(snapshot.height_px, body.y_px - 0.5 - snapshot.patch_px / 2 + snapshot.patch_px);
  if (left >= right || top >= bottom) return;
  // Inside the window, like draw_window's bands: the rectangle runs through the bands' middles.
  const double inset = thickness / 2.0;
  constexpr int kShift = 4;  // OpenCV fixed point: 1/16 output pixel
  auto fixed = [](double v) { return static_cast<int>(std::lround(v * (1 << kShift))); };
  cv::rectangle(image, cv::Point(fixed(left * s + inset), fixed(top * s + inset)),
                cv::Point(fixed(right * s - inset), fixed(bottom * s - inset)), colour, thickness, cv::LINE_AA, kShift);
}

// One horizontal bar per class, labelled with its index; the most probable class highlighted.
// `pending`: the labels only, nothing highlighted (no prediction yet).
void draw_panel(cv::Mat& panel, std::span<const float> probabilities, bool pending) {
  panel.setTo(kPanelBackground);
  const int classes = static_cast<int>(probabilities.size());
  const auto best = std::max_element(probabilities.begin(), probabilities.end());
  const int best_class = pending ? -1 : static_cast<int>(best - probabilities.begin());
  const double row_px = static_cast<double>(panel.rows) / classes;
  const int label_px = std::max(12, panel.cols / 6);
  const int bar_space_px = std::max(1, panel.cols - label_px - 8);
  const double font_scale = std::clamp(row_px / 40.0, 0.25, 0.6);
  for (int c = 0; c < classes; ++c) {
    const int top = static_cast<int>(std::lround(c * row_px));
    const int bottom = static_cast<int>(std::lround((c + 1) * row_px));
    const int margin = std::max(0, (bottom - top) / 6);
    float p = pending ? 0.0f : probabilities[static_cast<std::size_t>(c)];
    if (!std::isfinite(p)) p = 0.0f;
    p = std::clamp(p, 0.0f, 1.0f);
    const int length = static_cast<int>(std::lround(p * bar_space_px));
    const bool is_best = c == best_class;
    if (length > 0 && bottom - top - 2 * margin > 0) {
      cv::rectangle(panel, cv::Rect(label_px, top + margin, length, bottom - top - 2 * margin),
                    is_best ? kBestBarColour : kBarColour, cv::FILLED);
    }
    const int baseline_y = (top + bottom) / 2 + static_cast<int>(std::lround(font_scale * 10));
    cv::putText(panel, std::to_string(c), cv::Point(4, baseline_y), cv::FONT_HERSHEY_SIMPLEX, font_scale,
                is_best ? kBestBarColour : kTextColour, 1, cv::LINE_AA);
  }
}

// The heat map's colours, 1 x 256 BGR: INFERNO runs from near-black to pale yellow, so it
// neither dazzles the floor nor looks like the blue and green windows. Built once: OpenCV
// rebuilds its colormap table on every applyColorMap call.
const cv::Mat& heat_colours() {
  static const cv::Mat colours = [] {
    cv::Mat ramp(1, 256, CV_8UC1);
    for (int i = 0; i < 256; ++i) ramp.at<std::uint8_t>(0, i) = static_cast<std::uint8_t>(i);
    cv::Mat lut;
    cv::applyColorMap(ramp, lut, cv::COLORMAP_INFERNO);
    return lut;
  }();
  return colours;
}

// Negative and non-finite probabilities draw as 0 rather than throwing, like the class bars: a
// picture is a diagnostic, so it is drawn even for a broken distribution.
float heat_value(float p) { return std::isfinite(p) && p > 0.0f ? p : 0.0f; }

// Levels 0..255, p / max p: relative, because a distribution over hundreds of pixels has
// probabilities far too small to show on an absolute scale.
std::vector<std::uint8_t> heat_levels(std::span<const float> probabilities, float max_p) {
  std::vector<std::uint8_t> levels(probabilities.size(), 0);
  if (max_p <= 0.0f) return levels;
  for (std::size_t i = 0; i < probabilities.size(); ++i) {
    const double relative = static_cast<double>(heat_value(probabilities[i])) / max_p;
    levels[i] = static_cast<std::uint8_t>(std::clamp<long>(std::lround(255.0 * relative), 0, 255));
  }
  return levels;
}

// Half floor, half heat colour, rounded half up, so that both stay readable.
cv::Vec3b blend_heat(const cv::Vec3b& floor, const cv::Vec3b& heat) {
  cv::Vec3b out;
  for (int c = 0; c < 3; ++c) out[c] = static_cast<std::uint8_t>((floor[c] + heat[c] + 1) / 2);
  return out;
}

// The colour scale beside the heat map: a bar from level 255 (top) to 0 (bottom) and, where the
// picture is tall enough to read them, labels with max p and 0.
class HeatLegend {
 public:
  HeatLegend(int height, float max_p) : height_(height) {
    pad_ = std::max(2, height / 40);
    margin_ = std::min(std::max(2, height / 20), (height - 1) / 2);
    bar_width_ = std::max(4, height / 20);
    font_scale_ = std::clamp(height / 800.0, 0.3, 0.5);
    char text[32];
    std::snprintf(text, sizeof text, "%.2g", static_cast<double>(max_p));
    top_label_ = text;
    int baseline = 0;
    const cv::Size top = cv::getTextSize(top_label_, cv::FONT_HERSHEY_SIMPLEX, font_scale_, 1, &baseline);
    const cv::Size bottom = cv::getTextSize("0", cv::FONT_HERSHEY_SIMPLEX, font_scale_, 1, &baseline);
    text_height_ = std::max(top.height, bottom.height);
    // Two labels and a visible stretch of bar between them, or no labels at all.
    labelled_ = height - 2 * margin_ >= 4 * text_height_;
    width_ = pad_ + bar_width_ + pad_ + (labelled_ ? std::max(top.width, bottom.width) + pad_ : 0);
  }

  int width() const { return width_; }

  void draw(cv::Mat& strip, const cv::Mat& colours) const {
    strip.setTo(kPanelBackground);
    const int bar_height = height_ - 2 * margin_;
    for (int r = 0; r < bar_height; ++r) {
      const int level =
          bar_height == 1 ? 255 : static_cast<int>(std::lround(255.0 * (bar_height - 1 - r) / (bar_height - 1)));
      strip(cv::Rect(pad_, margin_ + r, bar_width_, 1)).setTo(colours.at<cv::Vec3b>(0, level));
    }
    if (!labelled_) return;
    const int text_x = pad_ + bar_width_ + pad_;
    cv::putText(strip, top_label_, cv::Point(text_x, margin_ + text_height_), cv::FONT_HERSHEY_SIMPLEX, font_scale_,
                kTextColour, 1, cv::LINE_AA);
    cv::putText(strip, "0", cv::Point(text_x, height_ - margin_), cv::FONT_HERSHEY_SIMPLEX, font_scale_, kTextColour, 1,
                cv::LINE_AA);
  }

 private:
  int height_ = 0;
  int pad_ = 0;
  int margin_ = 0;
  int bar_width_ = 0;
  int text_height_ = 0;
  int width_ = 0;
  double font_scale_ = 0.0;
  bool labelled_ = false;
  std::string top_label_;
};

}  // namespace

namespace {

// The true path (cyan, sub-pixel), then the path of poses (`colour`: lines and dots) over it.
void draw_paths(cv::Mat& map, int s, const std::vector<PixelPose>& path, const std::vector<FloorPoint>& true_path,
                const cv::Scalar& colour) {
  // Thin lines relative to a pixel block, but never thinner than one output pixel.
  const int line_px = std::max(1, s / 6);
  const int dot_radius_px = std::max(1, s / 5);
  // Fixed point, 1/16 output pixel: a sub-pixel path is drawn where it is, not on pixel centres.
  const auto exact_point = [s](const FloorPoint& p) {
    return cv::Point(static_cast<int>(std::lround(p.x * s * 16.0)), static_cast<int>(std::lround(p.y * s * 16.0)));
  };
  for (std::size_t i = 1; i < true_path.size(); ++i) {
    cv::line(map, exact_point(true_path[i - 1]), exact_point(true_path[i]), kTruePathColour, std::max(1, s / 10),
             cv::LINE_AA, 4);
  }
  for (std::size_t i = 1; i < path.size(); ++i) {
    cv::line(map, pixel_centre(path[i - 1], s), pixel_centre(path[i], s), colour, line_px, cv::LINE_AA);
  }
  for (const PixelPose& pose : path) {
    cv::circle(map, pixel_centre(pose, s), dot_radius_px, colour, cv::FILLED, cv::LINE_AA);
  }
}

// The floor, each pixel a scale x scale block: seen pixels in grey, unseen ones shaded, the heat
// map (`levels`, with `colours`) blended in, slip zones tinted and obstacles in brick red. A null
// `revealed` means everything is seen.
void draw_floor(cv::Mat& map, const Snapshot& snapshot, const cv::Mat& colours,
                const std::vector<std::uint8_t>& levels) {
  const int s = snapshot.scale;
  const bool has_heat = !levels.empty();
  for (int y = 0; y < snapshot.height_px; ++y) {
    for (int x = 0; x < snapshot.width_px; ++x) {
      const std::size_t index = static_cast<std::size_t>(y) * snapshot.width_px + x;
      const std::uint8_t gray = snapshot.floor[index];
      const bool seen = snapshot.revealed == nullptr || snapshot.revealed[index] != 0;
      const bool coarse = !seen && snapshot.wide_seen != nullptr && snapshot.wide_seen[index] != 0;
      cv::Vec3b colour = seen     ? cv::Vec3b(gray, gray, gray)
                         : coarse ? coarse_colour(snapshot.wide_revealed[index])
                                  : unseen_colour(gray, snapshot.faint_unseen_floor);
      if (has_heat) colour = blend_heat(colour, colours.at<cv::Vec3b>(0, levels[index]));
      if (snapshot.slip != nullptr && snapshot.slip[index] != 0)
        for (int c = 0; c < 3; ++c) colour[c] = static_cast<std::uint8_t>((2 * colour[c] + kSlipTint[c]) / 3);
      if (snapshot.obstacles != nullptr && snapshot.obstacles[index] != 0) colour = kObstacleColour;
      map(cv::Rect(x * s, y * s, s, s)).setTo(colour);
    }
  }
}

// One robot's camera window at its grid pose or, with a body (animations), the disc, light
// enough to show the floor under it, with a thin rim, and the window following it.
void draw_robot(cv::Mat& map, const Snapshot& snapshot, const PixelPose& robot,
                const std::optional<Snapshot::Body>& body, const cv::Scalar& window, const cv::Scalar& rim) {
  const int s = snapshot.scale;
  const int outline_px = std::max(1, s / 5);
  if (!body) {
    draw_window(map, snapshot, robot, outline_px, window);
    return;
  }
  constexpr int kShift = 4;  // OpenCV fixed point: 1/16 output pixel
  const cv::Point centre(static_cast<int>(std::lround(body->x_px * s * 16)),
                         static_cast<int>(std::lround(body->y_px * s * 16)));
  const int radius = static_cast<int>(std::lround(std::max(1.0, body->radius_px * s) * 16));
  cv::Mat overlay = map.clone();
  cv::circle(overlay, centre, radius, window, cv::FILLED, cv::LINE_AA, kShift);
  cv::addWeighted(overlay, 0.25, map, 0.75, 0.0, map);
  cv::circle(map, centre, radius, rim, std::max(1, s / 8), cv::LINE_AA, kShift);
  draw_moving_window(map, snapshot, *body, outline_px, window);
}

// Throws std::invalid_argument for a snapshot draw_snapshot cannot draw.
void check_snapshot(const Snapshot& snapshot) {
  if (snapshot.floor == nullptr) throw std::invalid_argument("draw_snapshot: floor is null");
  if (snapshot.width_px <= 0 || snapshot.height_px <= 0) {
    throw std::invalid_argument("draw_snapshot: floor size must be positive, got " + std::to_string(snapshot.width_px) +
                                " x " + std::to_string(snapshot.height_px));
  }
  if (snapshot.scale < 1 || snapshot.scale > kMaxScale) {
    throw std::invalid_argument("draw_snapshot: scale must be 1.." + std::to_string(kMaxScale) + ", got " +
                                std::to_string(snapshot.scale));
  }
  if (snapshot.patch_px < 1) {
    throw std::invalid_argument("draw_snapshot: patch_px must be positive, got " + std::to_string(snapshot.patch_px));
  }
  if (snapshot.wide.px < 0 || snapshot.wide.scale < 1 ||
      (snapshot.wide_revealed == nullptr) != (snapshot.wide_seen == nullptr)) {
    throw std::invalid_argument(
        "draw_snapshot: the wider view needs wide.px >= 0, wide.scale >= 1 and both its map and mask");
  }
  const long long map_width = static_cast<long long>(snapshot.width_px) * snapshot.scale;
  const long long map_height = static_cast<long long>(snapshot.height_px) * snapshot.scale;
  if (map_width > kMaxSidePx || map_height > kMaxSidePx) {
    throw std::invalid_argument("draw_snapshot: the picture would exceed " + std::to_string(kMaxSidePx) +
                                " px per side");
  }
  const std::size_t floor_pixels = static_cast<std::size_t>(snapshot.width_px) * snapshot.height_px;
  if (!snapshot.goal_probabilities.empty() && snapshot.goal_probabilities.size() != floor_pixels) {
    throw std::invalid_argument("draw_snapshot: goal_probabilities has " +
                                std::to_string(snapshot.goal_probabilities.size()) +
                                " entries, expected one per floor pixel (" + std::to_string(snapshot.width_px) + " x " +
                                std::to_string(snapshot.height_px) + " = " + std::to_string(floor_pixels) + ")");
  }
}

}  // namespace

Picture draw_snapshot(const Snapshot& snapshot) {
  check_snapshot(snapshot);
  const long long map_width = static_cast<long long>(snapshot.width_px) * snapshot.scale;
  const long long map_height = static_cast<long long>(snapshot.height_px) * snapshot.scale;
  const bool has_heat = !snapshot.goal_probabilities.empty();
  const int s = snapshot.scale;
  const int width = static_cast<int>(map_width);
  const int height = static_cast<int>(map_height);
  const bool has_panel = !snapshot.class_probabilities.empty();
  const int panel_width = has_panel ? std::max(160, height / 2) : 0;
  float max_heat = 0.0f;
  for (float p : snapshot.goal_probabilities) max_heat = std::max(max_heat, heat_value(p));
  std::optional<HeatLegend> legend;
  if (has_heat) legend.emplace(height, max_heat);
  const int legend_width = legend ? legend->width() : 0;

  cv::Mat image(height, width + legend_width + panel_width, CV_8UC3);
  cv::Mat map = image(cv::Rect(0, 0, width, height));

  const cv::Mat colours = has_heat ? heat_colours() : cv::Mat();
  const std::vector<std::uint8_t> levels = heat_levels(snapshot.goal_probabilities, max_heat);
  draw_floor(map, snapshot, colours, levels);
  // Every robot's path first, then the goals and the windows on top, so that a window stays
  // visible when it meets a goal or crosses a teammate's path.
  draw_paths(map, s, snapshot.path, snapshot.true_path, kPathColour);
  for (std::size_t k = 0; k < snapshot.teammates.size(); ++k)
    draw_paths(map, s, snapshot.teammates[k].path, snapshot.teammates[k].true_path, kTeammateColours[k % 7]);
  const int outline_px = std::max(1, s / 5);
  if (snapshot.goal) draw_window(map, snapshot, *snapshot.goal, outline_px, kGoalColour);
  for (std::size_t k = 0; k < snapshot.teammates.size(); ++k)
    if (snapshot.teammates[k].goal)
      draw_window(map, snapshot, *snapshot.teammates[k].goal, std::max(1, outline_px / 2), kTeammateColours[k % 7]);
  // The wider window, thin, under the robot's own: the blocks around the grid pose's block (the
  // camera takes it at the cell that holds the robot's centre), drawn as a window of its side
  // centred where that side's half puts it on those blocks.
  if (snapshot.wide.px > 0) {
    const PixelPose cell = snapshot.body ? PixelPose{static_cast<int>(std::floor(snapshot.body->x_px)),
                                                     static_cast<int>(std::floor(snapshot.body->y_px))}
                                         : snapshot.robot;
    const grid::BlockGrid blocks =
        grid::BlockGrid::over({.width_px = snapshot.width_px, .height_px = snapshot.height_px}, snapshot.wide.scale);
    const int side = snapshot.wide.px * snapshot.wide.scale;
    const auto centre_on_blocks = [&](int v) {
      return (blocks.block_of(v) - snapshot.wide.px / 2) * snapshot.wide.scale + side / 2;
    };
    draw_window(map, snapshot, {centre_on_blocks(cell.x), centre_on_blocks(cell.y)}, std::max(1, outline_px / 2),
                kRobotColour, side);
  }
  draw_robot(map, snapshot, snapshot.robot, snapshot.body, kRobotColour, kRimColour);
  for (std::size_t k = 0; k < snapshot.teammates.size(); ++k) {
    const Snapshot::Teammate& mate = snapshot.teammates[k];
    draw_robot(map, snapshot, mate.robot, mate.body, kTeammateColours[k % 7], kTeammateColours[k % 7]);
  }

  if (legend) {
    cv::Mat strip = image(cv::Rect(width, 0, legend_width, height));
    legend->draw(strip, colours);
  }
  if (has_panel) {
    cv::Mat panel = image(cv::Rect(width + legend_width, 0, panel_width, height));
    draw_panel(panel, snapshot.class_probabilities, snapshot.prediction_pending);
  }

  Picture picture;
  picture.width = image.cols;
  picture.height = image.rows;
  picture.bgr.assign(image.datastart, image.dataend);
  return picture;
}

std::uint32_t teammate_colour(int k) {
  if (k < 1 || k > 7) throw std::invalid_argument("teammate_colour: robot " + std::to_string(k) + " of 1 .. 7");
  const cv::Scalar& c = kTeammateColours[k - 1];
  return static_cast<std::uint32_t>(c[2]) << 16 | static_cast<std::uint32_t>(c[1]) << 8 |
         static_cast<std::uint32_t>(c[0]);
}

void write_png(const std::filesystem::path& file, const Picture& picture) {
  const std::string name = file.string();
  if (picture.width <= 0 || picture.height <= 0 ||
      picture.bgr.size() != static_cast<std::size_t>(picture.width) * picture.height * 3) {
    throw std::runtime_error("write_png: " + name + ": the picture is empty or its size (" +
                             std::to_string(picture.width) + " x " + std::to_string(picture.height) +
                             ") does not match its " + std::to_string(picture.bgr.size()) + " bytes");
  }
  // OpenCV takes a non-const pointer but only reads it.
  const cv::Mat image(picture.height, picture.width, CV_8UC3, const_cast<std::uint8_t*>(picture.bgr.data()));
  std::vector<std::uint8_t> encoded;
  if (!cv::imencode(".png", image, encoded)) {
    throw std::runtime_error("write_png: " + name + ": PNG encoding failed");
  }
  // Written beside the target and renamed, so a reader never sees a half-written PNG.
  std::filesystem::path temporary = file;
  temporary += ".tmp";
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error("write_png: cannot open " + temporary.string());
    out.write(reinterpret_cast<const char*>(encoded.data()), static_cast<std::streamsize>(encoded.size()));
    out.close();
    if (!out) {
      std::error_code ignored;
      std::filesystem::remove(temporary, ignored);
      throw std::runtime_error("write_png: cannot write " + temporary.string());
    }
  }
  std::error_code error;
  std::filesystem::rename(temporary, file, error);
  if (error) {
    std::error_code ignored;
    std::filesystem::remove(temporary, ignored);
    throw std::runtime_error("write_png: cannot rename " + temporary.string() + " to " + name + ": " + error.message());
  }
}

}  // namespace scout::render
