#include "agent/networks.hpp"

#include <iterator>
#include <numeric>
#include <stdexcept>
#include <string>

namespace scout::agent {
namespace {

namespace nn = torch::nn;

nn::Conv2d conv3x3(int in, int out, int stride = 1, bool bias = true) {
  return nn::Conv2d(nn::Conv2dOptions(in, out, 3).stride(stride).padding(1).bias(bias));
}

nn::Conv2d conv1x1(int in, int out, int stride = 1, bool bias = true) {
  return nn::Conv2d(nn::Conv2dOptions(in, out, 1).stride(stride).bias(bias));
}

// Shape errors are caught here, with the layer's name, rather than deep inside a convolution.
void check_input(const torch::Tensor& x, std::int64_t channels, const char* layer) {
  TORCH_CHECK(x.dim() == 4 && x.size(1) == channels, layer, ": expected a [B, ", channels, ", H, W] tensor, got ",
              x.sizes());
}

// Normalisations that also take bf16 activations (LibTorch's CPU kernels want the input's type to
// match the fp32 affine parameters): statistics and affine run in fp32, the result returns in the
// input's type. The parameters keep the names of nn::GroupNorm / nn::BatchNorm2d.
class GroupNormAnyTypeImpl : public nn::GroupNormImpl {
 public:
  using nn::GroupNormImpl::GroupNormImpl;
  torch::Tensor forward(const torch::Tensor& x) {
    if (x.scalar_type() == torch::kFloat) return nn::GroupNormImpl::forward(x);
    return nn::GroupNormImpl::forward(x.to(torch::kFloat)).to(x.scalar_type());
  }
};
TORCH_MODULE(GroupNormAnyType);

// BatchNorm2d's defaults (affine, running statistics, momentum 0.1, eps 1e-5), written out
// because deriving from nn::BatchNorm2dImpl needs symbols Debian's LibTorch does not export.
class BatchNormAnyTypeImpl : public nn::Module {
 public:
  explicit BatchNormAnyTypeImpl(int channels)
      : weight_(register_parameter("weight", torch::ones({channels}))),
        bias_(register_parameter("bias", torch::zeros({channels}))),
        running_mean_(register_buffer("running_mean", torch::zeros({channels}))),
        running_var_(register_buffer("running_var", torch::ones({channels}))),
        batches_tracked_(register_buffer("num_batches_tracked", torch::tensor(0, torch::kLong))) {}

  torch::Tensor forward(const torch::Tensor& x) {
    if (is_training()) {
      torch::NoGradGuard no_grad;
      batches_tracked_ += 1;
    }
    const torch::Tensor y = torch::batch_norm(x.to(torch::kFloat), weight_, bias_, running_mean_, running_var_,
                                              is_training(), kMomentum, kEpsilon, /*cudnn_enabled=*/false);
    return y.to(x.scalar_type());
  }

 private:
  static constexpr double kMomentum = 0.1, kEpsilon = 1e-5;
  torch::Tensor weight_, bias_, running_mean_, running_var_, batches_tracked_;
};
TORCH_MODULE(BatchNormAnyType);

// GroupNorm with up to kNormGroups groups; the group count must divide the width, which may be any
// classifier_width * 2^k.
constexpr int kNormGroups = 8;
GroupNormAnyType group_norm(int channels) { return GroupNormAnyType(std::gcd(kNormGroups, channels), channels); }

// Global average pooling: [B, C, H, W] -> [B, C]. Any H, W.
torch::Tensor global_average(const torch::Tensor& x) { return x.mean({2, 3}); }

/// METHOD.md's classifier: dense blocks at full resolution whose width doubles each block.
class PaperClassifierImpl : public ClassifierImpl {
 public:
  explicit PaperClassifierImpl(const NetworkConfig& config) : in_channels_(config.image_channels) {
    blocks_ = register_module("blocks", nn::ModuleList());
    int channels = config.image_channels;
    for (int k = 0; k < config.classifier_depth; ++k) {
      const int width = config.classifier_width << k;
      blocks_->push_back(conv3x3(channels, width));
      channels += width;
    }
    head_ = register_module("head", conv1x1(channels, config.classes));
  }

  torch::Tensor forward(torch::Tensor y) override {
    check_input(y, in_channels_, "paper classifier");
    torch::Tensor x = y;
    for (const auto& block : *blocks_) x = torch::cat({x, block->as<nn::Conv2d>()->forward(x).relu_()}, 1);
    return global_average(head_->forward(x));
  }

