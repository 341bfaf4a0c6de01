// The estimator proved right (METHOD.md § The estimator, § Training modes): on a floor small
// enough to enumerate every trajectory with the exact grid model, the mean of grad J-hat over
// many rollout batches -- the real path: make_batch, run_batch, the Box2D world and the OSMesa
// camera in the loop, the gradient by backward of the returned objective -- matches the exact
// grad J, for each layer's parameters, in modes (i), (ii) and (iii), with and without the
// leave-one-out baseline. A wrong estimator (REINFORCE term dropped or its sign flipped) fails
// the same comparison. Also: surrogate_objective's own algebra, and chi counted only where the
// action protocol lets the action layer choose.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "agent/networks.hpp"
#include "agent/state.hpp"
#include "grid/grid.hpp"
#include "learn/internal/agent_policy.hpp"
#include "learn/internal/estimator.hpp"
#include "learn/internal/objective.hpp"
#include "learn/internal/precision.hpp"
#include "learn/rollout.hpp"
#include "worlds/dataset.hpp"
#include "worlds/world.hpp"

namespace scout::learn {
namespace {

// ---------------------------------------------------------------------------------------------
// surrogate_objective on its own.

torch::Tensor values(std::vector<float> v) { return torch::tensor(v, torch::kFloat); }

TEST(EstimatorSurrogate, ValueIsMeanRewardPlusMeanReinforceTerm) {
  const torch::Tensor log_pi = values({-1.0f, -2.0f, -0.5f, -3.0f, -0.25f, -1.5f});
  const torch::Tensor reward = values({-0.7f, -0.1f, -2.0f, -0.3f, -1.1f, -0.9f});
  const EstimatorOptions options{.rollouts_per_image = 3};
  const double expected = reward.mean().item<double>() + (log_pi * reward).mean().item<double>();
  EXPECT_NEAR(surrogate_objective(log_pi, reward, options).item<double>(), expected, 1e-6);
  // No learned layer: J-hat is the mean reward alone.
  EXPECT_NEAR(surrogate_objective(torch::Tensor(), reward, options).item<double>(), reward.mean().item<double>(), 1e-6);
  // The entropy bonus adds beta * mean entropy, and only when asked for.
  const torch::Tensor entropy = values({0.1f, 0.2f, 0.3f, 0.4f, 0.5f, 0.6f});
  EstimatorOptions bonus = options;
  bonus.entropy_bonus = 0.5;
  EXPECT_NEAR(surrogate_objective(log_pi, reward, bonus, entropy).item<double>(), expected + 0.5 * 0.35, 1e-6);
  EXPECT_NEAR(surrogate_objective(log_pi, reward, options, entropy).item<double>(), expected, 1e-6);
}

TEST(EstimatorSurrogate, RewardIsStoppedInTheReinforceWeight) {
  const int n = 6;
  torch::Tensor log_pi = values({-1.0f, -2.0f, -0.5f, -3.0f, -0.25f, -1.5f}).requires_grad_();
  torch::Tensor reward = values({-0.7f, -0.1f, -2.0f, -0.3f, -1.1f, -0.9f}).requires_grad_();
  surrogate_objective(log_pi, reward, EstimatorOptions{.rollouts_per_image = 2}).backward();
  // d/d log_pi = sg(r) / n; d/dr = 1 / n only: without the stop-gradient it would be (1 + log_pi) / n.
  EXPECT_TRUE(torch::allclose(log_pi.grad(), reward.detach() / n, 1e-6, 1e-7)) << log_pi.grad();
  EXPECT_TRUE(torch::allclose(reward.grad(), torch::full({n}, 1.0f / n), 1e-6, 1e-7)) << reward.grad();
}

TEST(EstimatorSurrogate, LeaveOneOutWeightIsRewardMinusMeanOfTheOthers) {
  // Two images, N = 4: weights worked out by hand, r_k - mean of the other three of its image.
  torch::Tensor log_pi = values({-1.0f, -2.0f, -0.5f, -3.0f, -0.25f, -1.5f, -2.5f, -0.75f}).requires_grad_();
  torch::Tensor reward = values({1.0f, 2.0f, 3.0f, 6.0f, -1.0f, -1.0f, -4.0f, 2.0f}).requires_grad_();
  const torch::Tensor weight = values({1 - 11.0f / 3, 2 - 10.0f / 3, 0.0f, 4.0f, 0.0f, 0.0f, -4.0f, 4.0f});
  const EstimatorOptions options{.rollouts_per_image = 4, .leave_one_out = true};
  const torch::Tensor objective = surrogate_objective(log_pi, reward, options);
  const double expected = reward.mean().item<double>() + (log_pi.detach() * weight).mean().item<double>();
  EXPECT_NEAR(objective.item<double>(), expected, 1e-5);
  objective.backward();
  EXPECT_TRUE(torch::allclose(log_pi.grad(), weight / 8, 1e-5, 1e-6)) << log_pi.grad();
  // The baseline, like the weight, carries no gradient into r.
  EXPECT_TRUE(torch::allclose(reward.grad(), torch::full({8}, 1.0f / 8), 1e-6, 1e-7)) << reward.grad();
}

// A cost per rollout (stalled moves) lowers the planners' REINFORCE weight, before the baseline,
// and leaves the classifier's term r as it is.
TEST(EstimatorSurrogate, ACostLowersThePlannersWeightOnly) {
  torch::Tensor log_pi = values({-1.0f, -2.0f, -0.5f, -3.0f}).requires_grad_();
  torch::Tensor reward = values({1.0f, 2.0f, 3.0f, 6.0f}).requires_grad_();
  const torch::Tensor cost = values({0.0f, 0.5f, 0.0f, 1.5f});
  const EstimatorOptions options{.rollouts_per_image = 4, .leave_one_out = true};
  surrogate_objective(log_pi, reward, options, {}, cost).backward();
  // r - cost = 1, 1.5, 3, 4.5; minus the mean of the other three: -2, -1.333, 0.667, 2.667.
  const torch::Tensor weight = values({1 - 9.0f / 3, 1.5f - 8.5f / 3, 3 - 7.0f / 3, 4.5f - 5.5f / 3});
  EXPECT_TRUE(torch::allclose(log_pi.grad(), weight / 4, 1e-5, 1e-6)) << log_pi.grad();
  EXPECT_TRUE(torch::allclose(reward.grad(), torch::full({4}, 0.25f), 1e-6, 1e-7)) << reward.grad();
}

TEST(EstimatorSurrogate, RejectsInvalidInputs) {
  const torch::Tensor log_pi = torch::zeros({6});
  const torch::Tensor reward = torch::zeros({6});
  EXPECT_THROW(surrogate_objective(log_pi, reward, EstimatorOptions{.rollouts_per_image = 4}), std::invalid_argument);
  EXPECT_THROW(surrogate_objective(log_pi, reward, EstimatorOptions{.rollouts_per_image = 0}), std::invalid_argument);
  EXPECT_THROW(surrogate_objective(log_pi, reward, EstimatorOptions{.rollouts_per_image = 1, .leave_one_out = true}),
               std::invalid_argument);
  EXPECT_THROW(surrogate_objective(log_pi, torch::zeros({2, 3}), EstimatorOptions{.rollouts_per_image = 1}),
               std::invalid_argument);
  EXPECT_NO_THROW(
      surrogate_objective(log_pi, reward, EstimatorOptions{.rollouts_per_image = 3, .leave_one_out = true}));
}

// ---------------------------------------------------------------------------------------------
// The enumerable problem.

constexpr int kSide = 4;  // 4 x 4 floor: 16 goals
constexpr int kPatch = 2;

enum class Mode { I, II, III };
const char* mode_name(Mode mode) { return mode == Mode::I ? "(i)" : mode == Mode::II ? "(ii)" : "(iii)"; }
Sampling sampling_for(Mode mode) {
  Sampling s;
  s.learned_goals = mode != Mode::I;
  s.learned_actions = mode == Mode::III;
  s.with_grad = true;
  return s;
}

/// Two floors of two classes that differ only in the right-most column, a world and a tiny agent.
struct Problem {
  grid::FloorFrame frame{kSide, kSide, 0.1};
  worlds::World world;
  worlds::LabeledImages data;
  agent::Agent agent{nullptr};
};

/// Fits a layer with full-batch Adam steps (the test's set-up, not the estimator).
template <typename Loss>
void fit(torch::nn::Module& layer, int steps, double learning_rate, Loss loss) {
  torch::optim::Adam adam(layer.parameters(), torch::optim::AdamOptions(learning_rate));
  for (int k = 0; k < steps; ++k) {
    adam.zero_grad();
    loss().backward();
    adam.step();
  }
}

/// E episodes of T moves, a random start (drawn by make_batch, enumerated by the exact J).
Problem make_problem(int episodes, int steps) {
  Problem p;
  p.world.camera.patch_px = kPatch;
  p.world.task = {.episodes = episodes, .steps = steps, .step_px = 2};
  worlds::check_against_floor(p.world, kSide, kSide);
  const grid::FloorFrame& frame = p.frame;
  const int area = frame.area_px();

  // A shared high-contrast pattern (every revealed pixel moves the networks), and the class
  // written in the right-most column: 255 for class 0, 0 for class 1. A robot sees that column
  // only from x = 3, so from the left half of the floor it takes two moves right to read it:
  // the goal and, on the way, the axes decide whether it is read.
  std::mt19937_64 rng(5);
  std::vector<std::uint8_t> base(area);
  for (auto& b : base)
    b = (rng() & 1) ? static_cast<std::uint8_t>(200 + rng() % 56) : static_cast<std::uint8_t>(rng() % 56);
  p.data.images = {.count = 2, .rows = kSide, .cols = kSide, .pixels = {}};
  for (int label = 0; label < 2; ++label) {
    std::vector<std::uint8_t> img = base;
    for (int y = 0; y < kSide; ++y) img[y * kSide + kSide - 1] = label == 0 ? 255 : 0;
    p.data.images.pixels.insert(p.data.images.pixels.end(), img.begin(), img.end());
    p.data.labels.push_back(static_cast<std::uint8_t>(label));
  }

  agent::NetworkConfig config;
  config.classes = 2;
  config.planner_width = 4;
  config.planner_depth = 1;
  config.classifier_width = 4;
  config.classifier_depth = 1;
  torch::manual_seed(11);
  p.agent = agent::Agent(config);

  // Fresh networks are nearly uniform and blind: r then hardly depends on the path, and the
  // planners' gradients drown in the sampling noise (measured: relative standard errors of 1 to
  // 40 without a baseline). So, before the test:
  // - the classifier learns to read the class where it is seen (y from two camera windows
  //   anywhere), then gets a bias of 0.5 toward class 0 so that it is off its optimum and its own
  //   grad J is large;
  // - the goal planner learns a fixed distribution over goals with 60 % of its mass on (3, 1..3),
  //   where the axes decide whether the class column is reached, and 10 % on (3, 0).
  // Neither sits at an optimum of J: every layer's grad J stays large against the noise.
  {
    std::vector<float> ys;
    std::vector<std::int64_t> labels;
    for (int label = 0; label < 2; ++label)
      for (int a = 0; a < area; ++a)
        for (int b = 0; b < area; ++b) {
          grid::RevealMask mask(frame);
          mask.reveal(grid::camera_window({a % kSide, a / kSide}, kPatch, frame));
          mask.reveal(grid::camera_window({b % kSide, b / kSide}, kPatch, frame));
          std::vector<float> y(area);
          agent::write_revealed_image(frame, {p.data.images.image(label), mask.data().data(), {0, 0}, nullptr},
                                      y.data());
          ys.insert(ys.end(), y.begin(), y.end());
          labels.push_back(label);
        }
    const torch::Tensor x = torch::tensor(ys).view({-1, 1, kSide, kSide});
    const torch::Tensor t = torch::tensor(labels);
    fit(*p.agent->classifier, 100, 0.05,
        [&] { return torch::nll_loss(torch::log_softmax(p.agent->classifier->forward(x), 1), t); });
  }
  {
    // The goal planner's input at the first goal, for every start and both floors.
    std::vector<float> us;
    for (int image = 0; image < 2; ++image)
      for (int s = 0; s < area; ++s) {
        const grid::GridModel model(frame, kPatch, {s % kSide, s / kSide});
        std::vector<float> u(4 * area);
        agent::write_planner_input(frame, kPatch,
                                   {p.data.images.image(image), model.revealed().data().data(), model.pose(), nullptr},
                                   u.data());
        us.insert(us.end(), u.begin(), u.end());
      }
    const torch::Tensor u = torch::tensor(us).view({-1, 4, kSide, kSide});
    torch::Tensor target = torch::full({area}, 0.3 / (area - kSide));
    for (int y = 0; y < kSide; ++y) target[y * kSide + kSide - 1] = y == 0 ? 0.1 : 0.2;
    fit(*p.agent->goal, 200, 0.05,
        [&] { return -(torch::log_softmax(p.agent->goal->forward(u), 1) * target).sum(1).mean(); });
  }
  torch::NoGradGuard no_grad;
  for (auto& item : p.agent->named_parameters())
    if (item.key() == "classifier.head.bias") item.value()[0] += 0.5;
  return p;
}

/// The exact J of a mode: every trajectory of the grid model with its probability, for every image
/// and every start, with autograd's graph to the layers that the mode learns. Layers not learned
/// choose i.i.d. (1/16 per goal, 1/2 per axis). The states are written by the same functions
/// AgentPolicy uses (write_planner_input, write_revealed_image), from the grid model's pose and mask.
torch::Tensor exact_objective(Problem& p, Mode mode) {
  const grid::FloorFrame& frame = p.frame;
  const int area = frame.area_px(), m = p.world.camera.patch_px;
  const bool learned_goals = mode != Mode::I, learned_actions = mode == Mode::III;
  struct Node {
    int image;
    grid::GridModel model;
    grid::Cell goal;
  };
  std::vector<Node> nodes;
  for (int image = 0; image < p.data.images.count; ++image) {
    // make_batch draws the start uniformly over the floor (draw_start): every start, equally likely.
    for (int s = 0; s < area; ++s)
      nodes.push_back({image, grid::GridModel(frame, m, {s % frame.width_px, s / frame.width_px}), grid::Cell(-1, -1)});
  }
  const double roots = static_cast<double>(nodes.size());
  torch::Tensor log_p = torch::zeros({static_cast<long>(nodes.size())});

  // The planners' input for a set of nodes, written by the function AgentPolicy uses.
  auto planner_input = [&](const std::vector<int>& which, bool with_goal) {
    torch::Tensor u = torch::empty({static_cast<long>(which.size()), 4, frame.height_px, frame.width_px});
    for (std::size_t k = 0; k < which.size(); ++k) {
      const Node& node = nodes[which[k]];
      const agent::RobotView view{p.data.images.image(node.image), node.model.revealed().data().data(),
                                  node.model.pose(), with_goal ? &node.goal : nullptr};
      agent::write_planner_input(frame, m, view, u.data_ptr<float>() + k * 4 * area);
    }
    return u;
  };

  for (int e = 0; e < p.world.task.episodes; ++e) {
    // Goal layer: every node branches into all n^2 goals.
    const long count = static_cast<long>(nodes.size());
    torch::Tensor log_g;
    if (learned_goals) {
      std::vector<int> all(count);
      for (int i = 0; i < count; ++i) all[i] = i;
      log_g = torch::log_softmax(p.agent->goal->forward(planner_input(all, e > 0)), 1);
    } else {
      log_g = torch::full({count, area}, -std::log(static_cast<double>(area)));
    }
    log_p = (log_p.unsqueeze(1) + log_g).reshape({count * area});
    std::vector<Node> next;
    next.reserve(count * area);
    for (const Node& node : nodes)
      for (int g = 0; g < area; ++g)
        next.push_back({node.image, node.model, grid::Cell(g % frame.width_px, g / frame.width_px)});
    nodes = std::move(next);

    for (int t = 0; t < p.world.task.steps; ++t) {
      // Action protocol: forced axes keep one child; Choose branches into both axes.
      std::vector<int> choose;
      for (int i = 0; i < static_cast<int>(nodes.size()); ++i)
        if (grid::decide(nodes[i].model.pose(), nodes[i].goal) == grid::Decision::Choose) choose.push_back(i);
      const long c = static_cast<long>(choose.size());
      torch::Tensor log_a;
      if (learned_actions && c > 0) {
        log_a = torch::log_softmax(p.agent->action->forward(planner_input(choose, true)), 1);
      } else {
        log_a = torch::full({c, 2}, -std::log(2.0));
      }
      // Slots 0 .. 2c-1: log pi_a of chosen node k and axis a at 2k + a; slot 2c: 0 (no decision).
      const torch::Tensor slots = torch::cat({log_a.reshape({2 * c}), torch::zeros({1})});
      std::vector<std::int64_t> parent, slot;
      std::vector<Node> children;
      int k = 0;
      for (int i = 0; i < static_cast<int>(nodes.size()); ++i) {
        const Node& node = nodes[i];
        const grid::Decision d = grid::decide(node.model.pose(), node.goal);
        auto child = [&](grid::Axis axis, std::int64_t s) {
          Node n = node;
          n.model.move(grid::move_command(node.model.pose(), node.goal, axis, p.world.task.step_px));
          children.push_back(std::move(n));
          parent.push_back(i);
          slot.push_back(s);
        };
        if (d == grid::Decision::Choose) {
          child(grid::Axis::Horizontal, 2 * k);
          child(grid::Axis::Vertical, 2 * k + 1);
          ++k;
        } else {
          child(d == grid::Decision::Vertical     ? grid::Axis::Vertical
                : d == grid::Decision::Horizontal ? grid::Axis::Horizontal
                                                  : grid::Axis::None,
                2 * c);
        }
      }
      log_p = log_p.index_select(0, torch::tensor(parent, torch::kLong)) +
              slots.index_select(0, torch::tensor(slot, torch::kLong));
      nodes = std::move(children);
    }
  }

  // Classifier on y after the last move; r = log pi_c[label].
  const long leaves = static_cast<long>(nodes.size());
  torch::Tensor y = torch::empty({leaves, 1, frame.height_px, frame.width_px});
  std::vector<std::int64_t> labels(leaves);
  for (long i = 0; i < leaves; ++i) {
    const Node& node = nodes[i];
    const agent::RobotView view{p.data.images.image(node.image), node.model.revealed().data().data(), node.model.pose(),
                                nullptr};
    agent::write_revealed_image(frame, view, y.data_ptr<float>() + i * area);
    labels[i] = p.data.labels[node.image];
  }
  const torch::Tensor reward =
      torch::log_softmax(p.agent->classifier->forward(y), 1).gather(1, torch::tensor(labels).unsqueeze(1)).squeeze(1);
  const torch::Tensor prob = log_p.exp();
  // The probabilities of each root's trajectories sum to one: the enumeration misses nothing.
  EXPECT_NEAR(prob.sum().item<double>(), roots, 1e-4 * roots);
  return (prob * reward).sum() / roots;
}

// ---------------------------------------------------------------------------------------------
// Gradients as flat vectors per layer.

enum Group { kGoal = 0, kAction = 1, kClassifier = 2, kGroups = 3 };
const char* group_name(int g) { return g == kGoal ? "goal" : g == kAction ? "action" : "classifier"; }

std::vector<torch::Tensor> group_params(Problem& p, int group) {
  return group == kGoal     ? p.agent->goal->parameters()
         : group == kAction ? p.agent->action->parameters()
                            : p.agent->classifier->parameters();
}

/// d objective / d (each layer's parameters), flattened; an undefined tensor where the layer is not
/// in the graph at all.
std::vector<torch::Tensor> layer_gradients(Problem& p, const torch::Tensor& objective, bool retain) {
  std::vector<torch::Tensor> inputs, out(kGroups);
  std::vector<std::size_t> sizes;
  for (int g = 0; g < kGroups; ++g) {
    auto params = group_params(p, g);
    sizes.push_back(params.size());
    inputs.insert(inputs.end(), params.begin(), params.end());
  }
  const auto grads = torch::autograd::grad({objective}, inputs, {}, retain, false, /*allow_unused=*/true);
  std::size_t at = 0;
  for (int g = 0; g < kGroups; ++g) {
    std::vector<torch::Tensor> parts;
    bool any = false;
    for (std::size_t k = 0; k < sizes[g]; ++k, ++at) {
      any = any || grads[at].defined();
      parts.push_back(grads[at].defined() ? grads[at].flatten().to(torch::kDouble)
                                          : torch::zeros({inputs[at].numel()}, torch::kDouble));
    }
    if (any) out[g] = torch::cat(parts);
  }
  return out;
}

/// Sums and sums of squares of per-batch gradient vectors: their mean and its standard error.
struct Moments {
  torch::Tensor sum, sum_sq;
  int batches = 0;
  bool defined = false;
  void add(const torch::Tensor& g) {
    if (!g.defined()) return;
    if (!defined) {
      sum = torch::zeros_like(g);
      sum_sq = torch::zeros_like(g);
      defined = true;
    }
    sum += g;
    sum_sq += g * g;
    ++batches;
  }
  torch::Tensor mean() const { return sum / batches; }
  /// Per coordinate: the sample standard deviation over batches / sqrt(batches).
  torch::Tensor standard_error() const {
    const torch::Tensor m = mean();
    const torch::Tensor var = (sum_sq - batches * m * m).clamp_min(0) / (batches - 1);
    return (var / batches).sqrt();
  }
};

/// How far a sample mean of gradients lies from the exact gradient.
struct Comparison {
  double relative_error = 0;    ///< ||mean - exact|| / ||exact||
  double relative_se = 0;       ///< sqrt(sum SE^2) / ||exact||: the noise the test allows for
  double z = 0;                 ///< ||mean - exact|| / sqrt(sum SE^2)
  double worst_coordinate = 0;  ///< max over coordinates of |mean - exact| / (SE + eps)
};

Comparison compare(const Moments& sampled, const torch::Tensor& exact) {
  const torch::Tensor mean = sampled.mean(), se = sampled.standard_error();
  const double norm = exact.norm().item<double>();
  const double noise = se.norm().item<double>();
  const double error = (mean - exact).norm().item<double>();
  // eps keeps coordinates with no variance (a goal-head bias: softmax ignores it) from dividing by zero.
  const double eps = 1e-4 * norm / std::sqrt(static_cast<double>(exact.numel()));
  return {error / norm, noise / norm, error / noise, ((mean - exact).abs() / (se + eps)).max().item<double>()};
}

// The tolerances. The mean over B batches of grad J-hat is unbiased for grad J, with a per-coordinate
// standard error SE estimated from the B batch gradients (each batch is independent of the others:
// the leave-one-out baseline only mixes rollouts within a batch). Then E||mean - exact||^2 =
// sum SE^2, so z = ||mean - exact|| / sqrt(sum SE^2) is about 1 for a right estimator:
// - z < kMaxZ = 4 (the worst case, all noise along one direction, is chi^2_1: P(z > 4) = 6e-5);
// - every coordinate within kMaxCoordinate = 6 SE (Student t with B - 1 >= 47 dof:
//   P(|t| > 6) < 3e-7, times ~380 coordinates);
// - the test must be able to fail: relative SE sqrt(sum SE^2) / ||exact|| < kMaxRelativeSE = 0.06,
//   so a wrong gradient off by 100 % of the exact one is more than 16 SE away;
// - relative error ||mean - exact|| / ||exact|| < kMaxRelativeError = 0.25 (4 SE at the largest
//   noise allowed). The REINFORCE term dropped is off by 100 %, flipped by 200 %: both must fail.
constexpr double kMaxZ = 4.0;
constexpr double kMaxCoordinate = 6.0;
constexpr double kMaxRelativeSE = 0.06;
constexpr double kMaxRelativeError = 0.25;
constexpr int kRolloutsPerImage = 512;  // 2 images x 512 = 1024 robots per batch

struct Estimates {
  std::vector<torch::Tensor> exact;
  Moments right[kGroups], dropped[kGroups], flipped[kGroups];
};

/// Runs `batches` batches of the real path in `mode` and collects grad J-hat, and the gradients of
/// the same batches with the REINFORCE term dropped and with its sign flipped.
Estimates estimate(Problem& p, Mode mode, bool leave_one_out, int batches, std::uint64_t seed) {
  Estimates out;
  out.exact = layer_gradients(p, exact_objective(p, mode), false);

  const int robots = p.data.images.count * kRolloutsPerImage;
  RolloutEngine engine(p.world, p.frame, robots);
  AgentPolicy policy(*p.agent, p.frame, kPatch, robots);
  const Sampling sampling = sampling_for(mode);
  const EstimatorOptions options{.rollouts_per_image = kRolloutsPerImage, .leave_one_out = leave_one_out};
  const std::vector<int> indices = {0, 1};
  for (int b = 0; b < batches; ++b) {
    const RolloutBatch batch = make_batch(p.data, indices, kRolloutsPerImage, p.world, p.frame,
                                          core::derive_seed(seed, static_cast<std::uint64_t>(b)));
    const BatchOutcome outcome = run_batch(*p.agent, engine, policy, batch, sampling, options);
    const bool learned = mode != Mode::I;
    const auto g = layer_gradients(p, outcome.objective, learned);
    std::vector<torch::Tensor> reinforce(kGroups);
    if (learned) {
      // The REINFORCE part alone: outcome.reward is detached, so this is mean(log_pi * sg(r - b))
      // plus a constant, with gradients to the planners only.
      reinforce = layer_gradients(p, surrogate_objective(policy.log_pi(), outcome.reward, options), false);
    }
    for (int k = 0; k < kGroups; ++k) {
      out.right[k].add(g[k]);
      if (k == kClassifier || !g[k].defined()) continue;
      out.dropped[k].add(g[k] - reinforce[k]);
      out.flipped[k].add(g[k] - 2 * reinforce[k]);
    }
  }
  return out;
}

/// One mode of the estimator against the exact gradient on the E x T problem, with its negative controls.
void check_mode(Mode mode, bool leave_one_out, std::uint64_t seed, int episodes = 1, int steps = 2, int batches = 48) {
  const auto t0 = std::chrono::steady_clock::now();
  Problem p = make_problem(episodes, steps);
  const Estimates est = estimate(p, mode, leave_one_out, batches, seed);
  const bool learned_goals = mode != Mode::I, learned_actions = mode == Mode::III;
  const bool learned[kGroups] = {learned_goals, learned_actions, true};

  ASSERT_TRUE(est.exact[kClassifier].defined());
  const double classifier_norm = est.exact[kClassifier].norm().item<double>();
  for (int k = 0; k < kGroups; ++k) {
    SCOPED_TRACE(std::string("mode ") + mode_name(mode) + (leave_one_out ? " leave-one-out" : "") + ", layer " +
                 group_name(k));
    if (!learned[k]) {
      // A layer that is not learned is not in either graph.
      EXPECT_FALSE(est.exact[k].defined());
      EXPECT_FALSE(est.right[k].defined);
      continue;
    }
    ASSERT_TRUE(est.exact[k].defined());
    ASSERT_TRUE(est.right[k].defined);
    const double norm = est.exact[k].norm().item<double>();
    const Comparison c = compare(est.right[k], est.exact[k]);
    std::printf("  mode %-5s %-4s %-10s |exact| %.4g  rel.error %.4f  rel.SE %.4f  z %.2f  worst coord %.2f SE\n",
                mode_name(mode), leave_one_out ? "LOO" : "", group_name(k), norm, c.relative_error, c.relative_se, c.z,
                c.worst_coordinate);
    // The planners' exact gradient is clearly non-zero, a real share of the classifier's (and,
    // by the relative-SE bound below, far above the noise): the test would be empty otherwise.
    if (k != kClassifier) {
      EXPECT_GT(norm, 0.05 * classifier_norm);
    }
    EXPECT_LT(c.relative_se, kMaxRelativeSE);
    EXPECT_LT(c.relative_error, kMaxRelativeError);
    EXPECT_LT(c.z, kMaxZ);
    EXPECT_LT(c.worst_coordinate, kMaxCoordinate);
    if (k == kClassifier) continue;

    // Negative controls: the same comparison must fail for a wrong estimator.
    for (const auto& [name, moments] : {std::pair{"dropped", &est.dropped[k]}, std::pair{"flipped", &est.flipped[k]}}) {
      const Comparison bad = compare(*moments, est.exact[k]);
      std::printf("  mode %-5s %-4s %-10s REINFORCE %s: rel.error %.4f  z %.1f\n", mode_name(mode),
                  leave_one_out ? "LOO" : "", group_name(k), name, bad.relative_error, bad.z);
      EXPECT_GT(bad.relative_error, kMaxRelativeError) << name;
      EXPECT_GT(bad.z, kMaxZ) << name;
    }
  }
  std::printf("  mode %s%s: %d batches of %d rollouts, %.1f s\n", mode_name(mode), leave_one_out ? " LOO" : "", batches,
              2 * kRolloutsPerImage, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
}

TEST(EstimatorGradient, ModeIMatchesExactGradient) { check_mode(Mode::I, false, 101); }
TEST(EstimatorGradient, ModeIIMatchesExactGradient) { check_mode(Mode::II, false, 102); }
TEST(EstimatorGradient, ModeIIMatchesExactGradientWithLeaveOneOut) { check_mode(Mode::II, true, 103); }
TEST(EstimatorGradient, ModeIIIMatchesExactGradient) { check_mode(Mode::III, false, 104); }
TEST(EstimatorGradient, ModeIIIMatchesExactGradientWithLeaveOneOut) { check_mode(Mode::III, true, 105); }
// Two episodes: the second goal is planned from a state after moves, with g_l of the first goal.
TEST(EstimatorGradient, TwoEpisodesModeIIIMatchesExactGradient) { check_mode(Mode::III, false, 106, 2, 2, 96); }
TEST(EstimatorGradient, TwoEpisodesModeIIIMatchesExactGradientWithLeaveOneOut) {
  check_mode(Mode::III, true, 107, 2, 2, 96);
}

// ---------------------------------------------------------------------------------------------
// chi: the action layer's log-probabilities enter log pi only where decide() == Choose.

/// log pi_a[axis] and log pi_g[goal] for one robot, computed here from the grid model's state,
/// one robot at a time (AgentPolicy batches the robots that choose).
double action_log_prob(Problem& p, const grid::GridModel& model, const grid::Cell& goal, const std::uint8_t* floor,
                       grid::Axis axis) {
  torch::NoGradGuard no_grad;
  torch::Tensor u = torch::empty({1, 4, kSide, kSide});
  agent::write_planner_input(p.frame, kPatch, {floor, model.revealed().data().data(), model.pose(), &goal},
                             u.data_ptr<float>());
  return torch::log_softmax(p.agent->action->forward(u), 1)[0][axis == grid::Axis::Vertical ? 1 : 0].item<double>();
}

double goal_log_prob(Problem& p, const grid::GridModel& model, const std::uint8_t* floor, const grid::Cell& goal) {
  torch::NoGradGuard no_grad;
  torch::Tensor u = torch::empty({1, 4, kSide, kSide});
  agent::write_planner_input(p.frame, kPatch, {floor, model.revealed().data().data(), model.pose(), nullptr},
                             u.data_ptr<float>());
  return torch::log_softmax(p.agent->goal->forward(u), 1)[0][goal.y() * kSide + goal.x()].item<double>();
}

void check_chi(bool learned_goals) {
  Problem p = make_problem(/*episodes=*/1, /*steps=*/2);
  const int robots = 512;
  RolloutEngine engine(p.world, p.frame, robots);
  AgentPolicy policy(*p.agent, p.frame, kPatch, robots);
  const std::vector<int> indices = {0, 1};
  const RolloutBatch batch = make_batch(p.data, indices, robots / 2, p.world, p.frame, 77);
  Sampling sampling;
  sampling.learned_goals = learned_goals;
  sampling.learned_actions = true;
  policy.begin(batch.seeds, sampling);
  const auto records = engine.run(batch.floors, batch.starts, batch.motion_seeds, policy, /*record=*/true);
  const torch::Tensor log_pi = policy.log_pi();
  ASSERT_EQ(log_pi.size(0), robots);

  long choose = 0;
  int robots_by_decisions[3] = {0, 0, 0};  // robots with 0, 1, 2 Choose decisions
  for (int r = 0; r < robots; ++r) {
    const std::uint8_t* floor = batch.floors.data() + static_cast<std::size_t>(r) * p.frame.area_px();
    grid::GridModel model(p.frame, kPatch, batch.starts[r]);
    double expected = learned_goals ? goal_log_prob(p, model, floor, records[r].steps.front().goal) : 0.0;
    int decisions = 0;
    for (const StepRecord& s : records[r].steps) {
      // The count is independent of the record's own `sampled` flag: the protocol on the grid model.
      if (grid::decide(model.pose(), s.goal) == grid::Decision::Choose) {
        expected += action_log_prob(p, model, s.goal, floor, s.axis);
        ++decisions;
      }
      model.move(grid::move_command(model.pose(), s.goal, s.axis, p.world.task.step_px));
      ASSERT_EQ(model.pose(), s.grid_pose);
    }
    choose += decisions;
    ++robots_by_decisions[decisions];
    EXPECT_NEAR(log_pi[r].item<double>(), expected, 1e-4) << "robot " << r << ", " << decisions << " decisions";
    if (!learned_goals && decisions == 0) {
      EXPECT_EQ(log_pi[r].item<double>(), 0.0) << "robot " << r;
    }
  }
  EXPECT_EQ(policy.action_decisions(), choose);
  // The batch has robots with no, one and two decisions, so that each case was checked.
  for (int d = 0; d < 3; ++d) EXPECT_GT(robots_by_decisions[d], 10) << d << " decisions";
}

// Learned axes with i.i.d. goals is no mode of METHOD.md, but it leaves the action layer's share
// of log pi alone: exactly 0 for a robot that never had to choose.
TEST(EstimatorChi, ActionLogProbsEnterOnlyWhereTheProtocolChooses) { check_chi(/*learned_goals=*/false); }
TEST(EstimatorChi, ModeIIILogPiIsGoalPlusChosenActionLogProbs) { check_chi(/*learned_goals=*/true); }

}  // namespace
}  // namespace scout::learn

namespace scout::learn {
namespace {

// Several robots on one floor (METHOD.md § Several robots): a team is one rollout. Its robots
// drive E / K episodes each, hold the team's y, and the batch's outcome is one decision per team
// on that y, with J-hat over the team's joint log-probability (the sum of its robots').
// (Each robot's E / K episodes: Rollout.EachRobotOfATeamDrivesItsShareOfTheEpisodes.)
TEST(EstimatorTeams, ATeamIsOneRolloutWithOneDecisionAndTheSumOfItsRobotsLogPi) {
  Problem p = make_problem(/*episodes=*/2, /*steps=*/2);
  p.world.team.robots = 2;
  p.world.robot.radius_m = 0.1;  // a 1-px disc: two fit apart on the 4 x 4 floor
  const int teams = 16, robots = 2 * teams;
  RolloutEngine engine(p.world, p.frame, robots);
  AgentPolicy policy(*p.agent, p.frame, kPatch, robots);
  const std::vector<int> indices = {0, 1};
  const RolloutBatch batch = make_batch(p.data, indices, teams / 2, p.world, p.frame, 77);
  ASSERT_EQ(batch.count, robots);
  ASSERT_EQ(batch.rollouts(), teams);
  ASSERT_EQ(batch.labels.size(), static_cast<std::size_t>(teams));
  Sampling sampling;
  sampling.learned_goals = true;
  sampling.learned_actions = true;
  sampling.with_grad = false;
  sampling.precision = agent::Precision::Float32;
  const BatchOutcome out = run_batch(*p.agent, engine, policy, batch, sampling,
                                     {.rollouts_per_image = teams / 2, .leave_one_out = false, .entropy_bonus = 0});
  ASSERT_EQ(out.log_probs.size(0), teams);
  ASSERT_EQ(out.reward.size(0), teams);

  torch::NoGradGuard no_grad;
  const BatchState& state = engine.state();
  const torch::Tensor images = revealed_images(state, robots);
  const torch::Tensor log_pi = policy.log_pi();
  double expected_objective = 0;
  for (int t = 0; t < teams; ++t) {
    const int a = 2 * t, b = a + 1;
    // One y per team, what either robot saw.
    EXPECT_EQ(state.seen[a].data(), state.seen[b].data()) << t;
    EXPECT_TRUE(torch::equal(images[a], images[b])) << t;
    const torch::Tensor expected = classifier_log_probs(*p.agent, images.slice(0, a, a + 1), sampling.precision)[0];
    EXPECT_TRUE(torch::allclose(out.log_probs[t], expected, 1e-5, 1e-6)) << t;
    const double r = expected[batch.labels[t]].item<double>();
    EXPECT_NEAR(out.reward[t].item<double>(), r, 1e-5) << t;
    expected_objective += r + (log_pi[a].item<double>() + log_pi[b].item<double>()) * r;
  }
  EXPECT_NEAR(out.objective.item<double>(), expected_objective / teams, 1e-4);
  // The robots of a team start apart (their discs do not touch) and draw from seeds of their own.
  const double diameter = 2.0 * p.world.robot.radius_m / p.frame.pixel_size_m;
  for (int t = 0; t < teams; ++t) {
    EXPECT_GT((batch.starts[2 * t] - batch.starts[2 * t + 1]).cast<double>().norm(), diameter) << t;
    EXPECT_NE(batch.seeds[2 * t], batch.seeds[2 * t + 1]) << t;
    EXPECT_NE(batch.motion_seeds[2 * t], batch.motion_seeds[2 * t + 1]) << t;
  }
  // A team's first robot draws what the lone robot of the same rollout draws.
  worlds::World alone = p.world;
  alone.team.robots = 1;
  const RolloutBatch lone = make_batch(p.data, indices, teams / 2, alone, p.frame, 77);
  for (int t = 0; t < teams; ++t) {
    EXPECT_EQ(batch.seeds[2 * t], lone.seeds[t]) << t;
    EXPECT_EQ(batch.starts[2 * t], lone.starts[t]) << t;
    EXPECT_EQ(batch.labels[t], lone.labels[t]) << t;
  }
}

}  // namespace
}  // namespace scout::learn
