#include "arthrosim/core/parallel.h"

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace arthrosim