 private:
  int in_channels_;
  nn::ModuleList blocks_{nullptr};
  nn::Conv2d head_{nullptr};
};

/// METHOD.md's classifier read as ResNets downsample: block 0 at full resolution, then a stride-2
/// step at each doubling. A block's 3 x 3 convolution runs with stride 2 and its concatenated skip
/// (everything before it) is average-pooled 2 x 2 to the same ceil(n / 2) grid, as DenseNet's
/// transitions pool: 28 -> 14 -> 7 -> 4 -> 2. Receptive field of r blocks: 3, 5, 9, 17, 33 px (2^r + 1),
/// where the full-resolution reading sees 2r + 1 px. With `normalise`, GroupNorm (per sample)
/// follows each convolution; the paper names no normalisation, so both are variants.
class PaperStridedClassifierImpl : public ClassifierImpl {
 public:
  PaperStridedClassifierImpl(const NetworkConfig& config, bool normalise) : in_channels_(config.image_channels) {
    blocks_ = register_module("blocks", nn::ModuleList());
    int channels = config.image_channels;
    for (int k = 0; k < config.classifier_depth; ++k) {
      const int width = config.classifier_width << k;
      nn::Sequential block(conv3x3(channels, width, k == 0 ? 1 : 2, /*bias=*/!normalise));
      if (normalise) block->push_back(group_norm(width));
      block->push_back(nn::ReLU(nn::ReLUOptions(/*inplace=*/true)));
      blocks_->push_back(block);
      channels += width;
    }
    head_ = register_module("head", conv1x1(channels, config.classes));
  }

  torch::Tensor forward(torch::Tensor y) override {
    check_input(y, in_channels_, "paper-strided classifier");
    torch::Tensor x = y;
    for (std::size_t k = 0; k < blocks_->size(); ++k) {
      torch::Tensor added = blocks_[k]->as<nn::Sequential>()->forward(x);
      if (k > 0) x = torch::avg_pool2d(x, 2, 2, /*padding=*/0, /*ceil_mode=*/true);
      x = torch::cat({x, added}, 1);
    }
    return global_average(head_->forward(x));
  }

 private:
  int in_channels_;
  nn::ModuleList blocks_{nullptr};
  nn::Conv2d head_{nullptr};
};

/// Beyond the paper: each block halves the resolution and doubles the width, so that the deeper
/// layers see the whole digit at a cost the full-resolution dense blocks cannot afford. Each
/// convolution is followed by GroupNorm, a per-sample normalisation (so one image's logits never
/// depend on the others in its batch, unlike BatchNorm): on the 8,000-digit MNIST split (16 x 3,
/// Adam 1e-3, batch 60) it reached 87.5 % validation accuracy after one epoch where the same network
/// without it reached 50 % (agent/README.md).
class StridedClassifierImpl : public ClassifierImpl {
 public:
  explicit StridedClassifierImpl(const NetworkConfig& config) : in_channels_(config.image_channels) {
    blocks_ = register_module("blocks", nn::ModuleList());
    int channels = config.image_channels;
    for (int k = 0; k < config.classifier_depth; ++k) {
      const int width = config.classifier_width << k;
      // padding 1 with stride 2 maps n to ceil(n / 2): 28 -> 14 -> 7 -> 4 -> 2 -> 1 -> 1 ...
      // The norm's shift makes the convolutions' biases redundant.
      blocks_->push_back(nn::Sequential(conv3x3(channels, width, 2, /*bias=*/false), group_norm(width), nn::ReLU(),
                                        conv3x3(width, width, 1, /*bias=*/false), group_norm(width), nn::ReLU()));
      channels = width;
    }
    head_ = register_module("head", conv1x1(channels, config.classes));
  }

  torch::Tensor forward(torch::Tensor y) override {
    check_input(y, in_channels_, "strided classifier");
    torch::Tensor x = y;
    for (const auto& block : *blocks_) x = block->as<nn::Sequential>()->forward(x);
    return global_average(head_->forward(x));
  }

