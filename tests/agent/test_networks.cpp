// The three networks of METHOD.md § Networks: output shapes on any floor size, softmax-ready
// logits, batch independence of the planners, parameter names, determinism under a seed; and
// the classifiers learn synthetic digits.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <cmath>
#include <cstdlib>
#include <iterator>
#include <memory>
#include <numbers>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "agent/networks.hpp"

namespace scout::agent {
namespace {

const ClassifierKind kKinds[] = {ClassifierKind::Paper, ClassifierKind::PaperStrided, ClassifierKind::PaperStridedNorm,
                                 ClassifierKind::Strided, ClassifierKind::ResNet18};

// Floor sizes: MNIST's, smaller than a 6 x 6 patch, and non-square.
const std::pair<int, int> kSizes[] = {{28, 28}, {4, 4}, {12, 9}};  // (H, W)

NetworkConfig config_for(ClassifierKind kind) {
  NetworkConfig config;
  config.classifier = kind;
  // Small widths keep the test fast; the structure is what is tested.
  config.planner_width = 8;
  config.classifier_width = kind == ClassifierKind::ResNet18 ? 4 : 8;
  return config;
}

// The parameter of `module` named `name` (fails the test if there is none).
torch::Tensor parameter(const torch::nn::Module& module, const std::string& name) {
  const auto params = module.named_parameters();
  const torch::Tensor* found = params.find(name);
  if (found == nullptr) throw std::runtime_error("no parameter " + name);
  return *found;
}

// The registry (agent/config.hpp): every row's name round-trips, and its factory builds a
// classifier whose output is [B, D] for any channel count c.
TEST(Networks, EveryRegisteredClassifierRoundTripsAndBuildsBxDOutputs) {
  torch::manual_seed(1);
  ASSERT_GT(std::size(kClassifierVariants), 0u);
  for (const ClassifierVariant& variant : kClassifierVariants) {
    SCOPED_TRACE(variant.name);
    EXPECT_EQ(parse_classifier_kind(variant.name), variant.kind);
    EXPECT_STREQ(to_string(variant.kind), variant.name);
    EXPECT_NE(std::string(variant.help), "");
    for (const int channels : {1, 3}) {
      NetworkConfig config = config_for(variant.kind);
      config.image_channels = channels;
      config.classes = 7;
      const std::shared_ptr<ClassifierImpl> classifier = make_classifier(config);
      ASSERT_NE(classifier, nullptr);
      classifier->eval();
      torch::NoGradGuard no_grad;
      const torch::Tensor logits = classifier->forward(torch::rand({3, channels, 28, 28}) - 0.5);
      EXPECT_EQ(logits.sizes(), (std::vector<std::int64_t>{3, 7}));
      EXPECT_TRUE(torch::isfinite(logits).all().item<bool>());
    }
  }
}

TEST(Networks, OutputShapesAndSoftmaxesOnAnyFloorSize) {
  torch::manual_seed(1);
  for (const ClassifierKind kind : kKinds) {
    const NetworkConfig config = config_for(kind);
    Agent agent(config);
    agent->eval();  // the ResNet's BatchNorm then accepts a batch of one
    for (const auto& [h, w] : kSizes) {
      for (const int batch : {1, 3}) {
        SCOPED_TRACE(std::string(to_string(kind)) + " H=" + std::to_string(h) + " W=" + std::to_string(w) +
                     " B=" + std::to_string(batch));
        torch::NoGradGuard no_grad;
        const torch::Tensor u = torch::rand({batch, planner_channels(config), h, w}) - 0.5;
        const torch::Tensor y = torch::rand({batch, config.image_channels, h, w}) - 0.5;

        const torch::Tensor goal = agent->goal->forward(u);
        ASSERT_EQ(goal.sizes(), (std::vector<std::int64_t>{batch, h * w}));
        EXPECT_TRUE(torch::allclose(goal.softmax(1).sum(1), torch::ones({batch}), 1e-5, 1e-5));

        const torch::Tensor action = agent->action->forward(u);
        ASSERT_EQ(action.sizes(), (std::vector<std::int64_t>{batch, 2}));
        EXPECT_TRUE(torch::allclose(action.softmax(1).sum(1), torch::ones({batch}), 1e-5, 1e-5));

        const torch::Tensor classes = agent->classifier->forward(y);
        ASSERT_EQ(classes.sizes(), (std::vector<std::int64_t>{batch, config.classes}));
        EXPECT_TRUE(torch::allclose(classes.softmax(1).sum(1), torch::ones({batch}), 1e-5, 1e-5));
        EXPECT_TRUE(torch::isfinite(goal).all().item<bool>());
        EXPECT_TRUE(torch::isfinite(classes).all().item<bool>());
      }
    }
  }
}

TEST(Networks, StridedClassifierReachesDepthFourOn28x28) {
  NetworkConfig config = config_for(ClassifierKind::Strided);
  config.classifier_depth = 4;  // 28 -> 14 -> 7 -> 4 -> 2
  config.classes = 7;
  const auto classifier = make_classifier(config);
  EXPECT_EQ(classifier->forward(torch::zeros({2, 1, 28, 28})).sizes(), (std::vector<std::int64_t>{2, 7}));
  // Block k: conv stride 2 to w * 2^k, GroupNorm, ReLU, conv stride 1, GroupNorm, ReLU.
  for (int k = 0; k < 4; ++k) {
    const std::string block = "blocks." + std::to_string(k);
    const int width = config.classifier_width << k;
    const int in = k == 0 ? 1 : width / 2;
    EXPECT_EQ(parameter(*classifier, block + ".0.weight").sizes(), (std::vector<std::int64_t>{width, in, 3, 3}));
    EXPECT_EQ(parameter(*classifier, block + ".3.weight").sizes(), (std::vector<std::int64_t>{width, width, 3, 3}));
    EXPECT_EQ(parameter(*classifier, block + ".4.weight").sizes(), (std::vector<std::int64_t>{width}));  // GroupNorm
  }
  const auto strided_conv = classifier->named_modules()["blocks.0.0"]->as<torch::nn::Conv2d>();
  ASSERT_NE(strided_conv, nullptr);
  EXPECT_EQ((*strided_conv->options.stride())[0], 2);
  EXPECT_EQ(parameter(*classifier, "head.weight").sizes(), (std::vector<std::int64_t>{7, 64, 1, 1}));
}

TEST(Networks, StridedClassifierAcceptsWidthsThatAreNotMultiplesOfItsNormGroups) {
  for (const int width : {1, 3, 12}) {
    NetworkConfig config = config_for(ClassifierKind::Strided);
    config.classifier_width = width;
    const auto classifier = make_classifier(config);
    EXPECT_EQ(classifier->forward(torch::zeros({2, 1, 12, 9})).sizes(), (std::vector<std::int64_t>{2, 10}))
        << "width " << width;
  }
}

TEST(Networks, DenseBlocksGrowAsThePaperSays) {
  const NetworkConfig config;  // planners 16 x 3, paper classifier 16 x 3, c = 1, D = 10
  Agent agent(config);
  // Planner block k reads c + 3 + 16 k channels; the head reads all 4 + 48.
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(parameter(*agent, "goal.body.blocks." + std::to_string(k) + ".weight").sizes(),
              (std::vector<std::int64_t>{16, 4 + 16 * k, 3, 3}));
  }
  EXPECT_EQ(parameter(*agent, "goal.head.weight").sizes(), (std::vector<std::int64_t>{1, 52, 1, 1}));
  EXPECT_EQ(parameter(*agent, "action.head.weight").sizes(), (std::vector<std::int64_t>{2, 52, 1, 1}));
  // Classifier block k adds 16 * 2^k channels: 1 + 16 + 32 + 64 reach the head.
  EXPECT_EQ(parameter(*agent, "classifier.blocks.2.weight").sizes(), (std::vector<std::int64_t>{64, 49, 3, 3}));
  EXPECT_EQ(parameter(*agent, "classifier.head.weight").sizes(), (std::vector<std::int64_t>{10, 113, 1, 1}));
}

// The two readings of the paper's classifier differ in where they sample: at full resolution every
// block keeps the grid, so moving a digit by one pixel inside the floor leaves the logits as they
// were (global average pooling of a shifted map); the stride-2 reading samples every 2^(r-1)
// pixels after r blocks, so one pixel changes them and 2^(r-1) = 4 pixels (one cell of its last
// grid) does not. Padding stays out of it: the blob and everything it reaches are inside.
TEST(Networks, TheStridedReadingSamplesEvery2ToTheRMinus1Pixels) {
  torch::manual_seed(7);
  const torch::Tensor blob = torch::rand({1, 1, 5, 5});
  const auto floor_with_blob_at = [&](int x, int y) {
    torch::Tensor floor = torch::zeros({1, 1, 28, 28});
    floor.narrow(2, y, 5).narrow(3, x, 5).copy_(blob);
    return floor;
  };
  const auto max_change = [](const torch::Tensor& a, const torch::Tensor& b) {
    return (a - b).abs().max().item<float>();
  };
  for (const ClassifierKind kind :
       {ClassifierKind::Paper, ClassifierKind::PaperStrided, ClassifierKind::PaperStridedNorm}) {
    SCOPED_TRACE(to_string(kind));
    NetworkConfig config = config_for(kind);
    config.classifier_depth = 3;
    const std::shared_ptr<ClassifierImpl> classifier = make_classifier(config);
    torch::NoGradGuard no_grad;
    const torch::Tensor at_8 = classifier->forward(floor_with_blob_at(8, 8));
    const float by_one = max_change(at_8, classifier->forward(floor_with_blob_at(9, 8)));
    const float by_four = max_change(at_8, classifier->forward(floor_with_blob_at(12, 12)));
    EXPECT_LT(by_four, 1e-5);
    if (kind == ClassifierKind::Paper) {
      EXPECT_LT(by_one, 1e-5);
    } else {
      EXPECT_GT(by_one, 1e-4);
    }
  }
}

TEST(Networks, ResNet18AtWidth64HasResNet18sParameterCount) {
  // torchvision's resnet18 (3 channels, 1,000 classes) has 11,689,512 parameters; ours swaps the
  // 7 x 7 stem (3 * 64 * 49 weights) for a 3 x 3 one (3 * 64 * 9): 7,680 fewer.
  NetworkConfig config;
  config.image_channels = 3;
  config.classes = 1000;
  config.classifier = ClassifierKind::ResNet18;
  config.classifier_width = 64;
  const auto classifier = make_classifier(config);
  std::int64_t count = 0;
  for (const auto& p : classifier->parameters()) count += p.numel();
  EXPECT_EQ(count, 11'689'512 - 7'680);
  EXPECT_EQ(parameter(*classifier, "layer4.1.conv2.weight").sizes(), (std::vector<std::int64_t>{512, 512, 3, 3}));
  EXPECT_EQ(parameter(*classifier, "layer2.0.downsample.0.weight").sizes(), (std::vector<std::int64_t>{128, 64, 1, 1}));
  EXPECT_EQ(classifier->named_parameters().find("layer1.0.downsample.0.weight"), nullptr);  // same shape: identity
  EXPECT_EQ(parameter(*classifier, "fc.weight").sizes(), (std::vector<std::int64_t>{1000, 512}));
}

TEST(Networks, ParameterCountWithoutBuildingEqualsTheBuiltAgents) {
  struct Shape {
    int channels, classes, planner_width, planner_depth, classifier_width, classifier_depth;
  };
  const Shape shapes[] = {{1, 10, 16, 3, 16, 3}, {3, 7, 5, 1, 6, 1}, {2, 10, 8, 5, 9, 4}, {1, 2, 1, 2, 3, 2}};
  for (ClassifierKind kind : kKinds) {
    for (const Shape& s : shapes) {
      NetworkConfig config;
      config.goal_context = s.planner_width % 2 == 0 ? 2 * s.planner_width : 0;
      config.image_channels = s.channels;
      config.classes = s.classes;
      config.planner_width = s.planner_width;
      config.planner_depth = s.planner_depth;
      config.classifier = kind;
      config.classifier_width = s.classifier_width;
      config.classifier_depth = s.classifier_depth;
      const Agent agent(config);
      std::int64_t built = 0;
      for (const auto& p : agent->parameters()) built += p.numel();
      EXPECT_EQ(parameter_count(config), built)
          << to_string(kind) << " width " << s.classifier_width << " goal context " << config.goal_context;
    }
  }
}

TEST(Networks, GoalLogitsAreRowMajorAndSeeA7x7Neighbourhood) {
  // Three 3 x 3 blocks see 7 x 7: changing the input at pixel (x, y) = (8, 2) of a 12-wide, 9-high
  // floor may change only the logits within 3 pixels of it, found at index y * W + x.
  torch::manual_seed(3);
  const NetworkConfig config;
  Planner goal(config, PlannerImpl::Head::GoalPixels);
  const int h = 9, w = 12, px = 8, py = 2;
  torch::NoGradGuard no_grad;
  const torch::Tensor u = torch::rand({1, 4, h, w}) - 0.5;
  torch::Tensor v = u.clone();
  v[0][0][py][px] += 1.0;
  const torch::Tensor diff = (goal->forward(v) - goal->forward(u)).abs()[0];
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float d = diff[y * w + x].item<float>();
      if (std::abs(x - px) > 3 || std::abs(y - py) > 3) {
        EXPECT_EQ(d, 0.0f) << "x = " << x << ", y = " << y;
      }
    }
  }
  EXPECT_GT(diff[py * w + px].item<float>(), 0.0f);
}

