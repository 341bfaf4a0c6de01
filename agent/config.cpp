#include "agent/config.hpp"

#include <cctype>
#include <cstdlib>
#include <initializer_list>
#include <stdexcept>
#include <string>

namespace scout::agent {
namespace {

// One message format for every field, so that a bad value reads the same wherever it comes from
// (a command line or a checkpoint's config).
void check_range(const char* field, int value, int lo, int hi) {
  if (value < lo || value > hi) {
    throw std::invalid_argument(std::string(field) + ": expected an integer in " + std::to_string(lo) + ".." +
                                std::to_string(hi) + ", got " + std::to_string(value));
  }
}

}  // namespace

const char* to_string(Precision precision) {
  switch (precision) {
    case Precision::Float32:
      return "fp32";
    case Precision::BFloat16:
      return "bf16";
    case Precision::Auto:
      return "auto";
  }
  return "?";
}

Precision parse_precision(const std::string& text) {
  for (const Precision precision : {Precision::Float32, Precision::BFloat16, Precision::Auto}) {
    if (text == to_string(precision)) return precision;
  }
  throw std::invalid_argument("precision: expected one of fp32, bf16, auto, got \"" + text + "\"");
}

namespace {

// What oneDNN may use under each value of its ISA cap (ONEDNN_MAX_CPU_ISA, or its older name
// DNNL_MAX_CPU_ISA; oneDNN 2.x's names). A value not in the table is no cap: oneDNN ignores it.
struct IsaCap {
  const char* name;
  bool avx512;  // AVX-512 (where oneDNN has bf16 convolutions at all)
  bool bf16;    // AVX-512 BF16 instructions
  bool amx;     // AMX tiles
};
constexpr IsaCap kIsaCaps[] = {
    {"SSE41", false, false, false},
    {"AVX", false, false, false},
    {"AVX2", false, false, false},
    {"AVX2_VNNI", false, false, false},
    {"AVX2_VNNI_2", false, false, false},
    {"AVX512_MIC", true, false, false},
    {"AVX512_MIC_4OPS", true, false, false},
    {"AVX512_CORE", true, false, false},
    {"AVX512_CORE_VNNI", true, false, false},
    {"AVX512_CORE_BF16", true, true, false},
    {"AVX512_CORE_FP16", true, true, false},
    {"AVX10_1_512", true, true, false},
    {"AVX512_CORE_AMX", true, true, true},
    {"AVX512_CORE_AMX_FP16", true, true, true},
    {"AVX10_1_512_AMX", true, true, true},
    {"AVX10_1_512_AMX_FP16", true, true, true},
    {"ALL", true, true, true},
};

// The cap in effect, or nullptr; `variable` gets "NAME=value" as the user wrote it.
const IsaCap* onednn_isa_cap(std::string* variable) {
  for (const char* name : {"ONEDNN_MAX_CPU_ISA", "DNNL_MAX_CPU_ISA"}) {
    const char* value = std::getenv(name);
    if (value == nullptr || *value == '\0') continue;
    std::string cap(value);
    for (char& c : cap) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    for (const IsaCap& known : kIsaCaps) {
      if (cap != known.name) continue;
      if (variable) *variable = std::string(name) + "=" + value;
      return &known;
    }
    return nullptr;  // oneDNN reads the first variable set, and ignores a value it does not know
  }
  return nullptr;
}

}  // namespace

NativeBf16 native_bf16() {
  NativeBf16 found;
#if defined(__x86_64__) || defined(__i386__)
  __builtin_cpu_init();
  found.amx_bf16 = __builtin_cpu_supports("amx-bf16") != 0;
  found.avx512_bf16 = __builtin_cpu_supports("avx512bf16") != 0;
#endif
  // The cap is how a CPU with native bf16 stands in for one without (tests, CI, benchmarks): what
  // oneDNN may not use is not native to this process.
  std::string variable;
  if (const IsaCap* cap = onednn_isa_cap(&variable)) {
    if ((found.amx_bf16 && !cap->amx) || (found.avx512_bf16 && !cap->bf16)) found.capped_by = variable;
    found.amx_bf16 = found.amx_bf16 && cap->amx;
    found.avx512_bf16 = found.avx512_bf16 && cap->bf16;
  }
  return found;
}

std::string bf16_unavailable() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_cpu_init();
  // LibTorch sends bf16 convolutions to oneDNN on CPUs with AVX-512 BW, VL and DQ (elsewhere it
  // emulates them itself); oneDNN runs them only with AVX-512.
  const bool to_onednn =
      __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512dq");
  std::string variable;
  const IsaCap* cap = onednn_isa_cap(&variable);
  if (to_onednn && cap && !cap->avx512)
    return variable +
           " keeps oneDNN below AVX-512, where it has no bf16 convolutions, and LibTorch sends this "
           "CPU's bf16 convolutions to oneDNN; unset it, or use fp32";
#endif
  return {};
}

