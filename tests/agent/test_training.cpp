// The classifiers learn: a few Adam steps on a small fixed batch of synthetic 28 x 28 "digits"
// must clearly lower the cross-entropy. Synthetic, so that the test never needs the data set.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <cmath>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "agent/networks.hpp"

namespace scout::agent {
namespace {

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

}  // namespace
}  // namespace scout::agent
