#include "arthrosim/core/parallel.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace arthrosim {
namespace {

// A persistent pool: threads are started once (SetThreadCount) and wait for work, so a
// ParallelFor costs a wake-up, not thread creation (which took longer than a typical loop of a
// 2 ms step), and the workers' thread_local scratch survives from call to call.
class Pool {
 public:
  ~Pool() { Resize(0); }

  // Number of workers besides the calling thread.
  int Size() const { return static_cast<int>(workers_.size()); }

  void Resize(int workers) {
    if (workers == Size()) return;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_.store(true);
    }
    wake_.notify_all();
    for (std::thread& t : workers_) t.join();
    workers_.clear();
    stop_.store(false);
    for (int i = 0; i < workers; ++i) workers_.emplace_back([this] { Work(); });
  }

  // Runs blocks [0, blocks) on the calling thread and `helpers` workers; returns when all are
  // done. Rethrows the first exception a block threw.
  using BlockFn = void (*)(void* context, std::int64_t block);
  void Run(std::int64_t blocks, int helpers, BlockFn fn, void* context) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      fn_ = fn;
      context_ = context;
      blocks_ = blocks;
      next_.store(0);
      helpers_wanted_ = helpers;
      helpers_started_ = 0;
      helpers_done_.store(0);
      error_ = nullptr;
      generation_.fetch_add(1);
    }
    wake_.notify_all();
    Claim();
    // Helpers finish within microseconds of the last block: spin briefly before sleeping.
    for (int i = 0; i < kSpins && helpers_done_.load() != helpers_wanted_; ++i) Pause();
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [&] { return helpers_done_.load() == helpers_wanted_; });
    fn_ = nullptr;
    if (error_) std::rethrow_exception(error_);
  }

 private:
  void Claim() {
    for (std::int64_t b = next_++; b < blocks_; b = next_++) {
      try {
        fn_(context_, b);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!error_) error_ = std::current_exception();
        next_.store(blocks_);  // stop handing out blocks
      }
    }
  }

  void Work() {
    std::uint64_t seen = 0;
    for (;;) {
      // A step runs dozens of loops back to back: spin a little (~0.1 ms) for the next one
      // before sleeping, since a wake-up from sleep costs tens of microseconds.
      for (int i = 0; i < kSpins && generation_.load() == seen && !stop_.load(); ++i) Pause();
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stop_.load() || generation_.load() != seen; });
      if (stop_.load()) return;
      seen = generation_.load();
      if (helpers_started_ >= helpers_wanted_) continue;  // enough helpers for this loop
      ++helpers_started_;
      lock.unlock();
      Claim();
      lock.lock();
      if (helpers_done_.fetch_add(1) + 1 == helpers_wanted_) done_.notify_one();
    }
  }

  static void Pause() {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
  }
  static constexpr int kSpins = 2000;

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t> generation_{0};
  BlockFn fn_ = nullptr;
  void* context_ = nullptr;
  std::int64_t blocks_ = 0;
  std::atomic<std::int64_t> next_{0};
  int helpers_wanted_ = 0, helpers_started_ = 0;
  std::atomic<int> helpers_done_{0};
  std::exception_ptr error_;
};

int g_threads = 1;
thread_local bool t_in_parallel = false;  // nested loops run inline (no deadlock, same result)

Pool& GlobalPool() {
  static Pool pool;
  return pool;
}

}  // namespace

void SetThreadCount(int threads) {
  g_threads = std::max(1, threads);
  GlobalPool().Resize(g_threads - 1);
}

int ThreadCount() { return g_threads; }

void ParallelFor(std::int64_t n, std::int64_t block, BlockBody body) {
  if (n <= 0) return;
  block = std::max<std::int64_t>(1, block);
  const std::int64_t blocks = (n + block - 1) / block;
  auto run_block = [&](std::int64_t b) { body(b * block, std::min(n, (b + 1) * block)); };
  const int workers = static_cast<int>(std::min<std::int64_t>(g_threads, blocks));
  if (workers <= 1 || t_in_parallel) {
    for (std::int64_t b = 0; b < blocks; ++b) run_block(b);
    return;
  }
  // Blocks are claimed dynamically, but a block's result never depends on who runs it.
  struct Flag {
    Flag() { t_in_parallel = true; }
    ~Flag() { t_in_parallel = false; }
  } flag;
  GlobalPool().Run(
      blocks, workers - 1,
      [](void* context, std::int64_t b) {
        t_in_parallel = true;
        (*static_cast<decltype(run_block)*>(context))(b);
      },
      &run_block);
}

}  // namespace arthrosim
