#include "env/protocol.hpp"

#include <stdexcept>

namespace scout::env {

void forced_axes(std::span<const grid::Cell> poses, std::span<const grid::Cell> goals, std::span<std::uint8_t> need,
                 std::span<grid::Axis> axes) {
  if (goals.size() < poses.size() || need.size() < poses.size() || axes.size() < poses.size())
    throw std::invalid_argument("forced_axes: fewer goals, needs or axes than poses");
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const grid::Decision d = grid::decide(poses[i], goals[i]);
    need[i] = d == grid::Decision::Choose;
    axes[i] = d == grid::Decision::Vertical     ? grid::Axis::Vertical
              : d == grid::Decision::Horizontal ? grid::Axis::Horizontal
                                                : grid::Axis::None;
  }
}

void move_commands(std::span<const grid::Cell> poses, std::span<const grid::Cell> goals,
                   std::span<const grid::Axis> axes, int step_px, std::span<grid::Cell> commands) {
  if (goals.size() < poses.size() || axes.size() < poses.size() || commands.size() < poses.size())
    throw std::invalid_argument("move_commands: fewer goals, axes or commands than poses");
  for (std::size_t i = 0; i < poses.size(); ++i) commands[i] = grid::move_command(poses[i], goals[i], axes[i], step_px);
}

}  // namespace scout::env
