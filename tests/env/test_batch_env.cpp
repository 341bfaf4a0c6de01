// The batched environment with the real Box2D robots and the real OSMesa camera: what reset and
// step leave in the arrays, partial resets, the tick hook, and bad input.
#include <gtest/gtest.h>

#include <cstdint>
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

// Floor i's pixel (x, y) is (31 * i + 7 * x + 13 * y) % 251 + 1: never 0, different per robot.
std::vector<std::uint8_t> floors(int count) {
  std::vector<std::uint8_t> out(static_cast<std::size_t>(kFloor.area_px()) * count);
  for (int i = 0; i < count; ++i)
    for (int y = 0; y < kFloor.height_px; ++y)
      for (int x = 0; x < kFloor.width_px; ++x)
        out[static_cast<std::size_t>(i) * kFloor.area_px() + y * kFloor.width_px + x] =
            static_cast<std::uint8_t>((31 * i + 7 * x + 13 * y) % 251 + 1);
  return out;
}

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
  env.reset(f, starts);
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

TEST(BatchEnv, ResettingSomeRobotsLeavesTheOthersAsTheyWere) {
  BatchEnv env(small_world(3), kFloor, 4);
  std::vector<std::uint8_t> f = floors(3);
  env.reset(f, std::vector<grid::Cell>{{2, 2}, {5, 5}, {9, 9}});
  env.step(std::vector<grid::Cell>{{2, 0}, {2, 0}, {-2, 0}});
  const grid::RevealMask kept = env.seen()[0];
  const std::vector<std::uint8_t> fresh = floors(5);  // robot 1 gets floor 4's image
  const std::size_t area = static_cast<std::size_t>(kFloor.area_px());
  const std::vector<std::uint8_t> floor4(fresh.begin() + area * 4, fresh.end());
  env.reset_robots(std::vector<int>{1}, floor4, std::vector<grid::Cell>{{0, 0}});
  EXPECT_EQ(env.poses()[0], grid::Cell(4, 2));
  EXPECT_EQ(env.poses()[1], grid::Cell(0, 0));
  EXPECT_EQ(env.moves()[0], 1);
  EXPECT_EQ(env.moves()[1], 0);
  EXPECT_EQ(env.seen()[0].data(), kept.data());
  EXPECT_EQ(env.seen()[1].count(), 4);
  std::copy(floor4.begin(), floor4.end(), f.begin() + static_cast<std::ptrdiff_t>(area));
  expect_consistent(env, f);
  EXPECT_THROW(env.reset_robots(std::vector<int>{3}, floor4, std::vector<grid::Cell>{{0, 0}}), std::invalid_argument);
}

TEST(BatchEnv, TheTickHookSeesEveryTickOfEveryRobot) {
  BatchEnv env(small_world(3), kFloor, 2);
  env.reset(floors(2), std::vector<grid::Cell>{{2, 2}, {5, 5}});
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

TEST(BatchEnv, BadInputIsRefused) {
  BatchEnv env(small_world(3), kFloor, 2);
  EXPECT_THROW(env.reset(floors(3), std::vector<grid::Cell>{{0, 0}, {1, 1}, {2, 2}}), std::invalid_argument);
  EXPECT_THROW(env.reset(floors(1), std::vector<grid::Cell>{{0, 0}, {1, 1}}), std::invalid_argument);
  EXPECT_THROW(env.reset(floors(1), std::vector<grid::Cell>{{16, 0}}), std::invalid_argument);
  env.reset(floors(2), std::vector<grid::Cell>{{0, 0}, {1, 1}});
  EXPECT_THROW(env.step(std::vector<grid::Cell>{{1, 0}}), std::invalid_argument);
  EXPECT_THROW(BatchEnv(small_world(3), kFloor, 0), std::invalid_argument);
}

}  // namespace
}  // namespace scout::env
