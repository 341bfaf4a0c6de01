#pragma once
// Shared pieces of the training tests (tests/learn/test_trainer.cpp, test_checkpoint.cpp): the
// corner world over synthetic IDX floors, tiny networks, and the Training and Resume fixtures.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <array>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "learn/internal/checkpoint.hpp"
#include "learn/trainer.hpp"
#include "tests/support/corner_data.hpp"
#include "tests/support/temp_dir.hpp"
#include "worlds/world.hpp"

namespace scout::learn::test_support {

namespace fs = std::filesystem;
using scout::testing::corner_set;
using scout::testing::CornerSet;
using scout::testing::TempDir;
using scout::testing::write_set;
constexpr int kSide = scout::testing::kCornerSide;

// One LibTorch thread: these networks are too small to gain from more, and with two or more,
// OpenMP's busy-waiting makes two such tests side by side (`ctest -j2` on two cores) about 13x
// slower each. The corner figures below are the same with 1 and 2 threads.
constexpr int kThreads = 1;

// A world over the IDX folder `data`: m = 3, E episodes of T 2-px moves, random start.
inline worlds::World corner_world(const TempDir& temp, const fs::path& data, int episodes, int steps) {
  const fs::path file = temp.write("world.yaml", "floor: {dataset: " + data.string() +
                                                     ", split: train, index: random}\n"
                                                     "camera: {patch_px: 3}\n"
                                                     "task: {episodes: " +
                                                     std::to_string(episodes) + ", steps: " + std::to_string(steps) +
                                                     ", step_px: 2}\n"
                                                     "seed: 5\n");
  return worlds::load_world(file);
}

// Tiny networks: fast enough for many runs in one test.
inline TrainConfig tiny_config(const worlds::World& world, const fs::path& data) {
  TrainConfig c;
  c.world = world;
  c.data_folder = data;
  c.network.classes = 2;
  c.network.planner_width = 4;
  c.network.planner_depth = 1;
  c.network.classifier_width = 8;
  c.network.classifier_depth = 2;
  c.rollouts = 2;
  c.batch_images = 8;
  c.learning_rate = 3e-3;
  c.leave_one_out = true;
  c.precision = agent::Precision::Float32;  // not the default auto: the same figures on every CPU
  c.seed = 3;
  return c;
}

inline std::string read_bytes(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

// The parameters of two agents are bitwise the same (name by name).
inline void expect_same_weights(torch::nn::Module& a, torch::nn::Module& b) {
  const auto pa = a.named_parameters(), pb = b.named_parameters();
  ASSERT_EQ(pa.size(), pb.size());
  for (const auto& item : pa) {
    const torch::Tensor* other = pb.find(item.key());
    ASSERT_NE(other, nullptr) << item.key();
    EXPECT_TRUE(torch::equal(item.value(), *other)) << item.key() << " differs";
  }
}

// Everything of an epoch's metrics that is not a clock reading.
inline void expect_same_metrics(const EpochMetrics& a, const EpochMetrics& b) {
  EXPECT_EQ(a.stage, b.stage);
  EXPECT_EQ(a.epoch, b.epoch);
  EXPECT_EQ(a.reward, b.reward) << to_string(a.stage) << " " << a.epoch;
  EXPECT_EQ(a.loss, b.loss) << to_string(a.stage) << " " << a.epoch;
  EXPECT_EQ(a.train_accuracy, b.train_accuracy) << to_string(a.stage) << " " << a.epoch;
  EXPECT_EQ(a.validation_accuracy, b.validation_accuracy) << to_string(a.stage) << " " << a.epoch;
  EXPECT_EQ(a.validation_iid, b.validation_iid) << to_string(a.stage) << " " << a.epoch;
  EXPECT_EQ(a.validation_goals_only, b.validation_goals_only) << to_string(a.stage) << " " << a.epoch;
  EXPECT_EQ(a.validation_full_image, b.validation_full_image) << to_string(a.stage) << " " << a.epoch;
  EXPECT_EQ(a.gradient_norm, b.gradient_norm) << to_string(a.stage) << " " << a.epoch;
}

class Training : public ::testing::Test {
 protected:
  void SetUp() override { set_torch_threads(kThreads); }
  TempDir temp_{"scout_training"};

  // A fresh, empty run folder.
  fs::path run_dir(const std::string& name) const {
    const fs::path dir = temp_.path() / name;
    fs::create_directories(dir);
    return dir;
  }
};

class Resume : public Training {
 protected:
  void SetUp() override {
    Training::SetUp();
    data_ = temp_.path() / "data";
    write_set(data_, "train", corner_set(48, 4));  // 44 train (6 batches of 8) + 4 validation
    world_ = corner_world(temp_, data_, 1, 3);
  }
  TrainConfig config(std::array<int, 3> epochs) const {
    TrainConfig c = tiny_config(world_, data_);
    c.epochs = epochs;
    c.precision = precision_;
    return c;
  }
  // Trains `epochs` uninterrupted into a new folder; returns the trainer's history.
  std::vector<EpochMetrics> train(const std::string& name, std::array<int, 3> epochs) {
    Trainer trainer(config(epochs), run_dir(name), kThreads);
    const TrainResult r = trainer.run({});
    EXPECT_EQ(r.outcome, TrainOutcome::Finished) << r.message;
    return trainer.history();
  }
  void expect_same_checkpoints(const std::string& a, const std::string& b) {
    agent::Agent agent_a = load_agent(temp_.path() / a / kCheckpointFile);
    agent::Agent agent_b = load_agent(temp_.path() / b / kCheckpointFile);
    expect_same_weights(*agent_a, *agent_b);
  }
  void interrupted_run_resumed_is_the_uninterrupted_run();
  fs::path data_;
  worlds::World world_;
  agent::Precision precision_ = agent::Precision::Float32;
};

}  // namespace scout::learn::test_support
