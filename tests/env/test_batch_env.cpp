// The batched environment with the real Box2D robots and the real OSMesa camera: what reset and
// step leave in the arrays, partial resets, the tick hook, and bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "env/batch_env.hpp"
#include "render/camera.hpp"
#include "worlds/world.hpp"

namespace scout::env {
namespace {

const grid::FloorFrame kFloor{.width_px = 16, .height_px = 12, .pixel_size_m = 0.1};

worlds::World small_world(int patch_px) {
  worlds::World w;
  w.camera.patch_px = patch_px;
  return w;
}

// Motion seeds for an exact world, where they change nothing.
std::vector<std::uint64_t> no_motion(std::size_t count) { return std::vector<std::uint64_t>(count, 0); }

// Floor i's pixel (x, y) is (31 * i + 7 * x + 13 * y) % 251 + 1: never 0, different per robot.
std::vector<std::uint8_t> floors(int count, const grid::FloorFrame& frame = kFloor) {
  std::vector<std::uint8_t> out(static_cast<std::size_t>(frame.area_px()) * count);
  for (int i = 0; i < count; ++i)
    for (int y = 0; y < frame.height_px; ++y)
      for (int x = 0; x < frame.width_px; ++x)
        out[static_cast<std::size_t>(i) * frame.area_px() + y * frame.width_px + x] =
            static_cast<std::uint8_t>((31 * i + 7 * x + 13 * y) % 251 + 1);
  return out;
}

// The coarse maps that each robot's looks paint, kept here block by block (every block of the
// floor's grid in a look's window takes its wide pixel's value over what was there), checked
// against the environment's after each look.
class CoarseMaps {
 public:
  CoarseMaps(const BatchEnv& env, const std::vector<std::uint8_t>& floors, render::WideView wide)
      : env_(env),
        floors_(floors),
        wide_(wide),
        area_(static_cast<std::size_t>(env.frame().area_px())),
        grid_(grid::BlockGrid::over(env.frame(), wide.scale)),
        map_(static_cast<std::size_t>(env.count()),
             std::vector<std::uint8_t>(static_cast<std::size_t>(grid_.area()), 0)),
        seen_(map_) {}

  void clear(int robot) {
    std::fill(map_[robot].begin(), map_[robot].end(), 0);
    std::fill(seen_[robot].begin(), seen_[robot].end(), 0);
  }

  // Robot `robot`'s last look, painted here over its own maps, and the environment's window and
  // maps against them (a robot alone).
  void expect_look(int robot) {
    paint(robot, robot);
    expect_maps(robot);
  }

  // Robot `looker`'s last look (its window checked against the CPU's) painted over robot `into`'s
  // maps here.
  void paint(int looker, int into) {
    const grid::FloorFrame& frame = env_.frame();
    const int px = wide_.px, s = wide_.scale;
    std::vector<std::uint8_t> look(static_cast<std::size_t>(px) * px);
    const grid::Cell pose = env_.poses()[looker];
    render::wide_patch(floors_.data() + area_ * looker, frame.width_px, frame.height_px, wide_, {pose.x(), pose.y()},
                       look.data());
    for (std::size_t k = 0; k < look.size(); ++k)
      ASSERT_EQ(env_.wide_patches()[looker * look.size() + k], look[k]) << looker << ", " << k;
    // The look's first block: floor(px / 2) blocks before the one that holds the cell.
    const int u0 = pose.x() / s - px / 2, v0 = pose.y() / s - px / 2;
    for (int v = std::max(0, v0); v < std::min(grid_.rows, v0 + px); ++v)
      for (int u = std::max(0, u0); u < std::min(grid_.columns, u0 + px); ++u) {
        map_[into][static_cast<std::size_t>(v) * grid_.columns + u] = look[(v - v0) * px + (u - u0)];
        seen_[into][static_cast<std::size_t>(v) * grid_.columns + u] = 1;
      }
  }

