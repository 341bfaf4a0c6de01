// Mixed precision (agent::Precision, learn/internal/precision.hpp): bf16 runs the same networks as fp32
// to within bf16's rounding, accumulates the same gradients, the normalisations accept bf16
// activations without changing fp32 results, and the choice is stored with a run's config.
#include <ATen/autocast_mode.h>
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <cmath>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "agent/networks.hpp"
#include "agent/state.hpp"
#include "core/error.hpp"
#include "core/random.hpp"
#include "learn/auto_precision.hpp"
#include "learn/internal/agent_policy.hpp"
#include "learn/internal/objective.hpp"
#include "learn/internal/precision.hpp"
#include "learn/rollout.hpp"
#include "learn/trainer.hpp"
#include "worlds/world.hpp"

namespace scout::learn {
namespace {

constexpr int kSide = 28;

// `count` 28 x 28 floors: a bright random stroke pattern over a dark background, labels 0 - 9.
worlds::LabeledImages synthetic_digits(int count, std::uint64_t seed) {
  worlds::LabeledImages set;
  set.images.count = count;
  set.images.rows = set.images.cols = kSide;
  set.images.pixels.assign(static_cast<std::size_t>(count) * kSide * kSide, 0);
  set.labels.resize(count);
  core::Rng rng(seed);
  for (int i = 0; i < count; ++i) {
    set.labels[i] = static_cast<std::uint8_t>(i % 10);
    std::uint8_t* img = set.images.pixels.data() + static_cast<std::size_t>(i) * kSide * kSide;
    for (int k = 0; k < kSide * kSide; ++k)
      if (core::uniform_below(rng, 4) == 0) img[k] = static_cast<std::uint8_t>(128 + core::uniform_below(rng, 128));
  }
  return set;
}

worlds::World preset_world() { return worlds::load_world(std::string(SCOUT_SOURCE_DIR) + "/worlds/mnist.yaml"); }

// The agent's three outputs for the state after a mode (i) rollout, in `precision`.
struct Outputs {
  torch::Tensor goal, action, classifier;  // log-probabilities, fp32
};

// 24 robots after a mode (i) rollout (physics and camera) over synthetic digits: the planners'
// input (y, l, h, g_l) [24, 4, 28, 28] and the classifier's (y) [24, 1, 28, 28], fp32.
std::pair<torch::Tensor, torch::Tensor> inputs_after_a_rollout(std::uint64_t seed) {
  const worlds::World world = preset_world();
  const worlds::LabeledImages digits = synthetic_digits(24, seed);
  const grid::FloorFrame frame{kSide, kSide, world.floor.pixel_size_m};
  std::vector<int> indices(digits.images.count);
  for (int i = 0; i < digits.images.count; ++i) indices[i] = i;
  const RolloutBatch batch = make_batch(digits, indices, 1, world, frame, seed);
  RolloutEngine engine(world, frame, batch.count);
  RandomPolicy random(batch.seeds);
  engine.run(batch.floors, batch.starts, batch.motion_seeds, random, false);
  const BatchState& state = engine.state();
  const int area = frame.area_px();
  torch::Tensor input = torch::empty({batch.count, 4, kSide, kSide});
  for (int i = 0; i < batch.count; ++i) {
    agent::RobotView view{state.revealed_image(i), state.seen[i].data().data(), state.pose[i], &state.goal[i]};
    agent::write_planner_input(frame, world.camera.patch_px, view,
                               input.data_ptr<float>() + static_cast<std::size_t>(i) * 4 * area);
  }
  return {input, revealed_images(state, batch.count)};
}

torch::Tensor planner_inputs_after_a_rollout(std::uint64_t seed) { return inputs_after_a_rollout(seed).first; }

Outputs outputs_after_a_rollout(agent::AgentImpl& agent, agent::Precision precision) {
  torch::NoGradGuard no_grad;
  const auto [planner_input, revealed] = inputs_after_a_rollout(3);
  const ComputePrecision guard(precision);
  const torch::Tensor u = network_input(planner_input, precision);
  Outputs out;
  out.goal = torch::log_softmax(agent.goal->forward(u).to(torch::kFloat), 1);
  out.action = torch::log_softmax(agent.action->forward(u).to(torch::kFloat), 1);
  out.classifier = classifier_log_probs(agent, revealed, precision);
  return out;
}

// Largest difference of the probabilities, and the mean KL(fp32 || bf16) per row.
struct Divergence {
  double max_abs_p = 0, mean_kl = 0;
};
Divergence divergence(const torch::Tensor& log_p32, const torch::Tensor& log_p16) {
  const torch::Tensor p = log_p32.exp();
  return {(p - log_p16.exp()).abs().max().item<double>(), (p * (log_p32 - log_p16)).sum(1).mean().item<double>()};
}

class Precision : public ::testing::Test {
 protected:
  void SetUp() override { set_torch_threads(1); }
};

// With the same weights, bf16 gives the fp32 distributions to within bf16's 8-bit mantissa, for
// every classifier variant. Measured while this test was written (random init): goal max |dp|
// ~1e-5 (784 pixels share the mass), action and classifier ~2e-3, KL below 1e-4.
TEST_F(Precision, Bf16GivesTheFp32DistributionsToWithinRounding) {
  if (const std::string why = agent::bf16_unavailable(); !why.empty()) GTEST_SKIP() << "bf16 cannot run here: " << why;
  for (const agent::ClassifierKind kind :
       {agent::ClassifierKind::Paper, agent::ClassifierKind::PaperStrided, agent::ClassifierKind::PaperStridedNorm,
        agent::ClassifierKind::Strided, agent::ClassifierKind::ResNet18}) {
    agent::NetworkConfig config;
    config.classifier = kind;
    torch::manual_seed(5);
    agent::Agent agent(config);
    agent->eval();
    const Outputs fp32 = outputs_after_a_rollout(*agent, agent::Precision::Float32);
    const Outputs bf16 = outputs_after_a_rollout(*agent, agent::Precision::BFloat16);
    const char* name = agent::to_string(kind);
    for (const auto& [what, a, b] :
         {std::tuple{"goal", fp32.goal, bf16.goal}, std::tuple{"action", fp32.action, bf16.action},
          std::tuple{"classifier", fp32.classifier, bf16.classifier}}) {
      ASSERT_EQ(a.sizes(), b.sizes()) << what;
      EXPECT_EQ(b.scalar_type(), torch::kFloat) << what;
      const Divergence d = divergence(a, b);
      EXPECT_LT(d.max_abs_p, 0.02) << name << " " << what;
      EXPECT_LT(d.mean_kl, 1e-3) << name << " " << what;
      // Not trivially equal: bf16 really ran (rounding leaves a trace).
      EXPECT_FALSE(torch::equal(a, b)) << name << " " << what;
    }
  }
}

// The gradient of a REINFORCE-like sum over 20 moves, sum_k w_k log pi(a_k | s_k) with fixed
// decisions and weights of both signs, as one training step accumulates it for the planners, is
// the same in bf16 as in fp32 up to rounding: bf16 keeps the moves' contributions, even where
// they largely cancel. (Fixed decisions: a whole rollout in bf16 may sample another axis where
// rounding moves a CDF step, which changes a robot's trajectory, not the arithmetic under test.)
TEST_F(Precision, Bf16AccumulatesThePlannersGradientsOverMovesLikeFp32) {
  // Where bf16 is emulated the gradients differ far more (a cosine of about 0.5 on an AVX2 EPYC),
  // which is why auto never picks it there (tests/agent/test_config.cpp).
  if (!agent::native_bf16().any())
    GTEST_SKIP() << "this CPU has no native bf16: " << agent::fp32_without_native_bf16_note();
  torch::manual_seed(6);
  agent::Agent agent(agent::NetworkConfig{});
  agent->train();
  std::vector<torch::Tensor> inputs;
  for (int move = 0; move < 20; ++move) inputs.push_back(planner_inputs_after_a_rollout(100 + move));
  core::Rng rng(8);
  std::vector<std::int64_t> goals, axes;
  std::vector<float> weights;
  for (std::size_t k = 0; k < inputs.size() * inputs[0].size(0); ++k) {
    goals.push_back(static_cast<std::int64_t>(core::uniform_below(rng, kSide * kSide)));
    axes.push_back(static_cast<std::int64_t>(core::uniform_below(rng, 2)));
    weights.push_back(static_cast<float>(core::uniform_below(rng, 2001)) / 1000.0f - 1.0f);
  }
  auto gradient = [&](agent::Precision precision, torch::nn::Module& layer, bool goal_layer) {
    for (torch::Tensor& p : agent->parameters()) p.mutable_grad() = torch::Tensor();
    torch::Tensor loss = torch::zeros({});
    {
      const ComputePrecision guard(precision);
      std::size_t k = 0;
      for (const torch::Tensor& x : inputs) {
        const int n = static_cast<int>(x.size(0));
        const torch::Tensor u = network_input(x, precision);
        const torch::Tensor logits = goal_layer ? agent->goal->forward(u) : agent->action->forward(u);
        const torch::Tensor log_p = torch::log_softmax(logits.to(torch::kFloat), 1);
        const torch::Tensor chosen =
            torch::tensor(std::vector<std::int64_t>(goal_layer ? goals.begin() + k : axes.begin() + k,
                                                    goal_layer ? goals.begin() + k + n : axes.begin() + k + n))
                .unsqueeze(1);
        const torch::Tensor w = torch::tensor(std::vector<float>(weights.begin() + k, weights.begin() + k + n));
        loss = loss + (w * log_p.gather(1, chosen).squeeze(1)).sum();
        k += n;
      }
    }
    loss.backward();
    std::vector<torch::Tensor> parts;
    for (const torch::Tensor& p : layer.parameters()) parts.push_back(p.grad().flatten());
    return torch::cat(parts);
  };
  for (const bool goal_layer : {true, false}) {
    torch::nn::Module& layer = goal_layer ? static_cast<torch::nn::Module&>(*agent->goal) : *agent->action;
    const char* name = goal_layer ? "goal" : "action";
    const torch::Tensor g32 = gradient(agent::Precision::Float32, layer, goal_layer);
    const torch::Tensor g16 = gradient(agent::Precision::BFloat16, layer, goal_layer);
    ASSERT_GT(g32.norm().item<double>(), 0) << name;
    const double cosine = (g32 * g16).sum().item<double>() / (g32.norm() * g16.norm()).item<double>();
    const double ratio = g16.norm().item<double>() / g32.norm().item<double>();
    EXPECT_GT(cosine, 0.99) << name;
    EXPECT_NEAR(ratio, 1.0, 0.05) << name;
  }
}

// The classifiers' normalisations accept bf16 activations, and in fp32 the ResNet's BatchNorm
// keeps BatchNorm2d's semantics: batch statistics in training, running averages with momentum
// 0.1 (unbiased variance), a batch counter, and the running statistics in eval mode.
TEST_F(Precision, ResNetBatchNormKeepsBatchNorm2dSemantics) {
  if (const std::string why = agent::bf16_unavailable(); !why.empty()) GTEST_SKIP() << "bf16 cannot run here: " << why;
  agent::NetworkConfig config;
  config.classifier = agent::ClassifierKind::ResNet18;
  config.classifier_width = 8;
  torch::manual_seed(7);
  agent::Agent agent(config);
  agent->train();
  const torch::Tensor y = torch::randn({6, 1, kSide, kSide});
  const auto params = agent->classifier->named_parameters();
  const auto buffers = agent->classifier->named_buffers();
  ASSERT_NE(buffers.find("bn1.running_mean"), nullptr);
  ASSERT_NE(buffers.find("bn1.num_batches_tracked"), nullptr);
  ASSERT_NE(params.find("bn1.weight"), nullptr);
  const torch::Tensor stem = torch::conv2d(y, params["conv1.weight"], {}, 1, 1);  // bn1's input
  {
    torch::NoGradGuard no_grad;
    agent->classifier->forward(y);
  }
  const torch::Tensor expected_mean = 0.1 * stem.mean({0, 2, 3});
  const torch::Tensor expected_var = 0.9 + 0.1 * stem.permute({1, 0, 2, 3}).flatten(1).var(1, /*unbiased=*/true);
  EXPECT_TRUE(torch::allclose(buffers["bn1.running_mean"], expected_mean, 1e-5, 1e-6));
  EXPECT_TRUE(torch::allclose(buffers["bn1.running_var"], expected_var, 1e-5, 1e-6));
  EXPECT_EQ(buffers["bn1.num_batches_tracked"].item<std::int64_t>(), 1);

  // bf16 through every block, in training and in eval mode.
  for (const bool training : {true, false}) {
    agent->train(training);
    const torch::Tensor log_p = classifier_log_probs(*agent, y, agent::Precision::BFloat16);
    EXPECT_EQ(log_p.sizes(), (std::vector<std::int64_t>{6, 10}));
    EXPECT_TRUE(torch::isfinite(log_p).all().item<bool>());
  }
  EXPECT_EQ(buffers["bn1.num_batches_tracked"].item<std::int64_t>(), 2);
}

// The guard switches autocast on for bf16 and off for fp32 (also nested inside a bf16 guard),
// restores what was there when it ends, and leaves fp32 results bit for bit as they were.
TEST_F(Precision, TheGuardNestsAndRestoresAutocast) {
  if (const std::string why = agent::bf16_unavailable(); !why.empty()) GTEST_SKIP() << "bf16 cannot run here: " << why;
  agent::NetworkConfig config;
  config.classifier = agent::ClassifierKind::Strided;
  torch::manual_seed(9);
  agent::Agent agent(config);
  agent->eval();
  torch::NoGradGuard no_grad;
  const torch::Tensor y = torch::rand({4, 1, kSide, kSide}) - 0.5;
  const torch::Tensor before = classifier_log_probs(*agent, y, agent::Precision::Float32);
  ASSERT_FALSE(cpu_autocast_enabled());
  {
    const ComputePrecision outer(agent::Precision::BFloat16);
    EXPECT_TRUE(cpu_autocast_enabled());
    EXPECT_EQ(cpu_autocast_dtype(), at::kBFloat16);
    {
      const ComputePrecision inner(agent::Precision::Float32);
      EXPECT_FALSE(cpu_autocast_enabled());
      EXPECT_TRUE(torch::equal(classifier_log_probs(*agent, y, agent::Precision::Float32), before));
    }
    EXPECT_TRUE(cpu_autocast_enabled());
    EXPECT_FALSE(torch::equal(classifier_log_probs(*agent, y, agent::Precision::BFloat16), before));
  }
  EXPECT_FALSE(cpu_autocast_enabled());
  EXPECT_TRUE(torch::equal(classifier_log_probs(*agent, y, agent::Precision::Float32), before));
}

TEST_F(Precision, NamesRoundTripAndUnknownNamesAreRefused) {
  for (const agent::Precision p : {agent::Precision::Float32, agent::Precision::BFloat16})
    EXPECT_EQ(agent::parse_precision(agent::to_string(p)), p);
  try {
    agent::parse_precision("fp16");
    FAIL() << "fp16 was accepted";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("fp16"), std::string::npos) << what;
    EXPECT_NE(what.find("bf16"), std::string::npos) << what;
  }
}

// The precision is part of a run's config; a config written before it existed was fp32.
TEST_F(Precision, IsStoredInTheConfigAndOlderConfigsReadAsFp32) {
  TrainConfig c;
  c.world = preset_world();
  c.data_folder = "/data/mnist";
  c.precision = agent::Precision::BFloat16;
  const std::string text = c.to_json();
  EXPECT_EQ(TrainConfig::from_json(text, "run").precision, agent::Precision::BFloat16);

  const std::string key = "\"precision\": \"bf16\",";
  const std::size_t at = text.find(key);
  ASSERT_NE(at, std::string::npos) << text;
  std::string older = text;
  older.erase(at, key.size());
  EXPECT_EQ(TrainConfig::from_json(older, "run").precision, agent::Precision::Float32);

  std::string bad = text;
  bad.replace(at, key.size(), "\"precision\": \"fp8\",");
  try {
    TrainConfig::from_json(bad, "RUN/checkpoint.safetensors");
    FAIL() << "fp8 was accepted";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("RUN/checkpoint.safetensors"), std::string::npos) << what;
    EXPECT_NE(what.find("precision"), std::string::npos) << what;
  }
}

