#pragma once
/// The agent's network configuration (torch-free, so that tools and reports can read it without
/// pulling in LibTorch). Defaults and why: agent/README.md.
#include <cstdint>
#include <string>

namespace scout::agent {

/// Which classifier network f3 is. Each value has one row in kClassifierVariants (its name and
/// help) and one factory in agent/networks.cpp (checked at compile time).
enum class ClassifierKind {
  Paper,  ///< METHOD.md: dense blocks at full resolution, width doubling each block, 1x1 head, GAP
  /// METHOD.md's dense blocks read as ResNets downsample: a stride-2 step at each doubling (block
  /// k >= 1), the concatenated skip average-pooled to match; no normalisation (the paper names none)
  PaperStrided,
  PaperStridedNorm,  ///< PaperStrided with GroupNorm after each convolution
  Strided,           ///< beyond the paper: each block halves the resolution (stride 2), width doubling
  ResNet18,          ///< the paper's transfer variant: ResNet-18 (BasicBlocks 2-2-2-2), base width = classifier_width
};

/// A classifier variant as the command line, the checkpoint's config and the documentation name it.
struct ClassifierVariant {
  ClassifierKind kind;
  const char* name;    ///< what --classifier and the checkpoint's config say
  const char* help;    ///< one line for --help
  bool width_doubles;  ///< block k is classifier_width x 2^k wide (validate() bounds the widest block)
  bool uses_depth;     ///< classifier_depth sets its blocks (ResNet-18's are fixed: the field is ignored)
};

/// The classifier variants, in the order --help lists them; the first is the default. Parsing,
/// printing, --help, the choices in error messages and the factory (agent/networks.cpp) all read
/// this table. A new variant: its network class, a ClassifierKind value, a row here and its
/// factory row in agent/networks.cpp.
inline constexpr ClassifierVariant kClassifierVariants[] = {
    {.kind = ClassifierKind::Paper,
     .name = "paper",
     .help = "METHOD.md's dense blocks at full resolution",
     .width_doubles = true,
     .uses_depth = true},
    {.kind = ClassifierKind::PaperStrided,
     .name = "paper-strided",
     .help = "METHOD.md's dense blocks with a stride-2 step at each doubling (the ResNet reading)",
     .width_doubles = true,
     .uses_depth = true},
    {.kind = ClassifierKind::PaperStridedNorm,
     .name = "paper-strided-gn",
     .help = "paper-strided with GroupNorm after each convolution",
     .width_doubles = true,
     .uses_depth = true},
    {.kind = ClassifierKind::Strided,
     .name = "strided",
     .help = "stride-2 blocks with GroupNorm (beyond the paper)",
     .width_doubles = true,
     .uses_depth = true},
    {.kind = ClassifierKind::ResNet18,
     .name = "resnet18",
     .help = "ResNet-18, the paper's transfer variant",
     .width_doubles = false,
     .uses_depth = false},
};

/// The row of `kind`, or nullptr for a value outside the enum.
const ClassifierVariant* find_classifier_variant(ClassifierKind kind);
const char* to_string(ClassifierKind kind);  ///< the row's name ("paper", "strided", "resnet18")
struct NetworkConfig;
/// The classifier as logs and reports name it: "paper 16x3" (width x depth), "resnet18 width 16".
std::string describe_classifier(const NetworkConfig& config);
/// The planners as logs and reports name them: "16x3" (width x depth), then what is beyond the paper:
/// "16x3 with the occupancy channel, a goal context branch of 32, no action planner (goals only)".
std::string describe_planners(const NetworkConfig& config);
/// Parses a row's name; throws std::invalid_argument naming the choices.
ClassifierKind parse_classifier_kind(const std::string& text);
/// The names joined by `separator`: "paper, paper-strided, paper-strided-gn, strided, resnet18".
std::string classifier_choices(const std::string& separator = ", ");

/// The arithmetic the networks run in. Weights, gradients and the optimizer always stay fp32;
/// bf16 runs the convolutions and activations in bfloat16 (AMX / AVX-512 BF16, where a planner
/// step is several times faster) with fp32 master weights, as mixed-precision training does. Auto
/// is a request, never a stored value: learn::resolve_precision() turns it into the precision that
/// runs faster on this CPU (learn/auto_precision.hpp), which is fp32 where bf16 is not native.
enum class Precision { Float32, BFloat16, Auto };
const char* to_string(Precision precision);  ///< "fp32", "bf16", "auto"
/// Parses "fp32" | "bf16" | "auto"; throws std::invalid_argument naming the choices.
Precision parse_precision(const std::string& text);

/// The CPU's native bfloat16 arithmetic as this process may use it: x86 CPUID as GCC reads it (none
/// elsewhere), less what oneDNN's ISA cap forbids (ONEDNN_MAX_CPU_ISA or DNNL_MAX_CPU_ISA below
/// AVX512_CORE_BF16 leaves none; below AVX512_CORE_AMX leaves no AMX). The cap is also how a CPU
/// with native bf16 stands in for one without: `ONEDNN_MAX_CPU_ISA=AVX2 ATEN_CPU_CAPABILITY=avx2`.
struct NativeBf16 {
  bool amx_bf16 = false;     ///< AMX-BF16 (/proc/cpuinfo flag amx_bf16)
  bool avx512_bf16 = false;  ///< AVX-512 BF16 (/proc/cpuinfo flag avx512_bf16)
  std::string capped_by;     ///< "ONEDNN_MAX_CPU_ISA=AVX2" when the cap removed what the CPU has
  bool any() const { return amx_bf16 || avx512_bf16; }
};
NativeBf16 native_bf16();
/// Why bf16 cannot run at all in this process ("" where it can, natively or emulated): a oneDNN
/// cap below AVX-512 on a CPU with AVX-512, as the stand-in for a CPU without native bf16 sets.
std::string bf16_unavailable();
/// Auto's choice where native_bf16() has none, in one line: "precision: fp32 (no native bf16 on
/// this CPU; bf16 would be emulated and slower)", or naming the cap that removed it.
std::string fp32_without_native_bf16_note();

/// Widths and depths of the three networks.
struct NetworkConfig {
  int image_channels = 1;  ///< c: the floor images' channels (y has c, planners read c + 3); a new run takes its data's
  int classes = 10;        ///< D
  int planner_width = 16;  ///< d: channels each planner block adds
  int planner_depth = 3;   ///< r: planner blocks
  ClassifierKind classifier = ClassifierKind::Paper;
  int classifier_width = 16;  ///< first block's channels (doubling each block); ResNet-18: stem width
  int classifier_depth = 3;   ///< classifier blocks (ResNet-18: ignored, always 4 stages of 2)
  /// The planners also read o, the occupancy channel (docs/SCENARIOS.md § Obstacles): 1 on the
  /// cells where the robot cannot stand beside its run's obstacles, 0 elsewhere.
  bool occupancy = false;
  /// Channels of the goal planner's context branch (beyond the paper; 0, the paper's planner, has
  /// none): the planner input at 1/4 resolution through kGoalContextBlocks 3 x 3 convolutions, which
  /// see about 31 x 31 floor pixels where the dense stack sees 2r + 1; a 1 x 1 head scores each
  /// coarse cell from its features and their global average, and the scores, upsampled to the
  /// floor, are added to the goal logits. It lets f1 choose a goal from the whole revealed digit and
  /// the whole visit mask h rather than from a 7 x 7 neighbourhood of each pixel.
  int goal_context = 0;
  /// No action planner f2 (beyond the paper): the axis of every move that needs one is drawn i.i.d.
  /// 1/2 - 1/2 in every mode, as mode (ii) draws it. The agent then has no f2 parameters and spends
  /// no arithmetic on it in training or inference; it trains in modes (i) and (ii) only.
  bool goals_only = false;
  /// The planners also read t_p and t_g (beyond the paper): where the team's other robots stand
  /// and where their goals are (agent/state.hpp), and a team's robots choose their goals one after
  /// the other, each seeing the goals its teammates have just chosen (a joint proposal, factorised).
  bool team_channels = false;
  /// The planners also read the wider view (beyond the paper; a world with camera.wide_px > 0):
  /// y_w, the team's coarse map of it, and h_w, 0 where it has covered the floor, 1 elsewhere.
  bool wide_view = false;
  /// The route rule (beyond the paper; METHOD.md § Obstacles): the goal planner's distribution is
  /// renormalised over the cells that a monotone route of free cells joins to the robot's cell
  /// (grid::monotone_reach over the run's o), and a move's axis is forced where only one of the two
  /// keeps such a route to the goal. No parameters and no effect in a world without obstacles.
  bool free_routes = false;

