// Obstacles drawn anew for every run (`obstacles.random_boxes`, docs/SCENARIOS.md § Obstacles),
// with the real Box2D robots and the real OSMesa camera: a run's layout is a function of its motion
// seed alone, its boxes lie on the floor with sides in the stated range and leave the start clear;
// each robot of a batch collides with its own boxes only, sees them in their shade, and reads them
// in o, the occupancy channel.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "core/error.hpp"
#include "core/random.hpp"
#include "env/batch_env.hpp"
#include "env/runs.hpp"
#include "sim/robots.hpp"
#include "worlds/world.hpp"

namespace scout::env {
namespace {

const grid::FloorFrame kFloor{.width_px = 20, .height_px = 16, .pixel_size_m = 0.1};

worlds::World random_box_world() {
  worlds::World w;
  w.camera.patch_px = 4;
  w.obstacles.random_boxes = 3;
  w.obstacles.random_box_min_px = 2;
  w.obstacles.random_box_max_px = 4;
  w.obstacles.shade = 0;  // unlike every floor pixel below (never 0)
  return w;
}

std::vector<std::tuple<int, int, int, int>> boxes_of(const worlds::ObstacleSpec& layout) {
  std::vector<std::tuple<int, int, int, int>> boxes;
  for (const worlds::BoxObstacle& b : layout.boxes) boxes.emplace_back(b.x, b.y, b.w, b.h);
  return boxes;
}

TEST(RandomObstacles, ARunsLayoutIsItsMotionSeedsAndLiesOnTheFloor) {
  worlds::World world = random_box_world();
  world.obstacles.boxes = {{0, 0, 1, 1}};  // fixed ones stay, first
  world.obstacles.discs = {{15.25, 3.5, 1.75}};
  const double radius_px = world.robot.radius_m / kFloor.pixel_size_m;
  std::set<std::vector<std::tuple<int, int, int, int>>> layouts;
  std::vector<int> covered(static_cast<std::size_t>(kFloor.area_px()), 0);
  std::set<int> sides;
  const int runs = 400;
  for (int k = 0; k < runs; ++k) {
    const std::uint64_t seed = core::derive_seed(99, static_cast<std::uint64_t>(k));
    const worlds::ObstacleSpec layout = run_obstacles(world, kFloor, seed);
    ASSERT_EQ(boxes_of(layout), boxes_of(run_obstacles(world, kFloor, seed))) << "the same seed, the same boxes";
    ASSERT_EQ(layout.random_boxes, 0) << "a run's layout is concrete";
    ASSERT_EQ(layout.boxes.size(), 4u);
    EXPECT_EQ(layout.boxes[0], world.obstacles.boxes[0]);
    for (std::size_t i = 1; i < layout.boxes.size(); ++i) {
      const worlds::BoxObstacle& b = layout.boxes[i];
      ASSERT_GE(b.w, 2);
      ASSERT_LE(b.w, 4);
      ASSERT_GE(b.h, 2);
      ASSERT_LE(b.h, 4);
      ASSERT_GE(b.x, 0);
      ASSERT_GE(b.y, 0);
      ASSERT_LE(b.x + b.w, kFloor.width_px);
      ASSERT_LE(b.y + b.h, kFloor.height_px);
      sides.insert(b.w);
      for (int y = b.y; y < b.y + b.h; ++y)
        for (int x = b.x; x < b.x + b.w; ++x) ++covered[static_cast<std::size_t>(y) * kFloor.width_px + x];
    }
    layouts.insert(boxes_of(layout));
    // o is clearance_px < radius, cell by cell (occupied_cells looks only near each obstacle).
    const std::vector<std::uint8_t> o = occupied_cells(world, kFloor, layout);
    for (int y = 0; y < kFloor.height_px; ++y)
      for (int x = 0; x < kFloor.width_px; ++x)
        ASSERT_EQ(o[static_cast<std::size_t>(y) * kFloor.width_px + x],
                  layout.clearance_px(x + 0.5, y + 0.5) < radius_px ? 1 : 0)
            << "cell (" << x << ", " << y << ")";
    // The start is drawn beside this run's boxes.
    core::Rng rng(seed);
    const grid::Cell start = draw_start(world, kFloor, seed, rng);
    EXPECT_GE(layout.clearance_px(start.x() + 0.5, start.y() + 0.5), radius_px);
  }
  EXPECT_EQ(layouts.size(), static_cast<std::size_t>(runs)) << "each run its own boxes";
  EXPECT_EQ(sides, (std::set<int>{2, 3, 4}));
  // Positions are uniform over the floor: every pixel, corners and edges too, is under some box.
  EXPECT_EQ(std::count(covered.begin(), covered.end(), 0), 0);
}

TEST(RandomObstacles, AFixedStartIsNeverCovered) {
  worlds::World world = random_box_world();
  world.obstacles.random_boxes = 12;
  world.robot.start = std::pair{9, 7};
  const double radius_px = world.robot.radius_m / kFloor.pixel_size_m;
  for (std::uint64_t seed = 0; seed < 300; ++seed) {
    const worlds::ObstacleSpec layout = run_obstacles(world, kFloor, seed);
    ASSERT_EQ(layout.boxes.size(), 12u);
    ASSERT_GE(layout.clearance_px(9.5, 7.5), radius_px) << "seed " << seed;
  }
  // A start that no draw can leave clear is refused with the field's name.
  world.obstacles.random_boxes = 64;
  world.obstacles.random_box_min_px = 16;
  world.obstacles.random_box_max_px = 16;
  try {
    run_obstacles(world, kFloor, 1);
    ADD_FAILURE() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("obstacles.random_boxes: expected room for the robot"), std::string::npos)
        << e.what();
  }
  // Such a world's starts depend on each run's layout: the overload without one is a bug to call.
  core::Rng rng(1);
  EXPECT_THROW(draw_start(world, kFloor, rng), std::logic_error);
}

// Each robot of a batch drives among its own run's boxes: it sees them in their shade, o marks
// where its disc cannot stand beside them, and its body never enters one over hundreds of moves,
// while another robot's boxes do not stop it.
TEST(RandomObstacles, EachRobotDrivesAmongItsOwnBoxes) {
  worlds::World world = random_box_world();
  world.camera.patch_px = 8;  // wider than the disc: a robot against a box sees it
  const double radius_px = world.robot.radius_m / kFloor.pixel_size_m;
  const int robots = 40;
  const std::size_t area = static_cast<std::size_t>(kFloor.area_px());
  std::vector<std::uint8_t> floors(area * robots);
  for (std::size_t k = 0; k < floors.size(); ++k) floors[k] = static_cast<std::uint8_t>(k % 250 + 1);
  std::vector<std::uint64_t> seeds(robots);
  std::vector<grid::Cell> starts(robots);
  std::vector<worlds::ObstacleSpec> layouts(robots);
  for (int i = 0; i < robots; ++i) {
    seeds[i] = core::derive_seed(5, static_cast<std::uint64_t>(i));
    core::Rng rng(core::derive_seed(seeds[i], 77));
    starts[i] = draw_start(world, kFloor, seeds[i], rng);
    layouts[i] = run_obstacles(world, kFloor, seeds[i]);
  }
  BatchEnv env(world, kFloor, robots);
  env.reset(floors, starts, seeds);
  ASSERT_EQ(env.occupied().size(), area * robots);
  for (int i = 0; i < robots; ++i) {
    const std::vector<std::uint8_t> expected = occupied_cells(world, kFloor, layouts[i]);
    ASSERT_TRUE(std::equal(expected.begin(), expected.end(), env.occupied().begin() + area * i)) << "robot " << i;
    EXPECT_EQ(env.occupied()[area * i + starts[i].y() * kFloor.width_px + starts[i].x()], 0);
  }
  core::Rng rng(11);
  std::vector<grid::Cell> commands(robots);
  double closest = 1e9;
  long blocked = 0, shade_pixels = 0, wrong_pixels = 0, through_anothers_box = 0;
  for (int k = 0; k < 30; ++k) {
    for (int i = 0; i < robots; ++i) {
      const int length = 1 + static_cast<int>(core::uniform_below(rng, 3));
      const int sign = (rng() >> 63) != 0 ? 1 : -1;
      commands[i] = (rng() >> 63) != 0 ? grid::Cell(sign * length, 0) : grid::Cell(0, sign * length);
    }
    env.step(commands);
    for (int i = 0; i < robots; ++i) {
      const Eigen::Vector2d p = env.position_px(i);
      closest = std::min(closest, layouts[i].clearance_px(p.x(), p.y()));
      blocked += env.last_results()[i].blocked ? 1 : 0;
      // Where robot i stands another robot's box may lie: its own world has no body there.
      const worlds::ObstacleSpec& other = layouts[(i + 1) % robots];
      through_anothers_box += other.clearance_px(p.x(), p.y()) == 0.0 ? 1 : 0;
    }
  }
  // y holds the floor where seen, the shade (0) on the robot's own boxes and only there.
  for (int i = 0; i < robots; ++i) {
    const std::uint8_t* y = env.revealed().data() + area * i;
    for (int cy = 0; cy < kFloor.height_px; ++cy)
      for (int cx = 0; cx < kFloor.width_px; ++cx) {
        const std::size_t k = static_cast<std::size_t>(cy) * kFloor.width_px + cx;
        if (!env.seen()[i].seen(cx, cy)) continue;
        const bool on_box = layouts[i].covers(cx + 0.5, cy + 0.5);
        shade_pixels += on_box ? 1 : 0;
        wrong_pixels += y[k] != (on_box ? 0 : floors[area * i + k]) ? 1 : 0;
      }
  }
  std::printf(
      "[ measured ] %d robots x 30 moves: %ld blocked, %ld box pixels seen, closest approach %.3f px (radius "
      "%.2f), %ld poses on another robot's box\n",
      robots, blocked, shade_pixels, closest, radius_px, through_anothers_box);
  EXPECT_EQ(wrong_pixels, 0);
  EXPECT_GT(shade_pixels, 0) << "the robots should see some of their boxes";
  EXPECT_GT(blocked, 0) << "some moves should end against a box";
  // The bound of the fixed obstacles' test (tests/sim/test_obstacles.cpp): one tick's travel and
  // Box2D's slop inside the radius.
  const double tick_travel_px = world.robot.max_speed_mps * world.physics.dt_s / kFloor.pixel_size_m;
  EXPECT_GE(closest, radius_px - tick_travel_px - 0.06);
  EXPECT_GT(through_anothers_box, 0) << "another robot's boxes should not stop this one";
}

}  // namespace
}  // namespace scout::env