 private:
  int in_channels_;
  nn::ModuleList blocks_{nullptr};
  nn::Conv2d head_{nullptr};
};

/// ResNet-18's basic block. Submodules are named as in torchvision (conv1, bn1, conv2, bn2,
/// downsample.0/1), so that its weights map onto ours by name.
class BasicBlockImpl : public nn::Module {
 public:
  BasicBlockImpl(int in, int out, int stride) {
    conv1_ = register_module("conv1", conv3x3(in, out, stride, /*bias=*/false));
    bn1_ = register_module("bn1", BatchNormAnyType(out));
    conv2_ = register_module("conv2", conv3x3(out, out, 1, /*bias=*/false));
    bn2_ = register_module("bn2", BatchNormAnyType(out));
    if (stride != 1 || in != out) {
      downsample_ =
          register_module("downsample", nn::Sequential(conv1x1(in, out, stride, false), BatchNormAnyType(out)));
    }
  }

  torch::Tensor forward(torch::Tensor x) {
    torch::Tensor out = torch::relu(bn1_->forward(conv1_->forward(x)));
    out = bn2_->forward(conv2_->forward(out));
    return torch::relu(out + (downsample_ ? downsample_->forward(x) : x));
  }

 private:
  nn::Conv2d conv1_{nullptr}, conv2_{nullptr};
  BatchNormAnyType bn1_{nullptr}, bn2_{nullptr};
  nn::Sequential downsample_{nullptr};
};
TORCH_MODULE(BasicBlock);

/// The paper's transfer variant: ResNet-18 (stages of 2 BasicBlocks, widths w, 2w, 4w, 8w). For
/// 28 x 28 inputs the stem is a 3 x 3 stride-1 convolution without max-pooling (ImageNet's 7 x 7
/// stride-2 stem and pool would leave 7 x 7 after the stem and 1 x 1 by the last stage). It uses
/// BatchNorm: it classifies whole batches of images, never one robot's decision.
class ResNet18ClassifierImpl : public ClassifierImpl {
 public:
  explicit ResNet18ClassifierImpl(const NetworkConfig& config) : in_channels_(config.image_channels) {
    const int w = config.classifier_width;
    conv1_ = register_module("conv1", conv3x3(config.image_channels, w, 1, /*bias=*/false));
    bn1_ = register_module("bn1", BatchNormAnyType(w));
    int channels = w;
    for (int stage = 0; stage < 4; ++stage) {
      const int width = w << stage;
      const int stride = stage == 0 ? 1 : 2;
      layers_[stage] =
          register_module("layer" + std::to_string(stage + 1),
                          nn::Sequential(BasicBlock(channels, width, stride), BasicBlock(width, width, 1)));
      channels = width;
    }
    fc_ = register_module("fc", nn::Linear(channels, config.classes));
  }

  torch::Tensor forward(torch::Tensor y) override {
    check_input(y, in_channels_, "resnet18 classifier");
    torch::Tensor x = torch::relu(bn1_->forward(conv1_->forward(y)));
    for (auto& layer : layers_) x = layer->forward(x);
    return fc_->forward(global_average(x));
  }

