#include "core/worker_pool.hpp"

#include <algorithm>

namespace scout::core {

WorkerPool::WorkerPool(int threads) {
  if (threads <= 0) threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  for (int i = 1; i < threads; ++i) workers_.emplace_back([this] { work(); });
}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  for (std::thread& t : workers_) t.join();
}

void WorkerPool::run_chunks() {
  try {
    for (;;) {
      const int first = next_.fetch_add(chunk_, std::memory_order_relaxed);
      if (first >= n_) return;
      const int last = std::min(first + chunk_, n_);
      for (int i = first; i < last; ++i) call_(context_, i);
    }
  } catch (...) {
    // Keep the first error and let the other threads run out of work quickly.
    next_.store(n_, std::memory_order_relaxed);
    std::lock_guard lock(mutex_);
    if (!error_) error_ = std::current_exception();
  }
}

void WorkerPool::work() {
  std::uint64_t seen = 0;
  for (;;) {
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
    }
    run_chunks();
    {
      std::lock_guard lock(mutex_);
      if (--busy_ == 0) done_.notify_one();
    }
  }
}

void WorkerPool::run(int n, int chunk, void* context, Trampoline call) {
  if (n <= 0) return;
  if (workers_.empty() || n <= chunk) {
    for (int i = 0; i < n; ++i) call(context, i);
    return;
  }
  {
    std::lock_guard lock(mutex_);
    context_ = context;
    call_ = call;
    n_ = n;
    chunk_ = std::max(1, chunk);
    next_.store(0, std::memory_order_relaxed);
    busy_ = static_cast<int>(workers_.size());
    error_ = nullptr;
    ++generation_;
  }
  wake_.notify_all();
  run_chunks();
  std::exception_ptr error;
  {
    std::unique_lock lock(mutex_);
    done_.wait(lock, [&] { return busy_ == 0; });
    context_ = nullptr;
    std::swap(error, error_);
  }
  if (error) std::rethrow_exception(error);
}

}  // namespace scout::core
