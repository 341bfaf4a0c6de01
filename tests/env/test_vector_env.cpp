// The vector environment behind the Python package, with real Box2D and OSMesa: runs dealt from
// the seeded sequence (or a seed per robot), moves and the protocol's move toward a goal, episodes
// ending after E x T moves with NEXT_STEP autoreset or none (masked resets), dense and sparse
// rewards, and bad actions refused before anything moves.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "core/error.hpp"
#include "env/runs.hpp"
#include "env/vector_env.hpp"
#include "tests/support/corner_data.hpp"
#include "tests/support/temp_dir.hpp"

namespace scout::env {
namespace {

namespace fs = std::filesystem;

// Arrays for N robots of the corner floors (12 x 12, m = 3), and the outputs pointing at them.
struct Buffers {
  int n, m, h, w;
  std::vector<float> patch, revealed, reward;
  std::vector<std::int32_t> pose, time_step, label, index;
  std::vector<std::uint8_t> seen, terminated, truncated;
  std::vector<double> pose_m;
  std::vector<std::uint64_t> policy_seed;
  Buffers(int n_, int m_, int h_, int w_) : n(n_), m(m_), h(h_), w(w_) {
    patch.resize(static_cast<std::size_t>(n) * m * m);
    revealed.resize(static_cast<std::size_t>(n) * h * w);
    seen.resize(revealed.size());
    reward.resize(n);
    pose.resize(2 * n);
    pose_m.resize(2 * n);
    time_step.resize(n);
    label.resize(n);
    index.resize(n);
    terminated.resize(n);
    truncated.resize(n);
    policy_seed.resize(n);
  }
  VectorOutputs outputs() {
    return {patch.data(), pose.data(),   revealed.data(),    seen.data(),   time_step.data(),  label.data(),
            index.data(), pose_m.data(), policy_seed.data(), reward.data(), terminated.data(), truncated.data()};
  }
};

class VectorEnvTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const fs::path data = temp_.path() / "data";
    scout::testing::write_set(data, "train", scout::testing::corner_set(40, 1));
    scout::testing::write_set(data, "validation", scout::testing::corner_set(10, 2));
    scout::testing::write_set(data, "t10k", scout::testing::corner_set(30, 3));
    world_ = temp_.write("corner.yaml", "floor: {dataset: " + data.string() +
                                            ", split: test, index: random}\n"
                                            "camera: {patch_px: 3}\n"
                                            "task: {episodes: 2, steps: 3, step_px: 2}\n"
                                            "seed: 5\n");
  }
  VectorEnvConfig config(int n) const {
    VectorEnvConfig c;
    c.world_file = world_;
    c.num_envs = n;
    return c;
  }
  scout::testing::TempDir temp_{"scout_vector_env"};
  fs::path world_;
};

TEST_F(VectorEnvTest, RunsAreDealtFromTheSeededSequence) {
  VectorEnv env(config(4));
  EXPECT_EQ(env.episode_moves(), 6);
  EXPECT_EQ(env.classes(), 2);
  Buffers b(4, 3, 12, 12);
  env.reset(std::nullopt, b.outputs());  // the world's seed, 5
  const grid::FloorFrame frame{12, 12, 0.1};
  const RunSequence five(env.world(), frame, 30, 5);
  for (int i = 0; i < 4; ++i) {
    const PlannedRun r = five.run(static_cast<std::uint64_t>(i));
    EXPECT_EQ(b.index[i], r.index);
    EXPECT_EQ(b.pose[2 * i], r.start.x());
    EXPECT_EQ(b.pose[2 * i + 1], r.start.y());
    EXPECT_EQ(b.policy_seed[i], r.policy_seed);
    EXPECT_EQ(b.label[i], env.floors().labels[r.index]);
    EXPECT_EQ(b.time_step[i], 0);
  }
  // Another seed starts its own sequence over; no seed takes every robot's next run.
  env.reset(9, b.outputs());
  EXPECT_EQ(b.index[1], RunSequence(env.world(), frame, 30, 9).run(1).index);
  env.reset(std::nullopt, b.outputs());
  EXPECT_EQ(b.index[1], RunSequence(env.world(), frame, 30, 9).run(5).index);
}

