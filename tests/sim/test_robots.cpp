// Physics in the loop: the real Box2D world, driven by the real controller.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <random>
#include <vector>

#include "sim/robots.hpp"

namespace scout::sim {
namespace {

const grid::FloorFrame kFloor{28, 28, 0.1};

// The paper preset: 2 m/s at 0.1 m/px and dt = 1/60 s is 1/3 px per tick.
RobotParams preset() { return RobotParams{}; }

// How far past the border pixels' centres the centre may get while hitting a wall: the wall
// margin plus one tick's travel, and always less than half a pixel (it stays on the border pixel).
const double kImpactBound_px = RobotBatch::wall_margin_px() + 1.0 / 3.0 + 0.01;

MoveResult move_one(RobotBatch& batch, int robot, const grid::Cell& command) {
  std::vector<grid::Cell> commands(static_cast<std::size_t>(robot) + 1, grid::Cell(0, 0));
  commands[robot] = command;
  std::vector<MoveResult> results(commands.size());
  batch.move(commands, results);
  return results[robot];
}

void expect_on_cell_centre(const RobotBatch& batch, int robot, const grid::Cell& cell) {
  const Eigen::Vector2d centre = kFloor.cell_centre_px(cell);
  const Eigen::Vector2d at = batch.position_px(robot);
  EXPECT_EQ(batch.grid_pose(robot), cell);
  EXPECT_NEAR(at.x(), centre.x(), preset().controller.tolerance_px);
  EXPECT_NEAR(at.y(), centre.y(), preset().controller.tolerance_px);
}

TEST(RobotBatch, PlacedRobotRestsOnTheCellCentre) {
  RobotBatch batch(kFloor, preset(), 1);
  batch.place(0, {5, 9});
  expect_on_cell_centre(batch, 0, {5, 9});
  EXPECT_NEAR(batch.position_m(0).x(), 0.55, 1e-6);
}

TEST(RobotBatch, MovesLandOnTheCommandedCellInAllFourDirections) {
  const grid::Cell commands[] = {{2, 0}, {-2, 0}, {0, 2}, {0, -2}, {1, 0}, {0, -1}};
  for (const grid::Cell& command : commands) {
    RobotBatch batch(kFloor, preset(), 1);
    batch.place(0, {14, 14});
    const MoveResult r = move_one(batch, 0, command);
    EXPECT_TRUE(r.settled);
    EXPECT_FALSE(r.touched_wall);
    expect_on_cell_centre(batch, 0, grid::Cell(14, 14) + command);
    // Driven, not teleported: 2 px at 1/3 px per tick needs at least 6 ticks, and the speed
    // never exceeds the limit.
    EXPECT_GE(r.ticks, 3 * std::abs(command.x() + command.y()));
    EXPECT_GT(r.peak_speed_mps, 0.5 * preset().body.max_speed_mps);
    EXPECT_LE(r.peak_speed_mps, preset().body.max_speed_mps * (1 + 1e-5));
  }
}

// The tick traces (animations): one centre per tick, each at most a tick's travel from the last,
// ending where the robot is; the same moves with and without traces end in the same place.
TEST(RobotBatch, TickTracesFollowTheBodyTickByTick) {
  RobotBatch traced(kFloor, preset(), 3), plain(kFloor, preset(), 3);
  const std::vector<grid::Cell> starts = {{14, 14}, {0, 5}, {27, 27}};
  for (int i = 0; i < 3; ++i) {
    traced.place(i, starts[i]);
    plain.place(i, starts[i]);
  }
  const std::vector<grid::Cell> commands = {{2, 0}, {-2, 0}, {0, 0}};  // the second runs into the wall
  std::vector<MoveResult> traced_results(3), plain_results(3);
  std::vector<std::vector<Eigen::Vector2d>> traces(3);
  traced.move(commands, traced_results, traces);
  plain.move(commands, plain_results);
  const double tick_travel_px = preset().body.max_speed_mps * preset().physics.dt_s / kFloor.pixel_size_m;
  for (int i = 0; i < 3; ++i) {
    ASSERT_EQ(traces[i].size(), static_cast<std::size_t>(traced_results[i].ticks)) << i;
    EXPECT_EQ(traced_results[i].ticks, plain_results[i].ticks) << i;
    Eigen::Vector2d last = kFloor.cell_centre_px(starts[i]);
    for (const Eigen::Vector2d& p : traces[i]) {
      EXPECT_LE((p - last).norm(), tick_travel_px * (1 + 1e-4)) << i;
      last = p;
    }
    if (!traces[i].empty()) {
      EXPECT_LT((traces[i].back() - traced.position_px(i)).norm(), 1e-9) << i;
    }
    EXPECT_LT((traced.position_px(i) - plain.position_px(i)).norm(), 1e-12) << i;
  }
  EXPECT_GT(traces[0].size(), 5u);
  EXPECT_TRUE(traces[2].empty()) << "a robot already on its cell takes no tick";
  std::vector<std::vector<Eigen::Vector2d>> too_few(2);
  EXPECT_THROW(traced.move(commands, traced_results, too_few), std::invalid_argument);
}

TEST(RobotBatch, MovesOntoAndAwayFromEachBorder) {
  // For each border: onto it by 1 and by 2 pixels, then away from it by 2, and along it.
  struct Case {
    grid::Cell start, onto1, onto2, away, along;
  };
  const Case cases[] = {
      {{2, 10}, {-1, 0}, {-1, 0}, {2, 0}, {0, 2}},   // left: 2 -> 1 -> 0 -> 2
      {{25, 10}, {1, 0}, {1, 0}, {-2, 0}, {0, -2}},  // right: 25 -> 26 -> 27 -> 25
      {{10, 2}, {0, -1}, {0, -1}, {0, 2}, {2, 0}},   // top
      {{10, 25}, {0, 1}, {0, 1}, {0, -2}, {-2, 0}},  // bottom
      {{25, 25}, {0, 2}, {2, 0}, {-2, -2}, {0, 0}},  // onto the corner by 2 on each axis
  };
  for (const Case& c : cases) {
    RobotBatch batch(kFloor, preset(), 1);
    batch.place(0, c.start);
    grid::Cell expected = c.start;
    for (const grid::Cell& step : {c.onto1, c.onto2, c.away, c.along}) {
      const MoveResult r = move_one(batch, 0, step);
      expected += step;
      ASSERT_TRUE(kFloor.contains(expected));
      EXPECT_TRUE(r.settled) << "to " << expected.transpose();
      EXPECT_FALSE(r.touched_wall) << "to " << expected.transpose();
      EXPECT_EQ(r.beyond_border_px, 0.0);
      expect_on_cell_centre(batch, 0, expected);
    }
  }
}

TEST(RobotBatch, MovesReachEveryBorderCellWithoutTouchingTheWall) {
  // Drive along all four borders, and from near each border onto it.
  RobotBatch batch(kFloor, preset(), 1);
  batch.place(0, {2, 2});
  const grid::Cell legs[] = {{-2, 0}, {0, -2}};
  for (const grid::Cell& c : legs) {
    const MoveResult r = move_one(batch, 0, c);
    EXPECT_TRUE(r.settled);
    EXPECT_FALSE(r.touched_wall);
  }
  expect_on_cell_centre(batch, 0, {0, 0});
  const struct {
    grid::Cell step;
    int count;
  } sides[] = {{{1, 0}, 27}, {{0, 1}, 27}, {{-1, 0}, 27}, {{0, -1}, 27}};
  grid::Cell expected(0, 0);
  for (const auto& side : sides) {
    for (int k = 0; k < side.count; ++k) {
      const MoveResult r = move_one(batch, 0, side.step);
      expected += side.step;
      ASSERT_TRUE(r.settled) << "at " << expected.transpose();
      EXPECT_FALSE(r.touched_wall) << "at " << expected.transpose();
      expect_on_cell_centre(batch, 0, expected);
    }
  }
}

TEST(RobotBatch, AMovePastTheEdgeIsStoppedByTheWall) {
  ASSERT_LT(kImpactBound_px, 0.5);  // the bound itself keeps the centre on the border pixel
  const struct {
    grid::Cell start, command;
  } cases[] = {{{0, 14}, {-2, 0}}, {{1, 14}, {-5, 0}}, {{27, 3}, {2, 0}},   {{14, 0}, {0, -2}},
               {{14, 27}, {0, 2}}, {{27, 27}, {3, 3}}, {{26, 1}, {40, -40}}};
  for (const auto& c : cases) {
    RobotBatch batch(kFloor, preset(), 1);
    batch.place(0, c.start);
    const MoveResult r = move_one(batch, 0, c.command);
    EXPECT_TRUE(r.touched_wall) << c.start.transpose();
    EXPECT_TRUE(batch.touching_wall(0));
    // At no tick did the centre leave the border pixel: during the impact it may sink one tick's
    // travel (1/3 px) into the wall's contact skin before the contact pushes it back.
    EXPECT_GT(r.beyond_border_px, 0.0);
    EXPECT_LE(r.beyond_border_px, kImpactBound_px) << c.start.transpose();
    EXPECT_FALSE(r.settled);  // the target is unreachable
    EXPECT_EQ(r.ticks, preset().physics.max_ticks_per_move);
    // The centre stays on the floor's border pixels: within the wall margin of their centres.
    const Eigen::Vector2d at = batch.position_px(0);
    const double margin = RobotBatch::wall_margin_px() + 0.05;
    EXPECT_GE(at.x(), 0.5 - margin);
    EXPECT_LE(at.x(), 27.5 + margin);
    EXPECT_GE(at.y(), 0.5 - margin);
    EXPECT_LE(at.y(), 27.5 + margin);
    const grid::Cell expected{std::clamp(c.start.x() + c.command.x(), 0, 27),
                              std::clamp(c.start.y() + c.command.y(), 0, 27)};
    EXPECT_EQ(batch.grid_pose(0), expected);
  }
}

TEST(RobotBatch, BehavesTheSameInPixelsAtAnyFloorScale) {
  // Box2D's tolerances are fixed lengths; the robots must still land on cells and stay on the
  // floor whether a pixel is 5 mm or 5 m (sizes and speeds scale with the pixel).
  for (double pixel_size_m : {0.005, 0.01, 0.03, 0.1, 1.0, 5.0}) {
    const grid::FloorFrame floor{28, 28, pixel_size_m};
    RobotParams params = preset();
    params.body.radius_m = 2.5 * pixel_size_m;
    params.body.max_speed_mps = 20.0 * pixel_size_m;  // 20 px/s, 1/3 px per tick
    RobotBatch batch(floor, params, 1);
    batch.place(0, {1, 14});
    MoveResult r = move_one(batch, 0, {2, 0});
    EXPECT_TRUE(r.settled) << pixel_size_m;
    EXPECT_EQ(r.ticks, 6) << pixel_size_m;
    EXPECT_EQ(batch.grid_pose(0), grid::Cell(3, 14));
    EXPECT_NEAR(r.peak_speed_mps, params.body.max_speed_mps, 1e-4 * params.body.max_speed_mps);
    r = move_one(batch, 0, {-8, 0});  // 5 px past the edge
    EXPECT_TRUE(r.touched_wall) << pixel_size_m;
    EXPECT_FALSE(r.settled) << pixel_size_m;
    const Eigen::Vector2d at = batch.position_px(0);
    EXPECT_GE(at.x(), 0.5 - RobotBatch::wall_margin_px() - 0.05) << pixel_size_m;
    EXPECT_EQ(batch.grid_pose(0), grid::Cell(0, 14));
    EXPECT_NEAR(batch.position_m(0).x(), at.x() * pixel_size_m, 1e-6 * pixel_size_m);
  }
}

TEST(RobotBatch, AFastRobotDoesNotTunnelThroughTheWall) {
  // 60 m/s at dt = 1/60 s is 1 m = 10 px per tick, four times the radius: only continuous
  // collision can stop it.
  RobotParams fast = preset();
  fast.body.max_speed_mps = 60.0;
  fast.physics.max_ticks_per_move = 20;
  const grid::Cell commands[] = {{-60, 0}, {60, 0}, {0, -60}, {0, 60}, {45, 45}};
  for (const grid::Cell& command : commands) {
    RobotBatch batch(kFloor, fast, 1);
    batch.place(0, {14, 14});
    const MoveResult r = move_one(batch, 0, command);
    EXPECT_TRUE(r.touched_wall);
    EXPECT_GT(r.peak_speed_mps, 10.0);
    // Continuous collision stops it at the wall within the tick: never off the floor, at any tick.
    EXPECT_LT(r.beyond_border_px, 0.5) << command.transpose();
    EXPECT_LE(r.beyond_border_px, RobotBatch::wall_margin_px() + 0.05) << command.transpose();
  }
}

TEST(RobotBatch, NeverLeavesTheFloorUnderRandomPushes) {
  RobotBatch batch(kFloor, preset(), 8);
  std::mt19937 rng(3);
  for (int i = 0; i < 8; ++i) batch.place(i, {static_cast<int>(rng() % 28), static_cast<int>(rng() % 28)});
  std::vector<grid::Cell> commands(8);
  std::vector<MoveResult> results(8);
  for (int step = 0; step < 60; ++step) {
    for (grid::Cell& c : commands) c = grid::Cell(static_cast<int>(rng() % 41) - 20, static_cast<int>(rng() % 41) - 20);
    batch.move(commands, results);
    for (int i = 0; i < 8; ++i) {
      ASSERT_LE(results[i].beyond_border_px, kImpactBound_px);
      const Eigen::Vector2d at = batch.position_px(i);
      ASSERT_GT(at.x(), 0.0);
      ASSERT_LT(at.x(), 28.0);
      ASSERT_GT(at.y(), 0.0);
      ASSERT_LT(at.y(), 28.0);
    }
  }
}

// FNV-1a over the exact float positions: any change in any bit changes the hash.
std::uint64_t hash_positions(const RobotBatch& batch, std::uint64_t h) {
  for (int i = 0; i < batch.size(); ++i) {
    const Eigen::Vector2d p = batch.position_m(i);
    unsigned char bytes[sizeof(double) * 2];
    std::memcpy(bytes, p.data(), sizeof bytes);
    for (unsigned char b : bytes) h = (h ^ b) * 1099511628211ull;
  }
  return h;
}

std::uint64_t random_drive_hash(std::uint32_t seed, int robots, int moves, int threads = 0) {
  RobotBatch batch(kFloor, preset(), robots, threads);
  std::mt19937 rng(seed);
  for (int i = 0; i < robots; ++i) batch.place(i, {static_cast<int>(rng() % 28), static_cast<int>(rng() % 28)});
  std::vector<grid::Cell> commands(robots);
  std::vector<MoveResult> results(robots);
  std::uint64_t h = 1469598103934665603ull;
  for (int m = 0; m < moves; ++m) {
    for (grid::Cell& c : commands)
      c = (rng() % 2) ? grid::Cell(static_cast<int>(rng() % 5) - 2, 0) : grid::Cell(0, static_cast<int>(rng() % 5) - 2);
    batch.move(commands, results);
    h = hash_positions(batch, h);
  }
  return h;
}

TEST(RobotBatch, SameSeedSameTrajectoryHashDifferentSeedDifferent) {
  const std::uint64_t a = random_drive_hash(11, 16, 20);
  EXPECT_EQ(a, random_drive_hash(11, 16, 20));
  EXPECT_NE(a, random_drive_hash(12, 16, 20));
}

TEST(RobotBatch, ResultDoesNotDependOnTheThreadCount) {
  const std::uint64_t one = random_drive_hash(5, 64, 20, 1);
  EXPECT_EQ(one, random_drive_hash(5, 64, 20, 2));
  EXPECT_EQ(one, random_drive_hash(5, 64, 20, 3));
}

TEST(RobotBatch, RobotsInOneBatchDoNotInteract) {
  // Robot 0 alone, and robot 0 among 239 others that all start on its very cell and drive
  // through it: its positions are bit-identical.
  const grid::Cell start{14, 14};
  const grid::Cell path[] = {{2, 0}, {0, 2}, {-1, 0}, {0, -2}, {-2, 0}, {0, 1}};
  auto drive = [&](int robots) {
    RobotBatch batch(kFloor, preset(), robots);
    for (int i = 0; i < robots; ++i) batch.place(i, start);
    std::vector<grid::Cell> commands(robots);
    std::vector<MoveResult> results(robots);
    std::vector<Eigen::Vector2d> trace;
    for (std::size_t m = 0; m < std::size(path); ++m) {
      for (int i = 0; i < robots; ++i) commands[i] = i == 0 ? path[m] : path[(m + i) % std::size(path)];
      batch.move(commands, results);
      trace.push_back(batch.position_m(0));
    }
    return trace;
  };
  const auto alone = drive(1);
  const auto crowded = drive(240);
  ASSERT_EQ(alone.size(), crowded.size());
  for (std::size_t m = 0; m < alone.size(); ++m) {
    EXPECT_EQ(alone[m].x(), crowded[m].x());
    EXPECT_EQ(alone[m].y(), crowded[m].y());
  }
}

}  // namespace
}  // namespace scout::sim
