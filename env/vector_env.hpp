#pragma once
/// The Gymnasium-style vector environment behind the Python package (python/): num_envs robots
/// (or, in a world with teams of K, num_envs teams of K robots: docs/SCENARIOS.md § Several
/// robots) over the digits of one split, each moved one step at a time by an integer action, with
/// observations written into caller-owned arrays, rewards from the caller's predictions, and
/// Gymnasium's NEXT_STEP autoreset (or none: DISABLED, with partial resets). Every action and
/// reset is checked here, once; the Python layer only converts and wraps. Torch-free.
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "env/batch_env.hpp"
#include "env/runs.hpp"
#include "worlds/floors.hpp"
#include "worlds/world.hpp"

namespace scout::env {

/// dense: -cross-entropy of the prediction against the label after every move (ap_gym's
/// convention); sparse: only after the last move of an episode. 0 where no prediction is given.
enum class Reward { Dense, Sparse };

struct VectorEnvConfig {
  std::filesystem::path world_file;
  std::int64_t num_envs = 1;           ///< 1 .. VectorEnv::kMaxEnvs
  std::optional<std::uint64_t> seed;   ///< default: the world file's `seed`
  std::optional<worlds::Split> split;  ///< default: the world file's `floor.split`
  std::filesystem::path data_root;     ///< empty: worlds::default_data_root()
  Reward reward = Reward::Dense;
  bool force = false;  ///< start even when the memory estimate exceeds what is available
  /// true: Gymnasium's NEXT_STEP (the step after a run ends starts the robot's next run); false:
  /// DISABLED (a robot whose run ended waits for a reset that names it in VectorReset::mask).
  bool autoreset = true;
};

/// Which robots a reset starts on a new run, and which run.
struct VectorReset {
  /// Empty: every robot; else num_envs flags, 1 where the robot starts a new run (Gymnasium's
  /// reset_mask; the first reset starts every robot).
  std::vector<std::uint8_t> mask = {};
  /// One sequence for the batch: robot i runs run i of this seed's sequence, then i + num_envs,
  /// i + 2 num_envs, ... (`scout run --seed s --count K`'s run k is robot k mod N's).
  std::optional<std::uint64_t> seed = {};
  /// Or one seed per robot (num_envs entries): robot i runs runs 0, 1, 2, ... of its own seed's
  /// sequence (a single environment reset with that seed does the same); an empty entry keeps
  /// the robot's sequence. Not with `seed`.
  std::vector<std::optional<std::uint64_t>> robot_seeds = {};
};

/// Where reset and step write: caller-owned, C-contiguous arrays of num_envs rows each. The
/// step-only fields are ignored by reset. In a world with teams of K robots the per-robot arrays
/// (patch, pose, pose_m) hold K entries per row, robot-major: N x K x ...; y, h and o are the team's.
struct VectorOutputs {
  float* patch = nullptr;                ///< N x m x m (N x K x m x m), each camera's image in [0, 1]
  std::int32_t* pose = nullptr;          ///< N x 2 (N x K x 2), grid pose (x, y)
  float* revealed = nullptr;             ///< N x H x W, the floor where seen, 0 elsewhere, in [0, 1]
  std::uint8_t* seen = nullptr;          ///< N x H x W, 1 where seen (by any robot of a team)
  std::int32_t* time_step = nullptr;     ///< N, moves made in the episode
  std::int32_t* label = nullptr;         ///< N, the digit's class (-1: unknown)
  std::int32_t* index = nullptr;         ///< N, the digit's index in its split
  double* pose_m = nullptr;              ///< N x 2 (N x K x 2), the robot's centre in metres
  std::uint64_t* policy_seed = nullptr;  ///< N, the run's policy seed (scout.Agent draws from it)
  float* reward = nullptr;               ///< N (step)
  std::uint8_t* terminated = nullptr;    ///< N (step)
  std::uint8_t* truncated = nullptr;     ///< N (step): always 0
  /// N x H x W, o: 1 where the robot's disc cannot stand beside its run's obstacles (written in a
  /// world with obstacles only: VectorEnv::has_obstacles)
  std::uint8_t* occupied = nullptr;
  /// The wider view (written in a world with one only: VectorEnv::wide_px() > 0):
  float* wide_patch = nullptr;  ///< N x w x w (N x K x w x w), each robot's coarse window in [0, 1]
  /// N x H x W, the team's coarse map where set, 0 elsewhere, in [0, 1]: each floor pixel takes
  /// its block's value (env::BatchEnv::wide_grid) ...
  float* wide_revealed = nullptr;
  std::uint8_t* wide_seen = nullptr;  ///< ... N x H x W, 1 where the coarse map is set
};

/// The action of one step (spans of num_envs rows).
struct VectorAction {
  /// 0 = +x (right), 1 = -x (left), 2 = +y (down), 3 = -y (up), each step_px pixels; a move past
  /// the floor's edge ends on the border pixel (where the wall would stop it). N x K entries in a
  /// world with teams: every robot of a team moves in the same step.
  std::span<const std::int32_t> move = {};
  /// N x D logits of each robot's prediction, or empty.
  std::span<const float> prediction = {};
  /// N x 2 (N x K x 2) goals of the layered protocol, or empty. With goals, a move never passes its robot's
  /// goal on its axis (it is cut short, as in the paper's protocol), so a robot on the goal's
  /// row or column stays put there: what scout.Agent needs to replay `scout run` exactly.
  std::span<const std::int32_t> goal = {};
};

class VectorEnv {
 public:
  /// The most robots one environment holds (the camera's batch).
  static constexpr int kMaxEnvs = kMaxRobots;

