// Snapshot pictures: sizes, colours of seen and unseen pixels, the outlines, the panel, the goal
// heat map, and atomic PNG writing.
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "render/snapshot.hpp"

namespace scout::render {
namespace {

struct Bgr {
  int b = 0;
  int g = 0;
  int r = 0;
};

Bgr pixel(const Picture& picture, int x, int y) {
  const std::size_t at = (static_cast<std::size_t>(y) * picture.width + x) * 3;
  return {picture.bgr[at], picture.bgr[at + 1], picture.bgr[at + 2]};
}

bool is_gray(Bgr c, int value) { return c.b == value && c.g == value && c.r == value; }
bool is_blue(Bgr c) { return c.b >= 200 && c.g <= 80 && c.r <= 80; }
bool is_green(Bgr c) { return c.g >= 150 && c.b <= 80 && c.r <= 80; }
bool is_orange(Bgr c) { return c.r >= 200 && c.g >= 80 && c.g <= 200 && c.b <= 80; }

// A 12 x 10 floor whose pixel (x, y) has value 20 * x + y (never a colour an outline uses),
// left half (x < 6) seen, right half unseen.
struct Scene {
  static constexpr int kWidth = 12;
  static constexpr int kHeight = 10;
  std::vector<std::uint8_t> floor;
  std::vector<std::uint8_t> revealed;
  Scene() : floor(kWidth * kHeight), revealed(kWidth * kHeight) {
    for (int y = 0; y < kHeight; ++y) {
      for (int x = 0; x < kWidth; ++x) {
        floor[y * kWidth + x] = static_cast<std::uint8_t>(20 * x + y);
        revealed[y * kWidth + x] = x < 6 ? 1 : 0;
      }
    }
  }
  std::uint8_t value(int x, int y) const { return floor[y * kWidth + x]; }
  Snapshot snapshot() const {
    Snapshot s;
    s.floor = floor.data();
    s.revealed = revealed.data();
    s.width_px = kWidth;
    s.height_px = kHeight;
    s.patch_px = 3;
    s.scale = 10;
    s.robot = {3, 3};
    return s;
  }
};

TEST(DrawSnapshot, SizeIsTheFloorTimesTheScale) {
  const Scene scene;
  for (int scale : {1, 4, 10}) {
    Snapshot snapshot = scene.snapshot();
    snapshot.scale = scale;
    const Picture picture = draw_snapshot(snapshot);
    EXPECT_EQ(picture.width, Scene::kWidth * scale);
    EXPECT_EQ(picture.height, Scene::kHeight * scale);
    EXPECT_EQ(picture.bgr.size(), static_cast<std::size_t>(picture.width) * picture.height * 3);
  }
}

TEST(DrawSnapshot, SeenPixelsAreTheirGrayValueAndUnseenOnesAreShaded) {
  const Scene scene;
  Snapshot snapshot = scene.snapshot();
  snapshot.robot = {-50, -50};  // off the floor: no outline to step around
  const Picture picture = draw_snapshot(snapshot);
  const int s = snapshot.scale;
  for (int y = 0; y < Scene::kHeight; ++y) {
    for (int x = 0; x < Scene::kWidth; ++x) {
      const int value = scene.value(x, y);
      // Every output pixel of the block, corners and centre.
      for (int dy : {0, s / 2, s - 1}) {
        for (int dx : {0, s / 2, s - 1}) {
          const Bgr c = pixel(picture, x * s + dx, y * s + dy);
          if (x < 6) {
            EXPECT_TRUE(is_gray(c, value)) << "seen (" << x << ", " << y << ")";
          } else {
            EXPECT_FALSE(is_gray(c, value)) << "unseen (" << x << ", " << y << ")";
            EXPECT_GT(c.b, c.r) << "unseen (" << x << ", " << y << ") is tinted blue-grey";
            // ... and flat: nothing of the hidden image shows through.
            const Bgr corner = pixel(picture, Scene::kWidth * s - 1, 0);  // another unseen pixel
            EXPECT_TRUE(c.b == corner.b && c.g == corner.g && c.r == corner.r) << "unseen (" << x << ", " << y << ")";
          }
        }
      }
    }
  }
}

TEST(DrawSnapshot, UnseenBlackDiffersFromSeenBlack) {
  std::vector<std::uint8_t> floor(4, 0);
  std::vector<std::uint8_t> revealed = {1, 0, 1, 0};
  Snapshot snapshot;
  snapshot.floor = floor.data();
  snapshot.revealed = revealed.data();
  snapshot.width_px = 2;
  snapshot.height_px = 2;
  snapshot.robot = {-50, -50};
  snapshot.scale = 3;
  const Picture picture = draw_snapshot(snapshot);
  EXPECT_TRUE(is_gray(pixel(picture, 1, 1), 0));
  const Bgr unseen = pixel(picture, 4, 1);
  EXPECT_FALSE(is_gray(unseen, unseen.r));
  EXPECT_GE(unseen.b, 40) << "unseen black is visibly not black";
}

// Scenario marks: an obstacle is brick red whether seen or not; a slip zone tints the floor ice
// blue (a third of the tint, two thirds of what was there), seen or not; elsewhere nothing changes.
TEST(DrawSnapshot, ObstaclesAreBrickRedAndSlipZonesAreTintedIceBlue) {
  const Scene scene;
  Snapshot snapshot = scene.snapshot();
  snapshot.robot = {-50, -50};
  std::vector<std::uint8_t> obstacles(Scene::kWidth * Scene::kHeight, 0), slip(obstacles.size(), 0);
  obstacles[2 * Scene::kWidth + 1] = 1;                                     // (1, 2), seen
  obstacles[2 * Scene::kWidth + 9] = 1;                                     // (9, 2), unseen
  for (int x = 0; x < Scene::kWidth; ++x) slip[7 * Scene::kWidth + x] = 1;  // row 7
  const Picture plain = draw_snapshot(snapshot);
  snapshot.obstacles = obstacles.data();
  snapshot.slip = slip.data();
  const Picture marked = draw_snapshot(snapshot);
  const int s = snapshot.scale;
  for (const int x : {1, 9}) {
    const Bgr c = pixel(marked, x * s + s / 2, 2 * s + s / 2);
    EXPECT_TRUE(c.b == 40 && c.g == 50 && c.r == 170) << "obstacle at x = " << x;
  }
  for (const int x : {2, 10}) {  // a seen and an unseen pixel of the zone
    const Bgr before = pixel(plain, x * s + s / 2, 7 * s + s / 2);
    const Bgr after = pixel(marked, x * s + s / 2, 7 * s + s / 2);
    EXPECT_EQ(after.b, (2 * before.b + 255) / 3) << x;
    EXPECT_EQ(after.g, (2 * before.g + 200) / 3) << x;
    EXPECT_EQ(after.r, (2 * before.r + 120) / 3) << x;
  }
  const Bgr untouched = pixel(marked, 4 * s + s / 2, 5 * s + s / 2);
  const Bgr was = pixel(plain, 4 * s + s / 2, 5 * s + s / 2);
  EXPECT_TRUE(untouched.b == was.b && untouched.g == was.g && untouched.r == was.r);
}

TEST(DrawSnapshot, RobotWindowIsABlueOutlineAndGoalWindowAGreenOne) {
  const Scene scene;
  Snapshot snapshot = scene.snapshot();
  snapshot.robot = {3, 3};          // m = 3: columns and rows 2..4, output pixels 20..49
  snapshot.goal = PixelPose{9, 6};  // columns 8..10, rows 5..7: output x 80..109, y 50..79
  const Picture picture = draw_snapshot(snapshot);

  for (int along : {20, 35, 49}) {
    EXPECT_TRUE(is_blue(pixel(picture, 20, along))) << "left edge, y " << along;
    EXPECT_TRUE(is_blue(pixel(picture, 49, along))) << "right edge, y " << along;
    EXPECT_TRUE(is_blue(pixel(picture, along, 20))) << "top edge, x " << along;
    EXPECT_TRUE(is_blue(pixel(picture, along, 49))) << "bottom edge, x " << along;
  }
  // Just outside the window, and its inside, keep the floor.
  EXPECT_TRUE(is_gray(pixel(picture, 19, 35), scene.value(1, 3)));
  EXPECT_TRUE(is_gray(pixel(picture, 50, 35), scene.value(5, 3)));
  EXPECT_TRUE(is_gray(pixel(picture, 35, 19), scene.value(3, 1)));
  EXPECT_TRUE(is_gray(pixel(picture, 35, 50), scene.value(3, 5)));
  EXPECT_TRUE(is_gray(pixel(picture, 35, 35), scene.value(3, 3)));
  EXPECT_TRUE(is_gray(pixel(picture, 25, 25), scene.value(2, 2)));

  for (int along : {50, 65, 79}) {
    EXPECT_TRUE(is_green(pixel(picture, 80, along))) << "left edge, y " << along;
    EXPECT_TRUE(is_green(pixel(picture, 109, along))) << "right edge, y " << along;
  }
  for (int along : {80, 95, 109}) {
    EXPECT_TRUE(is_green(pixel(picture, along, 50))) << "top edge, x " << along;
    EXPECT_TRUE(is_green(pixel(picture, along, 79))) << "bottom edge, x " << along;
  }
  EXPECT_FALSE(is_green(pixel(picture, 79, 65)));
  EXPECT_FALSE(is_green(pixel(picture, 110, 65)));
  EXPECT_FALSE(is_green(pixel(picture, 95, 65)));
  EXPECT_FALSE(is_blue(pixel(picture, 95, 65)));
}

// A team (docs/SCENARIOS.md § Several robots): robot k > 0 is drawn in teammate_colour(k), its
// window, its path and its goal's thinner outline, beside robot 0 in the one-robot colours.
TEST(DrawSnapshot, TeammatesAreDrawnInTheirOwnColours) {
  const Scene scene;
  Snapshot snapshot = scene.snapshot();
  snapshot.robot = {3, 3};  // blue, output pixels 20..49
  Snapshot::Teammate& mate = snapshot.teammates.emplace_back();
  mate.robot = {9, 6};          // columns 8..10, rows 5..7: output x 80..109, y 50..79
  mate.goal = PixelPose{9, 2};  // rows 1..3: output y 10..39
  mate.path = {{9, 2}, {9, 6}};
  const Picture picture = draw_snapshot(snapshot);
  const std::uint32_t rgb = teammate_colour(1);
  const auto is_mate = [rgb](Bgr c) {
    return c.r == static_cast<int>(rgb >> 16) && c.g == static_cast<int>((rgb >> 8) & 0xFF) &&
           c.b == static_cast<int>(rgb & 0xFF);
  };
  for (int along : {50, 65, 79}) {
    EXPECT_TRUE(is_mate(pixel(picture, 80, along))) << "left edge, y " << along;
    EXPECT_TRUE(is_mate(pixel(picture, 109, along))) << "right edge, y " << along;
  }
  EXPECT_TRUE(is_mate(pixel(picture, 80, 25))) << "the goal's left edge";
  EXPECT_TRUE(is_mate(pixel(picture, 95, 25))) << "the path's dot at its first pose";
  EXPECT_TRUE(is_blue(pixel(picture, 20, 35))) << "robot 0 keeps its blue window";
  EXPECT_FALSE(is_mate(pixel(picture, 20, 35)));
  EXPECT_NE(teammate_colour(1), teammate_colour(2));
  EXPECT_THROW(teammate_colour(0), std::invalid_argument);
  EXPECT_THROW(teammate_colour(8), std::invalid_argument);
}

// Videos: a body between grid poses carries its camera window along at sub-pixel precision (at a
// cell centre it is exactly the grid window), and its disc tints the floor under it.
TEST(DrawSnapshot, ABodyBetweenCellsCarriesItsWindowAndItsDisc) {
  const Scene scene;
  Snapshot on_cell = scene.snapshot();
  on_cell.robot = {3, 3};
  const Picture grid_window = draw_snapshot(on_cell);
  Snapshot body = on_cell;
  body.body = Snapshot::Body{.x_px = 3.5, .y_px = 3.5, .radius_px = 0.5};
  const Picture at_centre = draw_snapshot(body);
  // The window's outline where draw_window puts it (output pixels 20..49).
  for (int along : {22, 35, 47}) {
    EXPECT_TRUE(is_blue(pixel(at_centre, 21, along))) << along;
    EXPECT_TRUE(is_blue(pixel(at_centre, 48, along))) << along;
    EXPECT_TRUE(is_blue(pixel(grid_window, 21, along))) << along;
  }
  EXPECT_TRUE(is_gray(pixel(at_centre, 18, 35), scene.value(1, 3)));
  // The disc's middle is tinted blue, not the floor's gray.
  const Bgr middle = pixel(at_centre, 35, 35);
  EXPECT_FALSE(is_gray(middle, scene.value(3, 3)));
  EXPECT_GT(middle.b, middle.r);
  // Half a pixel (5 output pixels) to the right, the window moves with the body.
  body.body->x_px = 4.0;
  const Picture moved = draw_snapshot(body);
  EXPECT_TRUE(is_blue(pixel(moved, 53, 35)));
  EXPECT_FALSE(is_blue(pixel(moved, 21, 35)));
}

TEST(DrawSnapshot, APendingPredictionDrawsThePanelWithoutBars) {
  const Scene scene;
  const std::array<float, 10> probabilities = {0.05f, 0.02f, 0.03f, 0.1f, 0.05f, 0.05f, 0.05f, 0.6f, 0.03f, 0.02f};
  Snapshot s = scene.snapshot();
  s.class_probabilities = probabilities;
  s.prediction_pending = true;
  const Picture pending = draw_snapshot(s);
  s.prediction_pending = false;
  const Picture shown = draw_snapshot(s);
  ASSERT_EQ(pending.width, shown.width);  // video frames keep one size
  ASSERT_EQ(pending.height, shown.height);
  auto count_bars = [](const Picture& p, int& bar_pixels, int& highlighted) {
    bar_pixels = highlighted = 0;
    for (int y = 0; y < p.height; ++y)
      for (int x = Scene::kWidth * 10; x < p.width; ++x) {
        const Bgr c = pixel(p, x, y);
        bar_pixels += (c.b == 150 && c.g == 150 && c.r == 150) ? 1 : 0;
        highlighted += (c.b == 0 && c.g == 140 && c.r == 255) ? 1 : 0;
      }
  };
  int bars = 0, best = 0;
  count_bars(pending, bars, best);
  EXPECT_EQ(bars, 0);
  EXPECT_EQ(best, 0);
  count_bars(shown, bars, best);  // the same colours are there once the prediction is
  EXPECT_GT(bars, 0);
  EXPECT_GT(best, 0);
}

TEST(DrawSnapshot, EvenWindowSitsLeftAndAboveThePose) {
  const Scene scene;
  Snapshot snapshot = scene.snapshot();
  snapshot.patch_px = 6;
  snapshot.robot = {5, 5};  // columns and rows 2..7: output 20..79
  const Picture picture = draw_snapshot(snapshot);
  EXPECT_TRUE(is_blue(pixel(picture, 20, 50)));
  EXPECT_TRUE(is_blue(pixel(picture, 79, 50)));
  EXPECT_TRUE(is_blue(pixel(picture, 50, 20)));
  EXPECT_TRUE(is_blue(pixel(picture, 50, 79)));
  EXPECT_FALSE(is_blue(pixel(picture, 80, 50)));
  EXPECT_FALSE(is_blue(pixel(picture, 50, 80)));
  EXPECT_FALSE(is_blue(pixel(picture, 19, 50)));
}

TEST(DrawSnapshot, WindowIsClippedToTheFloor) {
  const Scene scene;
  Snapshot snapshot = scene.snapshot();
  snapshot.patch_px = 6;
  snapshot.robot = {0, 9};  // columns -3..2 and rows 6..11, clipped to 0..2 and 6..9
  const Picture picture = draw_snapshot(snapshot);
  EXPECT_TRUE(is_blue(pixel(picture, 0, 80)));   // left edge at the floor's border
  EXPECT_TRUE(is_blue(pixel(picture, 29, 80)));  // right edge at column 2
  EXPECT_TRUE(is_blue(pixel(picture, 15, 60)));  // top edge at row 6
  EXPECT_TRUE(is_blue(pixel(picture, 15, 99)));  // bottom edge at the floor's border
  EXPECT_FALSE(is_blue(pixel(picture, 30, 80)));
  EXPECT_FALSE(is_blue(pixel(picture, 15, 59)));
}

TEST(DrawSnapshot, PathIsDrawnThroughPixelCentres) {
  const Scene scene;
  Snapshot snapshot = scene.snapshot();
  snapshot.robot = {-50, -50};
  snapshot.path = {{1, 1}, {1, 8}, {4, 8}};
  const Picture picture = draw_snapshot(snapshot);
  for (const PixelPose& pose : snapshot.path) {
    EXPECT_TRUE(is_orange(pixel(picture, pose.x * 10 + 5, pose.y * 10 + 5)))
        << "dot at (" << pose.x << ", " << pose.y << ")";
  }
  // Halfway along each segment, where no dot is.
  EXPECT_TRUE(is_orange(pixel(picture, 15, 45)));
  EXPECT_TRUE(is_orange(pixel(picture, 30, 85)));
  // Away from the path the floor is untouched.
  EXPECT_TRUE(is_gray(pixel(picture, 45, 45), scene.value(4, 4)));
  EXPECT_TRUE(is_gray(pixel(picture, 25, 45), scene.value(2, 4)));
}

TEST(DrawSnapshot, ClassPanelIsAppendedWithTheArgmaxHighlighted) {
  const Scene scene;
  const std::array<float, 10> probabilities = {0.05f, 0.02f, 0.03f, 0.1f, 0.05f, 0.05f, 0.05f, 0.6f, 0.03f, 0.02f};
  Snapshot plain = scene.snapshot();
  plain.goal = PixelPose{9, 6};
  Snapshot with_panel = plain;
  with_panel.class_probabilities = probabilities;
  const Picture without = draw_snapshot(plain);
  const Picture picture = draw_snapshot(with_panel);
  const int map_width = Scene::kWidth * 10;
  ASSERT_EQ(picture.height, Scene::kHeight * 10);
  ASSERT_GT(picture.width, map_width);

  // The map part is the same picture as without the panel.
  for (int y = 0; y < picture.height; ++y) {
    for (int x = 0; x < map_width; ++x) {
      const Bgr a = pixel(picture, x, y);
      const Bgr b = pixel(without, x, y);
      ASSERT_TRUE(a.b == b.b && a.g == b.g && a.r == b.r) << "(" << x << ", " << y << ")";
    }
  }

  // Per class band (rows c * H / 10 .. (c + 1) * H / 10): highlighted and plain bar pixels.
  std::array<int, 10> highlighted{};
  std::array<int, 10> plain_bar{};
  for (int y = 0; y < picture.height; ++y) {
    const int band = y * 10 / picture.height;
    for (int x = map_width; x < picture.width; ++x) {
      const Bgr c = pixel(picture, x, y);
      if (c.b == 0 && c.g == 140 && c.r == 255) ++highlighted[band];
      if (c.b == 150 && c.g == 150 && c.r == 150) ++plain_bar[band];
    }
  }
  for (int c = 0; c < 10; ++c) {
    if (c == 7) {
      EXPECT_GT(highlighted[c], 100) << "the argmax bar";
    } else {
      EXPECT_EQ(highlighted[c], 0) << "class " << c;
    }
  }
  EXPECT_GT(plain_bar[3], plain_bar[1] + 50) << "p = 0.1 gives a longer bar than p = 0.02";
  EXPECT_GT(highlighted[7], plain_bar[3] * 3) << "p = 0.6 gives a longer bar than p = 0.1";
}

// The heat map's documented colours: INFERNO at a level, blended half and half with the floor.
Bgr inferno(int level) {
  cv::Mat ramp(1, 256, CV_8UC1);
  for (int i = 0; i < 256; ++i) ramp.at<std::uint8_t>(0, i) = static_cast<std::uint8_t>(i);
  cv::Mat colours;
  cv::applyColorMap(ramp, colours, cv::COLORMAP_INFERNO);
  const cv::Vec3b c = colours.at<cv::Vec3b>(0, level);
  return {c[0], c[1], c[2]};
}
Bgr blended(Bgr floor, Bgr heat) {
  return {(floor.b + heat.b + 1) / 2, (floor.g + heat.g + 1) / 2, (floor.r + heat.r + 1) / 2};
}
bool same(Bgr a, Bgr b) { return a.b == b.b && a.g == b.g && a.r == b.r; }
std::string str(Bgr c) {
  return "(" + std::to_string(c.b) + ", " + std::to_string(c.g) + ", " + std::to_string(c.r) + ")";
}

// A peak on seen pixel (2, 7) and one half as high on unseen pixel (9, 1). Max p is 0.25, not 1,
// so the levels are relative: 255 at (2, 7), round(255 * 0.125 / 0.25) = 128 at (9, 1), 0 elsewhere.
std::vector<float> two_peaks() {
  std::vector<float> p(Scene::kWidth * Scene::kHeight, 0.0f);
  p[7 * Scene::kWidth + 2] = 0.25f;
  p[1 * Scene::kWidth + 9] = 0.125f;
  return p;
}

TEST(DrawSnapshot, GoalHeatMapBlendsEachFloorPixelWithItsInfernoColour) {
  const Scene scene;
  const std::vector<float> probabilities = two_peaks();
  Snapshot plain = scene.snapshot();
  plain.goal = PixelPose{9, 6};
  plain.path = {{1, 1}, {1, 8}};
  Snapshot with_heat = plain;
  with_heat.goal_probabilities = probabilities;
  const Picture without = draw_snapshot(plain);
  const Picture picture = draw_snapshot(with_heat);
  const int s = plain.scale;
  ASSERT_EQ(picture.height, without.height);
  ASSERT_GT(picture.width, without.width) << "the colour scale is appended";

  const Bgr top = inferno(255);
  const Bgr bottom = inferno(0);
  ASSERT_GT(top.r + top.g + top.b, bottom.r + bottom.g + bottom.b + 300) << "INFERNO runs from dark to bright";
  // Every output pixel of the hot block: the floor blended with the top colour, so changed.
  for (int dy = 0; dy < s; ++dy) {
    for (int dx = 0; dx < s; ++dx) {
      const int x = 2 * s + dx;
      const int y = 7 * s + dy;
      const Bgr floor = pixel(without, x, y);
      ASSERT_TRUE(is_gray(floor, scene.value(2, 7))) << "(" << x << ", " << y << ") is plain floor";
      const Bgr c = pixel(picture, x, y);
      EXPECT_TRUE(same(c, blended(floor, top))) << "(" << x << ", " << y << "): " << str(c);
      EXPECT_FALSE(same(c, floor)) << "(" << x << ", " << y << ")";
    }
  }
  // The unseen half-hot pixel: its blue-grey blended with level 128.
  for (int d : {0, s / 2, s - 1}) {
    const Bgr floor = pixel(without, 9 * s + d, 1 * s + d);
    EXPECT_TRUE(same(pixel(picture, 9 * s + d, 1 * s + d), blended(floor, inferno(128))));
  }
  // Far from both peaks, seen and unseen pixels alike take the colour of p = 0.
  for (const auto& [fx, fy] : std::vector<std::pair<int, int>>{{5, 0}, {0, 4}, {7, 9}, {11, 4}}) {
    for (int d : {0, s / 2, s - 1}) {
      const int x = fx * s + d;
      const int y = fy * s + d;
      const Bgr floor = pixel(without, x, y);
      const Bgr c = pixel(picture, x, y);
      EXPECT_TRUE(same(c, blended(floor, bottom))) << "(" << x << ", " << y << "): " << str(c);
    }
  }
  // The windows and the path are drawn on top, unblended.
  EXPECT_TRUE(same(pixel(picture, 20, 35), pixel(without, 20, 35)));
  EXPECT_TRUE(is_blue(pixel(picture, 20, 35)));
  EXPECT_TRUE(same(pixel(picture, 80, 65), pixel(without, 80, 65)));
  EXPECT_TRUE(is_green(pixel(picture, 80, 65)));
  // (The centres of the path's dots: its lines are anti-aliased, so partly floor.)
  for (const PixelPose& pose : plain.path) {
    const int x = pose.x * s + s / 2;
    const int y = pose.y * s + s / 2;
    EXPECT_TRUE(same(pixel(picture, x, y), pixel(without, x, y))) << "(" << x << ", " << y << ")";
    EXPECT_TRUE(is_orange(pixel(picture, x, y))) << "(" << x << ", " << y << ")";
  }
}

TEST(DrawSnapshot, GoalHeatMapLegendRunsFromTopColourToBottomColourBeforeTheClassPanel) {
  const Scene scene;
  const std::vector<float> probabilities = two_peaks();
  const std::array<float, 10> classes = {0.05f, 0.02f, 0.03f, 0.1f, 0.05f, 0.05f, 0.05f, 0.6f, 0.03f, 0.02f};
  Snapshot plain = scene.snapshot();
  plain.class_probabilities = classes;
  Snapshot with_heat = plain;
  with_heat.goal_probabilities = probabilities;
  const Picture without = draw_snapshot(plain);
  const Picture picture = draw_snapshot(with_heat);
  const int map_width = Scene::kWidth * plain.scale;
  const int panel_width = without.width - map_width;
  const int legend_width = picture.width - without.width;
  ASSERT_GT(legend_width, 0);

  // The class panel is the same, shifted right by the legend.
  for (int y = 0; y < picture.height; ++y) {
    for (int x = 0; x < panel_width; ++x) {
      ASSERT_TRUE(same(pixel(picture, map_width + legend_width + x, y), pixel(without, map_width + x, y)))
          << "panel (" << x << ", " << y << ")";
    }
  }
  // The legend shows the top colour in its upper part and the bottom colour in its lower part.
  const Bgr top = inferno(255);
  const Bgr bottom = inferno(0);
  int top_upper = 0, top_lower = 0, bottom_upper = 0, bottom_lower = 0;
  for (int y = 0; y < picture.height; ++y) {
    for (int x = map_width; x < map_width + legend_width; ++x) {
      const Bgr c = pixel(picture, x, y);
      const bool upper = y < picture.height / 2;
      if (same(c, top)) ++(upper ? top_upper : top_lower);
      if (same(c, bottom)) ++(upper ? bottom_upper : bottom_lower);
    }
  }
  EXPECT_GT(top_upper, 0);
  EXPECT_EQ(top_lower, 0);
  EXPECT_GT(bottom_lower, 0);
  EXPECT_EQ(bottom_upper, 0);
}

TEST(DrawSnapshot, GoalHeatMapOfTheWrongSizeThrows) {
  const Scene scene;
  for (const std::size_t size : {std::size_t{1}, std::size_t{Scene::kWidth * Scene::kHeight - 1},
                                 std::size_t{Scene::kWidth * Scene::kHeight + 1}}) {
    const std::vector<float> probabilities(size, 1.0f);
    Snapshot snapshot = scene.snapshot();
    snapshot.goal_probabilities = probabilities;
    try {
      draw_snapshot(snapshot);
      FAIL() << size << " entries did not throw";
    } catch (const std::invalid_argument& error) {
      EXPECT_NE(std::string(error.what()).find("goal_probabilities"), std::string::npos) << error.what();
    }
  }
}

TEST(DrawSnapshot, EmptyGoalHeatMapLeavesThePictureUnchanged) {
  const Scene scene;
  const std::array<float, 10> classes = {0.1f, 0.1f, 0.1f, 0.1f, 0.1f, 0.1f, 0.1f, 0.1f, 0.1f, 0.1f};
  const std::vector<float> none;
  for (const bool panel : {false, true}) {
    Snapshot plain = scene.snapshot();
    plain.goal = PixelPose{9, 6};
    plain.path = {{1, 1}, {3, 3}};
    if (panel) plain.class_probabilities = classes;
    Snapshot with_empty = plain;
    with_empty.goal_probabilities = none;
    const Picture a = draw_snapshot(plain);
    const Picture b = draw_snapshot(with_empty);
    EXPECT_EQ(a.width, b.width);
    EXPECT_EQ(a.height, b.height);
    EXPECT_EQ(a.bgr, b.bgr) << (panel ? "with" : "without") << " the class panel";
  }
}

TEST(DrawSnapshot, AllZeroOrBrokenGoalHeatMapTakesTheBottomColour) {
  const Scene scene;
  std::vector<float> probabilities(Scene::kWidth * Scene::kHeight, 0.0f);
  probabilities[5] = -1.0f;
  probabilities[6] = std::numeric_limits<float>::quiet_NaN();
  Snapshot plain = scene.snapshot();
  plain.robot = {-50, -50};
  Snapshot with_heat = plain;
  with_heat.goal_probabilities = probabilities;
  const Picture without = draw_snapshot(plain);
  const Picture picture = draw_snapshot(with_heat);
  const Bgr bottom = inferno(0);
  for (int y = 0; y < Scene::kHeight; ++y) {
    for (int x = 0; x < Scene::kWidth; ++x) {
      const Bgr floor = pixel(without, x * 10 + 5, y * 10 + 5);
      EXPECT_TRUE(same(pixel(picture, x * 10 + 5, y * 10 + 5), blended(floor, bottom))) << x << ", " << y;
    }
  }
}

TEST(DrawSnapshot, RejectsAMissingFloorAndBadSizes) {
  const Scene scene;
  Snapshot snapshot = scene.snapshot();
  snapshot.floor = nullptr;
  EXPECT_THROW(draw_snapshot(snapshot), std::invalid_argument);
  snapshot = scene.snapshot();
  snapshot.scale = 0;
  EXPECT_THROW(draw_snapshot(snapshot), std::invalid_argument);
  snapshot = scene.snapshot();
  snapshot.width_px = 0;
  EXPECT_THROW(draw_snapshot(snapshot), std::invalid_argument);
  snapshot = scene.snapshot();
  snapshot.patch_px = 0;
  EXPECT_THROW(draw_snapshot(snapshot), std::invalid_argument);
}

class WritePng : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    directory_ = std::filesystem::temp_directory_path() /
                 (std::string("scout_render_test_") + info->name() + "_" + std::to_string(::getpid()));
    std::filesystem::remove_all(directory_);
    std::filesystem::create_directories(directory_);
  }
  void TearDown() override { std::filesystem::remove_all(directory_); }
  std::filesystem::path directory_;
};

