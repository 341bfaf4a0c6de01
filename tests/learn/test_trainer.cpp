// Trainer (learn/trainer.cpp). The pinned training run: a short fp32 run through every stage (full images, modes i, ii and
// iii) on 96 fixed MNIST digits must end in exactly these weights. It pins the whole training
// path — data order, starts, sampling, physics, camera, networks, estimator, Adam — so that a
// change of structure provably changes no result. If a change is meant to change the numbers,
// update the digest in the same commit and say why.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <algorithm>
#include <cstdint>
#include <span>
#include <vector>
#include <cstring>
#include <filesystem>

#include "learn/internal/checkpoint.hpp"
#include "learn/training.hpp"
#include "tests/support/temp_dir.hpp"
#include "worlds/world.hpp"

namespace scout::learn {
namespace {

namespace fs = std::filesystem;

std::uint64_t fnv1a(std::uint64_t h, const void* data, std::size_t n) {
  const auto* bytes = static_cast<const unsigned char*>(data);
  for (std::size_t k = 0; k < n; ++k) h = (h ^ bytes[k]) * 1099511628211ull;
  return h;
}

// FNV-1a over every parameter's and buffer's fp32 bytes, in registration order.
std::uint64_t weights_digest(agent::AgentImpl& agent) {
  std::uint64_t h = 1469598103934665603ull;
  for (const auto& item : agent.named_parameters()) {
    const torch::Tensor t = item.value().detach().contiguous().to(torch::kFloat32);
    h = fnv1a(h, item.key().data(), item.key().size());
    h = fnv1a(h, t.data_ptr<float>(), static_cast<std::size_t>(t.numel()) * sizeof(float));
  }
  for (const auto& item : agent.named_buffers()) {
    const torch::Tensor t = item.value().detach().contiguous().to(torch::kFloat64);
    h = fnv1a(h, item.key().data(), item.key().size());
    h = fnv1a(h, t.data_ptr<double>(), static_cast<std::size_t>(t.numel()) * sizeof(double));
  }
  return h;
}

// The pinned run's config: 96 training and 32 validation digits, tiny networks, every stage.
TrainConfig pinned_config() {
  TrainConfig config;
  config.world = worlds::load_world(fs::path(SCOUT_SOURCE_DIR) / "worlds/mnist.yaml");
  config.data_folder = fs::path(SCOUT_SOURCE_DIR) / "tests/data/mnist-subset";
  config.network.planner_width = 4;
  config.network.planner_depth = 2;
  config.network.classifier_width = 4;
  config.network.classifier_depth = 2;
  config.precision = agent::Precision::Float32;
  config.pretrain_epochs = 1;
  config.epochs = {1, 1, 1};
  config.batch_images = 16;
  config.rollouts = 3;
  config.leave_one_out = true;
  config.seed = 2024;
  return config;
}

constexpr std::uint64_t kPinnedDigest = 8833687337048772615ull;

TEST(TrainerPin, AShortFp32RunThroughAllModesEndsInThePinnedWeights) {
  scout::testing::TempDir temp("trainer-pin");
  const TrainConfig config = pinned_config();
  Trainer trainer(config, temp.path(), /*threads=*/1);
  ASSERT_EQ(trainer.run({}).outcome, TrainOutcome::Finished);
  ASSERT_EQ(trainer.history().size(), 4u);
  agent::Agent agent = load_agent(trainer.checkpoint_file());
  const std::uint64_t digest = weights_digest(*agent);
  EXPECT_EQ(digest, kPinnedDigest) << "weights digest " << digest;
}

// The gradient hook sits between backward and Adam's step: a hook that leaves the gradients as
// they are changes nothing (the pinned weights), sees one buffer per batch holding every
// trainable parameter (the classifier's alone when pretraining on full images), and a hook that
// zeroes them makes every Adam step a no-op, so the run ends with its initial weights.
TEST(TrainerGradientHook, AnIdentityHookKeepsThePinnedWeightsAndSeesEveryBatch) {
  scout::testing::TempDir temp("trainer-hook");
  const TrainConfig config = pinned_config();
  Trainer trainer(config, temp.path(), /*threads=*/1);
  std::vector<std::size_t> sizes;
  TrainHooks hooks;
  hooks.on_gradients = [&](std::span<float> gradients) { sizes.push_back(gradients.size()); };
  ASSERT_EQ(trainer.run(hooks).outcome, TrainOutcome::Finished);
  agent::Agent agent = load_agent(trainer.checkpoint_file());
  EXPECT_EQ(weights_digest(*agent), kPinnedDigest);

  torch::manual_seed(config.seed);
  agent::NetworkConfig network = config.network;
  network.classes = 10;
  const agent::Agent fresh(network);
  std::size_t all = 0, classifier = 0;
  for (const torch::Tensor& p : fresh->parameters()) all += static_cast<std::size_t>(p.numel());
  for (const torch::Tensor& p : fresh->classifier->parameters()) classifier += static_cast<std::size_t>(p.numel());
  // 96 digits: 2 pretraining batches of 16 x 3 images, then 6 batches of 16 images per mode.
  ASSERT_EQ(sizes.size(), 2u + 3u * 6u);
  EXPECT_EQ(sizes[0], classifier);
  EXPECT_EQ(sizes[1], classifier);
  for (std::size_t k = 2; k < sizes.size(); ++k) EXPECT_EQ(sizes[k], all) << "batch " << k;
}

TEST(TrainerGradientHook, AHookThatZeroesTheGradientsLeavesTheInitialWeights) {
  scout::testing::TempDir temp("trainer-hook-zero");
  const TrainConfig config = pinned_config();
  Trainer trainer(config, temp.path(), /*threads=*/1);
  TrainHooks hooks;
  hooks.on_gradients = [](std::span<float> gradients) { std::fill(gradients.begin(), gradients.end(), 0.0f); };
  ASSERT_EQ(trainer.run(hooks).outcome, TrainOutcome::Finished);
  agent::Agent trained = load_agent(trainer.checkpoint_file());
  torch::manual_seed(config.seed);
  agent::NetworkConfig network = config.network;
  network.classes = 10;
  agent::Agent initial(network);
  EXPECT_EQ(weights_digest(*trained), weights_digest(*initial));
  EXPECT_NE(weights_digest(*trained), kPinnedDigest);
}

}  // namespace
}  // namespace scout::learn
