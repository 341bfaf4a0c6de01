// The pure pixel arithmetic of METHOD.md: frames, windows, the action protocol, the grid model.
#include <gtest/gtest.h>

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

}  // namespace
}  // namespace scout::grid
