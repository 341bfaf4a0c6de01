#include "learn/internal/precision.hpp"

#include <ATen/autocast_mode.h>

namespace scout::learn {

ComputePrecision::ComputePrecision(agent::Precision precision) : bf16_(precision == agent::Precision::BFloat16) {
  was_enabled_ = at::autocast::is_cpu_enabled();
  previous_dtype_ = at::autocast::get_autocast_cpu_dtype();
  // Float32 switches autocast off, so that an fp32 guard inside a bf16 one really runs fp32.
  at::autocast::set_cpu_enabled(bf16_);
  if (!bf16_) return;
  at::autocast::set_autocast_cpu_dtype(at::kBFloat16);
  at::autocast::increment_nesting();
}

ComputePrecision::~ComputePrecision() {
  if (bf16_ && at::autocast::decrement_nesting() == 0) at::autocast::clear_cache();
  at::autocast::set_cpu_enabled(was_enabled_);
  at::autocast::set_autocast_cpu_dtype(previous_dtype_);
}

torch::Tensor network_input(const torch::Tensor& x, agent::Precision precision) {
  if (precision != agent::Precision::BFloat16) return x.contiguous(torch::MemoryFormat::ChannelsLast);
  return x.to(torch::kBFloat16, /*non_blocking=*/false, /*copy=*/false, torch::MemoryFormat::ChannelsLast);
}

torch::Tensor classifier_log_probs(agent::AgentImpl& agent, const torch::Tensor& images, agent::Precision precision) {
  const ComputePrecision guard(precision);
  return torch::log_softmax(agent.classifier->forward(network_input(images, precision)).to(torch::kFloat), 1);
}

}  // namespace scout::learn
