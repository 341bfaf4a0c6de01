// Trajectory pictures: the floor enlarged, the unseen part shaded, the path, the camera window
// and the goal window, and optionally the classifier's bars. Drawn with OpenCV, in BGR.
#include "render/snapshot.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>
#include <system_error>

namespace scout::render {
namespace {

// Colours, BGR.
const cv::Scalar kRobotColour(255, 0, 0);   // blue: the camera window
const cv::Scalar kGoalColour(0, 200, 0);    // green: the goal window
const cv::Scalar kPathColour(0, 140, 255);  // orange: the path and its poses
const cv::Scalar kPanelBackground(32, 32, 32);
const cv::Scalar kBarColour(150, 150, 150);
const cv::Scalar kBestBarColour(0, 140, 255);  // the argmax, in the path's orange
const cv::Scalar kTextColour(230, 230, 230);

constexpr int kMaxScale = 64;
constexpr int kMaxSidePx = kMaxPictureSidePx;

// Unseen pixels are one flat blue-grey: the picture shows what the robot knows and nothing
// more. Blue exceeds red, so an unseen pixel never looks like a seen (gray) one, black included.
cv::Vec3b unseen_colour(std::uint8_t /*gray*/) { return {70, 52, 45}; }

// Draws the outline of a floor window (columns x - floor(m/2) .. + m - 1, same rows), clipped to
// the floor, as bands `thickness` output pixels wide lying inside the window, so that the
// outline covers exactly the window's border pixels and nothing outside.
void draw_window(cv::Mat& image, const Snapshot& snapshot, PixelPose centre, int thickness, const cv::Scalar& colour) {
  const long long half = snapshot.patch_px / 2;
  const long long x0 = std::max<long long>(0, centre.x - half);
  const long long y0 = std::max<long long>(0, centre.y - half);
  const long long x1 = std::min<long long>(snapshot.width_px - 1, centre.x - half + snapshot.patch_px - 1);
  const long long y1 = std::min<long long>(snapshot.height_px - 1, centre.y - half + snapshot.patch_px - 1);
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

// One horizontal bar per class, labelled with its index; the most probable class highlighted.
void draw_panel(cv::Mat& panel, std::span<const float> probabilities) {
  panel.setTo(kPanelBackground);
  const int classes = static_cast<int>(probabilities.size());
  const auto best = std::max_element(probabilities.begin(), probabilities.end());
  const int best_class = static_cast<int>(best - probabilities.begin());
  const double row_px = static_cast<double>(panel.rows) / classes;
  const int label_px = std::max(12, panel.cols / 6);
  const int bar_space_px = std::max(1, panel.cols - label_px - 8);
  const double font_scale = std::clamp(row_px / 40.0, 0.25, 0.6);
  for (int c = 0; c < classes; ++c) {
    const int top = static_cast<int>(std::lround(c * row_px));
    const int bottom = static_cast<int>(std::lround((c + 1) * row_px));
    const int margin = std::max(0, (bottom - top) / 6);
    float p = probabilities[static_cast<std::size_t>(c)];
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

}  // namespace

Picture draw_snapshot(const Snapshot& snapshot) {
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
  const long long map_width = static_cast<long long>(snapshot.width_px) * snapshot.scale;
  const long long map_height = static_cast<long long>(snapshot.height_px) * snapshot.scale;
  if (map_width > kMaxSidePx || map_height > kMaxSidePx) {
    throw std::invalid_argument("draw_snapshot: the picture would exceed " + std::to_string(kMaxSidePx) +
                                " px per side");
  }
  const int s = snapshot.scale;
  const int width = static_cast<int>(map_width);
  const int height = static_cast<int>(map_height);
  const bool has_panel = !snapshot.class_probabilities.empty();
  const int panel_width = has_panel ? std::max(160, height / 2) : 0;

  cv::Mat image(height, width + panel_width, CV_8UC3);
  cv::Mat map = image(cv::Rect(0, 0, width, height));

  // The floor, each pixel a scale x scale block; a null `revealed` means everything is seen.
  for (int y = 0; y < snapshot.height_px; ++y) {
    for (int x = 0; x < snapshot.width_px; ++x) {
      const std::size_t index = static_cast<std::size_t>(y) * snapshot.width_px + x;
      const std::uint8_t gray = snapshot.floor[index];
      const bool seen = snapshot.revealed == nullptr || snapshot.revealed[index] != 0;
      const cv::Vec3b colour = seen ? cv::Vec3b(gray, gray, gray) : unseen_colour(gray);
      map(cv::Rect(x * s, y * s, s, s)).setTo(colour);
    }
  }

  // Thin lines relative to a pixel block, but never thinner than one output pixel.
  const int line_px = std::max(1, s / 6);
  const int dot_radius_px = std::max(1, s / 5);
  for (std::size_t i = 1; i < snapshot.path.size(); ++i) {
    cv::line(map, pixel_centre(snapshot.path[i - 1], s), pixel_centre(snapshot.path[i], s), kPathColour, line_px,
             cv::LINE_AA);
  }
  for (const PixelPose& pose : snapshot.path) {
    cv::circle(map, pixel_centre(pose, s), dot_radius_px, kPathColour, cv::FILLED, cv::LINE_AA);
  }
  // The robot's window last, so that it stays visible when it meets the goal.
  const int outline_px = std::max(1, s / 5);
  if (snapshot.goal) draw_window(map, snapshot, *snapshot.goal, outline_px, kGoalColour);
  draw_window(map, snapshot, snapshot.robot, outline_px, kRobotColour);

  if (has_panel) {
    cv::Mat panel = image(cv::Rect(width, 0, panel_width, height));
    draw_panel(panel, snapshot.class_probabilities);
  }

  Picture picture;
  picture.width = image.cols;
  picture.height = image.rows;
  picture.bgr.assign(image.datastart, image.dataend);
  return picture;
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
