#pragma once
/// How much memory a request may take, before it takes it: the memory this process can still
/// use (the smaller of the kernel's MemAvailable and what its cgroup's limit leaves), a check
/// that refuses an estimate beyond it with one line, and the process's peak resident size for
/// benchmarks.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

namespace scout::core {

/// The memory left to this process and what bounds it.
struct AvailableMemory {
  std::uint64_t bytes = 0;
  std::string bound;  ///< "MemAvailable", "the cgroup limit (memory.max)", or "SCOUT_MEMORY_LIMIT"
};

/// The smallest of: /proc/meminfo's MemAvailable; for each cgroup from this process's up to the
/// root, its limit less its usage (v2: memory.max - memory.current; v1: memory.limit_in_bytes -
/// memory.usage_in_bytes); and $SCOUT_MEMORY_LIMIT (bytes, or with a K, M or G suffix: a cap a
/// user sets on a shared machine). Nullopt when none can be read. `proc` and `cgroup_root` are
/// /proc and /sys/fs/cgroup outside tests.
std::optional<AvailableMemory> available_memory(const std::filesystem::path& proc = "/proc",
                                                const std::filesystem::path& cgroup_root = "/sys/fs/cgroup");

/// Refuses a request whose estimate exceeds the available memory, unless `force`: throws
/// InputError "WHAT needs about 41.3 GiB of memory, 22.5 GiB is available (MemAvailable); ask for
/// less, or give --force to try anyway" (`force_hint`: how the caller's user forces it). Does
/// nothing when the available memory is unknown.
void check_memory(std::uint64_t estimate_bytes, const std::string& what, bool force,
                  const std::string& force_hint = "give --force");

/// The peak resident set size of this process so far (VmHWM), in bytes; 0 when unknown.
std::uint64_t peak_resident_bytes();

/// Makes the C allocator keep freed blocks for reuse instead of returning them to the kernel. A
/// training or evaluation step allocates and frees tensors of tens of MiB hundreds of times; by
/// default glibc maps each from the kernel and unmaps it when freed, so every step pays for
/// zeroing fresh pages again: measured, a quarter of a training step's time in page faults, and
/// modes (i) and (ii) twice as fast without them. The price is that the process keeps its peak heap
/// (up to 2 GiB more) for its lifetime, which a training or evaluation process reaches again at
/// every step anyway.
/// Call once, at the start of a process that runs the networks; the environment's MALLOC_*
/// settings are left as they are when any is set. No effect under a sanitizer's allocator.
void keep_freed_memory_for_reuse();

/// "512 KiB", "3.2 MiB", "41.3 GiB".
std::string format_bytes(std::uint64_t bytes);

}  // namespace scout::core
