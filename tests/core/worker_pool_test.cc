// WorkerPool (core/worker_pool.h): every item once, on a worker in range, one
// item at a time per worker, exceptions rethrown, many Runs in a row.

#include "core/worker_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <vector>

namespace sweptccd {
namespace {

TEST(WorkerPoolTest, EveryItemOnceOnAWorkerInRange) {
  for (int threads : {1, 2, 5}) {
    WorkerPool pool(threads);
    EXPECT_EQ(pool.size(), threads);
    for (size_t count : {0u, 1u, 3u, 1000u}) {
      std::vector<std::atomic<int>> seen(count);
      std::vector<std::atomic<int>> busy(static_cast<size_t>(threads));
      std::atomic<bool> overlap{false}, bad_worker{false};
      pool.Run(count, [&](size_t i, int w) {
        if (w < 0 || w >= threads) {
          bad_worker = true;
          return;
        }
        if (busy[w]++ != 0) overlap = true;  // Per-worker state needs no lock.
        ++seen[i];
        --busy[w];
      });
      for (size_t i = 0; i < count; ++i) EXPECT_EQ(seen[i], 1) << i;
      EXPECT_FALSE(overlap);
      EXPECT_FALSE(bad_worker);
    }
  }
}

TEST(WorkerPoolTest, ExceptionsComeBackAndThePoolGoesOn) {
  WorkerPool pool(3);
  EXPECT_THROW(pool.Run(100,
                        [](size_t i, int) {
                          if (i == 37) throw std::runtime_error("item 37");
                        }),
               std::runtime_error);
  std::atomic<int> n{0};
  pool.Run(50, [&](size_t, int) { ++n; });
  EXPECT_EQ(n, 50);
  EXPECT_THROW(WorkerPool(0), std::invalid_argument);
  EXPECT_GE(DefaultThreadCount(), 1);
}

}  // namespace
}  // namespace sweptccd