TEST_F(VectorEnvTest, EpisodesEndAfterETMovesAndTheNextStepStartsTheNextRun) {
  VectorEnv env(config(3));
  Buffers b(3, 3, 12, 12);
  env.reset(7, b.outputs());
  const std::vector<std::int32_t> right(3, 0), left(3, 1);
  for (int t = 1; t <= 6; ++t) {
    std::vector<std::int32_t> before = b.pose;
    env.step({.move = t % 2 ? std::span<const std::int32_t>(right) : std::span<const std::int32_t>(left)}, b.outputs());
    EXPECT_EQ(b.time_step[0], t);
    EXPECT_EQ(b.terminated[1], t == 6 ? 1 : 0) << t;
    EXPECT_EQ(b.truncated[1], 0);
    EXPECT_EQ(b.reward[2], 0.0f) << "no prediction, no reward";
    for (int i = 0; i < 3; ++i) {  // 2 px right or left, as far as the walls allow
      const int dx = b.pose[2 * i] - before[2 * i];
      EXPECT_TRUE(dx == (t % 2 ? 2 : -2) || (t % 2 ? before[2 * i] > 9 : before[2 * i] < 2)) << i << " " << dx;
      EXPECT_EQ(b.pose[2 * i + 1], before[2 * i + 1]);
    }
  }
  const grid::FloorFrame frame{12, 12, 0.1};
  const RunSequence seven(env.world(), frame, 30, 7);
  env.step({.move = right}, b.outputs());  // ignored: every robot starts its next run
  for (int i = 0; i < 3; ++i) {
    const PlannedRun next = seven.run(static_cast<std::uint64_t>(i + 3));
    EXPECT_EQ(b.index[i], next.index);
    EXPECT_EQ(b.pose[2 * i], next.start.x());
    EXPECT_EQ(b.pose[2 * i + 1], next.start.y());
    EXPECT_EQ(b.time_step[i], 0);
    EXPECT_EQ(b.terminated[i], 0);
    EXPECT_EQ(b.reward[i], 0.0f);
  }
  // What the camera saw after the reset is only the start's window.
  for (int i = 0; i < 3; ++i) {
    int seen = 0;
    for (int k = 0; k < 144; ++k) seen += b.seen[static_cast<std::size_t>(i) * 144 + k];
    EXPECT_LE(seen, 9);
    EXPECT_GE(seen, 4);
  }
}

TEST_F(VectorEnvTest, RewardsAreTheLogProbabilityOfTheLabelDenseOrAtTheEnd) {
  for (const Reward kind : {Reward::Dense, Reward::Sparse}) {
    VectorEnvConfig c = config(2);
    c.reward = kind;
    VectorEnv env(c);
    Buffers b(2, 3, 12, 12);
    env.reset(3, b.outputs());
    const std::vector<std::int32_t> down(2, 2);
    const std::vector<float> logits = {2.0f, -1.0f, 0.5f, 0.5f};  // robot 0 leans to 0, robot 1 unsure
    for (int t = 1; t <= 6; ++t) {
      env.step({.move = down, .prediction = logits}, b.outputs());
      for (int i = 0; i < 2; ++i) {
        const float* l = logits.data() + 2 * i;
        const double expected = l[b.label[i]] - std::log(std::exp(l[0]) + std::exp(l[1]));
        const bool paid = kind == Reward::Dense || t == 6;
        EXPECT_NEAR(b.reward[i], paid ? expected : 0.0, 1e-6) << t << " " << i;
      }
    }
  }
}

TEST_F(VectorEnvTest, WithAGoalAMoveIsTheProtocolsAlongItsAxis) {
  VectorEnv env(config(1));
  Buffers b(1, 3, 12, 12);
  env.reset(11, b.outputs());
  const int x0 = b.pose[0], y0 = b.pose[1];
  // A goal to the left (or right at the edge) on this row, and a move pointing away from it: the
  // protocol moves toward the goal along the move's axis (grid::move_command), at most step_px.
  const int gx = x0 >= 3 ? x0 - 3 : x0 + 3;
  env.step({.move = std::vector<std::int32_t>{gx < x0 ? 0 : 1}, .goal = std::vector<std::int32_t>{gx, y0}},
           b.outputs());
  EXPECT_EQ(b.pose[0], x0 + (gx < x0 ? -2 : 2));
  EXPECT_EQ(b.pose[1], y0);
}