TEST(Networks, PlannersAndPerSampleClassifiersAreBatchIndependent) {
  torch::manual_seed(5);
  for (const ClassifierKind kind : {ClassifierKind::Paper, ClassifierKind::PaperStrided,
                                    ClassifierKind::PaperStridedNorm, ClassifierKind::Strided}) {
    SCOPED_TRACE(to_string(kind));
    const NetworkConfig config = config_for(kind);
    Agent agent(config);
    agent->train();  // train mode too: nothing may look at the other robots
    torch::NoGradGuard no_grad;
    const torch::Tensor u = torch::rand({6, 4, 28, 28}) - 0.5;
    const torch::Tensor goal = agent->goal->forward(u);
    const torch::Tensor action = agent->action->forward(u);
    const torch::Tensor classes = agent->classifier->forward(u.narrow(1, 0, 1));
    for (const int robot : {0, 4}) {
      const torch::Tensor alone = u.narrow(0, robot, 1);
      EXPECT_TRUE(torch::allclose(agent->goal->forward(alone)[0], goal[robot], 1e-6, 1e-6));
      EXPECT_TRUE(torch::allclose(agent->action->forward(alone)[0], action[robot], 1e-6, 1e-6));
      EXPECT_TRUE(torch::allclose(agent->classifier->forward(alone.narrow(1, 0, 1))[0], classes[robot], 1e-6, 1e-6));
    }
    // And the batch's order does not matter.
    const torch::Tensor reversed = u.flip({0});
    EXPECT_TRUE(torch::allclose(agent->goal->forward(reversed).flip({0}), goal, 1e-6, 1e-6));
  }
}

