// A helper program of tools_tests (which never link LibTorch themselves): compares the weights
// of two checkpoints and prints one line "relative_l2 max_abs_difference identical WORST": the
// norm of the difference over the norm of A's weights (every parameter and buffer as one
// vector), the largest elementwise difference, 1 when all are equal bit for bit, and the tensor
// that differs most. SCOUT_COMPARE_VERBOSE=1 lists every tensor on stderr. Usage:
//   scout_test_compare_weights A/checkpoint.safetensors B/checkpoint.safetensors
#include <torch/torch.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <string>

#include "learn/internal/checkpoint.hpp"

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s CHECKPOINT_A CHECKPOINT_B\n", argv[0]);
    return 2;
  }
  try {
    const scout::agent::Agent a = scout::learn::load_agent(argv[1]);
    const scout::agent::Agent b = scout::learn::load_agent(argv[2]);
    const auto pa = a->named_parameters(), pb = b->named_parameters();
    const auto ba = a->named_buffers(), bb = b->named_buffers();
    if (pa.size() != pb.size() || ba.size() != bb.size()) {
      std::fprintf(stderr, "the checkpoints hold different networks\n");
      return 1;
    }
    double max_difference = 0, squared_difference = 0, squared_weight = 0;
    bool identical = true;
    std::string worst;
    double worst_difference = -1;
    auto compare = [&](const std::string& name, const torch::Tensor& x, const torch::Tensor& y) {
      if (!x.sizes().equals(y.sizes())) throw std::runtime_error("the checkpoints hold different networks");
      identical = identical && torch::equal(x, y);
      const double d = (x - y).abs().max().item<double>();
      if (d > worst_difference) {
        worst_difference = d;
        worst = name;
      }
      max_difference = std::max(max_difference, d);
      if (std::getenv("SCOUT_COMPARE_VERBOSE"))
        std::fprintf(stderr, "%-40s %.3g (max |w| %.3g)\n", name.c_str(), d, x.abs().max().item<double>());
      squared_difference += (x - y).to(torch::kDouble).pow(2).sum().item<double>();
      squared_weight += x.to(torch::kDouble).pow(2).sum().item<double>();
    };
    for (const auto& p : pa) compare(p.key(), p.value(), pb[p.key()]);
    for (const auto& p : ba) compare(p.key(), p.value(), bb[p.key()]);
    std::printf("%.9g %.9g %d %s\n", std::sqrt(squared_difference / squared_weight), max_difference, identical ? 1 : 0,
                worst.c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  return 0;
}
