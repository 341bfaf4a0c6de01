// The process group: c10d's ProcessGroupGloo over a TCPStore hosted by rank 0. What c10d
// leaves to the caller is done here: choosing the network interface (LibTorch's C++ side does
// not read GLOO_SOCKET_IFNAME), one timeout for everything, and naming the lost rank when a
// collective fails.
#include "learn/distributed.hpp"

#ifndef USE_C10D_GLOO  // LibTorch's CMake target defines it; ProcessGroupGloo.hpp needs it
#define USE_C10D_GLOO
#endif
#include <arpa/inet.h>
#include <fmt/format.h>
#include <netdb.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <torch/torch.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <future>
#include <memory>
#include <thread>
#include <torch/csrc/distributed/c10d/PrefixStore.hpp>
#include <torch/csrc/distributed/c10d/ProcessGroupGloo.hpp>
#include <torch/csrc/distributed/c10d/TCPStore.hpp>
#ifdef C10_USE_GLOG  // Debian's LibTorch logs through glog; the wheel's through c10's own logger
#include <glog/logging.h>
#endif

#include "core/error.hpp"
#include "core/timing.hpp"

namespace scout::learn {

namespace {

using std::chrono::milliseconds;

std::string seconds_text(milliseconds t) { return fmt::format("{:g} s", static_cast<double>(t.count()) / 1000); }

std::optional<std::string> env(const char* name) {
  const char* v = std::getenv(name);
  if (!v) return std::nullopt;
  return std::string(v);
}

int parse_env_int(const char* name, const std::string& text, int lo, int hi, const std::string& what) {
  const std::string expected = fmt::format("{}: expected {}, got '{}'", name, what, one_line(text));
  if (text.empty() || text.size() > 9 || text.find_first_not_of("0123456789") != std::string::npos)
    throw InputError(expected);
  const int v = std::stoi(text);
  if (v < lo || v > hi) throw InputError(expected);
  return v;
}

// The local IPv4 address whose route reaches `host`: a UDP socket's connect() picks the route
// without sending anything.
std::string address_towards(const std::string& host, int port) {
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_DGRAM;
  addrinfo* found = nullptr;
  if (getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &found) != 0 || !found)
    throw GroupError(fmt::format("MASTER_ADDR: cannot resolve '{}' to an IPv4 address", one_line(host)));
  const int fd = socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in local{};
  socklen_t length = sizeof(local);
  const bool ok = fd >= 0 && connect(fd, found->ai_addr, found->ai_addrlen) == 0 &&
                  getsockname(fd, reinterpret_cast<sockaddr*>(&local), &length) == 0;
  freeaddrinfo(found);
  if (fd >= 0) close(fd);
  if (!ok) throw GroupError(fmt::format("MASTER_ADDR: no route from this machine to '{}'", one_line(host)));
  char text[INET_ADDRSTRLEN] = {};
  inet_ntop(AF_INET, &local.sin_addr, text, sizeof(text));
  return text;
}

}  // namespace

std::optional<GroupOptions> group_from_environment() {
  const auto rank = env("RANK"), size = env("WORLD_SIZE");
  if (!rank && !size) return std::nullopt;
  if (!rank || !size)
    throw InputError(std::string(rank ? "WORLD_SIZE" : "RANK") + ": must be set together with " +
                     (rank ? "RANK" : "WORLD_SIZE") + " (PyTorch's launcher variables)");
  GroupOptions o;
  o.world_size = parse_env_int("WORLD_SIZE", *size, 1, 4096, "a process count in 1..4096");
  o.rank = parse_env_int("RANK", *rank, 0, o.world_size - 1,
                         fmt::format("an integer in 0..{} (WORLD_SIZE is {})", o.world_size - 1, o.world_size));
  if (const auto addr = env("MASTER_ADDR")) {
    if (addr->empty()) throw InputError("MASTER_ADDR: expected rank 0's host name or address, got an empty value");
    o.master_addr = *addr;
  }
  if (const auto port = env("MASTER_PORT")) o.master_port = parse_env_int("MASTER_PORT", *port, 1, 65535, "a port");
  if (const auto iface = env("GLOO_SOCKET_IFNAME")) o.interface = *iface;
  return o;
}

