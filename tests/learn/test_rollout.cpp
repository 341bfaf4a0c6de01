// Rollouts with the real Box2D world and the real OSMesa camera in the loop, checked against the
// exact grid model of sim/.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <random>

#include "core/random.hpp"
#include "env/runs.hpp"
#include "learn/rollout.hpp"

namespace scout::learn {
namespace {

const grid::FloorFrame kFloor{28, 28, 0.1};

worlds::World preset_world() { return worlds::World{}; }  // the struct's defaults are the paper preset

std::vector<std::uint8_t> random_floors(int count, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<std::uint8_t> floors(static_cast<std::size_t>(count) * kFloor.area_px());
  for (auto& p : floors) p = static_cast<std::uint8_t>(rng() & 0xFF);
  return floors;
}

struct Batch {
  std::vector<std::uint8_t> floors;
  std::vector<grid::Cell> starts;
  std::vector<std::uint64_t> seeds;
  std::vector<std::uint64_t> motion_seeds;
};

Batch random_batch(int count, std::uint64_t seed) {
  Batch b;
  b.floors = random_floors(count, seed);
  core::Rng rng(seed + 1);
  const worlds::World world = preset_world();
  for (int i = 0; i < count; ++i) {
    b.starts.push_back(env::draw_start(world, kFloor, rng));
    b.seeds.push_back(core::derive_seed(seed, static_cast<std::uint64_t>(i)));
    b.motion_seeds.push_back(core::derive_seed(seed + 1000, static_cast<std::uint64_t>(i)));
  }
  return b;
}

TEST(Rollout, PhysicsAndTheExactGridModelRevealIdenticalPixels) {
  const worlds::World world = preset_world();
  RolloutEngine engine(world, kFloor, 240);
  long compared_moves = 0, sampled = 0;
  for (std::uint64_t seed : {1u, 2u, 3u}) {
    const Batch b = random_batch(240, seed);
    RandomPolicy policy(b.seeds);
    const auto records = engine.run(b.floors, b.starts, b.motion_seeds, policy);
    ASSERT_EQ(records.size(), 240u);
    for (int i = 0; i < 240; ++i) {
      const RolloutRecord& rec = records[i];
      ASSERT_EQ(rec.steps.size(), static_cast<std::size_t>(world.task.episodes * world.task.steps));
      grid::GridModel model(kFloor, world.camera.patch_px, b.starts[i]);
      for (const StepRecord& s : rec.steps) {
        // The grid model takes the recorded goal and, only where the protocol lets the policy
        // choose, the recorded axis; everything else it computes itself.
        const grid::Decision d = grid::decide(model.pose(), s.goal);
        ASSERT_EQ(s.sampled, d == grid::Decision::Choose);
        grid::Axis axis = d == grid::Decision::Vertical     ? grid::Axis::Vertical
                          : d == grid::Decision::Horizontal ? grid::Axis::Horizontal
                                                            : grid::Axis::None;
        if (d == grid::Decision::Choose) {
          ASSERT_NE(s.axis, grid::Axis::None);
          axis = s.axis;
          ++sampled;
        }
        ASSERT_EQ(s.axis, axis);
        const grid::Cell command = grid::move_command(model.pose(), s.goal, axis, world.task.step_px);
        ASSERT_EQ(s.command, command);
        model.move(command);
        ASSERT_EQ(s.grid_pose, model.pose()) << "robot " << i << " episode " << s.episode << " step " << s.step;
        ASSERT_EQ(s.revealed_px, model.revealed().count());
        EXPECT_TRUE(s.result.settled);
        ++compared_moves;
      }
      // The physics run's seen pixels equal the model's, and y holds the floor exactly there.
      const auto& seen = engine.state().seen[i].data();
      ASSERT_EQ(seen, model.revealed().data());
      const std::uint8_t* y = engine.state().revealed_image(i);
      const std::uint8_t* x = b.floors.data() + static_cast<std::size_t>(i) * kFloor.area_px();
      for (int p = 0; p < kFloor.area_px(); ++p) ASSERT_EQ(y[p], seen[p] ? x[p] : 0) << "pixel " << p;
    }
  }
  EXPECT_EQ(compared_moves, 3 * 240 * 20);
  EXPECT_GT(sampled, 1000);  // the comparison exercised the policy's choices, not only forced moves
}

std::vector<RolloutRecord> run_batch(const Batch& b, int count, RolloutEngine& engine) {
  RandomPolicy policy(std::span(b.seeds.data(), count));
  return engine.run(std::span(b.floors.data(), static_cast<std::size_t>(count) * kFloor.area_px()),
                    std::span(b.starts.data(), count), std::span(b.motion_seeds.data(), count), policy);
}

void expect_same_trajectory(const RolloutRecord& a, const RolloutRecord& b) {
  ASSERT_EQ(a.steps.size(), b.steps.size());
  for (std::size_t k = 0; k < a.steps.size(); ++k) {
    EXPECT_EQ(a.steps[k].goal, b.steps[k].goal);
    EXPECT_EQ(a.steps[k].command, b.steps[k].command);
    EXPECT_EQ(a.steps[k].result.ticks, b.steps[k].result.ticks);
    // Bit for bit, not approximately.
    EXPECT_EQ(std::memcmp(a.steps[k].pose_m.data(), b.steps[k].pose_m.data(), 2 * sizeof(double)), 0);
  }
}

TEST(Rollout, ARobotDrivesTheSameAloneAndInABatchOf240) {
  const worlds::World world = preset_world();
  const Batch b = random_batch(240, 77);
  RolloutEngine big(world, kFloor, 240);
  const auto crowded = run_batch(b, 240, big);
  RolloutEngine small(world, kFloor, 1);
  const auto alone = run_batch(b, 1, small);
  expect_same_trajectory(alone[0], crowded[0]);
}

std::uint64_t trajectory_hash(const std::vector<RolloutRecord>& records) {
  std::uint64_t h = 1469598103934665603ull;
  auto add = [&h](const void* p, std::size_t n) {
    const auto* bytes = static_cast<const unsigned char*>(p);
    for (std::size_t k = 0; k < n; ++k) h = (h ^ bytes[k]) * 1099511628211ull;
  };
  for (const auto& r : records)
    for (const auto& s : r.steps) {
      add(s.pose_m.data(), 2 * sizeof(double));
      add(s.goal.data(), 2 * sizeof(int));
    }
  return h;
}

TEST(Rollout, SameSeedSameHashDifferentSeedDifferentHash) {
  const worlds::World world = preset_world();
  RolloutEngine engine(world, kFloor, 32);
  const std::uint64_t a = trajectory_hash(run_batch(random_batch(32, 5), 32, engine));
  EXPECT_EQ(a, trajectory_hash(run_batch(random_batch(32, 5), 32, engine)));
  EXPECT_NE(a, trajectory_hash(run_batch(random_batch(32, 6), 32, engine)));
}

TEST(Rollout, ThePresetGivesThePinnedTrajectory) {
  // Every pose of 8 robots over 20 moves, bit for bit, as this version of Scout computes them
  // with Box2D 2.4.1 on x86-64. A change to the controller, the walls, the seeding or the
  // protocol changes this hash: if that change is intended, update the constant in the same
  // commit and say so.
  const worlds::World world = preset_world();
  RolloutEngine engine(world, kFloor, 8);
  const std::uint64_t hash = trajectory_hash(run_batch(random_batch(8, 2024), 8, engine));
  EXPECT_EQ(hash, 11417450623629320635ull) << "trajectory hash " << hash;
}

TEST(Rollout, SnapshotsAtEachEpisodeStartAndAtTheEnd) {
  const worlds::World world = preset_world();
  RolloutEngine engine(world, kFloor, 4);
  const auto records = run_batch(random_batch(4, 9), 4, engine);
  for (const RolloutRecord& r : records) {
    ASSERT_EQ(r.snapshots.size(), static_cast<std::size_t>(world.task.episodes + 1));
    ASSERT_EQ(r.path.size(), r.steps.size() + 1);
    for (int e = 0; e < world.task.episodes; ++e) {
      const SnapshotRecord& s = r.snapshots[e];
      EXPECT_EQ(s.episode, e);
      ASSERT_TRUE(s.goal.has_value());
      EXPECT_EQ(*s.goal, r.steps[static_cast<std::size_t>(e) * world.task.steps].goal);
      EXPECT_EQ(s.path_length, static_cast<std::size_t>(e) * world.task.steps + 1);
    }
    EXPECT_FALSE(r.snapshots.back().goal.has_value());
    EXPECT_EQ(r.snapshots.back().robot, r.steps.back().grid_pose);
  }
}

// Several robots on one floor: the team's moves are the lone robot's E * T, shared out as E / K
// episodes per robot, all robots moving at once; the team's snapshots show the seen pixels of all.
TEST(Rollout, EachRobotOfATeamDrivesItsShareOfTheEpisodes) {
  worlds::World world = preset_world();
  world.team.robots = 2;
  const int teams = 6, robots = 2 * teams;
  RolloutEngine engine(world, kFloor, robots);
  Batch b = random_batch(robots, 21);
  for (int t = 0; t < teams; ++t) {  // a team shares its floor; its robots start apart
    std::copy_n(b.floors.begin() + 2 * t * kFloor.area_px(), kFloor.area_px(),
                b.floors.begin() + (2 * t + 1) * kFloor.area_px());
    core::Rng rng(100 + t);
    const std::vector<grid::Cell> starts = env::draw_team_starts(world, kFloor, b.motion_seeds[2 * t], rng);
    b.starts[2 * t] = starts[0];
    b.starts[2 * t + 1] = starts[1];
  }
  const auto records = run_batch(b, robots, engine);
  const int episodes = world.task.episodes / 2;
  for (int i = 0; i < robots; ++i) {
    const RolloutRecord& r = records[i];
    ASSERT_EQ(r.steps.size(), static_cast<std::size_t>(episodes * world.task.steps)) << i;
    ASSERT_EQ(r.snapshots.size(), static_cast<std::size_t>(episodes + 1)) << i;
    EXPECT_EQ(r.steps.back().episode, episodes - 1);
  }
  for (int t = 0; t < teams; ++t) {
    const RolloutRecord &a = records[2 * t], &c = records[2 * t + 1];
    EXPECT_EQ(a.snapshots.back().seen, c.snapshots.back().seen) << t;
    EXPECT_EQ(a.steps.back().revealed_px, c.steps.back().revealed_px) << t;
    // Both moved, at the same moves, from their own starts.
    EXPECT_NE(a.path, c.path) << t;
  }
}

TEST(RandomPolicy, GoalsCoverTheFloorUniformlyAndAxesAreFair) {
  const worlds::World world = preset_world();
  std::vector<std::uint64_t> seeds(64);
  for (int i = 0; i < 64; ++i) seeds[i] = static_cast<std::uint64_t>(i) + 1000;
  RandomPolicy policy(seeds);
  BatchState state;
  state.frame = kFloor;
  std::vector<int> hits(static_cast<std::size_t>(kFloor.area_px()), 0);
  std::vector<grid::Cell> goals(64);
  const int draws = 1000;
  for (int d = 0; d < draws; ++d) {
    policy.choose_goals(state, 0, goals);
    for (const grid::Cell& g : goals) {
      ASSERT_TRUE(kFloor.contains(g));
      ++hits[static_cast<std::size_t>(g.y()) * kFloor.width_px + g.x()];
    }
  }
  // 64,000 goals over 784 pixels: about 82 each; a chi-square far above its 783 degrees of
  // freedom would mean a biased or broken sampler.
  const double expected = 64.0 * draws / kFloor.area_px();
  double chi2 = 0;
  for (int h : hits) chi2 += (h - expected) * (h - expected) / expected;
  EXPECT_LT(chi2, 950.0);
  EXPECT_GT(chi2, 620.0);

  std::vector<std::uint8_t> need(64, 1);
  need[3] = 0;
  std::vector<grid::Axis> axes(64, grid::Axis::None);
  int vertical = 0, total = 0;
  for (int d = 0; d < 500; ++d) {
    std::fill(axes.begin(), axes.end(), grid::Axis::None);
    policy.choose_axes(state, need, axes);
    EXPECT_EQ(axes[3], grid::Axis::None);  // not asked, not chosen
    for (int i = 0; i < 64; ++i)
      if (need[i]) {
        ASSERT_NE(axes[i], grid::Axis::None);
        vertical += axes[i] == grid::Axis::Vertical;
        ++total;
      }
  }
  EXPECT_NEAR(double(vertical) / total, 0.5, 0.01);
}

// The axis tally (what the action layer's choices could change): a policy that, at every chi = 1
// decision, takes the axis whose move reveals more new pixels (by its own count on the same state)
// is credited with all of the differing decisions, and one that takes the other axis with none;
// i.i.d. goals, so the decisions are the same for both; the physics and the camera in the loop.
class RevealCountingPolicy final : public Policy {
 public:
  RevealCountingPolicy(std::span<const std::uint64_t> seeds, int step_px, bool prefer_more)
      : goals_(seeds), step_px_(step_px), prefer_more_(prefer_more) {}
  void choose_goals(const BatchState& state, int episode, std::span<grid::Cell> goals) override {
    goals_.choose_goals(state, episode, goals);
  }
  void choose_axes(const BatchState& state, std::span<std::uint8_t> need, std::span<grid::Axis> axes) override {
    for (std::size_t i = 0; i < need.size(); ++i) {
      if (!need[i]) continue;
      ++decisions;
      const int h = fresh(state, static_cast<int>(i), grid::Axis::Horizontal);
      const int v = fresh(state, static_cast<int>(i), grid::Axis::Vertical);
      differing += h != v ? 1 : 0;
      axes[i] = (h > v) == prefer_more_ ? grid::Axis::Horizontal : grid::Axis::Vertical;
    }
  }
  long decisions = 0, differing = 0;

