// The route rule (agent::NetworkConfig::free_routes, METHOD.md § Obstacles) with the physics and
// the camera in the loop: a 28 x 28 floor with two boxes, robots driven by a small agent with the
// rule and by the same agent without it, from the same starts and seeds.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <cmath>
#include <cstdint>
#include <numeric>
#include <random>
#include <vector>

#include "agent/networks.hpp"
#include "grid/grid.hpp"
#include "learn/internal/agent_policy.hpp"
#include "learn/internal/objective.hpp"
#include "learn/rollout.hpp"
#include "worlds/world.hpp"

namespace scout::learn {
namespace {

constexpr int kSide = 28;

struct Fixture {
  grid::FloorFrame frame{kSide, kSide, 0.1};
  worlds::World world;
  worlds::LabeledImages data;
};

// The paper's task on two noise floors, with a wall left of centre and a shelf right of it: many
// goals of a random planner lie behind one of them.
Fixture boxed_floor() {
  Fixture f;
  f.world.obstacles.boxes = {{.x = 9, .y = 4, .w = 3, .h = 14}, {.x = 15, .y = 16, .w = 9, .h = 3}};
  worlds::check_against_floor(f.world, kSide, kSide);
  f.data.images = {.count = 2, .rows = kSide, .cols = kSide, .pixels = {}};
  std::mt19937_64 rng(3);
  for (int label = 0; label < 2; ++label) {
    for (int k = 0; k < kSide * kSide; ++k) f.data.images.pixels.push_back(static_cast<std::uint8_t>(rng() % 256));
    f.data.labels.push_back(static_cast<std::uint8_t>(label));
  }
  return f;
}

struct Drive {
  long goals = 0, unreachable_goals = 0;  // goals chosen, and those no free monotone route reached
  long stalled = 0;                       // moves that did not arrive (RolloutEngine::stalled_moves)
  long forced_by_rule = 0;                // chi = 1 moves whose axis the rule chose (not the planner)
  long sampled = 0;                       // moves trajectory.json marks sampled
  long forced_off_route = 0;              // ... of the rule's, those whose axis loses the free route
  bool finite_log_pi = true;
};

Drive drive(const Fixture& f, bool free_routes, bool learned_goals) {
  agent::NetworkConfig config;
  config.classes = 2;
  config.planner_width = 4;
  config.planner_depth = 1;
  config.classifier_width = 4;
  config.classifier_depth = 1;
  config.free_routes = free_routes;
  torch::manual_seed(7);  // the same weights with and without the rule
  agent::Agent agent(config);
  const int robots = 96;
  RolloutEngine engine(f.world, f.frame, robots);
  AgentPolicy policy(*agent, f.frame, f.world.camera.patch_px, robots);
  const std::vector<int> indices = {0, 1};
  const RolloutBatch batch = make_batch(f.data, indices, robots / 2, f.world, f.frame, 41);
  Sampling sampling;
  sampling.learned_goals = learned_goals;
  sampling.learned_actions = true;
  policy.begin(batch.seeds, sampling);
  const std::vector<RolloutRecord> records =
      engine.run(batch.floors, batch.starts, batch.motion_seeds, policy, /*record=*/true);

  Drive d;
  const auto area = static_cast<std::size_t>(f.frame.area_px());
  const std::span<const std::uint8_t> blocked(engine.state().occupied_cells(0), area);
  std::vector<std::uint8_t> reach(area), scratch;
  long chi = 0;
  const int T = f.world.task.steps;
  for (const RolloutRecord& r : records) {
    grid::Cell pose = r.start;
    for (std::size_t k = 0; k < r.steps.size(); ++k) {
      const StepRecord& s = r.steps[k];
      if (s.step == 0) {  // the goal was drawn here, at `pose`
        grid::monotone_reach(blocked, f.frame, pose, reach);
        ++d.goals;
        d.unreachable_goals += reach[static_cast<std::size_t>(s.goal.y()) * kSide + s.goal.x()] == 0 ? 1 : 0;
      }
      const bool choose = grid::decide(pose, s.goal) == grid::Decision::Choose;
      chi += choose ? 1 : 0;
      d.sampled += s.sampled ? 1 : 0;
      if (choose && !s.sampled) {  // the rule chose: the move it took keeps a free route to the goal
        const grid::Cell to = pose + grid::move_command(pose, s.goal, s.axis, f.world.task.step_px);
        const bool keeps = grid::monotone_route_free(blocked, f.frame, pose, to, scratch) &&
                           grid::monotone_route_free(blocked, f.frame, to, s.goal, scratch);
        d.forced_off_route += keeps ? 0 : 1;
      }
      pose = s.grid_pose;
    }
    EXPECT_EQ(static_cast<int>(r.steps.size()), f.world.task.episodes * T);
  }
  for (int s : engine.stalled_moves()) d.stalled += s;
  d.forced_by_rule = chi - policy.action_decisions();
  EXPECT_EQ(d.sampled, policy.action_decisions()) << "a move the rule settled is recorded as not sampled";
  d.finite_log_pi =
      torch::isfinite(policy.log_pi()).all().item<bool>() && torch::isfinite(policy.entropy()).all().item<bool>();
  return d;
}

TEST(RouteRule, GoalsOnlyWhereAFreeRouteReachesAndFewerMovesEndAgainstTheBoxes) {
  const Fixture f = boxed_floor();
  const Drive without = drive(f, /*free_routes=*/false, /*learned_goals=*/true);
  const Drive with = drive(f, /*free_routes=*/true, /*learned_goals=*/true);
  ASSERT_EQ(with.goals, without.goals);
  // The control: without the rule the planner does choose goals behind the boxes and drives into them.
  EXPECT_GT(without.unreachable_goals, without.goals / 10);
  EXPECT_GT(without.stalled, 40);
  EXPECT_EQ(without.forced_by_rule, 0);
  EXPECT_EQ(with.unreachable_goals, 0);
  EXPECT_LE(2 * with.stalled, without.stalled) << with.stalled << " against " << without.stalled;
  // Some chi = 1 moves were settled by the rule, and they left the action planner's log pi.
  EXPECT_GT(with.forced_by_rule, 20);
  EXPECT_EQ(with.forced_off_route, 0);
  EXPECT_TRUE(with.finite_log_pi);  // masked goals enter as p = 0, never as NaN
}

TEST(RouteRule, IidGoalsAreDrawnAmongTheReachableCellsToo) {
  const Fixture f = boxed_floor();
  const Drive without = drive(f, /*free_routes=*/false, /*learned_goals=*/false);
  const Drive with = drive(f, /*free_routes=*/true, /*learned_goals=*/false);
  EXPECT_GT(without.unreachable_goals, without.goals / 10);
  EXPECT_EQ(with.unreachable_goals, 0);
  EXPECT_LE(2 * with.stalled, without.stalled) << with.stalled << " against " << without.stalled;
}

}  // namespace
}  // namespace scout::learn
