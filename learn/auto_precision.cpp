#include "learn/auto_precision.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <sched.h>
#include <sys/file.h>
#include <torch/torch.h>
#include <torch/version.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <fstream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <thread>
#include <vector>

#include "core/files.hpp"
#include "learn/internal/auto_precision.hpp"
#include "learn/internal/precision.hpp"

namespace scout::learn {

namespace {

constexpr int kProbeRobots = 24;               // enough for the kernels' steady state, small enough for ~1 s in all
constexpr int kProbeFloor = 28;                // the default floor
constexpr int kProbeRounds = 3;                // timed steps per precision (medians), after one warm-up each
constexpr double kBf16Margin = 0.90;           // bf16 must take at most 90 % of fp32's time
constexpr std::chrono::seconds kLockWait{60};  // the longest wait for another process's measurement

std::string cpu_model() {
  std::ifstream cpuinfo("/proc/cpuinfo");
  std::string line;
  while (std::getline(cpuinfo, line)) {
    if (line.rfind("model name", 0) == 0) {
      const auto colon = line.find(':');
      if (colon != std::string::npos) {
        std::string model = line.substr(colon + 1);
        model.erase(0, model.find_first_not_of(" \t"));
        return model;
      }
    }
  }
  return "unknown CPU";
}

}  // namespace

// Everything the choice depends on: the CPU, what of its bf16 the process may use and the kernels'
// library. (Not the process's thread count: the probe always runs on every core, so that a test
// process and the `scout` it starts find the same entry.)
std::string precision_cache_key() {
  const agent::NativeBf16 cpu = agent::native_bf16();
  std::string isa = cpu.amx_bf16 ? "amx-bf16" : "";
  if (cpu.avx512_bf16) isa += isa.empty() ? "avx512-bf16" : "+avx512-bf16";
  std::string caps;
  for (const char* variable : {"ONEDNN_MAX_CPU_ISA", "DNNL_MAX_CPU_ISA", "ATEN_CPU_CAPABILITY"}) {
    if (const char* value = std::getenv(variable); value != nullptr && *value != '\0')
      caps += fmt::format(" {}={}", variable, value);
  }
  return fmt::format("{} | {}{} | LibTorch {}", cpu_model(), isa, caps, TORCH_VERSION);
}

namespace {

// The cores this process may run on (its affinity mask, which a container's cpuset sets).
int usable_cores() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (::sched_getaffinity(0, sizeof set, &set) == 0) return std::max(1, CPU_COUNT(&set));
  return static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

// While alive, LibTorch runs on every usable core; the process's own count comes back after,
// whatever the probe throws.
class ProbeThreads {
 public:
  ProbeThreads() : saved_(torch::get_num_threads()) { torch::set_num_threads(usable_cores()); }
  ~ProbeThreads() { torch::set_num_threads(saved_); }
  ProbeThreads(const ProbeThreads&) = delete;
  ProbeThreads& operator=(const ProbeThreads&) = delete;

 private:
  int saved_;
};

double median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  return values[values.size() / 2];
}

}  // namespace

// Interleaved, so that a change in the machine's load falls on both precisions alike. LibTorch's
// global generator is restored: the probe must not change what a seeded run draws.
PrecisionMeasurement measure_precisions() {
  at::Generator generator = at::detail::getDefaultCPUGenerator();
  const torch::Tensor generator_state = generator.get_state();
  const agent::NetworkConfig config;
  agent::Agent networks(config);
  const torch::Tensor u = torch::rand({kProbeRobots, agent::planner_channels(config), kProbeFloor, kProbeFloor});
  const torch::Tensor y = torch::rand({kProbeRobots, config.image_channels, kProbeFloor, kProbeFloor});
  generator.set_state(generator_state);
  const ProbeThreads threads;

  auto step_ms = [&](agent::Precision precision) {
    const auto start = std::chrono::steady_clock::now();
    {
      const torch::NoGradGuard no_grad;
      const ComputePrecision guard(precision);
      (void)networks->goal->forward(network_input(u, precision));
      if (networks->action) (void)networks->action->forward(network_input(u, precision));
    }
    {
      const ComputePrecision guard(precision);
      const torch::Tensor loss =
          networks->goal->forward(network_input(u, precision)).to(torch::kFloat).mean() +
          (networks->action ? networks->action->forward(network_input(u, precision)).to(torch::kFloat).mean()
                            : torch::zeros({})) +
          classifier_log_probs(*networks, y, precision).mean();
      loss.backward();
    }
    networks->zero_grad();
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  };
  (void)step_ms(agent::Precision::Float32);
  (void)step_ms(agent::Precision::BFloat16);
  std::vector<double> fp32, bf16;
  for (int round = 0; round < kProbeRounds; ++round) {
    fp32.push_back(step_ms(agent::Precision::Float32));
    bf16.push_back(step_ms(agent::Precision::BFloat16));
  }
  return {median(fp32), median(bf16)};
}

agent::Precision choose_precision(const PrecisionMeasurement& m) {
  return m.bf16_ms <= kBf16Margin * m.fp32_ms ? agent::Precision::BFloat16 : agent::Precision::Float32;
}

