// The pure pixel arithmetic of METHOD.md: frames, windows, the action protocol, the grid model.
#include <gtest/gtest.h>

#include <random>
#include <stdexcept>
#include <vector>

#include "grid/grid.hpp"

namespace scout::grid {
namespace {

const FloorFrame kFloor{28, 28, 0.1};

TEST(FloorFrame, GridPoseIsTheCellHoldingTheCentreClampedToTheFloor) {
  EXPECT_EQ(kFloor.grid_pose({0.5, 0.5}), Cell(0, 0));
  EXPECT_EQ(kFloor.grid_pose({3.999, 7.0}), Cell(3, 7));
  EXPECT_EQ(kFloor.grid_pose({-0.2, 28.3}), Cell(0, 27));
  EXPECT_EQ(kFloor.grid_pose({27.99, 0.0}), Cell(27, 0));
  EXPECT_DOUBLE_EQ(kFloor.cell_centre_px({4, 9}).x(), 4.5);
  EXPECT_DOUBLE_EQ(kFloor.px_to_m({10.0, 2.0}).y(), 0.2);
}

TEST(CameraWindow, EvenPatchStartsHalfAPatchLeftAndUp) {
  const Window w = camera_window({10, 12}, 6, kFloor);
  EXPECT_EQ(w.x0, 7);
  EXPECT_EQ(w.x1, 13);  // columns 7 .. 12 = x-3 .. x+2
  EXPECT_EQ(w.y0, 9);
  EXPECT_EQ(w.y1, 15);
  EXPECT_EQ(w.area(), 36);
}

TEST(CameraWindow, OddPatchIsCentredOnThePose) {
  const Window w = camera_window({10, 12}, 5, kFloor);
  EXPECT_EQ(w.x0, 8);
  EXPECT_EQ(w.x1, 13);
}

TEST(CameraWindow, IsClippedAtTheBorders) {
  const Window corner = camera_window({0, 0}, 6, kFloor);
  EXPECT_EQ(corner.x0, 0);
  EXPECT_EQ(corner.x1, 3);
  EXPECT_EQ(corner.area(), 9);
  const Window far = camera_window({27, 27}, 6, kFloor);
  EXPECT_EQ(far.x0, 24);
  EXPECT_EQ(far.x1, 28);
  EXPECT_EQ(far.area(), 16);
}

TEST(BlockGrid, LaysBlocksFromTheCornerAndCutsTheLastOnesAtTheEdge) {
  const BlockGrid grid = BlockGrid::over({100, 60, 0.1}, 6);
  EXPECT_EQ(grid.columns, 17);  // 16 whole blocks and one of 4 columns
  EXPECT_EQ(grid.rows, 10);     // 10 whole blocks
  EXPECT_EQ(grid.area(), 170);
  // Floor division on both sides of 0.
  for (const auto& [v, block] : std::vector<std::pair<int, int>>{
           {0, 0}, {5, 0}, {6, 1}, {99, 16}, {-1, -1}, {-6, -1}, {-7, -2}, {-2147483647 - 1, -357913942}})
    EXPECT_EQ(grid.block_of(v), block) << v;
  EXPECT_THROW(BlockGrid::over(kFloor, 0), std::invalid_argument);
}

TEST(BlockGrid, ExpandedEveryPixelTakesItsBlocksByte) {
  const FloorFrame frame{7, 5, 0.1};
  const BlockGrid grid = BlockGrid::over(frame, 3);  // 3 x 2 blocks, the last column and row cut
  const std::vector<std::uint8_t> blocks = {1, 2, 3, 4, 5, 6};
  std::vector<std::uint8_t> pixels(35, 0xAB);
  expand_blocks(grid, frame, blocks.data(), pixels.data());
  for (int y = 0; y < 5; ++y)
    for (int x = 0; x < 7; ++x) EXPECT_EQ(pixels[y * 7 + x], blocks[(y / 3) * 3 + x / 3]) << x << ", " << y;
  EXPECT_EQ(pixels[6], 3);   // the cut column
  EXPECT_EQ(pixels[34], 6);  // the cut corner
}

TEST(Protocol, CoversTheFourCases) {
  EXPECT_EQ(decide({3, 4}, {3, 4}), Decision::AtGoal);
  EXPECT_EQ(decide({3, 4}, {3, 20}), Decision::Vertical);
  EXPECT_EQ(decide({3, 4}, {9, 4}), Decision::Horizontal);
  EXPECT_EQ(decide({3, 4}, {9, 20}), Decision::Choose);
}

TEST(Protocol, MoveGoesTowardTheGoalByAtMostTheStep) {
  EXPECT_EQ(move_command({3, 4}, {9, 20}, Axis::Horizontal, 2), Cell(2, 0));
  EXPECT_EQ(move_command({3, 4}, {9, 20}, Axis::Vertical, 2), Cell(0, 2));
  EXPECT_EQ(move_command({3, 4}, {2, 0}, Axis::Horizontal, 2), Cell(-1, 0));  // only 1 px left
  EXPECT_EQ(move_command({3, 4}, {2, 0}, Axis::Vertical, 2), Cell(0, -2));
  EXPECT_EQ(move_command({3, 4}, {3, 4}, Axis::None, 2), Cell(0, 0));
  EXPECT_EQ(move_command({3, 4}, {3, 4}, Axis::Horizontal, 2), Cell(0, 0));
}

TEST(RevealMask, CountsOnlyNewPixels) {
  RevealMask mask(kFloor);
  EXPECT_EQ(mask.reveal(camera_window({10, 10}, 6, kFloor)), 36);
  EXPECT_EQ(mask.reveal(camera_window({12, 10}, 6, kFloor)), 12);  // 2 new columns of 6
  EXPECT_EQ(mask.count(), 48);
  EXPECT_TRUE(mask.seen(7, 7));
  EXPECT_FALSE(mask.seen(6, 7));
  mask.clear();
  EXPECT_EQ(mask.count(), 0);
  EXPECT_FALSE(mask.seen(7, 7));
}

// clear() zeroes only the bounds of what was seen: they must hold every window revealed since,
// however scattered, and clearing must leave the whole mask as new.
TEST(RevealMask, ItsBoundsHoldEverythingSeenAndAClearLeavesNothing) {
  RevealMask mask(kFloor);
  EXPECT_EQ(mask.bounds().area(), 0);
  mask.reveal(camera_window({10, 10}, 6, kFloor));
  mask.reveal(camera_window({0, 27}, 6, kFloor));  // clipped at a corner
  mask.reveal(camera_window({20, 3}, 4, kFloor));
  mask.reveal({5, 5, 5, 9});  // empty: changes nothing
  const Window b = mask.bounds();
  EXPECT_EQ(b.x0, 0);
  EXPECT_EQ(b.y0, 1);
  EXPECT_EQ(b.x1, 22);
  EXPECT_EQ(b.y1, 28);
  for (int y = 0; y < 28; ++y)
    for (int x = 0; x < 28; ++x) {
      if (mask.seen(x, y)) {
        EXPECT_TRUE(x >= b.x0 && x < b.x1 && y >= b.y0 && y < b.y1) << x << ", " << y;
      }
    }
  mask.clear();
  EXPECT_EQ(mask.data(), std::vector<std::uint8_t>(28 * 28, 0));
  EXPECT_EQ(mask.bounds().area(), 0);
  // After assign(), anything may be seen: a clear zeroes the whole floor.
  std::vector<std::uint8_t> scattered(28 * 28, 0);
  scattered[0] = scattered[28 * 28 - 1] = 1;
  mask.assign(scattered);
  EXPECT_EQ(mask.count(), 2);
  mask.clear();
  EXPECT_EQ(mask.data(), std::vector<std::uint8_t>(28 * 28, 0));
  EXPECT_EQ(mask.count(), 0);
}

TEST(GridModel, LandsOnPosePlusCommandAndStopsAtTheBorder) {
  GridModel model(kFloor, 6, {1, 26});
  EXPECT_EQ(model.revealed().count(), 4 * 5);  // columns -2..3 clipped to 0..3, rows 23..28 to 23..27
  model.move({-2, 0});
  EXPECT_EQ(model.pose(), Cell(0, 26));
  model.move({0, 2});
  EXPECT_EQ(model.pose(), Cell(0, 27));
  model.move({2, 0});
  EXPECT_EQ(model.pose(), Cell(2, 27));
}

// A monotone route moves only towards its end: around a wall it may not turn back.
TEST(MonotoneRoutes, AWallShadowsTheCellsBehindIt) {
  const FloorFrame floor{7, 5, 0.1};
  // A vertical wall at x = 3, rows 0..3: only row 4 passes it.
  std::vector<std::uint8_t> blocked(35, 0);
  for (int y = 0; y < 4; ++y) blocked[y * 7 + 3] = 1;
  std::vector<std::uint8_t> reach(35);
  monotone_reach(blocked, floor, {1, 1}, reach);
  std::vector<std::uint8_t> scratch;
  for (int y = 0; y < 5; ++y)
    for (int x = 0; x < 7; ++x) {
      // From (1, 1): everything left of the wall; right of it only rows y >= 4 (down, across row 4,
      // on downwards), never rows above 4 (that would need a step back up).
      const bool expected = x < 3 || y == 4;
      EXPECT_EQ(reach[y * 7 + x] != 0, expected) << x << ", " << y;
      EXPECT_EQ(monotone_route_free(blocked, floor, {1, 1}, {x, y}, scratch), expected) << x << ", " << y;
    }
  // From below the wall the cells right of it are reached again, and the route back up is free.
  EXPECT_TRUE(monotone_route_free(blocked, floor, {1, 4}, {6, 0}, scratch));
  EXPECT_TRUE(monotone_route_free(blocked, floor, {5, 1}, {5, 3}, scratch));
  // The start counts as free, a blocked end does not.
  blocked[1 * 7 + 1] = 1;
  EXPECT_TRUE(monotone_route_free(blocked, floor, {1, 1}, {0, 0}, scratch));
  EXPECT_FALSE(monotone_route_free(blocked, floor, {0, 0}, {1, 1}, scratch));
  EXPECT_THROW(monotone_route_free(blocked, floor, {0, 0}, {7, 0}, scratch), std::invalid_argument);
  EXPECT_THROW(monotone_reach(std::span(blocked).first(34), floor, {0, 0}, reach), std::invalid_argument);
}

// The whole-floor map and the single-route check agree, and both match a route found by trying
// every staircase (a depth-first search over monotone steps) on random obstacle maps.
TEST(MonotoneRoutes, ReachAndRouteAgreeWithASearchOverStaircases) {
  const FloorFrame floor{9, 8, 0.1};
  std::mt19937 rng(12);
  std::vector<std::uint8_t> blocked(72), reach(72), scratch;
  for (int trial = 0; trial < 40; ++trial) {
    for (auto& b : blocked) b = rng() % 100 < 30 ? 1 : 0;
    const Cell from(static_cast<int>(rng() % 9), static_cast<int>(rng() % 8));
    monotone_reach(blocked, floor, from, reach);
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 9; ++x) {
        const Cell to(x, y);
        // The search: from `at`, one step along x or y towards `to`, over free cells.
        auto search = [&](auto&& self, Cell at) -> bool {
          if (at == to) return true;
          for (int axis = 0; axis < 2; ++axis) {
            if (at[axis] == to[axis]) continue;
            Cell next = at;
            next[axis] += to[axis] > at[axis] ? 1 : -1;
            if (blocked[next.y() * 9 + next.x()] == 0 && self(self, next)) return true;
          }
          return false;
        };
        const bool expected = search(search, from);
        ASSERT_EQ(reach[y * 9 + x] != 0, expected) << "trial " << trial << " at " << x << ", " << y;
        ASSERT_EQ(monotone_route_free(blocked, floor, from, to, scratch), expected) << trial;
      }
  }
}

}  // namespace
}  // namespace scout::grid
