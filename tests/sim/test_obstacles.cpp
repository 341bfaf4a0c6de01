// Physics in the loop for the `obstacles` section (docs/SCENARIOS.md § Obstacles): static Box2D
// bodies that the robot's disc collides with. A move into one ends at contact, and no robot's
// disc ever overlaps an obstacle by more than one tick's travel (the same bound as at the walls),
// over thousands of moves in any direction.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <vector>

#include "core/random.hpp"
#include "sim/robots.hpp"

namespace scout::sim {
namespace {

const grid::FloorFrame kFloor{40, 40, 0.1};

RobotParams with_obstacles() {
  RobotParams p;
  p.obstacles.boxes = {{8, 8, 4, 4}, {26, 6, 2, 10}, {14, 28, 10, 1}};
  p.obstacles.discs = {{30.5, 30.5, 3.0}, {12.0, 22.0, 1.5}};
  return p;
}

// One robot at rest on cell (9, 9), left of the box [14, 18) x [8, 12).
class BesideABox : public ::testing::Test {
 protected:
  static RobotParams one_box() {
    RobotParams p;
    p.obstacles.boxes = {{14, 8, 4, 4}};
    return p;
  }
  void SetUp() override { batch.place(0, {9, 9}); }

  RobotParams p = one_box();
  RobotBatch batch{kFloor, p, 1};
  std::vector<MoveResult> result = std::vector<MoveResult>(1);
};

TEST_F(BesideABox, AMoveIntoTheBoxEndsAtContact) {
  batch.move(std::vector<grid::Cell>{{4, 0}}, result);
  const double radius_px = p.body.radius_m / kFloor.pixel_size_m;
  EXPECT_TRUE(result[0].blocked);
  EXPECT_FALSE(result[0].settled);
  EXPECT_FALSE(result[0].touched_wall);
  EXPECT_LT(result[0].ticks, 30) << "the move should end at contact, not at the tick bound";
  // The disc stops against the box's face at x = 14 (its polygon stands inside by Box2D's skin less
  // the slop), within the slop and the last tick's shortfall (0.1 px).
  EXPECT_NEAR(batch.position_px(0).x(), 14.0 - radius_px, 0.1);
  EXPECT_NEAR(batch.position_px(0).y(), 9.5, 1e-3);
  EXPECT_EQ(batch.grid_pose(0), grid::Cell(11, 9));
  // A move away from it is an ordinary one.
  batch.move(std::vector<grid::Cell>{{-2, 0}}, result);
  EXPECT_TRUE(result[0].settled);
  EXPECT_FALSE(result[0].blocked);
  EXPECT_EQ(batch.grid_pose(0), grid::Cell(9, 9));
}

TEST_F(BesideABox, ACellWhoseDiscJustReachesTheBoxIsReachedLikeAnyOther) {
  // Cells (11, y) lie exactly the radius (2.5 px) from the box's face at x = 14: the disc fits
  // there touching the box (o = 0). Moves onto them and along the face settle on their cells,
  // not about 0.05 px short against Box2D's contact skin.
  for (const grid::Cell& command : {grid::Cell(2, 0), grid::Cell(0, 3), grid::Cell(0, -4), grid::Cell(0, 2)}) {
    batch.move(std::vector<grid::Cell>{command}, result);
    EXPECT_TRUE(result[0].settled) << command.transpose();
    EXPECT_FALSE(result[0].blocked) << command.transpose();
    EXPECT_NEAR(batch.position_px(0).x(), 11.5, p.controller.tolerance_px) << command.transpose();
  }
  EXPECT_EQ(batch.grid_pose(0), grid::Cell(11, 10));
}

TEST(Obstacles, NoRobotEverEntersAnObstacle) {
  const RobotParams p = with_obstacles();
  const double radius_px = p.body.radius_m / kFloor.pixel_size_m;
  const int robots = 100;
  RobotBatch batch(kFloor, p, robots);
  core::Rng rng(7);
  for (int i = 0; i < robots; ++i) {
    grid::Cell start;
    do start = {static_cast<int>(core::uniform_below(rng, 40)), static_cast<int>(core::uniform_below(rng, 40))};
    while (p.obstacles.clearance_px(start.x() + 0.5, start.y() + 0.5) < radius_px);
    batch.place(i, start);
  }
  std::vector<grid::Cell> commands(robots);
  std::vector<MoveResult> results(robots);
  std::vector<std::vector<Eigen::Vector2d>> traces(robots);
  double closest = 1e9;
  long ticks = 0, blocked = 0, moves = 0;
  for (int k = 0; k < 40; ++k) {
    for (int i = 0; i < robots; ++i) {
      const int length = 1 + static_cast<int>(core::uniform_below(rng, 4));
      const int sign = (rng() >> 63) != 0 ? 1 : -1;
      commands[i] = (rng() >> 63) != 0 ? grid::Cell(sign * length, 0) : grid::Cell(0, sign * length);
      traces[i].clear();
    }
    batch.move(commands, results, traces);
    for (int i = 0; i < robots; ++i) {
      for (const Eigen::Vector2d& q : traces[i]) closest = std::min(closest, p.obstacles.clearance_px(q.x(), q.y()));
      ticks += static_cast<long>(traces[i].size());
      blocked += results[i].blocked ? 1 : 0;
      ++moves;
      if (results[i].blocked) {
        ASSERT_LT(results[i].ticks, p.physics.max_ticks_per_move);
      }
    }
  }
  std::printf("[ measured ] %ld moves, %ld ticks, %ld blocked; closest approach to an obstacle %.3f px (radius %.2f)\n",
              moves, ticks, blocked, closest, radius_px);
  // A contact that begins during a tick is found at its end: the disc may overlap an obstacle by
  // up to one tick's travel (1/3 px at 2 m/s, 60 Hz, 0.1 m/px) plus Box2D's slop (0.05 px), as it
  // may a wall; the position solver then pushes it out.
  const double tick_travel_px = p.body.max_speed_mps * p.physics.dt_s / kFloor.pixel_size_m;
  EXPECT_GE(closest, radius_px - tick_travel_px - 0.06);
  EXPECT_GT(blocked, moves / 50) << "the obstacles should stop some moves";
}

}  // namespace
}  // namespace scout::sim