TEST(Networks, ParametersAreNamedByLayer) {
  for (const ClassifierKind kind : kKinds) {
    SCOPED_TRACE(to_string(kind));
    Agent agent(config_for(kind));
    std::set<std::string> layers;
    for (const auto& item : agent->named_parameters()) {
      const std::string& name = item.key();
      const std::string layer = name.substr(0, name.find('.'));
      EXPECT_TRUE(layer == "goal" || layer == "action" || layer == "classifier") << name;
      layers.insert(layer);
    }
    EXPECT_EQ(layers, (std::set<std::string>{"goal", "action", "classifier"}));
    EXPECT_NE(agent->named_parameters().find("goal.head.weight"), nullptr);
    EXPECT_NE(agent->named_parameters().find("action.body.blocks.0.bias"), nullptr);
  }
  Agent resnet(config_for(ClassifierKind::ResNet18));
  EXPECT_NE(resnet->named_parameters().find("classifier.layer3.1.bn2.weight"), nullptr);
  EXPECT_NE(resnet->named_buffers().find("classifier.bn1.running_mean"), nullptr);
}

TEST(Networks, TheSameSeedGivesTheSameParameters) {
  for (const ClassifierKind kind : kKinds) {
    SCOPED_TRACE(to_string(kind));
    const NetworkConfig config = config_for(kind);
    torch::manual_seed(11);
    Agent a(config);
    torch::manual_seed(11);
    Agent b(config);
    torch::manual_seed(12);
    Agent c(config);
    const auto pa = a->named_parameters();
    const auto pb = b->named_parameters();
    const auto pc = c->named_parameters();
    ASSERT_EQ(pa.size(), pb.size());
    bool any_differs = false;
    for (const auto& item : pa) {
      EXPECT_TRUE(torch::equal(item.value(), pb[item.key()])) << item.key();
      // BatchNorm starts at weight 1, bias 0 whatever the seed; the convolutions must not.
      if (!torch::equal(item.value(), pc[item.key()])) any_differs = true;
    }
    EXPECT_TRUE(any_differs);
  }
}

