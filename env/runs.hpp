#pragma once
/// Seeded sequences of rollouts: which digit and start run k of a command gets, and the seed its
/// policy draws from. `scout run --seed s --count n` runs 0 .. n - 1 of the sequence of seed s;
/// the Python environment's robot i runs k = i, then k = i + num_envs, i + 2 num_envs, ... (one
/// sequence, dealt out), so the two give the same runs for the same seed.
#include <cstdint>
#include <vector>

#include "core/random.hpp"
#include "grid/grid.hpp"
#include "worlds/world.hpp"

namespace scout::env {

/// The obstacles of one run (docs/SCENARIOS.md § Obstacles): the world's fixed boxes and discs,
/// and `obstacles.random_boxes` boxes drawn from derive_seed(motion_seed, kMotionObstacles), sides
/// uniform in [random_box_min_px, random_box_max_px], positions uniform over the floor. A draw
/// that leaves the world's fixed start, or (with a random start) every cell, too close to a box
/// for the robot's disc is drawn again; after 1000 such draws, InputError. Without random boxes,
/// the world's obstacles. The result is a concrete layout (its random_boxes is 0).
worlds::ObstacleSpec run_obstacles(const worlds::World& world, const grid::FloorFrame& frame,
                                   std::uint64_t motion_seed);

/// True where the robot's disc centred on the cell would overlap an obstacle of `layout` (its
/// centre is nearer to one than the robot's radius): H * W bytes, 1 there, 0 elsewhere. The
/// planners' occupancy channel o (docs/SCENARIOS.md § Obstacles).
std::vector<std::uint8_t> occupied_cells(const worlds::World& world, const grid::FloorFrame& frame,
                                         const worlds::ObstacleSpec& layout);

/// The start cell of a rollout: the world file's, or uniform over the cells where the robot's disc
/// fits beside the run's obstacles `layout` (run_obstacles), from `rng`.
grid::Cell draw_start(const worlds::World& world, const grid::FloorFrame& frame, const worlds::ObstacleSpec& layout,
                      core::Rng& rng);
/// The start of the run whose motion seed is `motion_seed`: beside its layout (run_obstacles).
grid::Cell draw_start(const worlds::World& world, const grid::FloorFrame& frame, std::uint64_t motion_seed,
                      core::Rng& rng);
/// The same beside the world's fixed obstacles, for a world without random boxes (std::logic_error
/// for one with them: its starts depend on each run's layout).
grid::Cell draw_start(const worlds::World& world, const grid::FloorFrame& frame, core::Rng& rng);

/// The seed of robot `member` of a team from the team's `seed` (a motion or a policy seed): the
/// first robot's is the team's own, so that a team of one is the lone robot of today's runs.
std::uint64_t member_seed(std::uint64_t seed, int member);

/// The starts of a team of world.team.robots robots (docs/SCENARIOS.md § Several robots): the
/// first as draw_start() gives it, the others drawn the same way from `rng` again until they
/// stand clear of every earlier one (centres more than two bumper radii apart,
/// sim::RobotBatch::bumper_radius_px: a diameter and two ticks' travel). Obstacles are
/// the run's whose motion seed is `motion_seed` (the first robot's). InputError after 1000 draws
/// that leave no room.
std::vector<grid::Cell> draw_team_starts(const worlds::World& world, const grid::FloorFrame& frame,
                                         std::uint64_t motion_seed, core::Rng& rng);

/// One run of a sequence.
struct PlannedRun {
  std::uint64_t seed = 0;          ///< derive_seed(sequence seed, k)
  int index = 0;                   ///< the digit, in its split
  grid::Cell start;                ///< drawn from derive_seed(seed, kRunStart) (or the world's start)
  std::vector<grid::Cell> starts;  ///< a team's: start, then its other robots' (draw_team_starts); size K
  worlds::ObstacleSpec obstacles;  ///< the run's obstacles (run_obstacles of its motion seed)
  std::uint64_t policy_seed = 0;   ///< derive_seed(seed, kRunPolicy): the run's goal and axis choices
  std::uint64_t motion_seed = 0;   ///< derive_seed(seed, kRunMotion): the run's motion errors and pushes
  std::uint64_t floor_key = 0;     ///< derive_seed(seed, kRunFloor): its floor's composition (FloorSet::floor)
  // A team's robot k draws from member_seed(policy_seed, k) and member_seed(motion_seed, k).
};

/// The runs of one sequence seed over a split of `split_size` digits. With `index: random` run k
/// takes entry k mod split_size of a permutation drawn from derive_seed(seed, kRunDigitOrder):
/// every run its own digit up to the split's size, and run k the same whatever the count.
class RunSequence {
 public:
  RunSequence(const worlds::World& world, const grid::FloorFrame& frame, int split_size, std::uint64_t seed);
  PlannedRun run(std::uint64_t k) const;
  std::uint64_t seed() const { return seed_; }

 private:
  worlds::World world_;
  grid::FloorFrame frame_;
  std::uint64_t seed_;
  std::vector<int> digit_order_;  // empty with a fixed index
};

}  // namespace scout::env
