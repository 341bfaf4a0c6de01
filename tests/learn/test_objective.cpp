// One batch's pieces (learn/objective.cpp): make_batch lays robots out as i * N + k with starts
// and seeds that depend on (stream, robot) only; count_correct counts argmax and top-2 hits;
// descend refuses a non-finite loss without touching the weights; sampling_for maps the stages
// to the layers that choose. (run_batch end to end: test_estimator.cpp, test_trainer.cpp.)
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <cstdint>
#include <limits>
#include <set>
#include <stdexcept>
#include <utility>
#include <vector>

#include "learn/internal/objective.hpp"
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

TEST_F(MakeBatch, RefusesNoRolloutsAndIndicesOutOfRange) {
  EXPECT_THROW(batch({0}, 0, 1), std::invalid_argument);
  EXPECT_THROW(batch({5}, 1, 1), std::out_of_range);
  EXPECT_THROW(batch({-1}, 1, 1), std::out_of_range);
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

TEST(Descend, ANonFiniteLossChangesNothingAndAFiniteOneSteps) {
  torch::manual_seed(1);
  torch::nn::Linear layer(3, 1);
  torch::optim::SGD sgd(layer->parameters(), torch::optim::SGDOptions(0.1));
  const torch::Tensor before = layer->weight.detach().clone();
  const torch::Tensor x = torch::ones({1, 3});
  double value = 0;
  const torch::Tensor nan_loss = layer->forward(x).sum() * std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(descend(nan_loss, sgd, value));
  EXPECT_TRUE(std::isnan(value));
  EXPECT_TRUE(torch::equal(layer->weight, before));
  const torch::Tensor loss = layer->forward(x).sum();
  EXPECT_TRUE(descend(loss, sgd, value));
  EXPECT_EQ(value, loss.item<double>());
  // d loss / d w = x = 1, so SGD moves every weight by -0.1.
  EXPECT_TRUE(torch::allclose(layer->weight, before - 0.1));
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