TEST_F(WritePng, WritesAFileThatReadsBackEqualAndLeavesNoTemporary) {
  const Scene scene;
  Snapshot snapshot = scene.snapshot();
  snapshot.goal = PixelPose{9, 6};
  snapshot.path = {{1, 1}, {3, 3}};
  const std::array<float, 10> probabilities = {0.1f, 0.1f, 0.1f, 0.1f, 0.1f, 0.1f, 0.1f, 0.1f, 0.1f, 0.1f};
  snapshot.class_probabilities = probabilities;
  const Picture picture = draw_snapshot(snapshot);
  const std::filesystem::path file = directory_ / "snapshot.png";
  write_png(file, picture);
  // Written twice: replacing an existing file works too.
  write_png(file, picture);

  const cv::Mat read = cv::imread(file.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(read.empty());
  ASSERT_EQ(read.cols, picture.width);
  ASSERT_EQ(read.rows, picture.height);
  ASSERT_TRUE(read.isContinuous());
  const std::vector<std::uint8_t> bytes(read.datastart, read.dataend);
  EXPECT_EQ(bytes, picture.bgr);

  std::vector<std::filesystem::path> entries;
  for (const auto& entry : std::filesystem::directory_iterator(directory_)) {
    entries.push_back(entry.path().filename());
  }
  ASSERT_EQ(entries.size(), 1u);
  EXPECT_EQ(entries[0], "snapshot.png");
}

TEST_F(WritePng, MissingDirectoryThrowsNamingTheFileAndLeavesNothing) {
  const Scene scene;
  const Picture picture = draw_snapshot(scene.snapshot());
  const std::filesystem::path missing = directory_ / "no_such_directory";
  const std::filesystem::path file = missing / "snapshot.png";
  try {
    write_png(file, picture);
    FAIL() << "write_png into a missing directory did not throw";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find("snapshot.png"), std::string::npos) << error.what();
  }
  EXPECT_FALSE(std::filesystem::exists(missing));
  EXPECT_TRUE(std::filesystem::is_empty(directory_));
}

TEST_F(WritePng, RejectsAPictureWhoseBytesDoNotMatchItsSize) {
  Picture picture;
  picture.width = 4;
  picture.height = 3;
  picture.bgr.assign(4 * 3 * 3 - 1, 0);
  const std::filesystem::path file = directory_ / "bad.png";
  EXPECT_THROW(write_png(file, picture), std::runtime_error);
  EXPECT_TRUE(std::filesystem::is_empty(directory_));
}

}  // namespace
}  // namespace scout::render