TEST_F(VectorEnvTest, AGoalCutsMovesShortAndHoldsARobotOnIt) {
  VectorEnv env(config(1));
  Buffers b(1, 3, 12, 12);
  env.reset(11, b.outputs());
  const int x0 = b.pose[0], y0 = b.pose[1];
  // A goal one pixel to the right (or left at the edge): the 2-px move stops on it.
  const int gx = x0 < 11 ? x0 + 1 : x0 - 1;
  const std::vector<std::int32_t> goal = {gx, y0};
  env.step({.move = std::vector<std::int32_t>{gx > x0 ? 0 : 1}, .goal = goal}, b.outputs());
  EXPECT_EQ(b.pose[0], gx);
  EXPECT_EQ(b.pose[1], y0);
  env.step({.move = std::vector<std::int32_t>{gx > x0 ? 0 : 1}, .goal = goal}, b.outputs());  // on it: stays
  EXPECT_EQ(b.pose[0], gx);
  EXPECT_EQ(b.time_step[0], 2);
}

TEST_F(VectorEnvTest, AMovePastTheEdgeEndsOnTheBorderPixelWithoutPushingTheWall) {
  VectorEnv env(config(1));
  Buffers b(1, 3, 12, 12);
  env.reset(11, b.outputs());
  const std::vector<std::int32_t> right(1, 0);
  // Right until the border, with a move of the episode left (a finished episode restarts).
  for (int t = 0; t < 30 && !(b.pose[0] == 11 && b.time_step[0] < 6); ++t) env.step({.move = right}, b.outputs());
  ASSERT_EQ(b.pose[0], 11);
  ASSERT_LT(b.time_step[0], 6);
  const int y = b.pose[1];
  env.step({.move = right}, b.outputs());  // nowhere to go: it stays, no tick spent on the wall
  EXPECT_EQ(b.pose[0], 11);
  EXPECT_EQ(b.pose[1], y);
  EXPECT_EQ(env.batch().last_results()[0].ticks, 0);
  EXPECT_FALSE(env.batch().last_results()[0].touched_wall);
}

TEST_F(VectorEnvTest, ASeedPerRobotRunsThatSeedsSequenceFromItsFirstRun) {
  VectorEnv env(config(3));
  Buffers b(3, 3, 12, 12);
  env.reset(VectorReset{.robot_seeds = {21, std::nullopt, 23}}, b.outputs());  // robot 1: the world's seed
  const grid::FloorFrame frame{12, 12, 0.1};
  const RunSequence s21(env.world(), frame, 30, 21), s23(env.world(), frame, 30, 23), five(env.world(), frame, 30, 5);
  EXPECT_EQ(b.index[0], s21.run(0).index);
  EXPECT_EQ(b.policy_seed[0], s21.run(0).policy_seed);
  EXPECT_EQ(b.policy_seed[1], five.run(1).policy_seed);
  EXPECT_EQ(b.policy_seed[2], s23.run(0).policy_seed);
  // Its next runs are its own sequence's next, by reset or by autoreset.
  env.reset(std::nullopt, b.outputs());
  EXPECT_EQ(b.policy_seed[0], s21.run(1).policy_seed);
  EXPECT_EQ(b.policy_seed[1], five.run(4).policy_seed);
  const std::vector<std::int32_t> stay(3, 0);
  for (int t = 0; t <= 6; ++t) env.step({.move = stay}, b.outputs());
  EXPECT_EQ(b.policy_seed[2], s23.run(2).policy_seed);
  EXPECT_EQ(b.time_step[2], 0);
}

