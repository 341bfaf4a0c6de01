// The agent's state (METHOD.md § The agent's state) on a small 6 x 5 floor, element by element
// against pictures drawn by hand, including windows clipped at the borders.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "agent/state.hpp"

namespace scout::agent {
namespace {

constexpr int kW = 6;
constexpr int kH = 5;
constexpr int kN = kW * kH;
const grid::FloorFrame kFloor{kW, kH, 0.1};

// A 0/1 plane from a picture: one character per pixel, rows top to bottom.
std::vector<float> plane(const std::string& picture) {
  if (picture.size() != static_cast<std::size_t>(kN)) throw std::invalid_argument("plane: wrong picture size");
  std::vector<float> out;
  for (const char ch : picture) out.push_back(ch == '1' ? 1.0f : 0.0f);
  return out;
}

// What the robot has seen: two 2 x 2 blocks. Unseen bytes hold 77, which must never reach y.
const std::vector<std::uint8_t> kSeen = {
    1, 1, 0, 0, 0, 0,  //
    1, 1, 0, 0, 0, 0,  //
    0, 0, 0, 0, 1, 1,  //
    0, 0, 0, 0, 1, 1,  //
    0, 0, 0, 0, 0, 0,  //
};
const std::vector<std::uint8_t> kObserved = {
    0,  255, 77, 77, 77,  77,   //
    51, 102, 77, 77, 77,  77,   //
    77, 77,  77, 77, 255, 0,    //
    77, 77,  77, 77, 153, 204,  //
    77, 77,  77, 77, 77,  77,   //
};
// y by hand: p / 255 - 0.5 where seen (0 -> -0.5, 51 -> -0.3, 102 -> -0.1, 153 -> 0.1, ...).
const std::vector<float> kY = {
    -0.5f, 0.5f,  0, 0, 0,    0,      //
    -0.3f, -0.1f, 0, 0, 0,    0,      //
    0,     0,     0, 0, 0.5f, -0.5f,  //
    0,     0,     0, 0, 0.1f, 0.3f,   //
    0,     0,     0, 0, 0,    0,      //
};
// h by hand: 0 where seen.
std::vector<float> unseen_plane() {
  return plane(
      "001111"
      "001111"
      "111100"
      "111100"
      "111111");
}

// Runs write_planner_input into a buffer pre-filled with NaN (so an unwritten element shows).
std::vector<float> planner_input(int patch_px, const grid::Cell& pose, const grid::Cell* goal) {
  std::vector<float> u(4 * kN, std::numeric_limits<float>::quiet_NaN());
  const RobotView view{kObserved.data(), kSeen.data(), pose, goal};
  write_planner_input(kFloor, patch_px, view, u.data());
  return u;
}

void expect_channel(const std::vector<float>& u, int channel, const std::vector<float>& expected, const char* name) {
  for (int i = 0; i < kN; ++i) {
    EXPECT_FLOAT_EQ(u[static_cast<std::size_t>(channel * kN + i)], expected[static_cast<std::size_t>(i)])
        << name << " at x = " << i % kW << ", y = " << i / kW;
  }
}

TEST(AgentState, PixelValueMapsBytesToMinusHalfToHalf) {
  EXPECT_FLOAT_EQ(pixel_value(0), -0.5f);
  EXPECT_FLOAT_EQ(pixel_value(255), 0.5f);
  EXPECT_NEAR(pixel_value(51), -0.3f, 1e-7);
}

TEST(AgentState, RevealedImageIsThePixelWhereSeenAndZeroElsewhere) {
  std::vector<float> y(kN, std::numeric_limits<float>::quiet_NaN());
  const RobotView view{kObserved.data(), kSeen.data(), {0, 0}, nullptr};
  write_revealed_image(kFloor, view, y.data());
  for (int i = 0; i < kN; ++i) EXPECT_NEAR(y[i], kY[i], 1e-6) << "x = " << i % kW << ", y = " << i / kW;
}

TEST(AgentState, OddPatchWindowsAreClippedAtTheLeftAndBottom) {
  // m = 3: the window at (x, y) is columns x-1 .. x+1, rows y-1 .. y+1.
  const grid::Cell goal{5, 4};                                   // columns 4..6 -> 4..5, rows 3..5 -> 3..4
  const std::vector<float> u = planner_input(3, {0, 2}, &goal);  // columns -1..1 -> 0..1, rows 1..3
  for (int i = 0; i < kN; ++i) EXPECT_NEAR(u[i], kY[i], 1e-6);
  expect_channel(u, 1,
                 plane("111111"
                       "001111"
                       "001111"
                       "001111"
                       "111111"),
                 "l");
  expect_channel(u, 2, unseen_plane(), "h");
  expect_channel(u, 3,
                 plane("111111"
                       "111111"
                       "111111"
                       "111100"
                       "111100"),
                 "g_l");
}

TEST(AgentState, EvenPatchWindowsStartHalfAPatchLeftAndUp) {
  // m = 2: the window at (x, y) is columns x-1 .. x, rows y-1 .. y.
  const grid::Cell goal{0, 0};                                   // clipped to the single pixel (0, 0)
  const std::vector<float> u = planner_input(2, {3, 1}, &goal);  // columns 2..3, rows 0..1
  expect_channel(u, 1,
                 plane("110011"
                       "110011"
                       "111111"
                       "111111"
                       "111111"),
                 "l");
  expect_channel(u, 2, unseen_plane(), "h");
  expect_channel(u, 3,
                 plane("011111"
                       "111111"
                       "111111"
                       "111111"
                       "111111"),
                 "g_l");
}

TEST(AgentState, WithoutAGoalTheGoalChannelIsAllOnes) {
  const std::vector<float> corner = planner_input(2, {5, 4}, nullptr);  // columns 4..5, rows 3..4
  expect_channel(corner, 1,
                 plane("111111"
                       "111111"
                       "111111"
                       "111100"
                       "111100"),
                 "l");
  expect_channel(corner, 3, plane(std::string(kN, '1')), "g_l");

  const std::vector<float> inside = planner_input(3, {2, 2}, nullptr);  // columns 1..3, rows 1..3
  expect_channel(inside, 1,
                 plane("111111"
                       "100011"
                       "100011"
                       "100011"
                       "111111"),
                 "l");
  expect_channel(inside, 2, unseen_plane(), "h");
  expect_channel(inside, 3, plane(std::string(kN, '1')), "g_l");
}

// o, the occupancy channel, is the fifth plane when asked for: 1 where the view's map says the
// robot cannot stand, 0 elsewhere and everywhere without a map; without it, four planes only.
TEST(AgentState, TheOccupancyChannelIsWrittenOnlyWhenAskedFor) {
  const std::string occupied_text =
      "000000"
      "011000"
      "011000"
      "000001"
      "000011";
  std::vector<std::uint8_t> occupied(kN);
  for (int i = 0; i < kN; ++i)
    occupied[static_cast<std::size_t>(i)] = occupied_text[static_cast<std::size_t>(i)] == '1';
  const grid::Cell goal{5, 4};
  std::vector<float> u(5 * kN, std::numeric_limits<float>::quiet_NaN());
  RobotView view{kObserved.data(), kSeen.data(), {2, 2}, &goal, occupied.data()};
  write_planner_input(kFloor, 3, view, u.data(), /*occupancy=*/true);
  expect_channel(u, 4, plane(occupied_text), "o");
  const std::vector<float> four = planner_input(3, {2, 2}, &goal);
  for (int i = 0; i < 4 * kN; ++i) EXPECT_FLOAT_EQ(u[static_cast<std::size_t>(i)], four[static_cast<std::size_t>(i)]);

  view.occupied = nullptr;  // a world without obstacles
  write_planner_input(kFloor, 3, view, u.data(), /*occupancy=*/true);
  expect_channel(u, 4, plane(std::string(kN, '0')), "o");

  std::fill(u.begin(), u.end(), std::numeric_limits<float>::quiet_NaN());
  view.occupied = occupied.data();
  write_planner_input(kFloor, 3, view, u.data());  // a model without the channel: four planes
  for (int i = 4 * kN; i < 5 * kN; ++i) EXPECT_TRUE(std::isnan(u[static_cast<std::size_t>(i)]));
}

// The teammates' channels, after o: t_p is 0 on the camera windows (m = 3) at the teammates'
// poses, t_g on those around their goals; a robot alone has both all ones. Without o they follow
// g_l directly.
TEST(AgentState, TheTeammatesChannelsMarkTheirWindowsAndGoals) {
  const grid::Cell goal{5, 4};
  const std::vector<grid::Cell> poses = {{0, 0}, {4, 2}}, goals = {{2, 3}};
  std::vector<float> u(7 * kN, std::numeric_limits<float>::quiet_NaN());
  RobotView view{kObserved.data(), kSeen.data(), {2, 2}, &goal, nullptr, poses, goals};
  write_planner_input(kFloor, 3, view, u.data(), /*occupancy=*/true, /*team=*/true);
  expect_channel(u, 5,
                 plane("001111"
                       "001000"
                       "111000"
                       "111000"
                       "111111"),
                 "t_p");
  expect_channel(u, 6,
                 plane("111111"
                       "111111"
                       "100011"
                       "100011"
                       "100011"),
                 "t_g");
  std::vector<float> without_o(6 * kN, std::numeric_limits<float>::quiet_NaN());
  write_planner_input(kFloor, 3, view, without_o.data(), /*occupancy=*/false, /*team=*/true);
  for (int i = 0; i < 2 * kN; ++i) EXPECT_FLOAT_EQ(without_o[4 * kN + i], u[5 * kN + i]);
  view.teammate_poses = {};
  view.teammate_goals = {};
  write_planner_input(kFloor, 3, view, u.data(), /*occupancy=*/true, /*team=*/true);
  expect_channel(u, 5, plane(std::string(kN, '1')), "t_p alone");
  expect_channel(u, 6, plane(std::string(kN, '1')), "t_g alone");
}

// The wider view's channels come last: y_w is the coarse map as the networks see pixels where it
// is set and 0 elsewhere, h_w 0 there and 1 elsewhere, each floor pixel its block's; without a
// coarse map, nothing seen.
TEST(AgentState, TheWiderViewsChannelsHoldTheCoarseMapAndWhereItIsSet) {
  const grid::BlockGrid blocks = grid::BlockGrid::over(kFloor, 4);  // 2 x 2 blocks, the last column and row cut short
  const int b = blocks.area();
  std::vector<std::uint8_t> coarse(b, 0), covered(b, 0);
  for (int i = 0; i < b / 2; ++i) {
    coarse[i] = static_cast<std::uint8_t>(3 * i + 1);
    covered[i] = 1;
  }
  coarse[b - 1] = 200;  // a stale byte where nothing is set must not show
  const grid::Cell goal{5, 4};
  RobotView view{kObserved.data(), kSeen.data(), {2, 2}, &goal, nullptr};
  view.wide_revealed = coarse.data();
  view.wide_seen = covered.data();
  view.wide_grid = blocks;
  std::vector<float> u(9 * kN, std::numeric_limits<float>::quiet_NaN());
  write_planner_input(kFloor, 3, view, u.data(), /*occupancy=*/true, /*team=*/true, /*wide=*/true);
  for (int i = 0; i < kN; ++i) {
    const int block = (i / kW) / blocks.scale * blocks.columns + (i % kW) / blocks.scale;
    EXPECT_FLOAT_EQ(u[7 * kN + i], covered[block] ? pixel_value(coarse[block]) : 0.0f) << i;
    EXPECT_FLOAT_EQ(u[8 * kN + i], covered[block] ? 0.0f : 1.0f) << i;
  }
  // A view whose grid does not cover the floor (left at its default) is refused, not read short.
  RobotView gridless = view;
  gridless.wide_grid = {};
  EXPECT_THROW(write_planner_input(kFloor, 3, gridless, u.data(), true, true, true), std::invalid_argument);
  std::vector<float> bare(6 * kN, std::numeric_limits<float>::quiet_NaN());
  write_planner_input(kFloor, 3, view, bare.data(), /*occupancy=*/false, /*team=*/false, /*wide=*/true);
  for (int i = 0; i < kN; ++i) EXPECT_FLOAT_EQ(bare[4 * kN + i], u[7 * kN + i]) << i;
  view.wide_seen = nullptr;
  write_planner_input(kFloor, 3, view, bare.data(), false, false, true);
  for (int i = 0; i < kN; ++i) {
    EXPECT_FLOAT_EQ(bare[4 * kN + i], 0.0f);
    EXPECT_FLOAT_EQ(bare[5 * kN + i], 1.0f);
  }
}

}  // namespace
}  // namespace scout::agent
