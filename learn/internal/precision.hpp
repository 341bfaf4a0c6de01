#pragma once
/// The networks' arithmetic for one batch (agent::Precision). Torch header: learn/ sources only.
#include <torch/torch.h>

#include "agent/config.hpp"
#include "agent/networks.hpp"
#include "learn/internal/private.hpp"

namespace scout::learn {

/// While alive, LibTorch's CPU autocast runs convolutions and linear layers in bfloat16
/// (Precision::BFloat16), or is off (Float32, also inside a bf16 guard). Autocast casts each fp32
/// weight that requires grad once and caches the copy (frozen weights are cast at every use); the
/// cache is cleared when the outermost guard ends, because the optimizer changes the weights
/// between batches. The graph keeps what backward needs, so backward may run afterwards.
/// Thread-local, like autocast itself. Caution: the cache does not know grad mode, so one guard
/// must not span both a no-grad and a with-grad forward of the same weights.
class ComputePrecision {
 public:
  explicit ComputePrecision(agent::Precision precision);
  ~ComputePrecision();
  ComputePrecision(const ComputePrecision&) = delete;
  ComputePrecision& operator=(const ComputePrecision&) = delete;

 private:
  bool bf16_ = false;
  bool was_enabled_ = false;
  at::ScalarType previous_dtype_ = at::kBFloat16;
};

/// LibTorch's CPU autocast state, through whichever API this LibTorch has (before 2.4 or since).
bool cpu_autocast_enabled();
at::ScalarType cpu_autocast_dtype();

/// A network input in the layout and type that `precision` runs fastest in: bf16 in channels-last
/// (NHWC, what oneDNN's AMX kernels want; a bf16 input also keeps the dense blocks' concatenations
/// in bf16 instead of promoting them back to fp32). Float32 inputs are returned as they are.
torch::Tensor network_input(const torch::Tensor& x, agent::Precision precision);

/// log pi_c for fp32 images [B, c, H, W]: the classifier run in `precision`, fp32 out [B, D].
torch::Tensor classifier_log_probs(agent::AgentImpl& agent, const torch::Tensor& images, agent::Precision precision);

}  // namespace scout::learn
