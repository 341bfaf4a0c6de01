// The local launcher of data-parallel commands: N copies of this very command, started with
// PyTorch's launcher variables, as `torchrun --nproc-per-node N` would start them.
#include "tools/group.hpp"

#include <fmt/format.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <thread>
#include <vector>

#include "core/process.hpp"
#include "tools/commands.hpp"
#include "tools/parsing.hpp"

namespace scout::tools {

namespace {

std::optional<int> rank_of_this_process;

// The command line without --nproc (the ranks must not launch again).
std::vector<std::string> rank_command(const std::vector<std::string>& argv) {
  std::vector<std::string> out;
  for (std::size_t i = 0; i < argv.size(); ++i) {
    if (argv[i] == "--nproc") {
      ++i;
      continue;
    }
    if (argv[i].rfind("--nproc=", 0) == 0) continue;
    out.push_back(argv[i]);
  }
  return out;
}

}  // namespace

void add_group_options(CLI::App& cmd, GroupFlags& flags) {
  cmd.add_option("--nproc", flags.nproc,
                 "Processes on this machine, each driving its share of every batch (data-parallel over c10d/Gloo); "
                 "on several machines start each process with RANK, WORLD_SIZE, MASTER_ADDR, MASTER_PORT instead")
      ->capture_default_str()
      ->check(decimal_in(1, 256));
  cmd.add_option("--timeout", flags.timeout_s,
                 "Seconds a process waits for the others (connecting, every all-reduce) before it stops with an error")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 86400.0));
  cmd.add_option("--interface", flags.interface,
                 "Network interface for the processes' traffic, e.g. eth0 (default: $GLOO_SOCKET_IFNAME, else the "
                 "one that reaches MASTER_ADDR)");
}

std::optional<learn::GroupOptions> group_from_flags(const GroupFlags& flags) {
  std::optional<learn::GroupOptions> group = learn::group_from_environment();
  if (!group) return std::nullopt;
  if (flags.nproc > 1)
    throw InputError(
        fmt::format("--nproc: this process is already rank {} of {} (RANK and WORLD_SIZE are set); "
                    "leave --nproc out when a launcher starts the processes",
                    group->rank, group->world_size));
  if (group->world_size == 1) return std::nullopt;
  group->timeout = std::chrono::milliseconds(static_cast<long>(flags.timeout_s * 1000));
  if (!flags.interface.empty()) group->interface = flags.interface;
  return group;
}

int threads_per_process(int requested) {
  if (requested > 0) return requested;
  const int cores = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  int local = 1;
  if (const char* v = std::getenv("LOCAL_WORLD_SIZE")) local = std::max(1, std::atoi(v));
  return std::max(1, cores / local);
}

void set_rank(int rank) { rank_of_this_process = rank; }
std::optional<int> current_rank() { return rank_of_this_process; }

std::optional<int> launch_local_group(const GroupFlags& flags, const Context& context) {
  if (flags.nproc <= 1) return std::nullopt;
  if (learn::group_from_environment())
    throw InputError("--nproc: RANK and WORLD_SIZE are set (a launcher started this process); leave --nproc out");
  int port = 0;
  try {
    port = core::free_loopback_port();  // rank 0 binds it moments later
  } catch (const InputError& e) {
    throw InputError(std::string("--nproc: ") + e.what());
  }
  const std::vector<std::string> command = rank_command(context.argv);
  // The parent blocks SIGINT/SIGTERM to take them synchronously and forward them; the children
  // start with the mask this process had before (posix_spawn sets it, nothing runs between fork
  // and exec).
  sigset_t forwarded, previous;
  sigemptyset(&forwarded);
  sigaddset(&forwarded, SIGINT);
  sigaddset(&forwarded, SIGTERM);
  sigprocmask(SIG_BLOCK, &forwarded, &previous);
  std::vector<pid_t> children;
  for (int rank = 0; rank < flags.nproc; ++rank) {
    const std::string r = std::to_string(rank), n = std::to_string(flags.nproc);
    try {
      children.push_back(core::spawn_child({.args = command,
                                            .executable = "/proc/self/exe",
                                            .environment = {{"RANK", r},
                                                            {"WORLD_SIZE", n},
                                                            {"LOCAL_RANK", r},
                                                            {"LOCAL_WORLD_SIZE", n},
                                                            {"MASTER_ADDR", "127.0.0.1"},
                                                            {"MASTER_PORT", std::to_string(port)}},
                                            .signal_mask = previous}));
    } catch (const InputError& e) {
      for (pid_t c : children) kill(c, SIGTERM);
      sigprocmask(SIG_SETMASK, &previous, nullptr);
      throw InputError(fmt::format("--nproc: rank {}: {}", rank, e.what()));
    }
  }
  std::vector<std::optional<int>> status(children.size());
  std::size_t running = children.size();
  const timespec tick{0, 100'000'000};
  while (running > 0) {
    siginfo_t info;
    if (sigtimedwait(&forwarded, &info, &tick) > 0)
      for (std::size_t r = 0; r < children.size(); ++r)
        if (!status[r]) kill(children[r], info.si_signo);
    int raw = 0;
    pid_t done;
    while ((done = waitpid(-1, &raw, WNOHANG)) > 0)
      for (std::size_t r = 0; r < children.size(); ++r)
        if (children[r] == done) {
          status[r] = WIFEXITED(raw) ? WEXITSTATUS(raw) : 128 + WTERMSIG(raw);
          --running;
          if (!WIFEXITED(raw)) std::fprintf(stderr, "scout: rank %zu was killed by signal %d\n", r, WTERMSIG(raw));
        }
  }
  sigprocmask(SIG_SETMASK, &previous, nullptr);
  if (*status[0] != 0) return *status[0];
  for (const std::optional<int>& s : status)
    if (*s != 0) return *s;
  return 0;
}

}  // namespace scout::tools
