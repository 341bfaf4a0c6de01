#pragma once
/// A small pool of worker threads for data-parallel loops over robots. Workers sleep on a
/// condition variable between loops (no spinning: on a 2-core machine that also runs other work,
/// spinning threads steal the time slices the loop needs), and take chunks of the index range
/// from a shared counter, so a core taken away by other work does not stall the loop.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace scout::sim {

class WorkerPool {
 public:
  /// `threads` in all, the calling thread included; 0 means one per hardware thread.
  explicit WorkerPool(int threads = 0);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int threads() const { return static_cast<int>(workers_.size()) + 1; }

  /// Calls body(i) for every i in [0, n), in chunks of `chunk`, on all threads; returns when all
  /// are done. The body must not throw.
  void parallel_for(int n, int chunk, const std::function<void(int)>& body);

 private:
  void work();
  void run_chunks();

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable done_;
  std::uint64_t generation_ = 0;   // bumped for each loop; workers wait for a new one
  int busy_ = 0;                   // workers still in the current loop
  bool stop_ = false;
  const std::function<void(int)>* body_ = nullptr;
  int n_ = 0;
  int chunk_ = 1;
  std::atomic<int> next_{0};
};

}  // namespace scout::sim