TEST(Networks, InvalidConfigOrInputIsRefused) {
  NetworkConfig config;
  config.planner_depth = 0;
  try {
    Agent agent(config);
    FAIL() << "planner_depth 0 was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("planner_depth"), std::string::npos) << e.what();
  }
  Agent agent{NetworkConfig{}};
  EXPECT_THROW(agent->goal->forward(torch::zeros({1, 3, 8, 8})), c10::Error);        // c + 3 = 4 channels
  EXPECT_THROW(agent->classifier->forward(torch::zeros({1, 4, 8, 8})), c10::Error);  // c = 1 channel
}

// --- The classifiers learn (moved from tests/agent/test_training.cpp) -----------------------------------------------
// A few Adam steps on a small fixed batch of synthetic 28 x 28 "digits" must clearly lower the
// cross-entropy. Synthetic, so that the test never needs the data set.

constexpr int kClasses = 10;
constexpr int kPerClass = 2;

// Ten classes of gratings (5 orientations x 2 periods) with a random phase per image plus noise,
// scaled like the floor (about -0.5 .. 0.5): classifiable only from local texture, as digits are
// from strokes.
std::pair<torch::Tensor, torch::Tensor> synthetic_digits() {
  const torch::Tensor ys = torch::arange(28, torch::kFloat).view({28, 1});
  const torch::Tensor xs = torch::arange(28, torch::kFloat).view({1, 28});
  std::vector<torch::Tensor> images;
  std::vector<std::int64_t> labels;
  for (int k = 0; k < kClasses; ++k) {
    const double angle = (k % 5) * std::numbers::pi / 5;
    const double period = k < 5 ? 4.0 : 9.0;
    for (int i = 0; i < kPerClass; ++i) {
      const double phase = 2 * std::numbers::pi * torch::rand({1}).item<double>();
      const torch::Tensor along = xs * std::cos(angle) + ys * std::sin(angle);
      images.push_back(0.4 * torch::sin(along * (2 * std::numbers::pi / period) + phase) +
                       0.1 * torch::randn({28, 28}));
      labels.push_back(k);
    }
  }
  return {torch::stack(images).unsqueeze(1), torch::tensor(labels)};
}

