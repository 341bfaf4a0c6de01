#pragma once
/// A batch of robots, each over its own floor or in teams of K on one (world.team), behind reset
/// and step: the controller and Box2D
/// move them (sim/), the OSMesa camera looks for them (render/), and every robot's observation
/// sits in contiguous arrays. Torch-free and below agent/ and learn/: Scout's own rollouts,
/// `scout run` and the Python package drive robots through this one API.
#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "grid/grid.hpp"
#include "render/limits.hpp"
#include "worlds/world.hpp"

// The physics and the camera stay behind this header: its users (learn/, tools/, python/) reach
// the world only through env/.
namespace scout::core {
class WorkerPool;
}  // namespace scout::core
namespace scout::sim {
class RobotBatch;
struct MoveResult;
}  // namespace scout::sim
namespace scout::render {
class PatchCamera;
struct PixelPose;
struct FloorPoint;
}  // namespace scout::render

namespace scout::env {

/// How one robot's last move went.
struct MoveResult {
  int ticks = 0;                  ///< physics ticks taken (0 for a no-op move already on target)
  bool settled = false;           ///< ended within tolerance of the commanded cell's centre
  bool touched_wall = false;      ///< touched a wall during the move
  double peak_speed_mps = 0.0;    ///< highest speed reached during the move, metres per second
  double beyond_border_px = 0.0;  ///< farthest the centre got past the border pixels' centres, px
  bool pushed = false;            ///< a push hit the robot during the move (worlds with `pushes`)
  bool blocked = false;           ///< an obstacle stopped the robot (worlds with `obstacles`)
};

/// Sees every physics tick of a step: called once per robot after the step, in robot order, with
/// the robot's centre (continuous floor pixels) after each tick of its move (none for a robot
/// that did not move). For animations.
using TickHook = std::function<void(int robot, std::span<const Eigen::Vector2d> tick_positions_px)>;

/// Where a batch's time went, seconds, since the last reset_timing().
struct EnvTiming {
  double physics_s = 0;  ///< the controller and Box2D
  double render_s = 0;   ///< the camera
  double observe_s = 0;  ///< a reset's robots placed, floors loaded (with their block means) and
                         ///< maps cleared, and each look revealed into y and the coarse map
  long moves = 0;        ///< agent-steps: moves x robots
  long ticks = 0;        ///< Box2D ticks summed over robots
  double peak_speed_mps = 0;
};

/// The most robots a batch holds: what one camera draws.
inline constexpr int kMaxRobots = render::kMaxCameraRobots;

class BatchEnv {
 public:
  /// Buffers for up to `max_robots` robots (a multiple of the world's team.robots, K) on floors of
  /// `frame`, with the world's robot, controller, physics and camera. Robots kK .. kK + K - 1 are
  /// team k: one floor, one Box2D world, and one y and h (each robot's arrays hold the team's).
  /// Throws std::runtime_error if the camera cannot start.
  BatchEnv(const worlds::World& world, const grid::FloorFrame& frame, int max_robots);
  ~BatchEnv();
  BatchEnv(const BatchEnv&) = delete;
  BatchEnv& operator=(const BatchEnv&) = delete;

  /// Starts robots 0 .. starts.size() - 1 (whole teams) over `floors` (H * W bytes each,
  /// concatenated; a team's robots get the same floor): each
  /// is placed at rest on its start cell, what it has seen is cleared, its move count is 0, and
  /// the camera takes its first look. Robots beyond are idle until the next reset.
  /// motion_seeds[i] (one per start) seeds robot i's motion errors and pushes in a world that
  /// has them (sim::RobotBatch::place); they change nothing in an exact world. A team's random
  /// boxes come from its first robot's motion seed.
  void reset(std::span<const std::uint8_t> floors, std::span<const grid::Cell> starts,
             std::span<const std::uint64_t> motion_seeds);
  /// Starts again only robots[k] (< count()), over floors[k] from starts[k] with motion_seeds[k];
  /// the others keep their state (an autoreset of finished robots). Teams start again whole: their
  /// robots listed together, in order. Each robot at most once.
  void reset_robots(std::span<const int> robots, std::span<const std::uint8_t> floors,
                    std::span<const grid::Cell> starts, std::span<const std::uint64_t> motion_seeds);
  /// One move per robot (commands.size() == count()): commands[i] pixels from its grid pose
  /// (zero: it stays, no tick), driven by the controller and Box2D; then the camera looks from
  /// every robot's new position and what it sees is revealed at the pose the agent reads.
  void step(std::span<const grid::Cell> commands);
  /// Set (or clear, with an empty function) the hook that sees every physics tick.
  void set_tick_hook(TickHook hook);

  int count() const { return count_; }
  int max_robots() const { return max_robots_; }
  int team_size() const { return team_size_; }  ///< K
  const grid::FloorFrame& frame() const { return frame_; }
  int patch_px() const { return patch_px_; }

