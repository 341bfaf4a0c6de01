// The layered protocol over a batch: the same decisions and moves as grid::decide and
// grid::move_command, robot by robot.
#include <gtest/gtest.h>

#include <vector>

#include "env/protocol.hpp"

namespace scout::env {
namespace {

TEST(Protocol, ForcedAxesAndMovesFollowTheGridRules) {
  const std::vector<grid::Cell> poses = {{5, 5}, {5, 5}, {5, 5}, {5, 5}, {0, 27}};
  const std::vector<grid::Cell> goals = {{5, 5}, {5, 9}, {1, 5}, {8, 1}, {27, 0}};
  std::vector<std::uint8_t> need(5, 7);
  std::vector<grid::Axis> axes(5, grid::Axis::Horizontal);
  forced_axes(poses, goals, need, axes);
  EXPECT_EQ(need, (std::vector<std::uint8_t>{0, 0, 0, 1, 1}));
  EXPECT_EQ(axes[0], grid::Axis::None);      // at the goal
  EXPECT_EQ(axes[1], grid::Axis::Vertical);  // x agrees
  EXPECT_EQ(axes[2], grid::Axis::Horizontal);
  axes[3] = grid::Axis::Vertical;  // the policy's choices
  axes[4] = grid::Axis::Horizontal;
  std::vector<grid::Cell> commands(5);
  move_commands(poses, goals, axes, 2, commands);
  const std::vector<grid::Cell> expected = {{0, 0}, {0, 2}, {-2, 0}, {0, -2}, {2, 0}};
  EXPECT_EQ(commands, expected);
  for (std::size_t i = 0; i < poses.size(); ++i)
    EXPECT_EQ(commands[i], grid::move_command(poses[i], goals[i], axes[i], 2)) << i;
  std::vector<grid::Cell> short_commands(2);
  EXPECT_THROW(move_commands(poses, goals, axes, 2, short_commands), std::invalid_argument);
}

}  // namespace
}  // namespace scout::env