namespace scout::env {
namespace {

// A team's starts (docs/SCENARIOS.md § Several robots): the first is the one robot's start, the
// others clear of it (centres more than two bumper radii apart: a diameter and two ticks' travel),
// and a floor without room is refused.
TEST(TeamStarts, TheFirstIsTheLoneRobotsAndTheOthersStandApart) {
  worlds::World world;
  world.team.robots = 3;
  worlds::World alone;
  const grid::FloorFrame floor{.width_px = 28, .height_px = 28, .pixel_size_m = 0.1};
  const double spacing = 2.0 * sim::RobotBatch::bumper_radius_px(sim::RobotParams::from_world(world), floor);
  EXPECT_NEAR(spacing, 2.0 * (2.5 + 2.0 / 60.0 / 0.1), 1e-9);  // the paper's robot: 2 m/s, 60 Hz
  double closest = 1e9;
  for (std::uint64_t seed = 0; seed < 500; ++seed) {
    core::Rng team_rng(seed), lone_rng(seed);
    const std::vector<grid::Cell> starts = draw_team_starts(world, floor, seed, team_rng);
    ASSERT_EQ(starts.size(), 3u);
    EXPECT_EQ(starts[0], draw_start(alone, floor, seed, lone_rng));
    for (int a = 0; a < 3; ++a)
      for (int b = a + 1; b < 3; ++b) closest = std::min(closest, (starts[a] - starts[b]).cast<double>().norm());
  }
  EXPECT_GT(closest, spacing);
  EXPECT_LT(closest, spacing + 1.5) << "the draws should come close to the bound";
  EXPECT_EQ(member_seed(77, 0), 77u);
  EXPECT_NE(member_seed(77, 1), member_seed(77, 2));

  world.team.robots = 8;  // eight discs of 5 px on an 8 x 8 floor: no room
  core::Rng rng(1);
  try {
    draw_team_starts(world, grid::FloorFrame{.width_px = 8, .height_px = 8, .pixel_size_m = 0.1}, 1, rng);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("team.robots: expected room for 8 robots' discs"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace scout::env
