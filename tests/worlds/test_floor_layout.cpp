// Floors larger than the digit: what the composer paints (the digit's own pixels where the plan
// puts them, black elsewhere, clutter from other digits, several digits in cells of their own and
// labelled by their sum), that it is a function of (index, key) alone, that placements cover the
// floor, and that each impossible layout is refused with one line naming the world's field.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <set>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "worlds/dataset.hpp"
#include "worlds/floor_layout.hpp"
#include "worlds/floors.hpp"
#include "worlds/world.hpp"

namespace scout::worlds {
namespace {

// Eight 6 x 5 "digits": image i is filled with grey level 10 + 20 i except a black first row, so
// that every painted pixel tells which image it came from. Labels i mod 4.
LabeledImages toy_digits() {
  LabeledImages d;
  d.images.count = 8;
  d.images.cols = 6;
  d.images.rows = 5;
  d.images.pixels.assign(static_cast<std::size_t>(8 * 6 * 5), 0);
  for (int i = 0; i < 8; ++i) {
    std::uint8_t* image = d.images.pixels.data() + static_cast<std::size_t>(i) * 30;
    std::fill(image + 6, image + 30, static_cast<std::uint8_t>(10 + 20 * i));
    d.labels.push_back(static_cast<std::uint8_t>(i % 4));
  }
  return d;
}

World world_of(const std::string& floor_yaml) { return parse_world("floor:\n" + floor_yaml, "w.yaml"); }

std::vector<std::uint8_t> compose(const FloorComposer& c, const LabeledImages& d, int index, std::uint64_t key,
                                  int* label = nullptr) {
  std::vector<std::uint8_t> floor(static_cast<std::size_t>(c.width_px()) * c.height_px());
  const int l = c.compose(d.images, d.labels, index, key, floor);
  if (label) *label = l;
  return floor;
}

TEST(FloorLayout, TodaysFloorIsTheImageItself) {
  const LabeledImages d = toy_digits();
  const FloorComposer c(world_of("  dataset: mnist\n"), 6, 5);
  EXPECT_TRUE(c.copies_images());
  EXPECT_EQ(c.width_px(), 6);
  int label = -1;
  const std::vector<std::uint8_t> floor = compose(c, d, 3, 99, &label);
  EXPECT_TRUE(std::equal(floor.begin(), floor.end(), d.images.image(3)));
  EXPECT_EQ(label, 3);
  EXPECT_EQ(c.classes(10), 10);
}

TEST(FloorLayout, CentredOnALargerFloorSitsInTheMiddle) {
  const LabeledImages d = toy_digits();
  const FloorComposer c(world_of("  size_px: [10, 9]\n"), 6, 5);
  EXPECT_FALSE(c.copies_images());
  const std::vector<std::uint8_t> floor = compose(c, d, 2, 1);
  // (10 - 6) / 2 = 2 columns, (9 - 5) / 2 = 2 rows of black before the digit; its own first row is black too.
  for (int y = 0; y < 9; ++y)
    for (int x = 0; x < 10; ++x) {
      const bool digit = x >= 2 && x < 8 && y >= 3 && y < 7;
      EXPECT_EQ(floor[y * 10 + x], digit ? 50 : 0) << x << "," << y;
    }
  EXPECT_EQ(compose(c, d, 2, 12345), floor);  // no randomness
}

TEST(FloorLayout, TranslatedPutsTheDigitsPixelsWhereThePlanSaysAndCoversTheFloor) {
  const LabeledImages d = toy_digits();
  const FloorComposer c(world_of("  size_px: [20, 16]\n  layout: translated\n"), 6, 5);
  std::set<int> xs, ys;
  for (std::uint64_t key = 0; key < 400; ++key) {
    const FloorPlan plan = c.plan(5, d.images.count, key);
    ASSERT_EQ(plan.digit_count, 1);
    ASSERT_EQ(plan.digits[0].image, 5);
    const int x0 = plan.digits[0].x, y0 = plan.digits[0].y;
    ASSERT_TRUE(x0 >= 0 && x0 <= 14 && y0 >= 0 && y0 <= 11) << x0 << "," << y0;
    xs.insert(x0);
    ys.insert(y0);
    int label = -1;
    const std::vector<std::uint8_t> floor = compose(c, d, 5, key, &label);
    EXPECT_EQ(label, 1);
    long sum = 0;
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 20; ++x) {
        const bool digit = x >= x0 && x < x0 + 6 && y >= y0 + 1 && y < y0 + 5;
        ASSERT_EQ(floor[y * 20 + x], digit ? 110 : 0) << "key " << key << " at " << x << "," << y;
        sum += floor[y * 20 + x];
      }
    EXPECT_EQ(sum, 110 * 24);
  }
  // Every corner position is reachable: the placement is uniform over [0, W - w] x [0, H - h].
  EXPECT_EQ(xs.size(), 15u);
  EXPECT_EQ(ys.size(), 12u);
  // A function of (index, key) alone.
  EXPECT_EQ(compose(c, d, 5, 7), compose(c, d, 5, 7));
  EXPECT_NE(compose(c, d, 5, 7), compose(c, d, 5, 8));
}

TEST(FloorLayout, ClutterComesFromOtherDigitsAndTheDigitStaysWhole) {
  const LabeledImages d = toy_digits();
  const FloorComposer c(world_of("  size_px: [24, 24]\n  layout: cluttered\n  clutter: 6\n  clutter_px: 3\n"), 6, 5);
  for (std::uint64_t key = 0; key < 50; ++key) {
    const FloorPlan plan = c.plan(0, d.images.count, key);
    ASSERT_EQ(plan.clutter.size(), 6u);
    const std::vector<std::uint8_t> floor = compose(c, d, 0, key);
    // The digit (level 10, the darkest) is under the brightest-wins blend: each of its pixels is
    // at least 10, and the clutter's pieces are there with their own levels.
    const int x0 = plan.digits[0].x, y0 = plan.digits[0].y;
    for (int y = y0 + 1; y < y0 + 5; ++y)
      for (int x = x0; x < x0 + 6; ++x) ASSERT_GE(floor[y * 24 + x], 10);
    std::set<int> levels(floor.begin(), floor.end());
    for (const FloorPlan::Piece& p : plan.clutter) {
      EXPECT_NE(p.image, 0) << "clutter from the floor's own digit";
      ASSERT_TRUE(p.from_x >= 0 && p.from_x <= 3 && p.from_y >= 0 && p.from_y <= 2);
      ASSERT_TRUE(p.x >= 0 && p.x <= 21 && p.y >= 0 && p.y <= 21);
      // A piece cut below the image's black first row shows its level somewhere on the floor.
      if (p.from_y > 0) {
        EXPECT_EQ(levels.count(10 + 20 * p.image), 1u);
      }
    }
    long covered = std::count_if(floor.begin(), floor.end(), [](std::uint8_t v) { return v > 0; });
    EXPECT_GT(covered, 24) << "clutter adds pixels beside the digit's 24";
  }
}

TEST(FloorLayout, SeveralDigitsLieInCellsOfTheirOwnAndAreLabelledByTheirSum) {
  const LabeledImages d = toy_digits();
  const FloorComposer c(world_of("  size_px: [13, 11]\n  layout: translated\n  digits: 4\n"), 6, 5);
  EXPECT_EQ(c.classes(4), 13);  // sums 0 .. 12 of four labels 0 .. 3
  std::set<int> partners;
  for (std::uint64_t key = 0; key < 100; ++key) {
    const FloorPlan plan = c.plan(6, d.images.count, key);
    ASSERT_EQ(plan.digit_count, 4);
    EXPECT_EQ(plan.digits[0].image, 6);
    int sum = 0;
    for (int a = 0; a < 4; ++a) {
      sum += d.labels[plan.digits[a].image];
      partners.insert(plan.digits[a].image);
      for (int b = a + 1; b < 4; ++b) {  // no two digits' boxes overlap
        const bool apart = plan.digits[a].x + 6 <= plan.digits[b].x || plan.digits[b].x + 6 <= plan.digits[a].x ||
                           plan.digits[a].y + 5 <= plan.digits[b].y || plan.digits[b].y + 5 <= plan.digits[a].y;
        ASSERT_TRUE(apart) << "digits " << a << " and " << b << " overlap, key " << key;
      }
    }
    int label = -1;
    compose(c, d, 6, key, &label);
    EXPECT_EQ(label, sum);
    EXPECT_EQ(c.label(d.labels, 6, key), sum);
  }
  EXPECT_EQ(partners.size(), 8u) << "the other digits are drawn from the whole split";
}

// The floor's rules, each one line naming the file, the line and the field.
void expect_refused(const std::string& floor_yaml, int image_w, int image_h, const std::string& message) {
  try {
    const World w = world_of(floor_yaml);
    const FloorComposer c(w, image_w, image_h);
    ADD_FAILURE() << "accepted:\n" << floor_yaml;
  } catch (const InputError& e) {
    const std::string text = e.what();
    EXPECT_EQ(text.find('\n'), std::string::npos) << text;
    EXPECT_EQ(text.rfind(message, 0), 0u) << "got: " << text << "\nwanted: " << message;
  }
}

TEST(FloorLayout, ImpossibleLayoutsAreRefusedWithOneLine) {
  expect_refused("  size_px: [20, 27]\n", 28, 28,
                 "w.yaml:2: floor.size_px: expected a floor at least the images' 28 x 28 pixels, got [20, 27]");
  expect_refused("  size_px: [60, 60]\n  layout: cluttered\n  clutter: 4\n  clutter_px: 29\n", 28, 28,
                 "w.yaml:5: floor.clutter_px: expected at most the images' smaller side, 28");
  expect_refused("  size_px: [60, 60]\n  layout: translated\n  digits: 5\n", 28, 28,
                 "w.yaml:4: floor.digits: expected at most 4 (a [60, 60] floor holds 2 x 2 cells");
  expect_refused("  size_px: [60, 60]\n  layout: cluttered\n", 28, 28,
                 "w.yaml:3: floor.clutter: expected at least 1 with layout cluttered, got 0 (the default)");
  expect_refused("  size_px: [60, 60]\n  clutter: 3\n", 28, 28,
                 "w.yaml:3: floor.clutter: expected 0 with layout centred, got 3");
  expect_refused("  layout: translated\n", 28, 28, "w.yaml:2: floor.size_px: expected [w, h] with layout translated");
  expect_refused("  size_px: [60, 60]\n  digits: 2\n", 28, 28,
                 "w.yaml:3: floor.layout: expected translated or cluttered with digits = 2, got centred (the default)");
  expect_refused("  image: a.png\n  size_px: [60, 60]\n", 28, 28,
                 "w.yaml:3: floor.size_px: expected floor.dataset (floors are composed from a data set's digits)");
  expect_refused("  size_px: [60, 0]\n", 28, 28, "w.yaml:2: floor.size_px: expected [w, h] (two integers in [1, 512]");
  expect_refused("  size_px: [600, 60]\n", 28, 28,
                 "w.yaml:2: floor.size_px: expected [w, h] (two integers in [1, 512]");
  expect_refused("  layout: diagonal\n", 28, 28, "w.yaml:2: floor.layout: expected centred, translated or cluttered");
  expect_refused("  image: a.png\n  clutter: 2\n", 28, 28, "w.yaml:3: floor.clutter: expected floor.dataset");
  expect_refused("  image: a.png\n  clutter_px: 4\n", 28, 28, "w.yaml:3: floor.clutter_px: expected floor.dataset");
}

TEST(FloorLayout, ADataSetFloorSetComposesWithTheWorldsLayout) {
  const World w = parse_world(
      "floor:\n  dataset: mnist-10k\n  split: validation\n  size_px: [60, 60]\n  layout: translated\n"
      "camera:\n  patch_px: 8\nrobot:\n  start: [59, 59]\n",
      std::string(SCOUT_SOURCE_DIR) + "/worlds/w.yaml");
  const FloorSet floors = load_floors(w, std::string(SCOUT_SOURCE_DIR) + "/data");
  EXPECT_EQ(floors.width_px(), 60);
  EXPECT_EQ(floors.height_px(), 60);
  std::vector<std::uint8_t> floor(3600);
  const int label = floors.floor(17, 5, floor);
  EXPECT_EQ(label, floors.labels[17]);
  // The whole digit is on the floor: the same ink, none lost at an edge.
  const long ink = std::accumulate(floor.begin(), floor.end(), 0L);
  const std::uint8_t* digit = floors.images.image(17);
  EXPECT_EQ(ink, std::accumulate(digit, digit + 784, 0L));
  // A wider view may cover the composed floor from any cell (twice its side), not more.
  World wide = w;
  wide.camera.wide_px = 15;
  wide.camera.wide_scale = 8;
  EXPECT_EQ(load_floors(wide, std::string(SCOUT_SOURCE_DIR) + "/data").width_px(), 60);
  wide.camera.wide_px = 16;
  try {
    load_floors(wide, std::string(SCOUT_SOURCE_DIR) + "/data");
    ADD_FAILURE() << "a wider view larger than the floor was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("camera.wide_px: expected wide_px x wide_scale at most twice the floor's "
                                         "larger side, 120 (the floor is 60x60 pixels), got 16 x 8 = 128"),
              std::string::npos)
        << e.what();
  }
  // A start on the 60 x 60 floor but off a 28 x 28 one is accepted; one off the floor is not.
  World off = w;
  off.robot.start = std::make_pair(60, 3);
  try {
    load_floors(off, std::string(SCOUT_SOURCE_DIR) + "/data");
    ADD_FAILURE() << "a start off the floor was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("robot.start: expected [x, y] with x in [0, 59]"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace scout::worlds
