#pragma once
/// Rollouts: the batched loop that drives robots through E episodes of T moves with the physics
/// and the camera in the loop (METHOD.md § One rollout). Who picks goals and axes is a Policy:
/// mode (i)'s i.i.d. choices here, the learned planners later.
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "core/random.hpp"
#include "env/batch_env.hpp"
#include "grid/grid.hpp"
#include "worlds/world.hpp"

namespace scout::learn {

/// What a policy can read: each robot's grid pose, goal and what it has seen (METHOD.md's y and
/// h). Views of the engine's arrays, valid until its next move.
struct BatchState {
  grid::FloorFrame frame;
  int patch_px = 0;
  int step_px = 0;                         ///< s: the longest move (task.step_px); the route rule reads it
  int count = 0;                           ///< robots in this rollout batch
  int team = 1;                            ///< K: robots t*K .. t*K+K-1 share floor t
  std::span<const grid::Cell> pose;        ///< the pose each robot reads (env::BatchEnv::poses)
  std::span<const grid::Cell> goal;        ///< current goal per robot
  std::span<const grid::RevealMask> seen;  ///< pixels seen so far, per robot (h = 1 - seen)
  std::span<const std::uint8_t> revealed;  ///< y as bytes: count * H * W, the floor where seen, 0 elsewhere
  /// o as bytes: count * H * W, 1 where the robot cannot stand (env::BatchEnv::occupied); empty in
  /// a world without obstacles.
  std::span<const std::uint8_t> occupied;
  /// The wider view's coarse map and where it is set, count * wide_grid.area() bytes each, a byte
  /// a block (env::BatchEnv::wide_revealed, wide_seen); empty in a world without it.
  std::span<const std::uint8_t> wide_revealed;
  std::span<const std::uint8_t> wide_seen;
  grid::BlockGrid wide_grid;  ///< the blocks they are laid on (env::BatchEnv::wide_grid)

  const std::uint8_t* revealed_image(int robot) const {
    return revealed.data() + static_cast<std::size_t>(robot) * frame.area_px();
  }
  /// Robot `robot`'s coarse map and its mask, or null in a world without the wider view.
  const std::uint8_t* wide_revealed_image(int robot) const {
    return wide_revealed.empty() ? nullptr : wide_revealed.data() + static_cast<std::size_t>(robot) * wide_grid.area();
  }
  const std::uint8_t* wide_seen_cells(int robot) const {
    return wide_seen.empty() ? nullptr : wide_seen.data() + static_cast<std::size_t>(robot) * wide_grid.area();
  }
  /// Robot `robot`'s o, or null in a world without obstacles.
  const std::uint8_t* occupied_cells(int robot) const {
    return occupied.empty() ? nullptr : occupied.data() + static_cast<std::size_t>(robot) * frame.area_px();
  }
};

/// Chooses goals and axes for a batch.
class Policy {
 public:
  virtual ~Policy() = default;
  /// The goal of `episode` for every robot (cells on the floor).
  virtual void choose_goals(const BatchState& state, int episode, std::span<grid::Cell> goals) = 0;
  /// An axis (Horizontal or Vertical) for every robot i with need[i] != 0; others are ignored. A
  /// policy whose own rule settles an axis without a decision (AgentPolicy's route rule) sets it and
  /// clears need[i]: the engine then records the move as not sampled (chi = 0).
  virtual void choose_axes(const BatchState& state, std::span<std::uint8_t> need, std::span<grid::Axis> axes) = 0;
};

/// Mode (i) of METHOD.md: goals i.i.d. uniform over the floor's pixels, axes i.i.d. 1/2 - 1/2.
/// Robot i draws from its own generator seeded with seeds[i], so its choices never depend on
/// the other robots of the batch.
class RandomPolicy final : public Policy {
 public:
  explicit RandomPolicy(std::span<const std::uint64_t> seeds);
  void choose_goals(const BatchState& state, int episode, std::span<grid::Cell> goals) override;
  void choose_axes(const BatchState& state, std::span<std::uint8_t> need, std::span<grid::Axis> axes) override;

