// One batch's pieces (learn/objective.cpp): make_batch lays robots out as i * N + k with starts
// and seeds that depend on (stream, robot) only; count_correct counts argmax and top-2 hits;
// backward_if_finite refuses a non-finite loss without touching the gradients, and
// apply_gradient_hook round-trips them through one flat buffer; sampling_for maps the stages
// to the layers that choose. (run_batch end to end: test_estimator.cpp, test_trainer.cpp.)
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <set>
#include <span>
#include <stdexcept>
#include <utility>
#include <vector>

#include "core/random.hpp"
#include "env/runs.hpp"
#include "learn/internal/agent_policy.hpp"
#include "learn/internal/objective.hpp"
#include "learn/rollout.hpp"
#include "tests/support/training_fixture.hpp"

namespace scout::learn {
namespace {

using namespace scout::learn::test_support;

class MakeBatch : public ::testing::Test {
 protected:
  void SetUp() override {
    const CornerSet set = corner_set(5, 21);
    data_.images = set.images;
    data_.labels = set.labels;
    world_ = corner_world(temp_, temp_.path(), 1, 1);
  }
  RolloutBatch batch(std::vector<int> indices, int rollouts, std::uint64_t stream) const {
    return make_batch(data_, indices, rollouts, world_, frame_, stream);
  }
  TempDir temp_{"scout_objective"};
  worlds::LabeledImages data_;
  worlds::World world_;
  grid::FloorFrame frame_{kSide, kSide, 0.1};  // the corner world's floors, 0.1 m per pixel
};

TEST_F(MakeBatch, RobotINTimesNPlusKDrivesImageI) {
  const std::vector<int> indices = {3, 0, 4};
  const RolloutBatch b = batch(indices, 2, 9);
  ASSERT_EQ(b.count, 6);
  ASSERT_EQ(b.floors.size(), 6u * kSide * kSide);
  ASSERT_EQ(b.labels.size(), 6u);
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 2; ++k) {
      const int r = i * 2 + k;
      EXPECT_EQ(b.labels[r], data_.labels[indices[i]]) << r;
      const std::uint8_t* floor = b.floors.data() + static_cast<std::size_t>(r) * kSide * kSide;
      EXPECT_TRUE(std::equal(floor, floor + kSide * kSide, data_.images.image(indices[i]))) << r;
    }
  // Every robot has its own sampling seed.
  EXPECT_EQ(std::set<std::uint64_t>(b.seeds.begin(), b.seeds.end()).size(), 6u);
}

TEST_F(MakeBatch, StartsAndSeedsDependOnTheStreamAndTheRobotOnly) {
  const RolloutBatch a = batch({1, 2}, 3, 9), again = batch({1, 2}, 3, 9);
  EXPECT_EQ(a.seeds, again.seeds);
  EXPECT_EQ(a.starts, again.starts);
  // Robot r's draws do not depend on which images the batch holds or how many there are.
  const RolloutBatch other = batch({4, 0, 3}, 3, 9);
  for (int r = 0; r < a.count; ++r) {
    EXPECT_EQ(a.seeds[r], other.seeds[r]) << r;
    EXPECT_EQ(a.starts[r], other.starts[r]) << r;
  }
  // Another stream gives other seeds.
  const RolloutBatch elsewhere = batch({1, 2}, 3, 10);
  for (int r = 0; r < a.count; ++r) EXPECT_NE(a.seeds[r], elsewhere.seeds[r]) << r;
}

// Data-parallel training splits one mini-batch over processes: the robots a process drives,
// numbered from their first global index, draw exactly what they draw in the whole batch.
TEST_F(MakeBatch, APartOfTheBatchDrawsWhatTheWholeBatchDrawsForItsRobots) {
  const std::vector<int> all = {3, 0, 4, 1};
  const RolloutBatch whole = batch(all, 2, 9);
  const RolloutBatch second_half = make_batch(data_, std::vector<int>{4, 1}, 2, world_, frame_, 9, /*first_robot=*/4);
  ASSERT_EQ(second_half.count, 4);
  for (int r = 0; r < 4; ++r) {
    EXPECT_EQ(second_half.seeds[r], whole.seeds[4 + r]) << r;
    EXPECT_EQ(second_half.starts[r], whole.starts[4 + r]) << r;
    EXPECT_EQ(second_half.labels[r], whole.labels[4 + r]) << r;
  }
  // Numbered from 0 instead, the same images draw other seeds: the index is what counts.
  const RolloutBatch local = batch({4, 1}, 2, 9);
  for (int r = 0; r < 4; ++r) EXPECT_NE(local.seeds[r], whole.seeds[4 + r]) << r;
}

TEST_F(MakeBatch, RefusesNoRolloutsAndIndicesOutOfRange) {
  EXPECT_THROW(batch({0}, 0, 1), std::invalid_argument);
  EXPECT_THROW(batch({5}, 1, 1), std::out_of_range);
  EXPECT_THROW(batch({-1}, 1, 1), std::out_of_range);
}

// With the teammates' channels a team's robots choose their goals one after the other. A goal
// planner that scores t_g alone (logit 50 where no teammate's goal window is, 0 on one) then never
// sends member 1 into the goal window member 0 has just chosen, nor member 0 into member 1's last
// one; the same planner reading all ones (no teammates' channels: the channel is not there, so its
// weight is dropped) draws goals uniformly and lands in them now and then. The physics and the
// camera in the loop, in worlds/scenarios/team-2.yaml (K = 2, each robot 2 episodes of 5 moves).
TEST(TeamGoals, EachMemberSeesTheGoalsItsTeammatesHaveJustChosen) {
  const worlds::World world = worlds::load_world(fs::path(SCOUT_SOURCE_DIR) / "worlds/scenarios/team-2.yaml");
  const grid::FloorFrame frame{28, 28, world.floor.pixel_size_m};
  constexpr int kTeams = 120, kRobots = 2 * kTeams;
  std::vector<std::uint8_t> floors(static_cast<std::size_t>(kRobots) * frame.area_px(), 128);
  std::vector<grid::Cell> starts;
  std::vector<std::uint64_t> seeds, motion_seeds;
  core::Rng rng(17);
  for (int t = 0; t < kTeams; ++t) {
    const std::uint64_t motion = core::derive_seed(99, static_cast<std::uint64_t>(t));
    for (const grid::Cell& start : env::draw_team_starts(world, frame, motion, rng)) starts.push_back(start);
    for (int m = 0; m < 2; ++m) {
      seeds.push_back(core::derive_seed(5, static_cast<std::uint64_t>(2 * t + m)));
      motion_seeds.push_back(env::member_seed(motion, m));
    }
  }
  auto collisions = [&](bool team_channels) {
    agent::NetworkConfig config;
    config.planner_width = 2;
    config.planner_depth = 1;
    config.team_channels = team_channels;
    agent::Agent agent(config);
    {
      torch::NoGradGuard no_grad;
      for (auto& p : agent->goal->parameters()) p.zero_();
      if (team_channels) agent->goal->named_parameters()["head.weight"][0][agent::planner_channels(config) - 1] = 50.0;
    }
    RolloutEngine engine(world, frame, kRobots);
    AgentPolicy policy(*agent, frame, world.camera.patch_px, kRobots);
    Sampling sampling;
    sampling.learned_goals = true;
    policy.begin(seeds, sampling);
    const auto records = engine.run(floors, starts, motion_seeds, policy);
    const int steps = world.task.steps, episodes = world.task.episodes / 2;
    auto inside = [&](const grid::Cell& goal, const grid::Cell& around) {
      const grid::Window w = grid::camera_window(around, world.camera.patch_px, frame);
      return goal.x() >= w.x0 && goal.x() < w.x1 && goal.y() >= w.y0 && goal.y() < w.y1;
    };
    int hits = 0;
    for (int t = 0; t < kTeams; ++t)
      for (int e = 0; e < episodes; ++e) {
        const grid::Cell first = records[2 * t].steps[e * steps].goal;
        const grid::Cell second = records[2 * t + 1].steps[e * steps].goal;
        hits += inside(second, first) ? 1 : 0;
        if (e > 0) hits += inside(first, records[2 * t + 1].steps[(e - 1) * steps].goal) ? 1 : 0;
      }
    return hits;
  };
  EXPECT_EQ(collisions(true), 0);
  EXPECT_GT(collisions(false), 0) << "uniform goals fall into a teammate's window now and then";
}

TEST(CountCorrect, CountsArgmaxAndTopTwoHits) {
  // Three robots, three classes: the argmax is 2, 0, 1; the runner-up 1, 2, 0.
  const torch::Tensor log_probs = torch::tensor({{0.1f, 0.3f, 0.6f}, {0.5f, 0.1f, 0.4f}, {0.35f, 0.45f, 0.2f}}).log();
  const std::vector<std::int64_t> labels = {2, 2, 2};
  EXPECT_EQ(count_correct(log_probs, labels), 1);
  EXPECT_EQ(count_correct(log_probs, labels, 2), 2);
  EXPECT_EQ(count_correct(log_probs, std::vector<std::int64_t>{2, 0, 1}), 3);
  EXPECT_EQ(count_correct(log_probs, std::vector<std::int64_t>{0, 1, 2}, 2), 0);
}

TEST(BackwardIfFinite, ANonFiniteLossLeavesNoGradientAndAFiniteOneHasItsGradient) {
  torch::manual_seed(1);
  torch::nn::Linear layer(3, 1);
  const torch::Tensor x = torch::ones({1, 3});
  const torch::Tensor nan_loss = layer->forward(x).sum() * std::numeric_limits<float>::quiet_NaN();
  EXPECT_TRUE(std::isnan(backward_if_finite(nan_loss)));
  EXPECT_FALSE(layer->weight.grad().defined());
  const torch::Tensor loss = layer->forward(x).sum();
  EXPECT_EQ(backward_if_finite(loss), loss.item<double>());
  // d loss / d w = x = 1.
  ASSERT_TRUE(layer->weight.grad().defined());
  EXPECT_TRUE(torch::allclose(layer->weight.grad(), torch::ones({1, 3})));
}

TEST(ApplyGradientHook, TheHookSeesEveryTrainableGradientInOrderAndWritesBack) {
  torch::manual_seed(2);
  torch::nn::Sequential net(torch::nn::Linear(3, 2), torch::nn::Linear(2, 1));
  auto params = net->parameters();     // w1 [2,3], b1 [2], w2 [1,2], b2 [1]
  params[3].set_requires_grad(false);  // frozen: not in the buffer
  net->forward(torch::ones({1, 3})).sum().backward();
  params[1].mutable_grad() = torch::Tensor();  // a parameter without a gradient contributes zeros
  std::vector<float> seen;
  apply_gradient_hook(*net, [&](std::span<float> g) {
    seen.assign(g.begin(), g.end());
    for (float& v : g) v = 2 * v + 1;
  });
  ASSERT_EQ(seen.size(), 6u + 2u + 2u);
  for (int k = 6; k < 8; ++k) EXPECT_EQ(seen[k], 0.0f) << k;
  // Written back: w1 and w2 doubled plus one; b1 had no gradient, got one (its slice is 1, not 0).
  EXPECT_TRUE(torch::allclose(params[0].grad().reshape({-1}), 2 * torch::from_blob(seen.data(), {6}).clone() + 1));
  ASSERT_TRUE(params[1].grad().defined());
  EXPECT_TRUE(torch::allclose(params[1].grad(), torch::ones({2})));
  EXPECT_FALSE(params[3].grad().defined());
}

TEST(SamplingFor, EachStageLearnsItsLayers) {
  const Sampling i = sampling_for(Stage::ModeI, true, agent::Precision::BFloat16);
  EXPECT_FALSE(i.learned_goals);
  EXPECT_FALSE(i.learned_actions);
  EXPECT_TRUE(i.with_grad);
  EXPECT_EQ(i.precision, agent::Precision::BFloat16);
  const Sampling ii = sampling_for(Stage::ModeII, false, agent::Precision::Float32);
  EXPECT_TRUE(ii.learned_goals);
  EXPECT_FALSE(ii.learned_actions);
  EXPECT_FALSE(ii.with_grad);
  const Sampling iii = sampling_for(Stage::ModeIII, true, agent::Precision::Float32);
  EXPECT_TRUE(iii.learned_goals);
  EXPECT_TRUE(iii.learned_actions);
}

}  // namespace
}  // namespace scout::learn
