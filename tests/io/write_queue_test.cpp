// The run writer's queue (src/io/write_queue.h): jobs run in the order queued, on a thread of
// their own when `background`, at once on the caller's otherwise; a job's error reaches the
// caller at the next call and stays.
#include "write_queue.h"

#include <gtest/gtest.h>

#include <condition_variable>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

namespace arthrosim::io::detail {
namespace {

struct Log {
  std::mutex mu;
  std::vector<int> order;
  std::vector<std::thread::id> threads;
  std::condition_variable cv;
  bool open = true;  // a job of kind Gate waits until open
};

struct Entry {
  Log* log;
  int id;
  bool gate = false;
  bool fail = false;
};

void Record(void* arg) {
  auto& e = *static_cast<Entry*>(arg);
  std::unique_lock<std::mutex> lock(e.log->mu);
  if (e.gate) e.log->cv.wait(lock, [&] { return e.log->open; });
  e.log->order.push_back(e.id);
  e.log->threads.push_back(std::this_thread::get_id());
  if (e.fail) throw std::runtime_error("job failed");
}

TEST(WriteQueue, BackgroundJobsRunInOrderOffTheCallersThread) {
  Log log;
  log.open = false;  // the first job blocks until the caller opens the gate
  std::vector<Entry> entries;
  entries.push_back({&log, 0, true});
  for (int i = 1; i < 100; ++i) entries.push_back({&log, i});
  WriteQueue q(true);
  // Queued while the first job is blocked: the caller never waits for a job to run.
  for (Entry& e : entries) q.Call(&Record, &e);
  {
    const std::lock_guard<std::mutex> lock(log.mu);
    EXPECT_TRUE(log.order.empty());
    log.open = true;
  }
  log.cv.notify_all();
  q.Drain();
  ASSERT_EQ(log.order.size(), entries.size());
  for (int i = 0; i < 100; ++i) EXPECT_EQ(log.order[static_cast<std::size_t>(i)], i);
  for (const std::thread::id& t : log.threads) EXPECT_NE(t, std::this_thread::get_id());
}

TEST(WriteQueue, ForegroundJobsRunAtOnceOnTheCallersThread) {
  Log log;
  Entry e{&log, 7};
  WriteQueue q(false);
  q.Call(&Record, &e);
  ASSERT_EQ(log.order.size(), 1u);  // before Drain
  EXPECT_EQ(log.threads[0], std::this_thread::get_id());
  q.Drain();
}

TEST(WriteQueue, AJobsErrorReachesTheCallerAndStays) {
  for (const bool background : {true, false}) {
    Log log;
    log.open = false;  // the three jobs are queued before the first runs
    std::vector<Entry> entries{{&log, 0, background}, {&log, 1, false, true}, {&log, 2}};
    WriteQueue q(background);
    try {
      for (Entry& e : entries) q.Call(&Record, &e);
    } catch (const std::runtime_error&) {
      EXPECT_FALSE(background);  // at once on the caller's thread
    }
    {
      const std::lock_guard<std::mutex> lock(log.mu);
      log.open = true;
    }
    log.cv.notify_all();
    EXPECT_THROW(q.Drain(), std::runtime_error) << background;
    EXPECT_THROW(q.Call(&Record, &entries[2]), std::runtime_error) << background;
    EXPECT_THROW(q.Drain(), std::runtime_error) << background;
    // Nothing runs after the failed job.
    EXPECT_EQ(log.order, (std::vector<int>{0, 1})) << background;
  }
}

}  // namespace
}  // namespace arthrosim::io::detail
