#pragma once
/// A small pool of worker threads for data-parallel loops over robots (the physics in sim/, the
/// observations in env/ share one). Workers sleep on a
/// condition variable between loops (no spinning: on a 2-core machine that also runs other work,
/// spinning threads steal the time slices the loop needs), and take chunks of the index range
/// from a shared counter, so a core taken away by other work does not stall the loop.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <mutex>
#include <thread>
#include <type_traits>
#include <vector>

namespace scout::core {

class WorkerPool {
 public:
  /// `threads` in all, the calling thread included; 0 means one per hardware thread.
  explicit WorkerPool(int threads = 0);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int threads() const { return static_cast<int>(workers_.size()) + 1; }

  /// Calls body(i) for every i in [0, n), in chunks of `chunk`, on all threads; returns when all
  /// are done. One loop at a time: a pool shared by several owners is called from one thread,
  /// never from inside a body. If a call throws, the loop still waits for every thread, then rethrows the first
  /// exception. No allocation: the body is called through a plain function pointer.
  template <typename Body>
  void parallel_for(int n, int chunk, Body&& body) {
    run(n, chunk, &body, [](void* context, int i) { (*static_cast<std::remove_reference_t<Body>*>(context))(i); });
  }

 private:
  using Trampoline = void (*)(void* context, int i);
  void run(int n, int chunk, void* context, Trampoline call);
  void work();
  void run_chunks();

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable done_;
  std::uint64_t generation_ = 0;  // bumped for each loop; workers wait for a new one
  int busy_ = 0;                  // workers still in the current loop
  bool stop_ = false;
  void* context_ = nullptr;
  Trampoline call_ = nullptr;
  int n_ = 0;
  int chunk_ = 1;
  std::atomic<int> next_{0};
  std::exception_ptr error_;  // the first exception of the current loop
};

}  // namespace scout::core
