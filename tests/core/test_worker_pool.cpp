// The worker pool under the robot batch and the env: every index once, any thread count, errors carried home.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>
#include <vector>

#include "core/worker_pool.hpp"

namespace scout::core {
namespace {

TEST(WorkerPool, CallsEveryIndexExactlyOnce) {
  for (int threads : {1, 2, 3}) {
    WorkerPool pool(threads);
    EXPECT_EQ(pool.threads(), threads);
    for (int n : {0, 1, 7, 8, 9, 240, 1001}) {
      std::vector<std::atomic<int>> calls(static_cast<std::size_t>(n));
      pool.parallel_for(n, 8, [&](int i) { calls[i].fetch_add(1); });
      for (int i = 0; i < n; ++i) ASSERT_EQ(calls[i].load(), 1) << "n " << n << " index " << i;
    }
  }
}

TEST(WorkerPool, RethrowsTheErrorAfterAllThreadsStopped) {
  WorkerPool pool(2);
  std::atomic<int> done{0};  // the failed loop's calls that returned
  EXPECT_THROW(pool.parallel_for(1000, 4,
                                 [&](int i) {
                                   if (i == 500) throw std::runtime_error("robot 500");
                                   std::this_thread::sleep_for(std::chrono::microseconds(50));
                                   done.fetch_add(1);
                                 }),
               std::runtime_error);
  // Stopped means stopped: no call of the failed loop still runs once the error is home, so the
  // count it left stays what it was (and index 500 never counted).
  const int at_rethrow = done.load();
  EXPECT_LE(at_rethrow, 999);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(done.load(), at_rethrow) << "a call of the failed loop ran after parallel_for threw";
  // The pool is still usable, and the failed loop's error does not leak into the next one.
  std::atomic<int> count{0};
  pool.parallel_for(100, 4, [&](int) { count.fetch_add(1); });
  EXPECT_EQ(count.load(), 100);
  EXPECT_EQ(done.load(), at_rethrow);
}

}  // namespace
}  // namespace scout::core
