#include "core/memory.hpp"

#include <fmt/format.h>

#include <climits>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string_view>
#include <vector>

#include "core/error.hpp"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace scout::core {

void keep_freed_memory_for_reuse() {
  for (const char* variable : {"MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "MALLOC_TOP_PAD_"})
    if (std::getenv(variable) != nullptr) return;  // the user's own tuning wins
#if defined(__GLIBC__)
  // Blocks up to 1 GiB come from the heap (not mmap), and the heap's top is returned to the kernel
  // only beyond 2 GiB free (mallopt takes an int).
  mallopt(M_MMAP_THRESHOLD, 1 << 30);
  mallopt(M_TRIM_THRESHOLD, INT_MAX);
#endif
}

namespace fs = std::filesystem;

namespace {

constexpr std::uint64_t kNoLimit = std::uint64_t{1} << 60;  // cgroup v1 writes ~2^63 for "none"

std::optional<std::uint64_t> read_number(const fs::path& file) {
  std::ifstream in(file);
  std::string word;
  if (!(in >> word) || word.empty() || word.find_first_not_of("0123456789") != std::string::npos) return std::nullopt;
  try {
    return std::stoull(word);
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

// "12345 kB" after "MemAvailable:" in /proc/meminfo.
std::optional<std::uint64_t> mem_available(const fs::path& proc) {
  std::ifstream in(proc / "meminfo");
  std::string key, unit;
  std::uint64_t value = 0;
  while (in >> key >> value) {
    std::getline(in, unit);
    if (key == "MemAvailable:") return value * 1024;
  }
  return std::nullopt;
}

// The smallest headroom (limit less usage) of the cgroup folders from `leaf` up to `root`.
std::optional<std::uint64_t> cgroup_headroom(const fs::path& root, const fs::path& leaf, const char* limit_file,
                                             const char* usage_file) {
  std::optional<std::uint64_t> best;
  // `leaf` lies under `root` (both made from the same root): walk up to it, inclusive.
  for (fs::path dir = leaf.lexically_normal();; dir = dir.parent_path()) {
    const std::optional<std::uint64_t> limit = read_number(dir / limit_file);  // "max" reads as none
    if (limit && *limit < kNoLimit) {
      const std::uint64_t usage = read_number(dir / usage_file).value_or(0);
      const std::uint64_t headroom = usage < *limit ? *limit - usage : 0;
      if (!best || headroom < *best) best = headroom;
    }
    if (dir == root.lexically_normal() || dir.native().size() <= root.lexically_normal().native().size() ||
        dir.parent_path() == dir)
      break;
  }
  return best;
}

// This process's cgroup headroom, v2 ("0::/path") or v1's memory controller ("N:memory:/path").
std::optional<std::uint64_t> cgroup_available(const fs::path& proc, const fs::path& cgroup_root) {
  std::ifstream in(proc / "self/cgroup");
  std::optional<std::uint64_t> best;
  for (std::string line; std::getline(in, line);) {
    const std::size_t a = line.find(':'), b = line.find(':', a + 1);
    if (a == std::string::npos || b == std::string::npos) continue;
    const std::string controllers = line.substr(a + 1, b - a - 1);
    const fs::path relative = fs::path(line.substr(b + 1)).relative_path();
    std::optional<std::uint64_t> headroom;
    if (controllers.empty()) {
      headroom = cgroup_headroom(cgroup_root, cgroup_root / relative, "memory.max", "memory.current");
    } else if (controllers == "memory") {
      const fs::path v1 = cgroup_root / "memory";
      // Inside a container the controller's root is often the container's own cgroup, so the
      // host's path may not exist below it: then the root's own files are the container's.
      const fs::path leaf = fs::exists(v1 / relative) ? v1 / relative : v1;
      headroom = cgroup_headroom(v1, leaf, "memory.limit_in_bytes", "memory.usage_in_bytes");
    }
    if (headroom && (!best || *headroom < *best)) best = headroom;
  }
  return best;
}

// SCOUT_MEMORY_LIMIT: "8G", "512M", "123456". Anything else is an error of the user's.
std::optional<std::uint64_t> user_limit() {
  const char* text = std::getenv("SCOUT_MEMORY_LIMIT");
  if (!text || !*text) return std::nullopt;
  const std::string s(text);
  std::size_t used = 0;
  unsigned long long value = 0;
  try {
    value = std::stoull(s, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  std::uint64_t scale = 1;
  const std::string suffix = s.substr(used);
  if (suffix == "K" || suffix == "k")
    scale = 1024;
  else if (suffix == "M" || suffix == "m")
    scale = 1024 * 1024;
  else if (suffix == "G" || suffix == "g")
    scale = std::uint64_t{1} << 30;
  else if (!suffix.empty())
    used = 0;
  if (used == 0 || s[0] == '-')
    throw InputError("SCOUT_MEMORY_LIMIT: expected bytes, optionally with a K, M or G suffix (e.g. 8G), got '" +
                     one_line(s) + "'");
  return value * scale;
}

}  // namespace

std::optional<AvailableMemory> available_memory(const fs::path& proc, const fs::path& cgroup_root) {
  std::optional<AvailableMemory> out;
  const auto consider = [&](std::optional<std::uint64_t> bytes, const char* bound) {
    if (bytes && (!out || *bytes < out->bytes)) out = AvailableMemory{*bytes, bound};
  };
  consider(mem_available(proc), "MemAvailable");
  consider(cgroup_available(proc, cgroup_root), "the cgroup's memory limit");
  consider(user_limit(), "SCOUT_MEMORY_LIMIT");
  return out;
}

void check_memory(std::uint64_t estimate_bytes, const std::string& what, bool force, const std::string& force_hint) {
  if (force) return;
  const std::optional<AvailableMemory> available = available_memory();
  if (!available || estimate_bytes <= available->bytes) return;
  throw InputError(fmt::format("{} needs about {} of memory, {} is available ({}); ask for less, or {} to try anyway",
                               what, format_bytes(estimate_bytes), format_bytes(available->bytes), available->bound,
                               force_hint));
}

std::uint64_t peak_resident_bytes() {
  std::ifstream in("/proc/self/status");
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("VmHWM:", 0) != 0) continue;
    std::istringstream fields(line.substr(6));
    std::uint64_t kib = 0;
    if (fields >> kib) return kib * 1024;
  }
  return 0;
}

std::string format_bytes(std::uint64_t bytes) {
  constexpr const char* kUnits[] = {"bytes", "KiB", "MiB", "GiB", "TiB"};
  double value = static_cast<double>(bytes);
  int unit = 0;
  while (value >= 1024 && unit < 4) {
    value /= 1024;
    ++unit;
  }
  return unit == 0 ? fmt::format("{} bytes", bytes) : fmt::format("{:.1f} {}", value, kUnits[unit]);
}

}  // namespace scout::core