// The library's defaults are the CLI's: epochs 2,2,2 and auto precision. Auto is never stored:
// the JSON holds what it resolves to, and a config that says "auto" is refused. A config without
// the key (written before precision existed) still reads as fp32, not as today's default.
TEST_F(Precision, TheDefaultIsAutoAndOnlyResolvedPrecisionsAreStored) {
  TrainConfig c;
  EXPECT_EQ(c.epochs, (std::array<int, 3>{2, 2, 2}));
  EXPECT_EQ(c.precision, agent::Precision::Auto);
  c.world = preset_world();
  c.data_folder = "/data/mnist";
  const std::string text = c.to_json();
  const agent::Precision resolved = resolve_precision(agent::Precision::Auto);
  const std::string key = std::string("\"precision\": \"") + agent::to_string(resolved) + "\",";
  const std::size_t at = text.find(key);
  ASSERT_NE(at, std::string::npos) << text;
  EXPECT_EQ(TrainConfig::from_json(text, "run").precision, resolved);

  std::string older = text;
  older.erase(at, key.size());
  EXPECT_EQ(TrainConfig::from_json(older, "run").precision, agent::Precision::Float32);

  std::string stored_auto = text;
  stored_auto.replace(at, key.size(), "\"precision\": \"auto\",");
  EXPECT_THROW(TrainConfig::from_json(stored_auto, "run"), InputError);
}

}  // namespace
}  // namespace scout::learn
