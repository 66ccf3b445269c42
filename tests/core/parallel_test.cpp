#include "arthrosim/core/parallel.h"

#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <vector>

namespace arthrosim {
namespace {

TEST(ParallelForTest, CoversEveryItemOnceForAnyThreadCount) {
  for (int threads : {1, 2, 3, 8}) {
    SetThreadCount(threads);
    std::vector<int> hits(1001, 0);
    ParallelFor(1001, 64, [&](std::int64_t b, std::int64_t e) {
      for (std::int64_t i = b; i < e; ++i) hits[i] += 1;
    });
    for (int h : hits) ASSERT_EQ(h, 1) << "threads=" << threads;
  }
  SetThreadCount(1);
}

// The pool is reused from call to call: many short loops in a row (a step has dozens), with
// the thread count changed in between, never hang and always cover every item once.
TEST(ParallelForTest, ManyShortLoopsReuseThePool) {
  for (int threads : {2, 3, 2}) {
    SetThreadCount(threads);
    std::vector<int> hits(17, 0);
    for (int call = 0; call < 3000; ++call) {
      ParallelFor(17, 4, [&](std::int64_t b, std::int64_t e) {
        for (std::int64_t i = b; i < e; ++i) hits[i] += 1;
      });
    }
    for (int h : hits) ASSERT_EQ(h, 3000) << "threads=" << threads;
  }
  SetThreadCount(1);
}

// A loop inside a loop body runs inline on that thread (no deadlock on the shared pool).
TEST(ParallelForTest, NestedLoopsRunInline) {
  SetThreadCount(2);
  std::vector<std::atomic<int>> hits(8 * 50);
  ParallelFor(8, 1, [&](std::int64_t b, std::int64_t) {
    ParallelFor(50, 7, [&](std::int64_t ib, std::int64_t ie) {
      for (std::int64_t i = ib; i < ie; ++i) hits[b * 50 + i] += 1;
    });
  });
  for (const auto& h : hits) ASSERT_EQ(h.load(), 1);
  SetThreadCount(1);
}

// An exception thrown by a block reaches the caller, and the pool still works afterwards.
TEST(ParallelForTest, ExceptionReachesTheCaller) {
  SetThreadCount(2);
  EXPECT_THROW(ParallelFor(100, 1,
                           [&](std::int64_t b, std::int64_t) {
                             if (b == 37) throw std::runtime_error("block 37");
                           }),
               std::runtime_error);
  std::atomic<int> count{0};
  ParallelFor(100, 1, [&](std::int64_t, std::int64_t) { ++count; });
  EXPECT_EQ(count.load(), 100);
  SetThreadCount(1);
}

}  // namespace
}  // namespace arthrosim