 private:
  int in_channels_;
  nn::Conv2d conv1_{nullptr};
  BatchNormAnyType bn1_{nullptr};
  nn::Sequential layers_[4] = {nullptr, nullptr, nullptr, nullptr};
  nn::Linear fc_{nullptr};
};

}  // namespace

DenseStackImpl::DenseStackImpl(int in_channels, int growth, int depth)
    : convs_(register_module("blocks", nn::ModuleList())), out_channels_(in_channels + depth * growth) {
  if (in_channels < 1 || growth < 1 || depth < 1) {
    throw std::invalid_argument("dense stack: expected positive channels, growth and depth, got " +
                                std::to_string(in_channels) + ", " + std::to_string(growth) + ", " +
                                std::to_string(depth));
  }
  for (int k = 0; k < depth; ++k) convs_->push_back(conv3x3(in_channels + k * growth, growth));
}

torch::Tensor DenseStackImpl::forward(torch::Tensor x) {
  // Both planners read their input through here, so this one check covers them.
  check_input(x, convs_[0]->as<nn::Conv2d>()->options.in_channels(), "planner");
  // In-place ReLU: the convolution's output is not needed by its backward, and a step saves one
  // full-size temporary per block.
  for (const auto& conv : *convs_) x = torch::cat({x, conv->as<nn::Conv2d>()->forward(x).relu_()}, 1);
  return x;
}

PlannerImpl::PlannerImpl(const NetworkConfig& config, Head head) : kind_(head) {
  config.validate();
  const int in = planner_channels(config);
  body_ = register_module("body", DenseStack(in, config.planner_width, config.planner_depth));
  const int features = body_->out_channels();
  if (head == Head::GoalPixels && config.goal_context > 0) {
    const int k = config.goal_context;
    nn::Sequential context(conv3x3(in, k, 2), nn::ReLU(nn::ReLUOptions(true)), conv3x3(k, k, 2),
                           nn::ReLU(nn::ReLUOptions(true)));
    for (int b = 0; b < kGoalContextBlocks; ++b) {
      context->push_back(conv3x3(k, k));
      context->push_back(nn::ReLU(nn::ReLUOptions(true)));
    }
    context_ = register_module("context", context);
    context_head_ = register_module("context_head", conv1x1(2 * k, 1));  // the coarse map and its global average
  }
  head_ = register_module("head", conv1x1(features, head == Head::GoalPixels ? 1 : 2));
}

torch::Tensor PlannerImpl::forward(torch::Tensor u) {
  torch::Tensor maps = head_->forward(body_->forward(u));
  if (context_) {
    // The coarse convolutions see about 31 x 31 pixels around each cell; the global average gives
    // every cell the whole floor (a corner's ink reaches the opposite corner). Their 1 x 1 head
    // scores the coarse cells, and the scores are upsampled (bilinear: smooth, not 4 x 4 steps)
    // and added to the dense stack's logits. One channel is upsampled, not the branch's k: the
    // full-resolution copy of k channels cost a third of a training step.
    const torch::Tensor coarse = context_->forward(u);
    const torch::Tensor whole = coarse.mean({2, 3}, /*keepdim=*/true).expand_as(coarse);
    const torch::Tensor scores = context_head_->forward(torch::cat({coarse, whole}, 1));
    maps = maps +
           torch::upsample_bilinear2d(scores, {u.size(2), u.size(3)}, /*align_corners=*/false).to(maps.scalar_type());
  }
  // Goals: [B, 1, H, W] -> [B, H * W], pixel (x, y) is logit y * W + x, the floor's row-major order.
  return kind_ == Head::GoalPixels ? maps.flatten(1) : global_average(maps);
}

namespace {

// The factories of the classifier variants, one row per row of kClassifierVariants (agent/config.hpp).
struct ClassifierFactory {
  ClassifierKind kind;
  std::shared_ptr<ClassifierImpl> (*make)(const NetworkConfig& config);
};

template <typename Network>
std::shared_ptr<ClassifierImpl> make_shared_classifier(const NetworkConfig& config) {
  return std::make_shared<Network>(config);
}

constexpr ClassifierFactory kClassifierFactories[] = {
    {.kind = ClassifierKind::Paper, .make = &make_shared_classifier<PaperClassifierImpl>},
    {.kind = ClassifierKind::PaperStrided,
     .make = [](const NetworkConfig& c) -> std::shared_ptr<ClassifierImpl> {
       return std::make_shared<PaperStridedClassifierImpl>(c, /*normalise=*/false);
     }},
    {.kind = ClassifierKind::PaperStridedNorm,
     .make = [](const NetworkConfig& c) -> std::shared_ptr<ClassifierImpl> {
       return std::make_shared<PaperStridedClassifierImpl>(c, /*normalise=*/true);
     }},
    {.kind = ClassifierKind::Strided, .make = &make_shared_classifier<StridedClassifierImpl>},
    {.kind = ClassifierKind::ResNet18, .make = &make_shared_classifier<ResNet18ClassifierImpl>},
};

constexpr bool every_variant_has_one_factory() {
  for (const ClassifierVariant& variant : kClassifierVariants) {
    int factories = 0;
    for (const ClassifierFactory& factory : kClassifierFactories) factories += factory.kind == variant.kind ? 1 : 0;
    if (factories != 1) return false;
  }
  return std::size(kClassifierFactories) == std::size(kClassifierVariants);
}
static_assert(every_variant_has_one_factory(),
              "every row of agent::kClassifierVariants needs exactly one row in kClassifierFactories");

}  // namespace

std::shared_ptr<ClassifierImpl> make_classifier(const NetworkConfig& config) {
  config.validate();
  for (const ClassifierFactory& factory : kClassifierFactories) {
    if (factory.kind == config.classifier) return factory.make(config);
  }
  throw std::invalid_argument("classifier: unknown kind " + std::to_string(static_cast<int>(config.classifier)));
}

AgentImpl::AgentImpl(const NetworkConfig& config) : config_(config) {
  config_.validate();
  goal = register_module("goal", Planner(config_, PlannerImpl::Head::GoalPixels));
  if (!config_.goals_only) action = register_module("action", Planner(config_, PlannerImpl::Head::ActionAxes));
  classifier = register_module("classifier", make_classifier(config_));
}

void copy_into_grown(const AgentImpl& from, AgentImpl& to) {
  const NetworkConfig& has = from.config();
  const NetworkConfig& wants = to.config();
  NetworkConfig grown = has;
  grown.occupancy = wants.occupancy;
  grown.goal_context = wants.goal_context;
  grown.goals_only = wants.goals_only;
  grown.team_channels = wants.team_channels;
  grown.wide_view = wants.wide_view;
  grown.free_routes = wants.free_routes;
  const bool adds_occupancy = wants.occupancy && !has.occupancy;
  const bool adds_team = wants.team_channels && !has.team_channels;
  const bool adds_wide = wants.wide_view && !has.wide_view;
  const bool adds_context = wants.goal_context > 0 && has.goal_context == 0;
  const bool drops_actions = wants.goals_only && !has.goals_only;
  if (!(grown == wants) || (!adds_occupancy && !adds_context && !drops_actions && !adds_team && !adds_wide) ||
      (has.occupancy && !wants.occupancy) || (has.goals_only && !wants.goals_only) ||
      (has.team_channels && !wants.team_channels) || (has.wide_view && !wants.wide_view) ||
      (has.goal_context != wants.goal_context && !adds_context))
    throw std::invalid_argument(
        "copy_into_grown: the target must be the source's networks with the occupancy channel, the "
        "teammates' channels, the wider view's channels or a goal context branch added, or the action planner "
        "removed");
  // The planners' inputs are concatenated [y, l, h, g_l, (o), (t_p, t_g), block outputs...]: each
  // of the source's input channels goes to its place in the target's order, and the added ones
  // (read with zero weights) fill the gaps.
  struct Layout {
    std::int64_t o = -1, team = -1, wide = -1, blocks = 0;  // first channel of each part (-1: absent)
  };
  const std::int64_t base = has.image_channels + 3;  // y, l, h, g_l
  auto layout = [base](const NetworkConfig& c) {
    Layout l;
    std::int64_t at = base;
    if (c.occupancy) l.o = at++;
    if (c.team_channels) {
      l.team = at;
      at += 2;
    }
    if (c.wide_view) {
      l.wide = at;
      at += 2;
    }
    l.blocks = at;
    return l;
  };
  const Layout from_layout = layout(has), to_layout = layout(wants);
  const std::int64_t inserted = to_layout.blocks - from_layout.blocks;
  torch::NoGradGuard no_grad;
  const auto source = from.named_parameters(/*recurse=*/true);
  for (auto& item : to.named_parameters(/*recurse=*/true)) {
    torch::Tensor& dst = item.value();
    if (!source.contains(item.key())) {
      // The new branch keeps its own initialisation, except its head, whose zero scores add nothing.
      if (adds_context && item.key().rfind("goal.context_head.", 0) == 0) {
        dst.zero_();
        continue;
      }
      if (adds_context && item.key().rfind("goal.context.", 0) == 0) continue;
      throw std::invalid_argument("copy_into_grown: the source has no " + item.key());
    }
    const torch::Tensor& src = source[item.key()];
    if (src.sizes() == dst.sizes()) {
      dst.copy_(src);
      continue;
    }
    const bool planner = item.key().rfind("goal.", 0) == 0 || item.key().rfind("action.", 0) == 0;
    if (!planner || src.dim() != 4 || dst.size(0) != src.size(0) || dst.size(1) != src.size(1) + inserted)
      throw std::invalid_argument("copy_into_grown: " + item.key() + " does not widen by the added input channels");
    dst.zero_();
    dst.narrow(1, 0, base).copy_(src.narrow(1, 0, base));
    if (from_layout.o >= 0) dst.narrow(1, to_layout.o, 1).copy_(src.narrow(1, from_layout.o, 1));
    if (from_layout.team >= 0) dst.narrow(1, to_layout.team, 2).copy_(src.narrow(1, from_layout.team, 2));
    if (from_layout.wide >= 0) dst.narrow(1, to_layout.wide, 2).copy_(src.narrow(1, from_layout.wide, 2));
    const std::int64_t blocks = src.size(1) - from_layout.blocks;
    dst.narrow(1, to_layout.blocks, blocks).copy_(src.narrow(1, from_layout.blocks, blocks));
  }
}

}  // namespace scout::agent
