// Snapshot pictures: sizes, colours of seen and unseen pixels, the outlines, the panel, and
// atomic PNG writing.
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cstdint>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <string>
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
