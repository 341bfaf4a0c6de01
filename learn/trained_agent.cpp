// The trained agent behind `scout run --checkpoint`: the checkpoint's networks, its policy on a
// rollout batch and its classifier, without exposing LibTorch to the CLI.
#include "learn/trained_agent.hpp"

#include <torch/torch.h>

#include <stdexcept>

#include "learn/auto_precision.hpp"
#include "learn/internal/agent_policy.hpp"
#include "learn/internal/checkpoint.hpp"
#include "learn/internal/precision.hpp"
#include "worlds/idx.hpp"

namespace scout::learn {

LearnedLayers learned_layers(const std::vector<EpochMetrics>& history) {
  LearnedLayers learned;
  for (const EpochMetrics& m : history) {
    learned.goals = learned.goals || m.stage == Stage::ModeII || m.stage == Stage::ModeIII;
    learned.actions = learned.actions || m.stage == Stage::ModeIII;
  }
  return learned;
}

struct TrainedAgent::Impl {
  agent::Agent agent{nullptr};
  CheckpointState state;
  LearnedLayers learned;
  agent::Precision precision = agent::Precision::Float32;
  std::unique_ptr<AgentPolicy> policy;
  // What the policy was built for: a new frame, patch or a larger batch builds it again.
  grid::FloorFrame frame{.width_px = 0, .height_px = 0, .pixel_size_m = 0};
  int patch_px = 0;
  int max_robots = 0;
};

TrainedAgent::TrainedAgent(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
TrainedAgent::~TrainedAgent() = default;

std::unique_ptr<TrainedAgent> TrainedAgent::load(const std::filesystem::path& checkpoint, agent::Precision precision) {
  return load(open_checkpoint(checkpoint), precision);
}

std::unique_ptr<TrainedAgent> TrainedAgent::load(const Checkpoint& checkpoint, agent::Precision precision) {
  auto impl = std::make_unique<Impl>();
  impl->precision = resolve_precision(precision);
  if (impl->precision == agent::Precision::BFloat16) {
    if (const std::string why = agent::bf16_unavailable(); !why.empty()) throw InputError("precision: bf16: " + why);
  }
  impl->agent = load_agent(checkpoint, &impl->state);
  if (impl->state.config.network.image_channels != worlds::ImageSet::channels)
    throw InputError(checkpoint.file().string() + ": network.image_channels: expected " +
                     std::to_string(worlds::ImageSet::channels) + " (the floors' channels), got " +
                     std::to_string(impl->state.config.network.image_channels));
  impl->learned = learned_layers(impl->state.history);
  return std::unique_ptr<TrainedAgent>(new TrainedAgent(std::move(impl)));
}

const TrainConfig& TrainedAgent::config() const { return impl_->state.config; }
LearnedLayers TrainedAgent::learned() const { return impl_->learned; }
int TrainedAgent::classes() const { return impl_->state.config.network.classes; }
agent::Precision TrainedAgent::precision() const { return impl_->precision; }

void TrainedAgent::begin(const grid::FloorFrame& frame, int patch_px, std::span<const std::uint64_t> seeds, bool greedy,
                         bool record_goal_maps) {
  Impl& m = *impl_;
  const int count = static_cast<int>(seeds.size());
  if (!m.policy || frame.width_px != m.frame.width_px || frame.height_px != m.frame.height_px ||
      frame.pixel_size_m != m.frame.pixel_size_m || patch_px != m.patch_px || count > m.max_robots) {
    m.policy = std::make_unique<AgentPolicy>(*m.agent, frame, patch_px, count);
    m.frame = frame;
    m.patch_px = patch_px;
    m.max_robots = count;
  }
  Sampling sampling;
  sampling.learned_goals = m.learned.goals;
  sampling.learned_actions = m.learned.actions;
  sampling.greedy = greedy;
  sampling.precision = m.precision;
  // Goal maps exist only where the goal planner chooses.
  sampling.record_goal_maps = record_goal_maps && m.learned.goals;
  m.policy->begin(seeds, sampling);
}

Policy& TrainedAgent::policy() {
  if (!impl_->policy) throw std::logic_error("TrainedAgent::policy: begin() was not called");
  return *impl_->policy;
}

const std::vector<float>& TrainedAgent::goal_map(int robot, int episode) const {
  if (!impl_->policy) throw std::logic_error("TrainedAgent::goal_map: begin() was not called");
  return impl_->policy->goal_map(robot, episode);
}

std::vector<float> TrainedAgent::classify(const BatchState& state, int count) {
  if (count < 0 || count > state.count) throw std::out_of_range("TrainedAgent::classify: more robots than the batch");
  if (count == 0) return {};
  torch::NoGradGuard no_grad;
  const torch::Tensor y = revealed_images(state, count);
  const torch::Tensor p = classifier_log_probs(*impl_->agent, y, impl_->precision).exp().contiguous();
  const float* data = p.data_ptr<float>();
  return std::vector<float>(data, data + static_cast<std::size_t>(count) * classes());
}

}  // namespace scout::learn