TEST_F(VectorEnvTest, AMaskedResetStartsOnlyTheMaskedRobots) {
  VectorEnvConfig c = config(3);
  c.autoreset = false;  // Gymnasium's DISABLED
  VectorEnv env(c);
  Buffers b(3, 3, 12, 12);
  EXPECT_THROW(env.reset(VectorReset{.mask = {1, 0, 0}}, b.outputs()), InputError) << "the first reset starts all";
  env.reset(4, b.outputs());
  const std::vector<std::int32_t> down(3, 2);
  for (int t = 1; t <= 6; ++t) env.step({.move = down}, b.outputs());
  EXPECT_EQ(b.terminated[0], 1);
  EXPECT_EQ(env.ended()[1], 1);
  try {  // without autoreset a finished robot waits for its reset
    env.step({.move = down}, b.outputs());
    ADD_FAILURE() << "a finished robot stepped";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "step: robot 0's run has ended: reset it first (autoreset is off)");
  }
  const std::vector<std::int32_t> pose_before = b.pose;
  env.reset(VectorReset{.mask = {1, 0, 1}}, b.outputs());
  const RunSequence four(env.world(), grid::FloorFrame{12, 12, 0.1}, 30, 4);
  EXPECT_EQ(b.policy_seed[0], four.run(3).policy_seed);
  EXPECT_EQ(b.policy_seed[1], four.run(1).policy_seed) << "robot 1 keeps its run";
  EXPECT_EQ(b.pose[2], pose_before[2]);
  EXPECT_EQ(b.pose[3], pose_before[3]);
  EXPECT_EQ(b.time_step[0], 0);
  EXPECT_EQ(b.time_step[1], 6);
  EXPECT_EQ(env.ended()[1], 1);
  env.reset(VectorReset{.mask = {0, 1, 0}}, b.outputs());
  env.step({.move = down}, b.outputs());
  EXPECT_EQ(b.time_step[1], 1);
  EXPECT_THROW(env.reset(VectorReset{.mask = {0, 0, 0}}, b.outputs()), InputError);
  EXPECT_THROW(env.reset(VectorReset{.mask = {1, 1}}, b.outputs()), InputError);
  EXPECT_THROW(env.reset(VectorReset{.robot_seeds = {1, 2}}, b.outputs()), InputError);
}

std::string refusal(VectorEnv& env, const VectorAction& action, Buffers& b) {
  try {
    env.step(action, b.outputs());
  } catch (const InputError& e) {
    return e.what();
  }
  return "(accepted)";
}

TEST_F(VectorEnvTest, BadActionsAreOneLineAndMoveNothing) {
  VectorEnv env(config(2));
  Buffers b(2, 3, 12, 12);
  EXPECT_EQ(refusal(env, {.move = std::vector<std::int32_t>{0, 0}}, b), "step: call reset first");
  env.reset(1, b.outputs());
  const std::vector<grid::Cell> poses(env.batch().poses().begin(), env.batch().poses().end());
  const std::vector<int> moves(env.batch().moves().begin(), env.batch().moves().end());
  EXPECT_EQ(refusal(env, {.move = std::vector<std::int32_t>{0}}, b),
            "action['move']: expected 2 moves (one per robot), got 1");
  EXPECT_EQ(refusal(env, {.move = std::vector<std::int32_t>{0, 4}}, b),
            "action['move'][1]: expected 0, 1, 2 or 3 (+x, -x, +y, -y), got 4");
  const std::vector<float> nan_logits = {0.0f, 1.0f, NAN, 0.0f};
  EXPECT_EQ(refusal(env, {.move = std::vector<std::int32_t>{0, 0}, .prediction = nan_logits}, b),
            "action['prediction'][1][0]: expected a finite logit, got nan");
  EXPECT_EQ(refusal(env, {.move = std::vector<std::int32_t>{0, 0}, .prediction = std::vector<float>{0.0f}}, b),
            "action['prediction']: expected 2 x 2 logits, got 1 values");
  EXPECT_EQ(refusal(env, {.move = std::vector<std::int32_t>{0, 0}, .goal = std::vector<std::int32_t>{0, 0, 12, 0}}, b),
            "action['goal'][1]: expected a cell of the 12 x 12 floor, got (12, 0)");
  EXPECT_EQ(std::vector<grid::Cell>(env.batch().poses().begin(), env.batch().poses().end()), poses)
      << "a refused step moved a robot";
  EXPECT_EQ(std::vector<int>(env.batch().moves().begin(), env.batch().moves().end()), moves);
  VectorEnvConfig zero = config(0);
  EXPECT_THROW(VectorEnv bad(zero), InputError);
}

}  // namespace
}  // namespace scout::env
