#pragma once
// Data-parallel commands (scout train / eval --nproc N): the options that say how a process
// joins its group, and the local launcher that starts N processes of the same command.
#include <optional>
#include <string>

#include "learn/distributed.hpp"

namespace CLI {
class App;
}

namespace scout::tools {

struct Context;

struct GroupFlags {
  int nproc = 1;          ///< processes to start on this machine (1: this one alone)
  double timeout_s = 60;  ///< bound on connecting and on every collective
  std::string interface;  ///< network interface (overrides GLOO_SOCKET_IFNAME)
};
/// Adds --nproc, --timeout and --interface to a command.
void add_group_options(CLI::App& cmd, GroupFlags& flags);

/// With --nproc N > 1 in a process that is not itself a rank (no RANK in the environment):
/// starts ranks 0..N-1 as copies of this command on 127.0.0.1 with a free MASTER_PORT, forwards
/// Ctrl-C and SIGTERM to them, waits for all, and returns the exit status (rank 0's if it failed,
/// else the first failing rank's). nullopt: this process runs the command itself.
std::optional<int> launch_local_group(const GroupFlags& flags, const Context& context);

/// This process's place in a group: from the launcher's variables (RANK, WORLD_SIZE,
/// MASTER_ADDR, MASTER_PORT, GLOO_SOCKET_IFNAME) with the flags' timeout and interface. nullopt
/// when it runs alone (no RANK, or WORLD_SIZE 1).
std::optional<learn::GroupOptions> group_from_flags(const GroupFlags& flags);

/// LibTorch threads for this process: `requested` if non-zero, else the cores divided among
/// the group's processes on this machine (LOCAL_WORLD_SIZE, set by the launcher and torchrun).
int threads_per_process(int requested);

/// Errors of a group member are printed with its rank ("scout: rank 1: error: ..."); only rank 0
/// prints anything else.
void set_rank(int rank);
std::optional<int> current_rank();

}  // namespace scout::tools
