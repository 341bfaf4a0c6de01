// Checkpoint files (learn/checkpoint.cpp) as a resumed run and load_agent read them: a future
// format version, garbage, a truncated or empty file, no file, and weights that do not fit their
// own config are each refused with one line naming the file.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

#include "core/error.hpp"
#include "learn/checkpoint.hpp"
#include "learn/evaluation.hpp"
#include "learn/internal/checkpoint.hpp"
#include "learn/trained_agent.hpp"
#include "learn/trainer.hpp"
#include "tests/support/safetensors_edit.hpp"
#include "tests/support/training_fixture.hpp"

namespace scout::learn {
namespace {

using namespace scout::learn::test_support;

// --- 5. Bad checkpoints are refused with one line naming the file ---------------------------------------------------

// The one-line InputError that resuming `run` throws (empty if none).
std::string resume_refusal(const fs::path& run) {
  try {
    Trainer::resume(run, kThreads);
  } catch (const InputError& e) {
    return e.what();
  }
  return {};
}

TEST_F(Resume, BadCheckpointsAreRefusedWithOneLine) {
  const fs::path good = run_dir("good");
  {
    Trainer trainer(config({1, 0, 0}), good, kThreads);
    ASSERT_EQ(trainer.run({}).outcome, TrainOutcome::Finished);
  }
  const std::string bytes = read_bytes(good / kCheckpointFile);

  // A future format version, otherwise well-formed.
  const fs::path future = run_dir("future");
  {
    scout::testing::SafetensorsParts parts = scout::testing::split(bytes);
    parts.header["__metadata__"]["format_version"] = std::to_string(kCheckpointFormat + 1);
    parts.header["__metadata__"]["progress"] = "{}";
    std::ofstream(future / kCheckpointFile, std::ios::binary) << scout::testing::join(parts);
  }
  const std::string line = resume_refusal(future);
  EXPECT_NE(line.find((future / kCheckpointFile).string()), std::string::npos) << line;
  EXPECT_NE(line.find("format"), std::string::npos) << line;
  EXPECT_NE(line.find(std::to_string(kCheckpointFormat + 1)), std::string::npos) << line;
  try {
    open_checkpoint(future / kCheckpointFile);
    ADD_FAILURE() << "a future format was read";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), line);
  }

  // Garbage, a truncated checkpoint, an empty file, no file.
  const fs::path garbage = run_dir("garbage"), truncated = run_dir("truncated"), empty = run_dir("empty");
  std::ofstream(garbage / kCheckpointFile, std::ios::binary) << "this is not a checkpoint\n";
  std::ofstream(truncated / kCheckpointFile, std::ios::binary) << bytes.substr(0, bytes.size() * 2 / 3);
  std::ofstream(empty / kCheckpointFile, std::ios::binary);
  for (const fs::path& run : {garbage, truncated, empty, run_dir("none")}) {
    const std::string message = resume_refusal(run);
    EXPECT_NE(message.find((run / kCheckpointFile).string()), std::string::npos) << run << ": " << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
  // The good one still resumes (and has nothing left to do).
  std::unique_ptr<Trainer> trainer = Trainer::resume(good, kThreads);
  EXPECT_EQ(trainer->run({}).outcome, TrainOutcome::Finished);
}

// A checkpoint whose weights do not fit its own network config (here: planners 4 wide, config
// 8) is refused, for training and for loading alike, rather than run with the file's shapes.
TEST_F(Resume, WeightsThatDoNotFitTheConfigAreRefused) {
  const fs::path good = run_dir("good");
  {
    Trainer trainer(config({1, 0, 0}), good, kThreads);
    ASSERT_EQ(trainer.run({}).outcome, TrainOutcome::Finished);
  }
  const fs::path mismatched = run_dir("mismatched");
  {
    const Checkpoint checkpoint = open_checkpoint(good / kCheckpointFile);
    CheckpointState state = checkpoint.contents().state;
    agent::Agent agent(state.config.network);
    torch::optim::Adam adam(agent->parameters(), torch::optim::AdamOptions(state.config.learning_rate));
    checkpoint.contents().load_into(*agent, &adam);
    state.config.network.planner_width *= 2;
    state.config.epochs = {1, 1, 0};
    save_checkpoint(mismatched / kCheckpointFile, *agent, &adam, state);
  }
  const std::string file = (mismatched / kCheckpointFile).string();
  const std::string line = resume_refusal(mismatched);
  EXPECT_NE(line.find(file), std::string::npos) << line;
  EXPECT_NE(line.find("agent"), std::string::npos) << line;
  EXPECT_EQ(line.find('\n'), std::string::npos) << line;
  try {
    load_agent(mismatched / kCheckpointFile);
    ADD_FAILURE() << "weights 4 wide were loaded into planners 8 wide";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(file), std::string::npos) << e.what();
  }
}

