#pragma once
/// The robots' bodies: a batch of Box2D worlds, one per robot, each a zero-gravity plane with
/// walls around its floor and one disc-shaped robot. A move command is executed by a velocity
/// controller ticking the world at a fixed dt until the robot settles on the commanded cell or a
/// tick bound is reached. Box2D stays behind this header.
#include <memory>
#include <span>
#include <string>

#include "sim/grid.hpp"
#include "worlds/world.hpp"

namespace scout::sim {

/// Physical and controller parameters of every robot in a batch (from a world file).
struct RobotParams {
  double radius_m = 0.25;        ///< disc radius, metres
  double mass_kg = 1.0;          ///< body mass, kilograms
  double max_speed_mps = 2.0;    ///< controller speed limit, metres per second
  double kp_per_s = 60.0;        ///< velocity = kp * error, saturated; kp * dt = 1 lands in one tick
  double tolerance_px = 0.05;    ///< settled when the centre is this close to the target cell's centre, pixels
  double dt_s = 1.0 / 60.0;      ///< tick, seconds
  int velocity_iterations = 8;   ///< Box2D solver iterations per tick
  int position_iterations = 3;   ///< Box2D solver iterations per tick
  int max_ticks_per_move = 120;  ///< a move ends after this many ticks even if not settled

  static RobotParams from_world(const worlds::World& world);
};

/// What one robot did during one move.
struct MoveResult {
  int ticks = 0;                  ///< world steps taken (0 for a no-op move already on target)
  bool settled = false;           ///< ended within tolerance of the commanded cell's centre
  bool touched_wall = false;      ///< touched a wall during the move
  double peak_speed_mps = 0.0;    ///< highest speed reached during the move, metres per second
  double beyond_border_px = 0.0;  ///< farthest the centre got past the border pixels' centres, px
};

/// A batch of robots, each alone in its own Box2D world: a robot's trajectory is bit-identical
/// whatever else is in the batch, and the batch is advanced in parallel by robot.
class RobotBatch {
 public:
  /// `count` robots on `frame`; `threads` advance them (0: one per hardware thread).
  RobotBatch(const FloorFrame& frame, const RobotParams& params, int count, int threads = 0);
  ~RobotBatch();
  RobotBatch(const RobotBatch&) = delete;
  RobotBatch& operator=(const RobotBatch&) = delete;

  int size() const;
  int threads() const;
  const FloorFrame& frame() const;
  const RobotParams& params() const;

  /// Puts robot `robot` at rest on the centre of `cell` (the start of a rollout: the only
  /// placement that is not driven).
  void place(int robot, const Cell& cell);

  /// Drives robot i from its grid pose to grid pose + commands[i] (pixels), for every robot
  /// i < commands.size(), all in one call; results[i] tells how it went. Targets are not
  /// clamped: a command past the floor's edge ends against the wall.
  void move(std::span<const Cell> commands, std::span<MoveResult> results);

  /// The robot centre's continuous position in the floor frame, pixels and metres.
  Eigen::Vector2d position_px(int robot) const;
  Eigen::Vector2d position_m(int robot) const;
  /// The grid pose of the actual position (what the agent reads).
  Cell grid_pose(int robot) const;
  /// True while the robot touches a wall.
  bool touching_wall(int robot) const;

  /// Closest approach of the robot's centre to the floor's border-pixel centres: the walls
  /// stop the centre `wall_margin_px()` beyond them (Box2D's contact skin), never further.
  static double wall_margin_px();

 private:
  struct Robot;
  FloorFrame frame_;
  RobotParams params_;
  std::unique_ptr<Robot[]> robots_;
  int count_;
  std::unique_ptr<class WorkerPool> pool_;
};

}  // namespace scout::sim