  // Robot `robot`'s coarse map and where it is set, the environment's against the ones here.
  void expect_maps(int robot) const {
    ASSERT_EQ(env_.wide_grid().columns, grid_.columns);
    ASSERT_EQ(env_.wide_grid().rows, grid_.rows);
    ASSERT_EQ(env_.wide_revealed().size(), map_.size() * grid_.area());
    const std::uint8_t* map = env_.wide_revealed().data() + static_cast<std::size_t>(grid_.area()) * robot;
    const std::uint8_t* seen = env_.wide_seen().data() + static_cast<std::size_t>(grid_.area()) * robot;
    const grid::Cell pose = env_.poses()[robot];
    EXPECT_TRUE(std::equal(map_[robot].begin(), map_[robot].end(), map))
        << "robot " << robot << " at " << pose.x() << ", " << pose.y();
    EXPECT_TRUE(std::equal(seen_[robot].begin(), seen_[robot].end(), seen)) << "robot " << robot;
  }

  long seen_count(int robot) const { return std::count(seen_[robot].begin(), seen_[robot].end(), 1); }

 private:
  const BatchEnv& env_;
  const std::vector<std::uint8_t>& floors_;
  render::WideView wide_;
  std::size_t area_;
  grid::BlockGrid grid_;
  std::vector<std::vector<std::uint8_t>> map_, seen_;
};

// y is the floor exactly where seen and 0 elsewhere; the patch is the CPU crop at the pose.
void expect_consistent(const BatchEnv& env, const std::vector<std::uint8_t>& floor_bytes) {
  const int m = env.patch_px();
  const std::size_t area = static_cast<std::size_t>(kFloor.area_px());
  std::vector<std::uint8_t> crop(static_cast<std::size_t>(m) * m);
  for (int i = 0; i < env.count(); ++i) {
    const std::uint8_t* floor = floor_bytes.data() + area * i;
    const std::uint8_t* y = env.revealed().data() + area * i;
    for (int py = 0; py < kFloor.height_px; ++py)
      for (int px = 0; px < kFloor.width_px; ++px) {
        const std::size_t k = static_cast<std::size_t>(py) * kFloor.width_px + px;
        ASSERT_EQ(y[k], env.seen()[i].seen(px, py) ? floor[k] : 0) << i << " (" << px << ", " << py << ")";
      }
    render::crop_patch(floor, kFloor.width_px, kFloor.height_px, m, {env.poses()[i].x(), env.poses()[i].y()},
                       crop.data());
    for (int k = 0; k < m * m; ++k) ASSERT_EQ(env.patches()[static_cast<std::size_t>(i) * m * m + k], crop[k]) << i;
  }
}

TEST(BatchEnv, ResetAndStepFillTheArraysWithWhatTheCameraSaw) {
  BatchEnv env(small_world(3), kFloor, 8);
  const std::vector<std::uint8_t> f = floors(3);
  const std::vector<grid::Cell> starts = {{2, 2}, {15, 0}, {8, 6}};
  env.reset(f, starts, no_motion(starts.size()));
  ASSERT_EQ(env.count(), 3);
  EXPECT_EQ(std::vector<grid::Cell>(env.poses().begin(), env.poses().end()), starts);
  EXPECT_EQ(env.seen()[0].count(), 9);
  EXPECT_EQ(env.seen()[1].count(), 4);  // a corner clips the 3 x 3 window to 2 x 2
  EXPECT_EQ(env.moves()[2], 0);
  expect_consistent(env, f);

  const std::vector<grid::Cell> commands = {{2, 0}, {0, 2}, {0, 0}};
  env.step(commands);
  EXPECT_EQ(env.poses()[0], grid::Cell(4, 2));
  EXPECT_EQ(env.poses()[1], grid::Cell(15, 2));
  EXPECT_EQ(env.poses()[2], grid::Cell(8, 6));
  EXPECT_EQ(env.moves()[0], 1);
  EXPECT_GT(env.last_results()[0].ticks, 3);  // driven, not teleported
  EXPECT_EQ(env.last_results()[2].ticks, 0);
  EXPECT_NEAR(env.pose_m(0).x(), 0.45, 0.01);
  EXPECT_EQ(env.seen()[0].count(), 15);  // two new columns of three
  expect_consistent(env, f);
  EXPECT_EQ(env.timing().moves, 3);
  EXPECT_GT(env.timing().ticks, 0);
}

// The wider view, driven by the real physics: each robot's coarse window is the CPU reference's at
// its pose, and the coarse map holds, on every block the latest look covered, that block's mean;
// a block seen earlier keeps its value, and the map starts empty again on a reset.
TEST(BatchEnv, TheWiderViewFillsTheCoarseMapWithTheBlocksMeans) {
  worlds::World world = small_world(3);
  world.camera.wide_px = 3;
  world.camera.wide_scale = 2;
  BatchEnv env(world, kFloor, 4);
  const std::vector<std::uint8_t> f = floors(2);
  const std::vector<grid::Cell> starts = {{2, 2}, {12, 9}};
  env.reset(f, starts, no_motion(starts.size()));
  CoarseMaps coarse(env, f, {3, 2});
  coarse.expect_look(0);
  coarse.expect_look(1);
  env.step(std::vector<grid::Cell>{{2, 0}, {0, -2}});
  coarse.expect_look(0);  // the new look over the old one; the rest stays
  coarse.expect_look(1);
  EXPECT_EQ(coarse.seen_count(0), 12) << "two looks of 3 x 3 blocks, one block column apart";
  env.reset(f, starts, no_motion(starts.size()));
  coarse.clear(0);
  coarse.expect_look(0);
  // A world without the wider view has none.
  const std::size_t area = static_cast<std::size_t>(kFloor.area_px());
  BatchEnv plain(small_world(3), kFloor, 2);
  plain.reset(std::vector<std::uint8_t>(f.begin(), f.begin() + static_cast<std::ptrdiff_t>(area)), {{{1, 1}}},
              no_motion(1));
  EXPECT_TRUE(plain.wide_patches().empty() && plain.wide_revealed().empty() && plain.wide_seen().empty());
}

TEST(BatchEnv, TheCoarseMapsRowsArePaintedWholeAtEveryWidthAndForTheWholeTeam) {
  // Windows of 6 blocks of 4 on a 40 x 30 floor (10 x 8 blocks, the last row cut to 2 floor rows):
  // rows painted whole, clipped at either edge and at the top and bottom, and moved over one
  // another. In teams of two, each look goes into both teammates' maps, the second robot's over
  // the first's.
  const grid::FloorFrame frame{.width_px = 40, .height_px = 30, .pixel_size_m = 0.1};
  worlds::World world = small_world(3);
  world.camera.wide_px = 6;
  world.camera.wide_scale = 4;
  world.team.robots = 2;
  BatchEnv env(world, frame, 4);
  const std::size_t area = static_cast<std::size_t>(frame.area_px());
  const std::vector<std::uint8_t> two = floors(2, frame);
  std::vector<std::uint8_t> f;  // a team's robots over the same floor
  for (const int team : {0, 0, 1, 1})
    f.insert(f.end(), two.begin() + static_cast<std::ptrdiff_t>(area * team),
             two.begin() + static_cast<std::ptrdiff_t>(area * (team + 1)));
  const std::vector<grid::Cell> starts = {{20, 15}, {3, 3}, {37, 28}, {9, 15}};
  env.reset(f, starts, no_motion(starts.size()));
  CoarseMaps coarse(env, f, {6, 4});
  auto expect_team_looks = [&] {
    for (int robot = 0; robot < 4; ++robot) {
      const int first = robot - robot % 2;
      coarse.paint(first, robot);
      coarse.paint(first + 1, robot);
      coarse.expect_maps(robot);
    }
  };
  expect_team_looks();
  for (const std::vector<grid::Cell>& commands : {std::vector<grid::Cell>{{4, 0}, {0, 4}, {-4, 0}, {4, 0}},
                                                  std::vector<grid::Cell>{{0, -4}, {1, 0}, {0, -4}, {-4, 0}}}) {
    env.step(commands);
    expect_team_looks();
  }
  EXPECT_EQ(env.poses()[1], grid::Cell(4, 7)) << "the window's blocks [-2, 4): clipped to 4";
}

TEST(BatchEnv, ResettingSomeRobotsLeavesTheOthersAsTheyWere) {
  BatchEnv env(small_world(3), kFloor, 4);
  std::vector<std::uint8_t> f = floors(3);
  env.reset(f, std::vector<grid::Cell>{{2, 2}, {5, 5}, {9, 9}}, no_motion(3));
  env.step(std::vector<grid::Cell>{{2, 0}, {2, 0}, {-2, 0}});
  const grid::RevealMask kept = env.seen()[0];
  const std::vector<std::uint8_t> fresh = floors(5);  // robot 1 gets floor 4's image
  const std::size_t area = static_cast<std::size_t>(kFloor.area_px());
  const std::vector<std::uint8_t> floor4(fresh.begin() + area * 4, fresh.end());
  env.reset_robots(std::vector<int>{1}, floor4, std::vector<grid::Cell>{{0, 0}}, no_motion(1));
  EXPECT_EQ(env.poses()[0], grid::Cell(4, 2));
  EXPECT_EQ(env.poses()[1], grid::Cell(0, 0));
  EXPECT_EQ(env.moves()[0], 1);
  EXPECT_EQ(env.moves()[1], 0);
  EXPECT_EQ(env.seen()[0].data(), kept.data());
  EXPECT_EQ(env.seen()[1].count(), 4);
  std::copy(floor4.begin(), floor4.end(), f.begin() + static_cast<std::ptrdiff_t>(area));
  expect_consistent(env, f);
  EXPECT_THROW(env.reset_robots(std::vector<int>{3}, floor4, std::vector<grid::Cell>{{0, 0}}, no_motion(1)),
               std::invalid_argument);
  // A robot named twice (its buffers are started in parallel) is refused, and nothing moves.
  std::vector<std::uint8_t> twice(floor4);
  twice.insert(twice.end(), floor4.begin(), floor4.end());
  EXPECT_THROW(env.reset_robots(std::vector<int>{2, 2}, twice, std::vector<grid::Cell>{{0, 0}, {1, 1}}, no_motion(2)),
               std::invalid_argument);
  EXPECT_EQ(env.moves()[2], 1);
  expect_consistent(env, f);
}

// Robots started again alone with the wider view, on a floor whose last column and row of blocks
// are cut short: the camera sees the new floors (patch and wider view), their coarse maps start
// empty, and the other robots keep theirs.
TEST(BatchEnv, RobotsResetAloneSeeTheirNewFloorsThroughBothViews) {
  const grid::FloorFrame frame{.width_px = 17, .height_px = 13, .pixel_size_m = 0.1};
  worlds::World world = small_world(3);
  world.camera.wide_px = 3;
  world.camera.wide_scale = 2;
  BatchEnv env(world, frame, 3);
  EXPECT_EQ(env.wide_grid().columns, 9);
  EXPECT_EQ(env.wide_grid().rows, 7);
  std::vector<std::uint8_t> f = floors(3, frame);
  env.reset(f, std::vector<grid::Cell>{{2, 2}, {15, 11}, {8, 6}}, no_motion(3));
  CoarseMaps coarse(env, f, {3, 2});
  for (int i = 0; i < 3; ++i) coarse.expect_look(i);
  env.step(std::vector<grid::Cell>{{2, 0}, {0, 1}, {0, -2}});
  for (int i = 0; i < 3; ++i) coarse.expect_look(i);
  // Robot 1 over a fresh floor from (16, 12), the corner where both cut blocks meet.
  const std::size_t area = static_cast<std::size_t>(frame.area_px());
  const std::vector<std::uint8_t> fresh = floors(5, frame);
  const std::vector<std::uint8_t> floor4(fresh.begin() + static_cast<std::ptrdiff_t>(area * 4), fresh.end());
  env.reset_robots(std::vector<int>{1}, floor4, std::vector<grid::Cell>{{16, 12}}, no_motion(1));
  std::copy(floor4.begin(), floor4.end(), f.begin() + static_cast<std::ptrdiff_t>(area));
  coarse.clear(1);
  coarse.expect_look(1);
  coarse.expect_maps(0);
  coarse.expect_maps(2);
  std::vector<std::uint8_t> crop(9);
  render::crop_patch(floor4.data(), frame.width_px, frame.height_px, 3, {16, 12}, crop.data());
  EXPECT_TRUE(std::equal(crop.begin(), crop.end(), env.patches().begin() + 9));
  env.step(std::vector<grid::Cell>{{-2, 0}, {-2, 0}, {2, 0}});
  for (int i = 0; i < 3; ++i) coarse.expect_look(i);
}

TEST(BatchEnv, TheTickHookSeesEveryTickOfEveryRobot) {
  BatchEnv env(small_world(3), kFloor, 2);
  env.reset(floors(2), std::vector<grid::Cell>{{2, 2}, {5, 5}}, no_motion(2));
  std::vector<int> calls(2, 0);
  std::vector<std::size_t> seen_ticks(2, 0);
  std::vector<Eigen::Vector2d> last(2);
  env.set_tick_hook([&](int robot, std::span<const Eigen::Vector2d> ticks) {
    ++calls[robot];
    seen_ticks[robot] += ticks.size();
    if (!ticks.empty()) last[robot] = ticks.back();
  });
  env.step(std::vector<grid::Cell>{{2, 0}, {0, 0}});
  EXPECT_EQ(calls, (std::vector<int>{1, 1}));
  EXPECT_EQ(seen_ticks[0], static_cast<std::size_t>(env.last_results()[0].ticks));
  EXPECT_EQ(seen_ticks[1], 0u);
  EXPECT_LT((last[0] - env.position_px(0)).norm(), 1e-9);
  env.set_tick_hook({});
  env.step(std::vector<grid::Cell>{{2, 0}, {0, 0}});
  EXPECT_EQ(calls, (std::vector<int>{1, 1}));
}

// With imperfect motion the camera samples the floor where the robot really is (bilinearly,
// render::sample_patch_bilinear within its stated grey level), and the agent writes what it saw
// at the pose it reads (here its odometry's), not where it is.
TEST(BatchEnv, WithImperfectMotionTheCameraLooksFromTheTruePosition) {
  worlds::World world = small_world(4);
  world.motion.scale_sd = 0.2;
  world.motion.heading_sd_deg = 10.0;
  world.motion.pose = worlds::PoseSource::Odometry;
  const int robots = 8;
  BatchEnv env(world, kFloor, robots);
  const std::vector<std::uint8_t> f = floors(robots);
  std::vector<grid::Cell> starts;
  std::vector<std::uint64_t> seeds;
  for (int i = 0; i < robots; ++i) {
    starts.emplace_back(4 + i, 3 + i % 5);
    seeds.push_back(1000 + static_cast<std::uint64_t>(i));
  }
  env.reset(f, starts, seeds);
  const int m = 4;
  const std::size_t area = static_cast<std::size_t>(kFloor.area_px());
  std::vector<std::uint8_t> expected(m * m), crop(m * m);
  int off_cell_centre = 0, differs_from_crop = 0;
  for (int k = 0; k < 12; ++k) {
    std::vector<grid::Cell> commands(robots);
    for (int i = 0; i < robots; ++i) {
      const grid::Cell at = env.poses()[i];
      commands[i] = k % 2 ? grid::Cell(at.x() < 8 ? 2 : -2, 0) : grid::Cell(0, at.y() < 6 ? 2 : -2);
    }
    env.step(commands);
    for (int i = 0; i < robots; ++i) {
      const Eigen::Vector2d p = env.position_px(i);
      render::sample_patch_bilinear(f.data() + area * i, kFloor.width_px, kFloor.height_px, m,
                                    {static_cast<float>(p.x()), static_cast<float>(p.y())}, expected.data());
      const std::uint8_t* patch = env.patches().data() + static_cast<std::size_t>(i) * m * m;
      for (int q = 0; q < m * m; ++q) ASSERT_LE(std::abs(patch[q] - expected[q]), 1) << "robot " << i << " pixel " << q;
      // y holds the patch at the window of the pose the agent reads.
      const grid::Cell pose = env.poses()[i];
      const grid::Window w = grid::camera_window(pose, m, kFloor);
      const std::uint8_t* y = env.revealed().data() + area * i;
      for (int yy = w.y0; yy < w.y1; ++yy)
        for (int xx = w.x0; xx < w.x1; ++xx)
          ASSERT_EQ(y[yy * kFloor.width_px + xx], patch[(yy - pose.y() + m / 2) * m + (xx - pose.x() + m / 2)]);
      off_cell_centre += (p - kFloor.cell_centre_px(pose)).norm() > 0.1 ? 1 : 0;
      render::crop_patch(f.data() + area * i, kFloor.width_px, kFloor.height_px, m, {pose.x(), pose.y()}, crop.data());
      differs_from_crop += std::equal(crop.begin(), crop.end(), patch) ? 0 : 1;
    }
  }
  EXPECT_GT(off_cell_centre, robots * 12 / 2) << "the motion errors should leave most robots off their cells' centres";
  EXPECT_GT(differs_from_crop, robots * 12 / 2) << "the camera should see sub-pixel views, not crops";
}

// The camera over an obstacle sees the obstacle (its shade), not the floor under it.
TEST(BatchEnv, TheCameraSeesObstaclesInTheirShade) {
  worlds::World world = small_world(10);
  world.obstacles.boxes = {{8, 4, 3, 3}};
  world.obstacles.shade = 0;  // black, unlike any pixel of floors(), which are never 0
  BatchEnv env(world, kFloor, 1);
  const std::vector<std::uint8_t> f = floors(1);
  std::vector<std::uint8_t> painted = f;
  for (int y = 4; y < 7; ++y)
    for (int x = 8; x < 11; ++x) painted[static_cast<std::size_t>(y) * kFloor.width_px + x] = 0;
  std::vector<std::uint8_t> crop(100);
  const auto zeros = [&env] {
    return static_cast<int>(std::count(env.patches().begin(), env.patches().end(), std::uint8_t{0}));
  };
  // At (3, 5) the window spans x = -2 .. 7: two columns off the floor, the box (x >= 8) outside.
  env.reset(f, std::vector<grid::Cell>{{3, 5}}, no_motion(1));
  EXPECT_EQ(zeros(), 20);
  // One pixel right (the disc still clear of the box) the window spans x = -1 .. 8: the box's
  // first column (rows 4 .. 6) comes in, in its shade.
  env.step(std::vector<grid::Cell>{{1, 0}});
  ASSERT_EQ(env.poses()[0], grid::Cell(4, 5));
  ASSERT_FALSE(env.last_results()[0].blocked);
  EXPECT_EQ(zeros(), 10 + 3);
  render::crop_patch(painted.data(), kFloor.width_px, kFloor.height_px, 10, {4, 5}, crop.data());
  EXPECT_TRUE(std::equal(crop.begin(), crop.end(), env.patches().begin()));
}

// Several robots on one floor (docs/SCENARIOS.md § Several robots): what one robot of a team has
// seen, every robot of the team has; the other team's masks are its own.
TEST(BatchEnv, ATeamSharesWhatEachOfItsRobotsHasSeen) {
  worlds::World world = small_world(3);
  world.team.robots = 2;
  BatchEnv env(world, kFloor, 4);
  EXPECT_EQ(env.team_size(), 2);
  std::vector<std::uint8_t> f = floors(4);
  std::copy_n(f.begin(), kFloor.area_px(), f.begin() + kFloor.area_px());  // a team shares its floor
  std::copy_n(f.begin() + 2 * kFloor.area_px(), kFloor.area_px(), f.begin() + 3 * kFloor.area_px());
  const std::vector<grid::Cell> starts = {{2, 2}, {12, 8}, {2, 9}, {13, 2}};
  env.reset(f, starts, no_motion(starts.size()));
  // Each robot alone would have seen 9 pixels; each team's mask holds both windows.
  for (int i = 0; i < 4; ++i) EXPECT_EQ(env.seen()[i].count(), 18) << i;
  expect_consistent(env, f);

  std::vector<grid::RevealMask> alone(4, grid::RevealMask(kFloor));
  for (int i = 0; i < 4; ++i) alone[i].reveal(grid::camera_window(starts[i], 3, kFloor));
  const std::vector<std::vector<grid::Cell>> moves = {
      {{2, 0}, {-2, 0}, {0, -2}, {0, 2}}, {{2, 0}, {0, -2}, {2, 0}, {-2, 0}}, {{0, 2}, {-2, 0}, {0, 0}, {0, 2}}};
  for (const std::vector<grid::Cell>& commands : moves) {
    env.step(commands);
    for (int i = 0; i < 4; ++i) alone[i].reveal(grid::camera_window(env.poses()[i], 3, kFloor));
    expect_consistent(env, f);
  }
  for (int team = 0; team < 2; ++team) {
    const int a = 2 * team, b = a + 1;
    EXPECT_EQ(env.seen()[a].data(), env.seen()[b].data()) << team;
    for (int y = 0; y < kFloor.height_px; ++y)
      for (int x = 0; x < kFloor.width_px; ++x)
        EXPECT_EQ(env.seen()[a].seen(x, y), alone[a].seen(x, y) || alone[b].seen(x, y)) << team << " " << x << "," << y;
    EXPECT_GT(env.seen()[a].count(), std::max(alone[a].count(), alone[b].count()));
  }
  EXPECT_NE(env.seen()[0].data(), env.seen()[2].data());

  // A team starts again whole, its robots listed in order.
  const std::vector<std::uint8_t> one(f.begin(), f.begin() + kFloor.area_px());
  EXPECT_THROW(env.reset_robots(std::vector<int>{1}, one, std::vector<grid::Cell>{{3, 3}}, no_motion(1)),
               std::invalid_argument);
  std::vector<std::uint8_t> two(f.begin(), f.begin() + 2 * kFloor.area_px());
  env.reset_robots(std::vector<int>{2, 3}, two, std::vector<grid::Cell>{{3, 3}, {10, 3}}, no_motion(2));
  EXPECT_EQ(env.seen()[2].count(), 18);
  EXPECT_EQ(env.seen()[3].count(), 18);
  // y cleared within the mask's bounds, which held the teammate's windows too: nothing is left of
  // the team's earlier run.
  std::vector<std::uint8_t> now(f);
  std::copy(two.begin(), two.end(), now.begin() + 2 * kFloor.area_px());
  expect_consistent(env, now);
  const std::vector<std::uint8_t> three(f.begin(), f.begin() + 3 * kFloor.area_px());
  EXPECT_THROW(env.reset(three, std::vector<grid::Cell>(3, grid::Cell(1, 1)), no_motion(3)),
               std::invalid_argument);  // not whole teams
}

TEST(BatchEnv, BadInputIsRefused) {
  BatchEnv env(small_world(3), kFloor, 2);
  EXPECT_THROW(env.reset(floors(3), std::vector<grid::Cell>{{0, 0}, {1, 1}, {2, 2}}, no_motion(3)),
               std::invalid_argument);
  EXPECT_THROW(env.reset(floors(1), std::vector<grid::Cell>{{0, 0}, {1, 1}}, no_motion(2)), std::invalid_argument);
  EXPECT_THROW(env.reset(floors(1), std::vector<grid::Cell>{{16, 0}}, no_motion(1)), std::invalid_argument);
  EXPECT_THROW(env.reset(floors(1), std::vector<grid::Cell>{{0, 0}}, no_motion(2)), std::invalid_argument);
  env.reset(floors(2), std::vector<grid::Cell>{{0, 0}, {1, 1}}, no_motion(2));
  EXPECT_THROW(env.step(std::vector<grid::Cell>{{1, 0}}), std::invalid_argument);
  EXPECT_THROW(BatchEnv(small_world(3), kFloor, 0), std::invalid_argument);
}

}  // namespace
}  // namespace scout::env