  /// Loads the world and its floors. Throws InputError (one line) for a bad world, split or data.
  explicit VectorEnv(const VectorEnvConfig& config);
  ~VectorEnv();

  int num_envs() const { return num_envs_; }
  int patch_px() const { return world_.camera.patch_px; }
  /// The world has obstacles (fixed or drawn per run): observations then carry o.
  bool has_obstacles() const { return !world_.obstacles.none(); }
  int wide_px() const { return world_.camera.wide_px; }  ///< the wider view's side (0: none)
  int width() const { return frame_.width_px; }
  int height() const { return frame_.height_px; }
  int classes() const { return classes_; }      ///< D: the split's largest label + 1 (0: unlabelled)
  int episode_moves() const { return moves_; }  ///< E x T (E / K x T in teams): an episode's steps
  int team_size() const { return team_; }       ///< K robots per env (world.team.robots)
  int step_px() const { return world_.task.step_px; }
  const worlds::World& world() const { return world_; }
  const worlds::FloorSet& floors() const { return floors_; }
  const BatchEnv& batch() const { return *env_; }

  /// Starts every robot on a new run. With a seed, the sequence starts over: robot i runs run i
  /// of that seed's sequence (as `scout run --seed s --count num_envs` does); without one, each
  /// robot takes its next run (the first reset uses the configured or the world's seed).
  void reset(std::optional<std::uint64_t> seed, const VectorOutputs& out);
  /// Starts the robots `which` names on a new run (see VectorReset); the others keep theirs. The
  /// outputs describe every robot. Throws InputError (one line) for a bad mask or seed list.
  void reset(const VectorReset& which, const VectorOutputs& out);
  /// One move per robot. A robot whose episode ended on the previous step starts its next run
  /// instead (its action is ignored, its reward is 0); without autoreset such a step is refused.
  /// Throws InputError naming the bad entry of `action` before anything moves.
  void step(const VectorAction& action, const VectorOutputs& out);
  /// 1 where the robot's run ended on the last step (it starts its next run with the next step,
  /// or, without autoreset, waits for a reset).
  std::span<const std::uint8_t> ended() const { return done_; }
  /// The digit robot i's current run drives over (its index in the split).
  int floor_index(int robot) const { return planned_[robot].index; }
  /// The floor env `env_index` drives over in its current run (H * W bytes; composed by the
  /// world's floor layout).
  std::vector<std::uint8_t> floor_image(int env_index) const;

 private:
  void take(const VectorAction& action);
  const RunSequence* sequence(std::uint64_t seed);
  void plan(std::span<const int> envs);
  void start_planned();
  void write(const VectorOutputs& out) const;

  worlds::World world_;
  worlds::FloorSet floors_;
  grid::FloorFrame frame_;
  int num_envs_;
  int team_ = 1;  // K robots per env
  int classes_ = 0;
  int moves_;
  Reward reward_;
  std::uint64_t seed_;
  bool autoreset_;
  std::map<std::uint64_t, std::unique_ptr<RunSequence>> sequences_;  // by seed, those in use
  std::unique_ptr<BatchEnv> env_;
  std::vector<const RunSequence*> sequence_;  // each robot's sequence (null before the first reset)
  std::vector<std::uint64_t> stride_;         // and how far its next run is: num_envs, or 1 (own seed)
  std::vector<std::uint64_t> run_;            // each robot's current run k
  std::vector<PlannedRun> planned_;           // and what it is
  std::vector<int> label_;                    // its floor's label (composed once, when planned)
  std::vector<std::uint8_t> done_;            // its episode ended on the last step
  std::vector<int> time_step_;                // moves made in its episode
  std::vector<std::uint8_t> reset_now_;       // started its next run on this step
  std::vector<std::int32_t> move_;            // the step's action, copied before it is checked
  std::vector<float> prediction_;
  std::vector<std::int32_t> goal_;
  std::vector<grid::Cell> commands_;
  std::vector<int> finished_;
  std::vector<std::uint8_t> floor_bytes_;
  std::vector<grid::Cell> starts_;
  std::vector<int> robots_;  // the batch's robots plan() planned
  std::vector<std::uint64_t> motion_seeds_;
};

}  // namespace scout::env