struct ProcessGroup::Impl {
  GroupOptions options;
  c10::intrusive_ptr<c10d::Store> store;
  c10::intrusive_ptr<c10d::ProcessGroupGloo> group;
  CollectiveTiming timing;

  // Which ranks still answer: each survivor of a failed collective says so in the store and
  // waits a little for the others. A rank that cannot reach the store has lost rank 0, its host.
  // The store's client has no time limit of its own on set() and check(): where a host's link went
  // down, its recv() would wait forever (no reset ever arrives). So the question is asked on a
  // thread of its own, which holds the store alive, and given up after the same bound plus a
  // second: rank 0, the store's host, is then the lost one. The thread is left behind, blocked,
  // in a process that is about to report the error and exit.
  std::vector<int> lost_ranks() {
    const milliseconds bound = std::min<milliseconds>(options.timeout, std::chrono::seconds(10));
    auto answer = std::make_shared<std::promise<std::vector<int>>>();
    std::future<std::vector<int>> silent_ranks = answer->get_future();
    std::thread([store = store, rank = options.rank, world_size = options.world_size, bound, answer] {
      try {
        store->set(fmt::format("scout/alive/{}", rank), std::vector<std::uint8_t>{1});
        const auto deadline = core::Clock::now() + bound;
        std::vector<int> silent;
        while (true) {
          silent.clear();
          for (int r = 0; r < world_size; ++r)
            if (!store->check({fmt::format("scout/alive/{}", r)})) silent.push_back(r);
          if (silent.empty() || core::Clock::now() > deadline) break;
          std::this_thread::sleep_for(milliseconds(50));
        }
        answer->set_value(silent);
      } catch (const std::exception&) {
        answer->set_value({0});
      }
    }).detach();
    if (silent_ranks.wait_for(bound + std::chrono::seconds(1)) == std::future_status::ready) return silent_ranks.get();
    return {0};
  }

  [[noreturn]] void fail(const char* collective, const std::exception& e) {
    const std::string cause = first_line(e.what());
    const std::vector<int> lost = options.world_size > 1 ? lost_ranks() : std::vector<int>{};
    if (lost.empty())
      throw GroupError(fmt::format("the {} across {} processes failed: {}", collective, options.world_size, cause));
    throw GroupError(fmt::format("rank {} was lost (no answer within {}; {} failed: {})", fmt::join(lost, ", rank "),
                                 seconds_text(options.timeout), collective, cause));
  }

  void wait(const std::function<c10::intrusive_ptr<c10d::Work>()>& start, const char* collective) {
    try {
      start()->wait();
    } catch (const std::exception& e) {
      fail(collective, e);
    }
  }

  // Every collective passes tensors that wrap Scout's own memory and reads its result from that
  // memory, never from a tensor after the collective: Gloo's worker thread inside LibTorch may
  // drop the last reference to a tensor and free it after Scout is woken, which is safe (atomic
  // reference counts) but invisible to ThreadSanitizer, for which LibTorch is not instrumented.
  void all_reduce(torch::Tensor t) {
    const auto t0 = core::Clock::now();
    const auto bytes = static_cast<double>(t.nbytes());
    std::vector<torch::Tensor> tensors{std::move(t)};
    wait([&] { return group->allreduce(tensors); }, "all-reduce");
    timing.all_reduce_s += core::seconds_since(t0);
    timing.all_reduces += 1;
    timing.all_reduce_bytes += bytes;
  }
};