  // Robots 0 .. count() - 1, robot-major and contiguous:
  /// The camera's last image of each robot, count * m * m bytes, row-major; pixels of the window
  /// that lie off the floor are 0. In an exact world it is the crop of the window at the grid
  /// pose; with imperfect motion or pushes, the floor sampled bilinearly where the robot really
  /// is (render::PatchCamera::capture_at).
  std::span<const std::uint8_t> patches() const;
  /// The pose each robot's agent reads (METHOD.md's l): the grid pose of its actual position, or
  /// in a world with `motion.pose: odometry` the one its odometry believes.
  std::span<const grid::Cell> poses() const;
  /// y: each robot's floor where it (or, in a team, any robot of its team) has seen it, 0
  /// elsewhere, count * H * W bytes (obstacles, in a world with them, in their shade: what the
  /// camera saw).
  std::span<const std::uint8_t> revealed() const;
  /// The wider view (a world with camera.wide_px > 0; empty spans otherwise): each robot's last
  /// coarse window, count * wide_px^2 bytes (render::PatchCamera::capture's wide_patches: at the
  /// grid pose, or at the cell of the true centre with imperfect motion) ...
  std::span<const std::uint8_t> wide_patches() const;
  /// ... and the team's coarse map, one byte a block of wide_grid(): each block a look has covered
  /// holds its mean (the latest look wins), 0 elsewhere, count * wide_grid().area() bytes, placed
  /// at the pose the agent reads as y is ...
  std::span<const std::uint8_t> wide_revealed() const;
  /// ... and where it is set: 1, count * wide_grid().area() bytes.
  std::span<const std::uint8_t> wide_seen() const;
  /// The floor's block grid the wider view sees in (empty, 0 x 0, without one).
  const grid::BlockGrid& wide_grid() const { return wide_grid_; }
  /// o: 1 on each cell where the robot's disc would overlap one of its run's obstacles, 0
  /// elsewhere, count * H * W bytes (env::occupied_cells); empty in a world without obstacles.
  std::span<const std::uint8_t> occupied() const;
  std::span<const grid::RevealMask> seen() const;    ///< the pixels each robot's team has seen
  std::span<const int> moves() const;                ///< step() calls since each robot's reset (a zero command counts)
  std::span<const MoveResult> last_results() const;  ///< how each robot's last move went
  /// A robot's centre in metres (floor frame), continuous.
  Eigen::Vector2d pose_m(int robot) const;
  /// A robot's centre in floor pixels, continuous (pixel (x, y) spans [x, x + 1) x [y, y + 1)).
  Eigen::Vector2d position_px(int robot) const;

  const EnvTiming& timing() const { return timing_; }
  void reset_timing() { timing_ = {}; }
  /// The GL renderer in use (for manifests).
  std::string camera_description() const;

 private:
  void start_buffers(int robot, std::span<const std::uint8_t> floor);
  void place(int robot, const grid::Cell& start, std::uint64_t motion_seed, std::uint64_t layout_seed);
  void observe();
  void reveal_patch(int robot);
  void reveal_wide(int robot);

  grid::FloorFrame frame_;
  int patch_px_;
  int max_robots_;
  int team_size_;  // K robots per floor (world.team.robots)
  int count_ = 0;
  std::shared_ptr<core::WorkerPool> pool_;  // the physics' threads, also spreading the robots' observations
  std::unique_ptr<sim::RobotBatch> robots_;
  std::unique_ptr<render::PatchCamera> camera_;
  std::vector<grid::Cell> poses_;
  std::vector<grid::RevealMask> seen_;
  std::vector<std::uint8_t> revealed_;
  // The floors as the camera holds them, with obstacles painted over (re-uploaded on a reset); in a
  // world without obstacles empty: the camera takes the caller's floors as they are.
  std::vector<std::uint8_t> floors_;
  worlds::World world_;
  // Floor pixels whose centre lies on one of the world's fixed obstacles, and the grey the camera
  // sees there: painted over each floor the camera holds (a run's random boxes are painted as it
  // is placed). Empty without obstacles.
  std::vector<std::size_t> obstacle_pixels_;
  std::uint8_t obstacle_shade_ = 0;
  std::vector<std::uint8_t> fixed_occupied_;  // o of the fixed obstacles (H * W), in a world without random boxes
  std::vector<std::uint8_t> occupied_;        // o per robot (max_robots * H * W), in a world with obstacles
  std::vector<std::uint8_t> patches_;
  int wide_px_ = 0;                             // the world's wider view: window side (0: none) ...
  int wide_scale_ = 1;                          // ... and floor pixels per wide pixel
  std::vector<std::uint8_t> wide_patches_;      // each robot's last wide window
  grid::BlockGrid wide_grid_;                   // the floor's blocks (0 x 0 without a wider view)
  std::vector<std::uint8_t> wide_revealed_;     // the team's coarse map per robot, a byte a block
  std::vector<std::uint8_t> wide_seen_;         // where it is set
  bool exact_motion_ = true;                    // moves land on cells: the camera crops at grid poses
  std::vector<render::PixelPose> pixel_poses_;  // exact worlds: the grid poses the camera crops at
  std::vector<render::FloorPoint> centres_;     // otherwise: the true centres it samples at
  std::vector<int> moves_;
  std::vector<sim::MoveResult> sim_results_;  // what the physics reports, copied into results_
  std::vector<MoveResult> results_;
  TickHook tick_hook_;
  std::vector<std::vector<Eigen::Vector2d>> ticks_;  // per robot, the step's tick positions (hook only)
  EnvTiming timing_;
};

}  // namespace scout::env