// Cross-entropy on the batch before and after `steps` Adam steps.
std::pair<double, double> train(ClassifierImpl& classifier, int steps, double lr) {
  const auto [images, labels] = synthetic_digits();
  classifier.train();
  torch::optim::Adam adam(classifier.parameters(), torch::optim::AdamOptions(lr));
  double first = 0;
  for (int step = 0; step < steps; ++step) {
    adam.zero_grad();
    const torch::Tensor loss = torch::nn::functional::cross_entropy(classifier.forward(images), labels);
    if (step == 0) first = loss.item<double>();
    loss.backward();
    adam.step();
  }
  torch::NoGradGuard no_grad;
  const double last = torch::nn::functional::cross_entropy(classifier.forward(images), labels).item<double>();
  return {first, last};
}

TEST(Training, ResNet18LearnsSyntheticDigits) {
  torch::set_num_threads(2);
  torch::manual_seed(2024);
  NetworkConfig config;
  config.classifier = ClassifierKind::ResNet18;
  config.classifier_width = 8;
  const auto classifier = make_classifier(config);
  const auto [first, last] = train(*classifier, 30, 3e-3);
  RecordProperty("first_loss", std::to_string(first));
  RecordProperty("last_loss", std::to_string(last));
  EXPECT_LT(last, 0.5 * first) << "cross-entropy " << first << " -> " << last;
}

TEST(Training, StridedClassifierLearnsSyntheticDigits) {
  torch::set_num_threads(2);
  torch::manual_seed(2025);
  NetworkConfig config;
  config.classifier = ClassifierKind::Strided;
  const auto classifier = make_classifier(config);
  const auto [first, last] = train(*classifier, 30, 3e-3);
  RecordProperty("first_loss", std::to_string(first));
  RecordProperty("last_loss", std::to_string(last));
  EXPECT_LT(last, 0.5 * first) << "cross-entropy " << first << " -> " << last;
}

