#include "arthrosim/core/parallel.h"

#include <algorithm>
#include <atomic>
#include <thread>
#include <vector>

namespace arthrosim {
namespace {
int g_threads = 1;
}  // namespace

void SetThreadCount(int threads) { g_threads = std::max(1, threads); }
int ThreadCount() { return g_threads; }

void ParallelFor(std::int64_t n, std::int64_t block, BlockBody body) {
  if (n <= 0) return;
  block = std::max<std::int64_t>(1, block);
  const std::int64_t blocks = (n + block - 1) / block;
  auto run_block = [&](std::int64_t b) { body(b * block, std::min(n, (b + 1) * block)); };
  const int workers = static_cast<int>(std::min<std::int64_t>(g_threads, blocks));
  if (workers <= 1) {
    for (std::int64_t b = 0; b < blocks; ++b) run_block(b);
    return;
  }
  // Blocks are claimed dynamically, but a block's result never depends on who runs it.
  std::atomic<std::int64_t> next{0};
  auto worker = [&] {
    for (std::int64_t b = next++; b < blocks; b = next++) run_block(b);
  };
  std::vector<std::thread> pool;
  pool.reserve(static_cast<std::size_t>(workers - 1));
  for (int t = 1; t < workers; ++t) pool.emplace_back(worker);
  worker();
  for (std::thread& t : pool) t.join();
}

}  // namespace arthrosim