ProcessGroup::ProcessGroup(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ProcessGroup::~ProcessGroup() = default;

std::unique_ptr<ProcessGroup> ProcessGroup::connect(const GroupOptions& options) {
  if (options.world_size < 1 || options.rank < 0 || options.rank >= options.world_size)
    throw std::invalid_argument(fmt::format("ProcessGroup: rank {} of {}", options.rank, options.world_size));
    // c10d logs its errors to stderr; Scout reports each failure as one line.
#ifdef C10_USE_GLOG
  FLAGS_minloglevel = google::GLOG_FATAL;
#else
  FLAGS_caffe2_log_level = c10::GLOG_FATAL;
#endif
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  const std::string where = fmt::format("{}:{}", options.master_addr, options.master_port);
  c10d::TCPStoreOptions store_options;
  store_options.port = static_cast<std::uint16_t>(options.master_port);
  store_options.isServer = options.rank == 0;
  store_options.numWorkers = options.world_size;
  store_options.waitWorkers = true;
  store_options.timeout = options.timeout;
  // Rank 0 cannot tell a rank that never started from one given another address or port.
  const std::string not_all = fmt::format(
      "the {} processes did not all arrive at {} within {} (a rank never started, or was given another "
      "MASTER_ADDR or MASTER_PORT)",
      options.world_size, where, seconds_text(options.timeout));
  try {
    impl->store = c10::make_intrusive<c10d::TCPStore>(options.master_addr, store_options);
  } catch (const std::exception& e) {
    if (options.rank == 0) throw GroupError(not_all + ": " + first_line(e.what()));
    throw GroupError(
        fmt::format("cannot reach rank 0's store at {} within {} (is rank 0 running, with the same MASTER_ADDR and "
                    "MASTER_PORT?): {}",
                    where, seconds_text(options.timeout), first_line(e.what())));
  }
  try {
    auto gloo_options = c10d::ProcessGroupGloo::Options::create(options.timeout);
    const std::string local =
        options.interface.empty() ? address_towards(options.master_addr, options.master_port) : "";
    gloo_options->devices = {options.interface.empty()
                                 ? c10d::ProcessGroupGloo::createDeviceForHostname(local)
                                 : c10d::ProcessGroupGloo::createDeviceForInterface(options.interface)};
    gloo_options->threads = 1;  // one collective at a time: the training step waits for it
    impl->group = c10::make_intrusive<c10d::ProcessGroupGloo>(
        c10::make_intrusive<c10d::PrefixStore>("gloo", impl->store), options.rank, options.world_size, gloo_options);
  } catch (const GroupError&) {
    throw;
  } catch (const std::exception& e) {
    throw GroupError(not_all + (options.interface.empty() ? "" : " on interface " + options.interface) + ": " +
                     first_line(e.what()));
  }
  return std::unique_ptr<ProcessGroup>(new ProcessGroup(std::move(impl)));
}

int ProcessGroup::rank() const { return impl_->options.rank; }
int ProcessGroup::size() const { return impl_->options.world_size; }
const GroupOptions& ProcessGroup::options() const { return impl_->options; }

void ProcessGroup::all_reduce_sum(std::span<float> values) {
  if (size() == 1 || values.empty()) return;
  impl_->all_reduce(torch::from_blob(values.data(), {static_cast<long>(values.size())}, torch::kFloat32));
}

void ProcessGroup::all_reduce_sum(std::span<double> values) {
  if (size() == 1 || values.empty()) return;
  impl_->all_reduce(torch::from_blob(values.data(), {static_cast<long>(values.size())}, torch::kFloat64));
}

void ProcessGroup::broadcast(std::string& bytes) {
  if (size() == 1) return;
  std::int64_t size = static_cast<std::int64_t>(bytes.size());
  std::vector<torch::Tensor> length{torch::from_blob(&size, {1}, torch::kInt64)};
  impl_->wait([&] { return impl_->group->broadcast(length); }, "broadcast");
  bytes.resize(static_cast<std::size_t>(size));
  if (bytes.empty()) return;
  std::vector<torch::Tensor> data{torch::from_blob(bytes.data(), {static_cast<long>(bytes.size())}, torch::kUInt8)};
  impl_->wait([&] { return impl_->group->broadcast(data); }, "broadcast");
}

std::vector<std::string> ProcessGroup::all_gather(const std::string& bytes) {
  if (size() == 1) return {bytes};
  std::string mine = bytes;
  std::vector<torch::Tensor> input{torch::from_blob(mine.data(), {static_cast<long>(mine.size())}, torch::kUInt8)};
  std::vector<std::string> all(static_cast<std::size_t>(size()), std::string(mine.size(), '\0'));
  std::vector<std::vector<torch::Tensor>> output(1);
  for (std::string& r : all)
    output[0].push_back(torch::from_blob(r.data(), {static_cast<long>(r.size())}, torch::kUInt8));
  impl_->wait([&] { return impl_->group->allgather(output, input); }, "all-gather");
  return all;
}

const CollectiveTiming& ProcessGroup::timing() const { return impl_->timing; }
void ProcessGroup::reset_timing() { impl_->timing = {}; }

}  // namespace scout::learn