// Fine-tuning a model trained without obstacles in a world with them: the widened planners read o
// with zero weights, so they compute exactly what the model did, whatever o holds; and training
// can move those weights (they are ordinary parameters).
TEST(Networks, AddingTheOccupancyChannelKeepsWhatThePlannersCompute) {
  torch::manual_seed(3);
  NetworkConfig config;
  config.planner_width = 5;
  config.planner_depth = 3;
  Agent from(config);
  NetworkConfig widened = config;
  widened.occupancy = true;
  Agent to(widened);
  EXPECT_EQ(planner_channels(widened), planner_channels(config) + 1);
  copy_into_grown(*from, *to);
  torch::NoGradGuard no_grad;
  const torch::Tensor u = torch::rand({4, planner_channels(config), 9, 7}) - 0.5;
  for (const double o : {0.0, 1.0}) {
    const torch::Tensor u_o = torch::cat({u, torch::full({4, 1, 9, 7}, o) * (torch::rand({4, 1, 9, 7}) > 0.5)}, 1);
    EXPECT_TRUE(torch::allclose(to->goal->forward(u_o), from->goal->forward(u), 1e-6, 1e-6)) << "o = " << o;
    EXPECT_TRUE(torch::allclose(to->action->forward(u_o), from->action->forward(u), 1e-6, 1e-6)) << "o = " << o;
  }
  const torch::Tensor y = torch::rand({2, 1, 9, 7}) - 0.5;
  EXPECT_TRUE(torch::equal(to->classifier->forward(y), from->classifier->forward(y)));
  // One more input channel in each planner's r 3 x 3 convolutions (d outputs) and in its 1 x 1
  // head (1 output for goals, 2 for axes).
  EXPECT_EQ(parameter_count(widened),
            parameter_count(config) + 2 * config.planner_depth * config.planner_width * 9 + 3);
  EXPECT_EQ(parameter_count(widened),
            static_cast<std::int64_t>(torch::nn::utils::parameters_to_vector(to->parameters()).numel()));
  // The channel's weights are zero, not absent: a change of them changes the output.
  const torch::Tensor u_1 = torch::cat({u, torch::ones({4, 1, 9, 7})}, 1);
  to->goal->named_parameters()["body.blocks.0.weight"].narrow(1, planner_channels(config), 1).fill_(0.5);
  EXPECT_FALSE(torch::allclose(to->goal->forward(u_1), from->goal->forward(u), 1e-3, 1e-3));
  // Anything else than one added channel is refused.
  EXPECT_THROW(copy_into_grown(*from, *from), std::invalid_argument);
  NetworkConfig wider = widened;
  wider.planner_width = 6;
  Agent other(wider);
  EXPECT_THROW(copy_into_grown(*from, *other), std::invalid_argument);
}

// The goal context branch sees the whole 28 x 28 floor: a change at one corner moves the goal logits
// at the opposite corner, which the dense stack alone (7 x 7) cannot see.
TEST(Networks, GoalContextBranchSeesTheWholeFloor) {
  torch::manual_seed(5);
  NetworkConfig config;
  config.goal_context = 32;
  Planner goal(config, PlannerImpl::Head::GoalPixels);
  torch::NoGradGuard no_grad;
  const int n = 28;
  const torch::Tensor u = torch::rand({1, planner_channels(config), n, n}) - 0.5;
  torch::Tensor v = u.clone();
  v.narrow(2, 0, 4).narrow(3, 0, 4) += 1.0;  // ink in the top left 4 x 4 corner, in every channel
  const torch::Tensor a = goal->forward(u), b = goal->forward(v);
  ASSERT_EQ(a.sizes(), (std::vector<std::int64_t>{1, n * n}));
  EXPECT_GT((b - a).abs()[0][n * n - 1].item<float>(), 0.0f);
  NetworkConfig plain;
  Planner local(plain, PlannerImpl::Head::GoalPixels);
  EXPECT_EQ((local->forward(v) - local->forward(u)).abs()[0][n * n - 1].item<float>(), 0.0f);
  // Any floor size, odd ones included.
  const torch::Tensor odd = torch::rand({2, planner_channels(config), 9, 13}) - 0.5;
  EXPECT_EQ(goal->forward(odd).sizes(), (std::vector<std::int64_t>{2, 9 * 13}));
}

