#pragma once
/// The agent's state (METHOD.md § The agent's state) written as floats from what a robot has seen
/// and where it is. Torch-free: callers write straight into a tensor's storage.
#include <cstdint>
#include <span>

#include "grid/grid.hpp"

namespace scout::agent {

/// One robot's view, all arrays H * W row-major (the floor frame).
struct RobotView {
  const std::uint8_t* revealed = nullptr;  ///< the floor's bytes where seen (anything elsewhere)
  const std::uint8_t* seen = nullptr;      ///< 1 where seen so far, 0 elsewhere
  grid::Cell pose;                         ///< current grid pose
  const grid::Cell* goal = nullptr;        ///< goal for g_l; null: no goal yet (g_l all ones)
  const std::uint8_t* occupied = nullptr;  ///< o: 1 where the robot cannot stand; null: no obstacles (o all zeros)
  std::span<const grid::Cell> teammate_poses{};  ///< the team's other robots' grid poses (none alone)
  std::span<const grid::Cell> teammate_goals{};  ///< the goals they hold now (those that have one)
  const std::uint8_t* wide_revealed = nullptr;   ///< the wider view's coarse map, a byte a block of wide_grid
                                                 ///< (env::BatchEnv::wide_revealed)
  const std::uint8_t* wide_seen = nullptr;       ///< 1 where it is set; null: nothing seen coarsely
  grid::BlockGrid wide_grid{};                   ///< the floor's blocks the two are laid on
};

/// A floor byte as the networks see it: p / 255 - 0.5 (METHOD.md § Symbols).
inline float pixel_value(std::uint8_t p) { return static_cast<float>(p) / 255.0f - 0.5f; }

/// y: pixel_value(revealed) where seen, 0 elsewhere. Writes H * W floats (c = 1).
void write_revealed_image(const grid::FloorFrame& frame, const RobotView& view, float* dst);

/// u = concat(y, l, h, g_l), then o with `occupancy`, then t_p and t_g with `team`: writes
/// (4 + occupancy + 2 team) * H * W floats, channel-major. l: 0 on the camera window at the pose,
/// 1 elsewhere; h: 0 where seen, 1 elsewhere; g_l: 0 on the m x m window around the goal, 1
/// elsewhere (all ones without a goal); o: 1 where view.occupied says the robot cannot stand, 0
/// elsewhere; t_p: 0 on the camera windows at the teammates' poses, 1 elsewhere; t_g: 0 on the
/// m x m windows around the teammates' goals, 1 elsewhere (both all ones for a robot alone).
/// With `wide`, then y_w (pixel_value of wide_revealed where wide_seen, 0 elsewhere) and h_w (0
/// where wide_seen, 1 elsewhere): 2 more planes, each floor pixel taking its block's value.
void write_planner_input(const grid::FloorFrame& frame, int patch_px, const RobotView& view, float* dst,
                         bool occupancy = false, bool team = false, bool wide = false);

}  // namespace scout::agent
