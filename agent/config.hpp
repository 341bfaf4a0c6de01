#pragma once
/// The agent's network configuration (torch-free, so that tools and reports can read it without
/// pulling in LibTorch). Defaults and why: agent/README.md.
#include <string>

namespace scout::agent {

/// Which classifier network f3 is.
enum class ClassifierKind {
  Paper,     ///< METHOD.md: dense blocks at full resolution, width doubling each block, 1x1 head, GAP
  Strided,   ///< beyond the paper: each block halves the resolution (stride 2), width doubling
  ResNet18,  ///< the paper's transfer variant: ResNet-18 (BasicBlocks 2-2-2-2), base width = classifier_width
};
const char* to_string(ClassifierKind kind);  ///< "paper", "strided", "resnet18"
/// Parses "paper" | "strided" | "resnet18"; throws std::invalid_argument naming the choices.
ClassifierKind parse_classifier_kind(const std::string& text);

/// The arithmetic the networks run in. Weights, gradients and the optimizer always stay fp32;
/// bf16 runs the convolutions and activations in bfloat16 (AMX / AVX-512 BF16 on this CPU, where
/// a planner step is several times faster) with fp32 master weights, as mixed-precision training does.
enum class Precision { Float32, BFloat16 };
const char* to_string(Precision precision);  ///< "fp32", "bf16"
/// Parses "fp32" | "bf16"; throws std::invalid_argument naming the choices.
Precision parse_precision(const std::string& text);

/// Widths and depths of the three networks.
struct NetworkConfig {
  int image_channels = 1;  ///< c: channels of the floor image (y has c, planners read c + 3)
  int classes = 10;        ///< D
  int planner_width = 16;  ///< d: channels each planner block adds
  int planner_depth = 3;   ///< r: planner blocks
  ClassifierKind classifier = ClassifierKind::Paper;
  int classifier_width = 16;  ///< first block's channels (doubling each block); ResNet-18: stem width
  int classifier_depth = 3;   ///< classifier blocks (ResNet-18: ignored, always 4 stages of 2)

  /// Throws std::invalid_argument naming the field when a value is out of range.
  void validate() const;
  bool operator==(const NetworkConfig&) const = default;
};

/// Limits checked by validate(): generous for research, small enough to fail before an
/// out-of-memory.
inline constexpr int kMaxWidth = 512;
inline constexpr int kMaxPlannerDepth = 16;
inline constexpr int kMaxClassifierDepth = 8;
/// The widest classifier block (width doubles each block): classifier_width x 2^(depth - 1).
inline constexpr int kMaxClassifierBlockWidth = 4096;

}  // namespace scout::agent
