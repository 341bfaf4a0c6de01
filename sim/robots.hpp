#pragma once
/// The robots' bodies: a batch of Box2D worlds, one per team of robots (one robot: the paper's),
/// each a zero-gravity plane with walls around its floor and the team's disc-shaped robots. A move command is executed
/// by a velocity controller ticking the world at a fixed dt until the robot settles on the commanded cell or a tick
/// bound is reached. Box2D stays behind this header.
#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "grid/grid.hpp"
#include "worlds/world.hpp"

namespace scout::core {
class WorkerPool;
}  // namespace scout::core

namespace scout::sim {

/// Physical and controller parameters of every robot in a batch: the world file's own sections,
/// so their defaults and ranges are written once (worlds/world.hpp).
struct RobotParams {
  worlds::RobotSpec body;             ///< disc radius, mass, speed limit (the start is the caller's)
  worlds::ControllerSpec controller;  ///< gain and settling tolerance
  worlds::PhysicsSpec physics;        ///< tick, solver iterations, tick bound per move
  worlds::MotionSpec motion;          ///< unsensed scale and heading errors of each move, the pose the agent reads
  worlds::PushSpec pushes;            ///< random pushes during moves
  worlds::ObstacleSpec obstacles;     ///< static bodies on the floor
  worlds::TeamSpec team;              ///< robots per floor: K consecutive robots of a batch share one world

  /// Every move lands on its commanded cell (no motion error, no pushes): the paper's robot.
  bool exact() const { return motion.exact() && pushes.none(); }

  static RobotParams from_world(const worlds::World& world);
};

/// What one robot did during one move.
struct MoveResult {
  int ticks = 0;                  ///< world steps taken (0 for a no-op move already on target)
  bool settled = false;           ///< ended within tolerance of the commanded cell's centre
  bool touched_wall = false;      ///< touched a wall during the move
  double peak_speed_mps = 0.0;    ///< highest speed reached during the move, metres per second
  double beyond_border_px = 0.0;  ///< farthest the centre got past the border pixels' centres, px
  bool pushed = false;            ///< a push hit the robot during the move
  bool blocked = false;           ///< an obstacle or a teammate stopped the robot: the move ended at contact
};

/// A batch of robots in teams of K (params.team.robots): robots kK .. kK + K - 1 share team k's
/// Box2D world, tick together and collide; a team's trajectory is bit-identical whatever else is
/// in the batch, and the batch is advanced in parallel by team. With K = 1 every robot is alone.
class RobotBatch {
 public:
  /// `count` robots (a multiple of K) on `frame`; `threads` advance them (0: one per hardware thread).
  RobotBatch(const grid::FloorFrame& frame, const RobotParams& params, int count, int threads = 0);
  /// The same, advanced by a pool shared with other per-robot work (env::BatchEnv's observations).
  RobotBatch(const grid::FloorFrame& frame, const RobotParams& params, int count,
             std::shared_ptr<core::WorkerPool> pool);
  ~RobotBatch();
  RobotBatch(const RobotBatch&) = delete;
  RobotBatch& operator=(const RobotBatch&) = delete;

  int size() const;
  int team_size() const;  ///< K
  int threads() const;
  const grid::FloorFrame& frame() const;
  const RobotParams& params() const;

  /// Puts robot `robot` at rest on the centre of `cell` (the start of a rollout: the only
  /// placement that is not driven), with its odometry exact. `motion_seed` seeds the robot's
  /// motion errors and pushes (one stream per robot, so that its moves never depend on the
  /// batch); unused in an exact world.
  void place(int robot, const grid::Cell& cell, std::uint64_t motion_seed = 0);

  /// Replaces the obstacles of robot `robot`'s team with `layout`'s boxes and discs (a run's own,
  /// in a world that draws them per run: env::run_obstacles), before place() puts it on a clear start.
  void set_obstacles(int robot, const worlds::ObstacleSpec& layout);

  /// Drives robot i from its grid pose to grid pose + commands[i] (pixels), for every robot
  /// i < commands.size() (whole teams), all in one call; results[i] tells how it went. A team's
  /// robots tick together until each has settled, been blocked (by an obstacle or a teammate) or
  /// run out of ticks; one that is done holds its place (a million times heavier) while the others finish. In a world
  /// with motion errors the move starts from the pose the robot believes it is at (odometry_pose(): the true one when
  /// the world's `motion.pose` is `localised`) and lands near the target, not on it. Targets are not clamped: a command
  /// past the floor's edge ends against the wall. With `tick_positions_px` (one vector per commanded robot), robot i
  /// appends its centre (pixels) after every tick: the motion between grid poses, for animations.
  void move(std::span<const grid::Cell> commands, std::span<MoveResult> results,
            std::span<std::vector<Eigen::Vector2d>> tick_positions_px = {});

  /// The robot centre's continuous position in the floor frame, pixels and metres.
  Eigen::Vector2d position_px(int robot) const;
  Eigen::Vector2d position_m(int robot) const;
  /// The grid pose of the actual position (what the agent reads).
  grid::Cell grid_pose(int robot) const;
  /// The grid pose dead reckoning believes: the true position minus the odometry's unsensed
  /// error (equal to grid_pose() in an exact world and after a localised move).
  grid::Cell odometry_pose(int robot) const;
  /// The pose the agent reads: grid_pose() or odometry_pose(), as the world's `motion.pose` says.
  grid::Cell agent_pose(int robot) const;
  /// True while the robot touches a wall.
  bool touching_wall(int robot) const;
  /// True while the robot touches an obstacle.
  bool touching_obstacle(int robot) const;
  /// True while the robot touches another robot of its team.
  bool touching_teammate(int robot) const;

  /// Closest approach of the robot's centre to the floor's border-pixel centres: the walls
  /// stop the centre `wall_margin_px()` beyond them (Box2D's contact skin), never further.
  static double wall_margin_px();
  /// The radius at which a robot meets its teammates: its disc's and one tick's travel at its
  /// fastest (a massless bumper, docs/SCENARIOS.md § Several robots), pixels. Teammates starting
  /// more than two of these apart start clear of each other.
  static double bumper_radius_px(const RobotParams& params, const grid::FloorFrame& frame);

 private:
  struct Team;
  struct Robot;
  struct MoveContext;
  struct MemberMove;
  void move_team(const MoveContext& c, int team, std::span<const grid::Cell> commands, std::span<MoveResult> results,
                 std::span<std::vector<Eigen::Vector2d>> traces);
  bool begin_move(const MoveContext& c, int robot, const grid::Cell& command, MemberMove& m);
  bool before_tick(const MoveContext& c, int robot, MemberMove& m);
  void after_tick(const MoveContext& c, int robot, MemberMove& m);
  void end_move(const MoveContext& c, int robot, MemberMove& m);

  grid::FloorFrame frame_;
  RobotParams params_;
  std::unique_ptr<Team[]> teams_;
  std::unique_ptr<Robot[]> robots_;
  int count_;
  int team_size_;
  std::shared_ptr<core::WorkerPool> pool_;
};

}  // namespace scout::sim