 private:
  int fresh(const BatchState& state, int robot, grid::Axis axis) const {
    const grid::Cell to = state.pose[robot] + grid::move_command(state.pose[robot], state.goal[robot], axis, step_px_);
    const grid::Window w = grid::camera_window(to, state.patch_px, state.frame);
    int count = 0;
    for (int y = w.y0; y < w.y1; ++y)
      for (int x = w.x0; x < w.x1; ++x) count += state.seen[robot].seen(x, y) ? 0 : 1;
    return count;
  }
  RandomPolicy goals_;
  int step_px_;
  bool prefer_more_;
};

TEST(RolloutEngine, TheAxisTallyCreditsTheMoreRevealingChoice) {
  const worlds::World world = preset_world();
  RolloutEngine engine(world, kFloor, 60);
  const Batch b = random_batch(60, 9);
  for (const bool prefer_more : {true, false}) {
    RevealCountingPolicy policy(b.seeds, world.task.step_px, prefer_more);
    engine.reset_axis_tally();
    engine.run(b.floors, b.starts, b.motion_seeds, policy, /*record=*/false);
    const AxisTally& t = engine.axis_tally();
    EXPECT_EQ(t.decisions, policy.decisions);
    EXPECT_EQ(t.differing, policy.differing);
    EXPECT_GT(t.differing, 0);
    EXPECT_LT(t.differing, t.decisions) << "equal candidates happen too (a fresh floor in both directions)";
    EXPECT_EQ(t.chose_more, prefer_more ? t.differing : 0);
    EXPECT_GE(t.gap_px, t.differing);
  }
  engine.reset_axis_tally();
  EXPECT_EQ(engine.axis_tally().decisions, 0);
}

// Stalled moves (what --stalled-move-cost charges and scout eval counts) are the recorded moves
// marked blocked, or with ticks but not settled, in a world whose boxes block robots.
TEST(RolloutEngine, StalledMovesAreTheRecordedBlockedOrUnsettledMoves) {
  const worlds::World world =
      worlds::load_world(std::filesystem::path(SCOUT_SOURCE_DIR) / "worlds/scenarios/obstacles-strong.yaml");
  RolloutEngine engine(world, kFloor, 60);
  const Batch b = random_batch(60, 4);
  RandomPolicy policy(b.seeds);
  const auto records = engine.run(b.floors, b.starts, b.motion_seeds, policy);
  long total = 0;
  for (int i = 0; i < 60; ++i) {
    int stalled = 0;
    for (const StepRecord& s : records[i].steps)
      stalled += s.result.blocked || (s.result.ticks > 0 && !s.result.settled) ? 1 : 0;
    EXPECT_EQ(engine.stalled_moves()[i], stalled) << "robot " << i;
    total += stalled;
  }
  EXPECT_GT(total, 0) << "random moves among boxes end against one now and then";
}

TEST(RolloutEngine, RunsBatchesSmallerThanItsCapacity) {
  // A command's last batch is usually partial (e.g. 5,000 runs = 20 x 240 + 200).
  const worlds::World world = preset_world();
  RolloutEngine engine(world, kFloor, 8);
  const Batch b = random_batch(8, 3);
  const auto full = run_batch(b, 8, engine);
  const auto partial = run_batch(b, 5, engine);
  ASSERT_EQ(partial.size(), 5u);
  for (int i = 0; i < 5; ++i) expect_same_trajectory(full[i], partial[i]);
}

TEST(RolloutEngine, RefusesBadBatches) {
  const worlds::World world = preset_world();
  RolloutEngine engine(world, kFloor, 4);
  const Batch b = random_batch(5, 1);
  RandomPolicy policy(b.seeds);
  EXPECT_THROW(engine.run(b.floors, b.starts, b.motion_seeds, policy), std::invalid_argument);  // 5 robots > 4
  std::vector<grid::Cell> off{{28, 0}};
  const std::vector<std::uint64_t> seed{0};
  EXPECT_THROW(engine.run(std::span(b.floors.data(), static_cast<std::size_t>(kFloor.area_px())), off, seed, policy),
               std::invalid_argument);
  std::vector<grid::Cell> one{{3, 3}};
  EXPECT_THROW(engine.run(std::span(b.floors.data(), 10), one, seed, policy), std::invalid_argument);
}

}  // namespace
}  // namespace scout::learn
