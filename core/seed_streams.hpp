#pragma once
/// Every seed stream of Scout in one place. A stream number s gives an independent seed
/// core::derive_seed(parent, s) below a parent seed; each constant names one use. The values are
/// part of every pinned result (trajectory hashes, the pinned weights, eval reports): never
/// change one, and give a new use a new name and a new number. (The data split's seed is the
/// data set's, worlds/dataset.hpp's kSplitSeed.)
#include <cstdint>

namespace scout::streams {

// `scout run`: run k's seed is derive_seed(command seed, k); below it:
inline constexpr std::uint64_t kRunStart = 2;   ///< run k's start cell
inline constexpr std::uint64_t kRunPolicy = 3;  ///< run k's goal and axis choices
inline constexpr std::uint64_t kRunMotion = 4;  ///< run k's motion errors and pushes (worlds that have them)
inline constexpr std::uint64_t kRunFloor = 5;   ///< run k's floor: where its digits and clutter go (floor.layout)
/// Below the command seed itself: the permutation of the split that `index: random` walks.
inline constexpr std::uint64_t kRunDigitOrder = ~std::uint64_t{0};

// A rollout of a batch (make_batch): its seed is derive_seed(batch stream, global rollout index);
// below it:
inline constexpr std::uint64_t kRobotStart = 1;   ///< the robot's start cell
inline constexpr std::uint64_t kRobotPolicy = 2;  ///< the robot's goal and axis choices
inline constexpr std::uint64_t kRobotMotion = 3;  ///< the robot's motion errors and pushes (worlds that have them)

// Below a run's or a robot's motion seed (kRunMotion, kRobotMotion), which also seeds the
// robot's motion errors and pushes directly:
inline constexpr std::uint64_t kMotionObstacles = 1;  ///< the run's random boxes (env::run_obstacles)

// Robot k > 0 of a team (docs/SCENARIOS.md § Several robots) draws from derive_seed(s, kTeamMember
// + k) below the run's motion or policy seed s (env::member_seed; robot 0 from s itself).
inline constexpr std::uint64_t kTeamMember = std::uint64_t{1} << 41;

// A training run's seed; below it, then the stage and the epoch:
inline constexpr std::uint64_t kTrainOrder = 11;       ///< data order of (stage, epoch)
inline constexpr std::uint64_t kTrainBatch = 12;       ///< batch streams of (stage, epoch), then the batch index
inline constexpr std::uint64_t kTrainValidation = 13;  ///< validation passes (the same every epoch)
/// The per-epoch baselines' validation passes (the same every epoch).
inline constexpr std::uint64_t kTrainValidationIid = 14;        ///< i.i.d. goals and actions
inline constexpr std::uint64_t kTrainValidationGoalsOnly = 15;  ///< learned goals, i.i.d. actions
/// Composed floors (floor.layout): the training floors of (stage, epoch), drawn anew each epoch,
/// and the validation floors, the same every epoch.
inline constexpr std::uint64_t kTrainFloors = 16;
inline constexpr std::uint64_t kTrainValidationFloors = 17;

// An evaluation: stochastic run k's seed is derive_seed(eval seed, k), and image i of a pass
// drives with derive_seed(pass seed, i). The baselines' passes take these streams below run k's
// seed (the greedy pass below the eval seed); they lie beyond any image index, so no baseline
// ever repeats the stochastic run's starts and choices.
inline constexpr std::uint64_t kEvalIid = std::uint64_t{1} << 40;  ///< i.i.d. goals and actions
inline constexpr std::uint64_t kEvalGoalsOnly = kEvalIid + 1;      ///< learned goals, i.i.d. actions
inline constexpr std::uint64_t kEvalGreedy = kEvalIid + 2;         ///< the greedy run (below the eval seed)
/// The evaluated floors (floor.layout), below the eval seed: the same in every run and baseline.
inline constexpr std::uint64_t kEvalFloors = kEvalIid + 3;

}  // namespace scout::streams