 private:
  std::vector<core::Rng> rngs_;
};

/// One move of one robot, as trajectory.json reports it.
struct StepRecord {
  int episode = 0;
  int step = 0;
  grid::Cell goal;
  grid::Axis axis = grid::Axis::None;  ///< the axis moved along (None: at the goal, no move)
  bool sampled = false;                ///< the axis was chosen by the policy (chi = 1)
  grid::Cell command;                  ///< commanded move, pixels
  env::MoveResult result;              ///< ticks, settled, wall contact, peak speed
  Eigen::Vector2d pose_m;              ///< actual centre after the move, metres (floor frame)
  grid::Cell grid_pose;                ///< grid pose after the move
  int revealed_px = 0;                 ///< pixels seen so far, cumulative
};

/// The state shown by one trajectory image.
struct SnapshotRecord {
  int episode = 0;  ///< episode about to start (E for the final image)
  grid::Cell robot;
  std::optional<grid::Cell> goal;
  std::vector<std::uint8_t> seen;  ///< H * W, 1 where seen
  /// The wider view's coarse map and where it is set, written out per floor pixel (H * W each,
  /// grid::expand_blocks; empty in a world without it).
  std::vector<std::uint8_t> wide_revealed, wide_seen;
  std::size_t path_length = 0;  ///< poses of RolloutRecord::path visited so far
};

/// Everything one robot did in one rollout.
struct RolloutRecord {
  grid::Cell start;
  std::vector<StepRecord> steps;          ///< E / K * T of them, no-op moves included
  std::vector<grid::Cell> path;           ///< start, then the grid pose after each move
  std::vector<SnapshotRecord> snapshots;  ///< at the start of each episode (goal drawn) and at the end
  /// The robot's centre (floor pixels, continuous) at the start and after every physics tick:
  /// move k added steps[k].result.ticks of them (animations, `scout run --video`).
  std::vector<Eigen::Vector2d> tick_path_px;
};

/// Where a batch's time went, seconds: the environment's (physics, camera, revealing) and the
/// learner's own.
struct RolloutTiming {
  env::EnvTiming env;
  double other_s = 0;  ///< the policy, the protocol, the records
};

/// What the axis decisions (chi = 1: both axes move toward the goal) could change, counted since
/// the last RolloutEngine::reset_axis_tally(): for each, the new pixels of the window each of the
/// two candidate moves would end at (on the grid, before the physics), against what the robot (its
/// team) had seen. Where the two counts are equal the choice reveals the same amount either way.
struct AxisTally {
  long decisions = 0;   ///< chi = 1 decisions
  long differing = 0;   ///< ... whose two candidates would reveal different numbers of new pixels
  long chose_more = 0;  ///< ... of those, where the chosen axis reveals more
  long gap_px = 0;      ///< summed |new pixels(horizontal) - new pixels(vertical)|
};

/// Runs batches of rollouts: E episodes of T moves of the paper's protocol (env/protocol.hpp),
/// with goals and axes from a Policy, over an env::BatchEnv (the physics and the camera).
/// In a world with teams of K robots (world.team), each robot drives E / K episodes, the team's
/// robots moving at once. Buffers are allocated once for up to `max_robots` (a multiple of K).
class RolloutEngine {
 public:
  RolloutEngine(const worlds::World& world, const grid::FloorFrame& frame, int max_robots);
  ~RolloutEngine();
  RolloutEngine(const RolloutEngine&) = delete;
  RolloutEngine& operator=(const RolloutEngine&) = delete;

  /// Runs one rollout per robot (per team of K): robot i drives over floors[i] (H * W bytes each, concatenated)
  /// from starts[i], its motion errors and pushes (in worlds that have them) drawn from
  /// motion_seeds[i]. With `record` false only the final state is kept (benchmarks, training).
  std::vector<RolloutRecord> run(std::span<const std::uint8_t> floors, std::span<const grid::Cell> starts,
                                 std::span<const std::uint64_t> motion_seeds, Policy& policy, bool record = true);

  const BatchState& state() const { return state_; }
  /// Where the time went.
  RolloutTiming timing() const;
  void reset_timing();
  /// Per robot of the last run: its moves that did not arrive, because an obstacle or a teammate
  /// blocked them or they ran out of ticks (MoveResult: blocked, or ticks > 0 and not settled);
  /// what trajectory.json marks blocked or unsettled, less the no-op moves at a goal.
  std::span<const int> stalled_moves() const { return {stalled_.data(), static_cast<std::size_t>(state_.count)}; }
  /// The axis decisions of the rollouts run since the last reset (AxisTally).
  const AxisTally& axis_tally() const { return axis_tally_; }
  void reset_axis_tally() { axis_tally_ = {}; }
  int max_robots() const;
  /// The GL renderer in use (for manifests).
  std::string camera_description() const;

 private:
  void refresh_state();
  void check_inputs(std::span<const std::uint8_t> floors, std::span<const grid::Cell> starts) const;
  void open_records(std::vector<RolloutRecord>& records, std::span<const grid::Cell> starts);
  void record_snapshots(std::vector<RolloutRecord>& records, int episode, bool with_goal) const;
  void record_moves(std::vector<RolloutRecord>& records, int e, int t) const;
  void tally_axis_decisions(int count);

  worlds::TaskSpec task_;
  int team_size_ = 1;  // K: robots per floor, each driving E / K episodes
  std::unique_ptr<env::BatchEnv> env_;
  BatchState state_;
  std::vector<grid::Cell> goals_;
  std::vector<grid::Cell> commands_;  // per-move scratch, sized once per batch
  std::vector<std::uint8_t> need_;
  std::vector<grid::Axis> axes_;
  double other_s_ = 0;
  AxisTally axis_tally_;
  std::vector<int> stalled_;  // per robot, this run
};

}  // namespace scout::learn