// Fine-tuning a trained model with a goal context branch added (and the occupancy channel with it):
// the branch's score head starts at zero, so the grown agent computes what the model did.
TEST(Networks, AddingAGoalContextBranchKeepsWhatThePlannersCompute) {
  torch::manual_seed(4);
  NetworkConfig config;
  config.planner_width = 5;
  Agent from(config);
  NetworkConfig grown = config;
  grown.goal_context = 6;
  grown.occupancy = true;
  Agent to(grown);
  copy_into_grown(*from, *to);
  torch::NoGradGuard no_grad;
  const torch::Tensor u = torch::rand({3, planner_channels(config), 11, 10}) - 0.5;
  const torch::Tensor u_o = torch::cat({u, (torch::rand({3, 1, 11, 10}) > 0.5).to(torch::kFloat)}, 1);
  EXPECT_TRUE(torch::allclose(to->goal->forward(u_o), from->goal->forward(u), 1e-6, 1e-6));
  EXPECT_TRUE(torch::allclose(to->action->forward(u_o), from->action->forward(u), 1e-6, 1e-6));
  EXPECT_EQ(parameter_count(grown),
            static_cast<std::int64_t>(torch::nn::utils::parameters_to_vector(to->parameters()).numel()));
  // The branch is live: weights on its channels change the goals.
  EXPECT_EQ(to->goal->named_parameters()["context_head.weight"].abs().sum().item<float>(), 0.0f);
  to->goal->named_parameters()["context_head.weight"].fill_(0.5);
  EXPECT_FALSE(torch::allclose(to->goal->forward(u_o), from->goal->forward(u), 1e-3, 1e-3));
  // A branch of another width, or one taken away, is refused.
  NetworkConfig other = grown;
  other.goal_context = 3;
  Agent with_three(other);
  EXPECT_THROW(copy_into_grown(*to, *with_three), std::invalid_argument);
  EXPECT_THROW(copy_into_grown(*to, *from), std::invalid_argument);
}

// `config` grown by `grow` into two more planner channels, which come last and are read with
// zero weights: the grown planners compute what the model's did whatever the channels hold
// (`extra`: their values), and a grown model does not copy back into the smaller one.
void expect_two_grown_channels_change_nothing(const NetworkConfig& config, void (*grow)(NetworkConfig&),
                                              const torch::Tensor& extra) {
  Agent from(config);
  NetworkConfig grown = config;
  grow(grown);
  Agent to(grown);
  copy_into_grown(*from, *to);
  EXPECT_EQ(planner_channels(grown), planner_channels(config) + 2);
  torch::NoGradGuard no_grad;
  const torch::Tensor u = torch::rand({3, planner_channels(config), 9, 8}) - 0.5;
  const torch::Tensor u_grown = torch::cat({u, extra}, 1);
  EXPECT_TRUE(torch::allclose(to->goal->forward(u_grown), from->goal->forward(u), 1e-6, 1e-6));
  EXPECT_TRUE(torch::allclose(to->action->forward(u_grown), from->action->forward(u), 1e-6, 1e-6));
  EXPECT_THROW(copy_into_grown(*to, *from), std::invalid_argument);
}

// The teammates' channels added to a model that reads o already: t_p and t_g come after o.
TEST(Networks, AddingTheTeammatesChannelsKeepsWhatThePlannersCompute) {
  torch::manual_seed(6);
  NetworkConfig config;
  config.planner_width = 4;
  config.occupancy = true;
  config.goal_context = 4;
  const torch::Tensor team = (torch::rand({3, 2, 9, 8}) > 0.5).to(torch::kFloat);
  expect_two_grown_channels_change_nothing(
      config, [](NetworkConfig& c) { c.team_channels = true; }, team);
}

// The wider view's channels added to a model with every other extra: y_w and h_w come last.
TEST(Networks, AddingTheWiderViewsChannelsKeepsWhatThePlannersCompute) {
  torch::manual_seed(7);
  NetworkConfig config;
  config.planner_width = 4;
  config.occupancy = true;
  config.team_channels = true;
  config.goal_context = 4;
  expect_two_grown_channels_change_nothing(
      config, [](NetworkConfig& c) { c.wide_view = true; }, torch::rand({3, 2, 9, 8}));
}

}  // namespace
}  // namespace scout::agent