std::string fp32_without_native_bf16_note() {
  const NativeBf16 cpu = native_bf16();
  if (!cpu.capped_by.empty())
    return "precision: fp32 (" + cpu.capped_by + " leaves no native bf16; bf16 would be emulated and slower)";
  return "precision: fp32 (no native bf16 on this CPU; bf16 would be emulated and slower)";
}

const ClassifierVariant* find_classifier_variant(ClassifierKind kind) {
  for (const ClassifierVariant& variant : kClassifierVariants) {
    if (variant.kind == kind) return &variant;
  }
  return nullptr;
}

const char* to_string(ClassifierKind kind) {
  const ClassifierVariant* variant = find_classifier_variant(kind);
  return variant != nullptr ? variant->name : "?";
}

std::string describe_planners(const NetworkConfig& config) {
  std::string text = std::to_string(config.planner_width) + "x" + std::to_string(config.planner_depth);
  std::string extras;
  auto add = [&](const std::string& what) { extras += (extras.empty() ? " with " : ", ") + what; };
  if (config.occupancy) add("the occupancy channel");
  if (config.goal_context > 0) add("a goal context branch of " + std::to_string(config.goal_context));
  if (config.team_channels) add("the teammates' channels");
  if (config.wide_view) add("the wider view's channels");
  if (config.goals_only) add("no action planner (goals only)");
  if (config.free_routes) add("the route rule (free routes only)");
  return text + extras;
}

std::string describe_classifier(const NetworkConfig& config) {
  const ClassifierVariant* variant = find_classifier_variant(config.classifier);
  if (variant == nullptr) return "?";
  if (!variant->uses_depth) return std::string(variant->name) + " width " + std::to_string(config.classifier_width);
  return std::string(variant->name) + " " + std::to_string(config.classifier_width) + "x" +
         std::to_string(config.classifier_depth);
}

std::string classifier_choices(const std::string& separator) {
  std::string names;
  for (const ClassifierVariant& variant : kClassifierVariants) names += (names.empty() ? "" : separator) + variant.name;
  return names;
}

ClassifierKind parse_classifier_kind(const std::string& text) {
  for (const ClassifierVariant& variant : kClassifierVariants) {
    if (text == variant.name) return variant.kind;
  }
  throw std::invalid_argument("classifier: expected one of " + classifier_choices() + ", got \"" + text + "\"");
}

