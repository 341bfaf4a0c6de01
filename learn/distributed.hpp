#pragma once
/// Data-parallel training and evaluation over several processes and machines: a process group
/// on LibTorch's c10d with Gloo and a TCP store (the master, rank 0, hosts the store). Every
/// collective is bounded by one timeout, so a lost process or a rank that never arrives ends the
/// run with one line instead of a hang. Torch-free: the CLI includes this header.
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "core/error.hpp"

namespace scout::learn {

/// Where a process stands in a group and how it reaches the others.
struct GroupOptions {
  int rank = 0;
  int world_size = 1;
  std::string master_addr = "127.0.0.1";  ///< host of rank 0's TCP store
  int master_port = 29500;
  /// Network interface Gloo's sockets use (e.g. eth0). Empty: the address that routes to the
  /// master (127.0.0.1 on one machine), never the host name's (127.0.1.1 on Debian).
  std::string interface;
  /// Bound on connecting, on the store and on every collective (Gloo's own default is 30 min).
  std::chrono::milliseconds timeout{std::chrono::seconds(60)};
};

/// The launcher's variables (PyTorch's names): RANK, WORLD_SIZE, MASTER_ADDR, MASTER_PORT, and
/// GLOO_SOCKET_IFNAME for the interface. nullopt when RANK and WORLD_SIZE are both unset; throws
/// InputError naming the variable for a malformed or contradictory value.
std::optional<GroupOptions> group_from_environment();

/// Rank `rank`'s contiguous share [first, end) of `count` items split over `ranks` processes
/// (shares differ by at most one; a lone process gets them all).
inline std::pair<int, int> share_of(int count, int rank, int ranks) {
  const auto part = [&](int r) { return static_cast<int>(static_cast<long>(count) * r / ranks); };
  return {part(rank), part(rank + 1)};
}

/// A collective failed or did not finish within the timeout: one line for the user, naming the
/// lost rank where it can be told. An InputError: the CLI reports it as one line, exit status 1.
class GroupError : public InputError {
 public:
  using InputError::InputError;
};

/// Rank 0 could not start a run; it reports why itself, so the other ranks stay quiet.
class LeaderFailed : public GroupError {
 public:
  using GroupError::GroupError;
};

/// Time spent in collectives (benchmarks).
struct CollectiveTiming {
  double all_reduce_s = 0;
  long all_reduces = 0;
  double all_reduce_bytes = 0;
};

/// A process group (Gloo over TCP). Every member calls the same collectives in the same order.
class ProcessGroup {
 public:
  /// Joins the group: rank 0 opens the store on master_port, the others connect to it; returns
  /// once all world_size processes are connected. Throws GroupError within the timeout.
  static std::unique_ptr<ProcessGroup> connect(const GroupOptions& options);
  ~ProcessGroup();
  ProcessGroup(const ProcessGroup&) = delete;
  ProcessGroup& operator=(const ProcessGroup&) = delete;

  int rank() const;
  int size() const;
  const GroupOptions& options() const;

  /// Element-wise sum over the ranks, in place; every rank gets the same bits.
  void all_reduce_sum(std::span<float> values);
  void all_reduce_sum(std::span<double> values);
  /// Rank 0's bytes, on every rank (`bytes` is resized on the others).
  void broadcast(std::string& bytes);
  /// Every rank's `bytes` (all the same length), in rank order.
  std::vector<std::string> all_gather(const std::string& bytes);

  const CollectiveTiming& timing() const;
  void reset_timing();

 private:
  struct Impl;
  explicit ProcessGroup(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace scout::learn
