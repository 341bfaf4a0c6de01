#pragma once
// Which family of fp32 kernels this process's LibTorch runs, for the pins that depend on it (the
// short training run's weights digest, the golden evaluation files). oneDNN (convolutions) and
// ATen (everything else) each pick their kernels by the CPU's instruction sets, capped by
// ONEDNN_MAX_CPU_ISA (or DNNL_MAX_CPU_ISA) and ATEN_CPU_CAPABILITY; their sums round differently
// per family, so an fp32 result is reproducible bit for bit within a family, not across.
//
// Families: "avx512" (AVX-512 CPUs: Intel Xeon with AMX, AMD EPYC with AVX-512 BF16 — the same
// fp32 kernels) and "avx2" (CPUs with AVX2 and FMA only, or an AVX-512 CPU capped to stand in for
// one: ONEDNN_MAX_CPU_ISA=AVX2 ATEN_CPU_CAPABILITY=avx2, which gave an AVX2-only EPYC's digest
// bit for bit with the code of e1a07b2; today's avx2 pins were made that way, and the avx512 ones
// on an AMD EPYC with AVX-512 BF16, not yet checked on an AMX Xeon). Anything else (a mixed cap, an older or non-x86
// CPU) is its own family, which has no pins: those tests skip there, saying so.
//
// The pins are rewritten with scripts/write_pins.sh (SCOUT_WRITE_PINS=1 makes a pin test write
// what it got for its family instead of comparing).
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <string>

namespace scout::testing {

namespace kernel_family_detail {

inline std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

inline std::string env(const char* name) {
  const char* v = std::getenv(name);
  return v ? std::string(v) : std::string();
}

inline bool cpu_has_avx512() {
#if defined(__x86_64__)
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
         __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512dq");
#else
  return false;
#endif
}

inline bool cpu_has_avx2() {
#if defined(__x86_64__)
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#else
  return false;
#endif
}

// oneDNN's fp32 convolutions: avx512 (avx512_core and above), avx2, or older.
inline std::string onednn_family() {
  std::string family = cpu_has_avx512() ? "avx512" : cpu_has_avx2() ? "avx2" : "older";
  std::string cap = upper(env("ONEDNN_MAX_CPU_ISA"));
  if (cap.empty()) cap = upper(env("DNNL_MAX_CPU_ISA"));
  if (cap.empty() || cap == "ALL" || cap.rfind("AVX512_CORE", 0) == 0 || cap.rfind("AVX10", 0) == 0) return family;
  if (cap.rfind("AVX2", 0) == 0) return family == "avx512" ? "avx2" : family;
  return "older";
}

// ATen's own kernels (ATEN_CPU_CAPABILITY: default, avx2, avx512, compared as written, in lower case).
inline std::string aten_family() {
  const std::string family = cpu_has_avx512() ? "avx512" : cpu_has_avx2() ? "avx2" : "older";
  const std::string cap = env("ATEN_CPU_CAPABILITY");
  if (cap == "default") return "older";
  if (cap == "avx2") return family == "avx512" ? "avx2" : family;
  return family;
}

}  // namespace kernel_family_detail

/// "avx512", "avx2", or another family with no pins ("onednn-avx2+aten-avx512", "older").
inline std::string fp32_kernel_family() {
  const std::string dnn = kernel_family_detail::onednn_family(), aten = kernel_family_detail::aten_family();
  return dnn == aten ? dnn : "onednn-" + dnn + "+aten-" + aten;
}

/// True while scripts/write_pins.sh runs the pin tests: they write their family's pin instead.
inline bool writing_pins() { return kernel_family_detail::env("SCOUT_WRITE_PINS") == "1"; }

/// The pins of one test, a text file of "FAMILY VALUE" lines.
class PinFile {
 public:
  explicit PinFile(std::filesystem::path file) : file_(std::move(file)) {
    std::ifstream in(file_);
    std::string family, value;
    while (in >> family >> value) pins_[family] = value;
  }
  std::optional<std::string> get(const std::string& family) const {
    const auto it = pins_.find(family);
    return it == pins_.end() ? std::nullopt : std::optional<std::string>(it->second);
  }
  void set(const std::string& family, const std::string& value) {
    pins_[family] = value;
    std::ofstream out(file_);
    for (const auto& [f, v] : pins_) out << f << ' ' << v << '\n';
  }

 private:
  std::filesystem::path file_;
  std::map<std::string, std::string> pins_;
};

}  // namespace scout::testing