void NetworkConfig::validate() const {
  check_range("image_channels", image_channels, 1, kMaxImageChannels);
  check_range("classes", classes, 2, 1000);
  check_range("planner_width", planner_width, 1, kMaxWidth);
  check_range("planner_depth", planner_depth, 1, kMaxPlannerDepth);
  check_range("classifier_width", classifier_width, 1, kMaxWidth);
  check_range("classifier_depth", classifier_depth, 1, kMaxClassifierDepth);
  check_range("goal_context", goal_context, 0, kMaxWidth);
  // An enum cast from an out-of-range integer would otherwise reach make_classifier.
  const ClassifierVariant* variant = find_classifier_variant(classifier);
  if (variant == nullptr) {
    throw std::invalid_argument("classifier: expected one of " + classifier_choices() + ", got " +
                                std::to_string(static_cast<int>(classifier)));
  }
  // The paper and strided classifiers double their width each block: bound the widest block,
  // so that a typo fails here and not as an out-of-memory an hour later.
  if (variant->width_doubles) {
    const long widest = static_cast<long>(classifier_width) << (classifier_depth - 1);
    if (widest > kMaxClassifierBlockWidth)
      throw std::invalid_argument("classifier_width: expected classifier_width x 2^(classifier_depth - 1) <= " +
                                  std::to_string(kMaxClassifierBlockWidth) + ", got " + std::to_string(widest));
  }
}

namespace {

std::int64_t conv(std::int64_t in, std::int64_t out, std::int64_t kernel, bool bias) {
  return in * out * kernel * kernel + (bias ? out : 0);
}

// A dense stack and its 1x1 head (agent/networks.cpp's planners).
std::int64_t planner(const NetworkConfig& c, std::int64_t head_channels) {
  const std::int64_t in = planner_channels(c);
  std::int64_t n = 0;
  for (int k = 0; k < c.planner_depth; ++k) n += conv(in + std::int64_t{k} * c.planner_width, c.planner_width, 3, true);
  n += conv(in + std::int64_t{c.planner_depth} * c.planner_width, head_channels, 1, true);
  if (head_channels == 1 && c.goal_context > 0) {  // the goal planner's context branch and its head inputs
    const std::int64_t k = c.goal_context;
    n +=
        conv(in, k, 3, true) + conv(k, k, 3, true) + kGoalContextBlocks * conv(k, k, 3, true) + conv(2 * k, 1, 1, true);
  }
  return n;
}

std::int64_t classifier(const NetworkConfig& c) {
  const std::int64_t w = c.classifier_width;
  std::int64_t n = 0;
  std::int64_t channels = c.image_channels;
  switch (c.classifier) {
    case ClassifierKind::Paper:
      for (int k = 0; k < c.classifier_depth; ++k) {
        n += conv(channels, w << k, 3, true);
        channels += w << k;
      }
      return n + conv(channels, c.classes, 1, true);
    case ClassifierKind::PaperStrided:
    case ClassifierKind::PaperStridedNorm: {
      const bool norm = c.classifier == ClassifierKind::PaperStridedNorm;
      for (int k = 0; k < c.classifier_depth; ++k) {
        n += conv(channels, w << k, 3, !norm) + (norm ? 2 * (w << k) : 0);
        channels += w << k;
      }
      return n + conv(channels, c.classes, 1, true);
    }
    case ClassifierKind::Strided:
      for (int k = 0; k < c.classifier_depth; ++k) {
        const std::int64_t width = w << k;
        n += conv(channels, width, 3, false) + conv(width, width, 3, false) + 4 * width;  // two GroupNorms
        channels = width;
      }
      return n + conv(channels, c.classes, 1, true);
    case ClassifierKind::ResNet18: {
      n = conv(channels, w, 3, false) + 2 * w;  // stem and its BatchNorm
      channels = w;
      for (int stage = 0; stage < 4; ++stage) {
        const std::int64_t width = w << stage;
        const bool downsample = stage != 0 || channels != width;
        n += conv(channels, width, 3, false) + conv(width, width, 3, false) + 4 * width;
        if (downsample) n += conv(channels, width, 1, false) + 2 * width;
        n += 2 * conv(width, width, 3, false) + 4 * width;
        channels = width;
      }
      return n + channels * c.classes + c.classes;  // the fully connected head
    }
  }
  throw std::invalid_argument("classifier: unknown kind " + std::to_string(static_cast<int>(c.classifier)));
}

}  // namespace

std::int64_t parameter_count(const NetworkConfig& config) {
  return planner(config, 1) + (config.goals_only ? 0 : planner(config, 2)) + classifier(config);
}

}  // namespace scout::agent
