#pragma once
/// The paper's layered protocol on top of BatchEnv (METHOD.md § One rollout): a goal per robot per
/// episode, and each move along one axis toward it, the axis forced where the goal is in line
/// with the pose and chosen by the policy (chi = 1) elsewhere.
#include <cstdint>
#include <span>

#include "grid/grid.hpp"

namespace scout::env {

/// For each robot: need[i] = 1 where the policy must choose the axis (the goal differs from the
/// pose in both x and y), else 0 with axes[i] the forced axis (Vertical when x agrees, Horizontal
/// when y agrees, None at the goal). Axes where need[i] = 1 are left for the policy to fill.
void forced_axes(std::span<const grid::Cell> poses, std::span<const grid::Cell> goals, std::span<std::uint8_t> need,
                 std::span<grid::Axis> axes);

/// Each robot's move: along axes[i] toward goals[i], at most step_px pixels (zero with Axis::None).
void move_commands(std::span<const grid::Cell> poses, std::span<const grid::Cell> goals,
                   std::span<const grid::Axis> axes, int step_px, std::span<grid::Cell> commands);

}  // namespace scout::env
