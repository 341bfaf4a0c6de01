// A helper program of tools_tests (which never link LibTorch themselves): sets one classifier
// weight of a checkpoint to NaN, keeping Adam's state, the config and the schedule, as a diverged
// step would leave it (tests/learn/test_trainer.cpp does the same in-process). Usage:
//   scout_test_poison_checkpoint RUN/checkpoint.safetensors
#include <torch/torch.h>

#include <cstdio>
#include <exception>
#include <filesystem>
#include <limits>

#include "learn/internal/checkpoint.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s CHECKPOINT\n", argv[0]);
    return 2;
  }
  try {
    const std::filesystem::path file = argv[1];
    const scout::learn::Checkpoint checkpoint = scout::learn::open_checkpoint(file);
    const scout::learn::CheckpointState& state = checkpoint.contents().state;
    scout::agent::Agent agent(state.config.network);
    torch::optim::Adam adam(agent->parameters(), torch::optim::AdamOptions(state.config.learning_rate));
    checkpoint.contents().load_into(*agent, &adam);
    {
      torch::NoGradGuard no_grad;
      agent->classifier->parameters().front().view(-1)[0].fill_(std::numeric_limits<float>::quiet_NaN());
    }
    scout::learn::save_checkpoint(file, *agent, &adam, state);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  return 0;
}
