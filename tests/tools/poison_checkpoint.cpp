// A helper program of tools_tests (which never link LibTorch themselves): sets the first classifier
// layer's weights to the largest float, keeping Adam's state, the config and the schedule, so that
// the next step's loss is not finite, as after a diverged step (a NaN weight itself is refused when
// the file is read) (tests/learn/test_trainer.cpp does the same in-process). Usage:
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
      agent->classifier->parameters().front().fill_(std::numeric_limits<float>::max());
    }
    scout::learn::save_checkpoint(file, *agent, &adam, state);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  return 0;
}
