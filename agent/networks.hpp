#pragma once
/// The three networks of METHOD.md § Networks, in LibTorch. Include only from agent/ and learn/
/// sources: this header pulls in torch.
#include <torch/torch.h>

#include <memory>

#include "agent/config.hpp"

namespace scout::agent {

/// r DenseNet-style blocks (conv 3x3 -> ReLU, output concatenated to the input), d channels each.
/// No normalisation: one robot's output never depends on the others in its batch.
class DenseStackImpl : public torch::nn::Module {
 public:
  DenseStackImpl(int in_channels, int growth, int depth);
  torch::Tensor forward(torch::Tensor x);
  int out_channels() const { return out_channels_; }

 private:
  torch::nn::ModuleList convs_;
  int out_channels_;
};
TORCH_MODULE(DenseStack);

/// f1 and f2, one network with two heads: a dense stack, then a 1 x 1 convolution.
/// - f1, the goal planner: u_g [B, planner_channels, H, W] -> goal logits [B, H*W], one per floor pixel
///   (softmax over them, row-major); with config.goal_context > 0 the context branch's scores
///   (NetworkConfig::goal_context), upsampled bilinearly to H x W, are added to the logits;
/// - f2, the action planner: u_a [B, planner_channels, H, W] -> axis logits [B, 2] (0 horizontal, 1 vertical),
///   the head's two maps averaged over the floor.
class PlannerImpl : public torch::nn::Module {
 public:
  enum class Head { GoalPixels, ActionAxes };
  PlannerImpl(const NetworkConfig& config, Head head);
  torch::Tensor forward(torch::Tensor u);

 private:
  Head kind_;
  DenseStack body_{nullptr};
  torch::nn::Sequential context_{nullptr};   ///< the goal planner's context branch, where configured
  torch::nn::Conv2d context_head_{nullptr};  ///< its scores per coarse cell, added to the goal logits
  torch::nn::Conv2d head_{nullptr};
};
TORCH_MODULE(Planner);

/// f3: u_c [B, c, H, W] -> class logits [B, D]. One interface, three variants (ClassifierKind).
class ClassifierImpl : public torch::nn::Module {
 public:
  virtual torch::Tensor forward(torch::Tensor y) = 0;
};

/// The classifier named by config.classifier, freshly initialised.
std::shared_ptr<ClassifierImpl> make_classifier(const NetworkConfig& config);

/// The whole agent: its three layers registered as "goal", "action" and "classifier", so that a
/// state dict names each parameter by its layer.
class AgentImpl : public torch::nn::Module {
 public:
  explicit AgentImpl(const NetworkConfig& config);
  const NetworkConfig& config() const { return config_; }

  Planner goal{nullptr};    ///< f1, Head::GoalPixels
  Planner action{nullptr};  ///< f2, Head::ActionAxes; null (no module, no parameters) with config.goals_only
  std::shared_ptr<ClassifierImpl> classifier;

 private:
  NetworkConfig config_;
};
TORCH_MODULE(Agent);

/// Copies `from`'s weights into `to`, whose config is `from`'s grown by what a fine-tuning run may
/// add (`scout train --init-from`), so that `to` computes exactly what `from` does and training can
/// learn to use the new inputs:
/// - the occupancy channel or the teammates' channels: every planner convolution of `to` reads
///   one (o) or two (t_p, t_g) more input channels, whose weights are set to zero;
/// - a goal context branch (from none): the branch keeps its fresh initialisation and its score
///   head is set to zero;
/// - the action planner removed (goals_only): its weights are left behind, and the grown agent
///   computes what the source does with i.i.d. actions (its goals-only figure).
/// Throws std::invalid_argument when the configs differ otherwise.
void copy_into_grown(const AgentImpl& from, AgentImpl& to);

}  // namespace scout::agent
