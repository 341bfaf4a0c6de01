#include "learn/internal/precision.hpp"

#include <ATen/autocast_mode.h>
#include <torch/version.h>

namespace scout::learn {

// LibTorch 2.4 replaced the CPU-specific autocast switches by ones taking the device (and later
// removed the old ones); before it, only the old exist.
#if TORCH_VERSION_MAJOR > 2 || (TORCH_VERSION_MAJOR == 2 && TORCH_VERSION_MINOR >= 4)
bool cpu_autocast_enabled() { return at::autocast::is_autocast_enabled(at::kCPU); }
at::ScalarType cpu_autocast_dtype() { return at::autocast::get_autocast_dtype(at::kCPU); }
static void set_cpu_autocast_enabled(bool enabled) { at::autocast::set_autocast_enabled(at::kCPU, enabled); }
static void set_cpu_autocast_dtype(at::ScalarType dtype) { at::autocast::set_autocast_dtype(at::kCPU, dtype); }
#else
bool cpu_autocast_enabled() { return at::autocast::is_cpu_enabled(); }
at::ScalarType cpu_autocast_dtype() { return at::autocast::get_autocast_cpu_dtype(); }
static void set_cpu_autocast_enabled(bool enabled) { at::autocast::set_cpu_enabled(enabled); }
static void set_cpu_autocast_dtype(at::ScalarType dtype) { at::autocast::set_autocast_cpu_dtype(dtype); }
#endif

ComputePrecision::ComputePrecision(agent::Precision precision) : bf16_(precision == agent::Precision::BFloat16) {
  was_enabled_ = cpu_autocast_enabled();
  previous_dtype_ = cpu_autocast_dtype();
  // Float32 switches autocast off, so that an fp32 guard inside a bf16 one really runs fp32.
  set_cpu_autocast_enabled(bf16_);
  if (!bf16_) return;
  set_cpu_autocast_dtype(at::kBFloat16);
  at::autocast::increment_nesting();
}

ComputePrecision::~ComputePrecision() {
  if (bf16_ && at::autocast::decrement_nesting() == 0) at::autocast::clear_cache();
  set_cpu_autocast_enabled(was_enabled_);
  set_cpu_autocast_dtype(previous_dtype_);
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