// Each reader opens a checkpoint once (issue 23: a resume read, checked and parsed it three times,
// load_agent twice, scout report once per budget point): the file is read, checked and handed to
// LibTorch by one open_checkpoint, and a reader given an opened checkpoint opens nothing.
TEST_F(Resume, EachReaderOpensACheckpointOnce) {
  train("run", {1, 0, 0});
  const fs::path file = run_dir("run") / kCheckpointFile;
  const auto opens = [](const auto& read) {
    const int before = checkpoints_opened();
    read();
    return checkpoints_opened() - before;
  };
  EXPECT_EQ(opens([&] { Trainer::resume(run_dir("run"), kThreads); }), 1);
  EXPECT_EQ(opens([&] { load_agent(file); }), 1);
  EXPECT_EQ(opens([&] { TrainedAgent::load(file, agent::Precision::Float32); }), 1);
  EXPECT_EQ(opens([&] { export_model(open_checkpoint(file), temp_.path() / "model.safetensors"); }), 1);
  const Checkpoint opened = open_checkpoint(file);
  EXPECT_EQ(opens([&] { Trainer::resume(opened, run_dir("run"), kThreads); }), 0);
  EXPECT_EQ(opens([&] { TrainedAgent::load(opened, agent::Precision::Float32); }), 0);
  // An evaluation given the opened checkpoint (scout report's budget sweep, point after point).
  EvalConfig config;
  config.checkpoint = file;
  config.opened = opened;
  config.images = data_ / "train-images-idx3-ubyte";
  config.labels = data_ / "train-labels-idx1-ubyte";
  config.runs = 2;
  config.agent_only = true;
  config.threads = kThreads;
  double first = 0;
  EXPECT_EQ(opens([&] { first = evaluate(config).accuracy.mean; }), 0);
  EXPECT_EQ(opens([&] { EXPECT_EQ(evaluate(config).accuracy.mean, first); }), 0);
  // The networks are shared by the readers that run them, and training a resumed run's own leaves
  // what the opened checkpoint holds as it was.
  EXPECT_EQ(opened.contents().networks().get(), opened.contents().networks().get());
  agent::Agent before = load_agent(file);  // an independent open
  agent::Agent trained(opened.info().config.network);
  opened.contents().load_into(*trained, nullptr);
  {
    torch::NoGradGuard no_grad;
    for (torch::Tensor& p : trained->parameters()) p.add_(1.0);
  }
  agent::Agent again(opened.info().config.network);
  opened.contents().load_into(*again, nullptr);
  expect_same_weights(*before, *again);
}

// Files written before this version still load once converted (and later versions keep it so): the
// model that shipped for the 8,000-digit set predates the per-epoch baselines, which read as absent and
// leave their metrics.csv fields empty.
TEST(OlderFiles, AModelWrittenBeforeTheValidationBaselinesStillLoads) {
  const std::filesystem::path model = std::filesystem::path(SCOUT_SOURCE_DIR) / "tests/data/mnist-8k-v1.safetensors";
  const CheckpointInfo info = open_checkpoint(model).info();
  ASSERT_EQ(info.history.size(), 52u);  // 5 full-image epochs, then 10 + 15 + 22 of modes i - iii
  for (const EpochMetrics& m : info.history) {
    EXPECT_FALSE(m.validation_iid.has_value());
    EXPECT_FALSE(m.validation_goals_only.has_value());
    EXPECT_FALSE(m.validation_full_image.has_value());
    EXPECT_GT(m.validation_accuracy, 0.5);
  }
  const std::string row = metrics_csv_row(info.history.back()), header = metrics_csv_header();
  EXPECT_EQ(row.substr(row.size() - 4), ",,,\n") << row;
  EXPECT_EQ(std::count(row.begin(), row.end(), ','), std::count(header.begin(), header.end(), ','));
}

}  // namespace
}  // namespace scout::learn