namespace {

std::string measured_note(const PrecisionMeasurement& m, agent::Precision chosen, const std::string& where) {
  const char* why = chosen == agent::Precision::BFloat16 ? "faster" : "not 10 % faster";
  return fmt::format(
      "precision: {} (native bf16 measured on this CPU with LibTorch {}: a training step of the default networks "
      "on 24 robots takes {:.0f} ms in bf16, {:.0f} ms in fp32, bf16 {}; {})",
      agent::to_string(chosen), TORCH_VERSION, m.bf16_ms, m.fp32_ms, why, where);
}

std::optional<PrecisionMeasurement> cached(const nlohmann::json& cache, const std::string& key) {
  if (!cache.is_object() || !cache.contains("choices") || !cache["choices"].is_object()) return std::nullopt;
  const auto found = cache["choices"].find(key);
  if (found == cache["choices"].end() || !found->is_object()) return std::nullopt;
  const auto fp32 = found->find("fp32_ms"), bf16 = found->find("bf16_ms");
  if (fp32 == found->end() || bf16 == found->end() || !fp32->is_number() || !bf16->is_number()) return std::nullopt;
  const PrecisionMeasurement m{fp32->get<double>(), bf16->get<double>()};
  if (!(m.fp32_ms > 0) || !(m.bf16_ms > 0)) return std::nullopt;
  return m;
}

// A cache that cannot be read as one (missing, damaged, another program's) is measured again.
nlohmann::json read_cache(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) return nlohmann::json::object();
  std::stringstream text;
  text << in.rdbuf();
  nlohmann::json cache = nlohmann::json::parse(text.str(), nullptr, /*allow_exceptions=*/false);
  return cache.is_object() ? cache : nlohmann::json::object();
}

// Holds an exclusive flock on a lock file beside the cache while alive.
class CacheLock {
 public:
  explicit CacheLock(const std::filesystem::path& file) {
    fd_ = ::open(file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0) return;
    // Another process measuring takes about a second; one that holds the lock far longer is
    // stopped or stuck, and this one measures for itself rather than wait on it.
    const auto deadline = std::chrono::steady_clock::now() + kLockWait;
    while (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
      if ((errno != EWOULDBLOCK && errno != EINTR) || std::chrono::steady_clock::now() > deadline) {
        ::close(fd_);
        fd_ = -1;
        return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  ~CacheLock() {
    if (fd_ >= 0) ::close(fd_);  // closing releases the lock
  }
  CacheLock(const CacheLock&) = delete;
  CacheLock& operator=(const CacheLock&) = delete;
  bool held() const { return fd_ >= 0; }

 private:
  int fd_ = -1;
};

}  // namespace

PrecisionChoice cached_or_measured_precision(const std::filesystem::path& file, const std::string& key) {
  std::error_code error;
  std::filesystem::create_directories(file.parent_path(), error);
  const CacheLock lock(file.string() + ".lock");
  if (!lock.held()) {
    const PrecisionMeasurement m = measure_precisions();
    return {choose_precision(m),
            measured_note(m, choose_precision(m), "not cached: cannot lock " + file.string() + ".lock within 60 s")};
  }
  nlohmann::json cache = read_cache(file);
  if (const auto m = cached(cache, key))
    return {choose_precision(*m), measured_note(*m, choose_precision(*m), "cached in " + file.string())};
  const PrecisionMeasurement m = measure_precisions();
  if (!cache["choices"].is_object()) cache["choices"] = nlohmann::json::object();  // another program's
  cache["choices"][key] = {
      {"fp32_ms", m.fp32_ms}, {"bf16_ms", m.bf16_ms}, {"precision", agent::to_string(choose_precision(m))}};
  std::string where = "cached in " + file.string();
  try {
    core::write_file_atomic(file, cache.dump(2) + "\n");
  } catch (const std::exception& e) {
    where = std::string("not cached: ") + e.what();
  }
  return {choose_precision(m), measured_note(m, choose_precision(m), where)};
}

std::filesystem::path precision_cache_file() {
  if (const char* dir = std::getenv("SCOUT_CACHE_DIR"); dir != nullptr && *dir != '\0')
    return std::filesystem::path(dir) / "precision.json";
  if (const char* dir = std::getenv("XDG_CACHE_HOME"); dir != nullptr && *dir != '\0')
    return std::filesystem::path(dir) / "scout" / "precision.json";
  const char* home = std::getenv("HOME");
  return std::filesystem::path(home != nullptr && *home != '\0' ? home : "/tmp") / ".cache" / "scout" /
         "precision.json";
}

PrecisionChoice auto_precision() {
  const agent::NativeBf16 cpu = agent::native_bf16();
  if (!cpu.any()) return {agent::Precision::Float32, agent::fp32_without_native_bf16_note()};
  static std::mutex mutex;
  static std::map<std::string, PrecisionChoice> remembered;  // per key: a test may change the caps
  const std::string key = precision_cache_key();
  const std::lock_guard lock(mutex);
  const auto found = remembered.find(key);
  if (found != remembered.end()) return found->second;
  return remembered[key] = cached_or_measured_precision(precision_cache_file(), key);
}

agent::Precision resolve_precision(agent::Precision requested) {
  return requested == agent::Precision::Auto ? auto_precision().precision : requested;
}

}  // namespace scout::learn
