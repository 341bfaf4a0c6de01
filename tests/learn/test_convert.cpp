// Files of Scout's format 1 (.pt: LibTorch's zip of pickles) converted to format 2 (safetensors)
// by convert_legacy_checkpoint, the one reader of .pt files left: the weights, Adam's state and the
// schedule carry over bit for bit, and a converted checkpoint resumes exactly as the checkpoint it
// was made from.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "core/digest.hpp"
#include "core/error.hpp"
#include "learn/checkpoint.hpp"
#include "learn/internal/checkpoint.hpp"
#include "learn/trainer.hpp"
#include "tests/support/safetensors_edit.hpp"
#include "tests/support/training_fixture.hpp"

namespace scout::learn {
namespace {

using namespace scout::learn::test_support;
using scout::testing::split;

// A format-1 file as Scout's writer made it before safetensors (learn/checkpoint.cpp at format 1:
// torch::serialize::OutputArchive with the format number, the config and the progress as strings,
// the agent's module archive, Adam's and LibTorch's generator state), from an opened checkpoint.
void write_legacy(const Checkpoint& checkpoint, const fs::path& file) {
  const TrainConfig& config = checkpoint.info().config;
  agent::Agent agent(config.network);
  torch::optim::Adam adam(agent->parameters(), torch::optim::AdamOptions(config.learning_rate));
  checkpoint.contents().load_into(*agent, &adam);
  torch::serialize::OutputArchive archive;
  archive.write("scout_checkpoint_format", c10::IValue(static_cast<int64_t>(1)));
  archive.write("config", c10::IValue(checkpoint.contents().tensors.metadata.at("config")));
  archive.write("progress", c10::IValue(checkpoint.contents().tensors.metadata.at("progress")));
  torch::serialize::OutputArchive weights;
  agent->save(weights);
  archive.write("agent", weights);
  torch::serialize::OutputArchive optimizer;
  adam.save(optimizer);
  archive.write("optimizer", optimizer);
  archive.write("torch_rng_state", at::detail::getDefaultCPUGenerator().get_state());
  archive.save_to(file.string());
}

TEST_F(Resume, AConvertedCheckpointHoldsTheSameStateAndResumesBitForBit) {
  train("original", {1, 1, 0});
  const fs::path original = run_dir("original") / kCheckpointFile;
  const fs::path legacy = temp_.path() / "legacy.pt", converted_run = run_dir("converted");
  write_legacy(open_checkpoint(original), legacy);
  const CheckpointInfo info = convert_legacy_checkpoint(legacy, converted_run / kCheckpointFile, "{\"a\": 1}");
  EXPECT_EQ(info.format_version, kCheckpointFormat);

  // Every tensor (weights, Adam's steps and moments) the same bytes; config and progress the same.
  const auto a = split(read_bytes(original)), b = split(read_bytes(converted_run / kCheckpointFile));
  EXPECT_EQ(a.data, b.data);
  for (const char* key : {"format", "format_version", "config", "progress", "optimizer"})
    EXPECT_EQ(a.header["__metadata__"][key], b.header["__metadata__"][key]) << key;
  // The manifest given, and where the weights came from.
  const nlohmann::json manifest = nlohmann::json::parse(b.header["__metadata__"]["manifest"].get<std::string>());
  EXPECT_EQ(manifest["a"], 1);
  EXPECT_EQ(manifest["converted_from"]["sha256"], core::sha256_hex(legacy));
  EXPECT_GT(a.header.size(), 3 * agent::Agent(info.config.network)->parameters().size());  // Adam's state is there

  // Both resumed for one more epoch of mode ii: the same weights and Adam state, bit for bit.
  for (const fs::path& run : {run_dir("original"), converted_run}) {
    std::unique_ptr<Trainer> trainer = Trainer::resume(run, kThreads, {.epochs = std::array<int, 3>{1, 2, 0}});
    ASSERT_EQ(trainer->run({}).outcome, TrainOutcome::Finished);
  }
  EXPECT_EQ(split(read_bytes(original)).data, split(read_bytes(converted_run / kCheckpointFile)).data);
}

// The shipped 8,000-digit model, kept in format 1 as the converter's input: converted, its weights
// equal LibTorch's own reading of the .pt file bit for bit, and the converted file shipped beside it.
TEST(Convert, TheOldModelConvertsToTheWeightsLibTorchReads) {
  const fs::path source = fs::path(SCOUT_SOURCE_DIR) / "tests/data";
  scout::testing::TempDir temp{"scout_convert"};
  const fs::path out = temp.path() / "m.safetensors";
  const CheckpointInfo info = convert_legacy_checkpoint(source / "mnist-8k-v1.pt", out, "");
  agent::Agent converted = load_agent(out);
  agent::Agent reference(info.config.network);
  torch::serialize::InputArchive archive, weights;
  archive.load_from((source / "mnist-8k-v1.pt").string());
  archive.read("agent", weights);
  reference->load(weights);
  expect_same_weights(*reference, *converted);
  EXPECT_EQ(split(read_bytes(out)).data, split(read_bytes(source / "mnist-8k-v1.safetensors")).data);

  // A format-1 file LibTorch reads but Scout refuses (a NaN weight): nothing is written, and a file
  // already at the output stays.
  {
    const CheckpointInfo model = open_checkpoint(out).info();
    agent::Agent poisoned = load_agent(out);
    {
      torch::NoGradGuard no_grad;
      poisoned->parameters().front().view(-1)[0].fill_(std::numeric_limits<float>::quiet_NaN());
    }
    torch::serialize::OutputArchive legacy;
    legacy.write("scout_checkpoint_format", c10::IValue(static_cast<int64_t>(1)));
    legacy.write("config", c10::IValue(model.config.to_json()));
    legacy.write("progress", c10::IValue(split(read_bytes(out)).header["__metadata__"]["progress"].get<std::string>()));
    torch::serialize::OutputArchive weights_out;
    poisoned->save(weights_out);
    legacy.write("agent", weights_out);
    legacy.save_to((temp.path() / "nan.pt").string());
    const std::string before = read_bytes(out);
    try {
      convert_legacy_checkpoint(temp.path() / "nan.pt", out, "");
      ADD_FAILURE() << "a NaN weight was converted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("not finite"), std::string::npos) << e.what();
    }
    EXPECT_EQ(read_bytes(out), before);
  }

  // Not a Scout file of format 1, or not there: one line naming it; nothing written.
  const fs::path junk = temp.write("junk.pt", "not a zip");
  for (const fs::path& bad : {junk, temp.path() / "none.pt"}) {
    try {
      convert_legacy_checkpoint(bad, temp.path() / "x.safetensors", "");
      ADD_FAILURE() << bad;
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(bad.string(), 0), 0u) << e.what();
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
    }
    EXPECT_FALSE(fs::exists(temp.path() / "x.safetensors"));
  }
}

}  // namespace
}  // namespace scout::learn