  /// Throws std::invalid_argument naming the field when a value is out of range.
  void validate() const;
  bool operator==(const NetworkConfig&) const = default;
};

/// Whether a model of `has` loads into networks of `wants` as it is: equal but for the settings
/// that carry no weights (free_routes).
inline bool same_weights(NetworkConfig has, const NetworkConfig& wants) {
  has.free_routes = wants.free_routes;
  return has == wants;
}

/// Input channels of both planners: y (c), l, h, g_l, o with `occupancy`, t_p and t_g with
/// `team_channels`, y_w and h_w with `wide_view`.
inline int planner_channels(const NetworkConfig& config) {
  return config.image_channels + 3 + (config.occupancy ? 1 : 0) + (config.team_channels ? 2 : 0) +
         (config.wide_view ? 2 : 0);
}

/// The agent's trainable parameters (all three networks) for `config`, counted without building
/// them: what a checkpoint of this config must hold, and the base of memory estimates. A test
/// holds it equal to the built networks' count for every classifier variant.
std::int64_t parameter_count(const NetworkConfig& config);

/// Limits checked by validate(): generous for research, small enough to fail before an
/// out-of-memory.
inline constexpr int kMaxImageChannels = 4;
inline constexpr int kMaxWidth = 512;
inline constexpr int kMaxPlannerDepth = 16;
inline constexpr int kMaxClassifierDepth = 8;
/// The goal planner's context branch: two stride-2 convolutions, then this many at 1/4 resolution.
inline constexpr int kGoalContextBlocks = 3;
/// The widest classifier block (width doubles each block): classifier_width x 2^(depth - 1).
inline constexpr int kMaxClassifierBlockWidth = 4096;

}  // namespace scout::agent
