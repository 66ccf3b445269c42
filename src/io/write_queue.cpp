#include "write_queue.h"

#include <algorithm>
#include <cstring>

#include "arthrosim/io/hdf5.h"
#include "run_series.h"

namespace arthrosim::io::detail {

WriteQueue::WriteQueue(bool background, int max_flushes_behind)
    : background_(background), max_flushes_behind_(max_flushes_behind) {
  if (background_) thread_ = std::thread([this] { Loop(); });
}

WriteQueue::~WriteQueue() {
  if (!thread_.joinable()) return;
  {
    const std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  work_cv_.notify_all();
  thread_.join();
}

void WriteQueue::Run(const Job& job, const unsigned char* data) {
  switch (job.kind) {
    case Job::Kind::kExtent:
      job.ds->SetExtent(job.rank, job.at.data());
      break;
    case Job::Kind::kChunk:
      job.codec->Write(*job.ds, job.at.data(), data, job.count);
      break;
    case Job::Kind::kFlush:
      job.file->Flush();
      if (job.frames >= 0) {
        durable_.store(job.frames, std::memory_order_release);
        flushes_done_.fetch_add(1, std::memory_order_release);
      }
      break;
    case Job::Kind::kCall:
      job.fn(job.arg);
      break;
  }
}

void WriteQueue::ThrowIfFailed() {
  if (error_) std::rethrow_exception(error_);
}

void WriteQueue::Enqueue(const Job& job, const unsigned char* data, std::size_t bytes) {
  if (!background_) {
    if (error_) std::rethrow_exception(error_);
    try {
      Run(job, data);
    } catch (...) {
      error_ = std::current_exception();
      throw;
    }
    return;
  }
  std::unique_lock<std::mutex> lock(mu_);
  ThrowIfFailed();
  if (job.kind == Job::Kind::kFlush && job.frames >= 0) {
    // Memory bound: wait while the writer thread is more than max_flushes_behind_ flushes of
    // frames behind (it notifies idle_cv_ after every batch). A flush of a checkpoint alone
    // adds no frames: it never waits (it follows a flush of frames at the same step).
    idle_cv_.wait(lock, [&] {
      return flushes_queued_ - flushes_done_.load(std::memory_order_acquire) <=
                 max_flushes_behind_ - 1 ||
             error_;
    });
    ThrowIfFailed();
    ++flushes_queued_;
  }
  Job& j = incoming_.jobs.emplace_back(job);  // capacity is kept across batches
  if (bytes > 0) {
    j.data = incoming_.bytes.size();
    incoming_.bytes.insert(incoming_.bytes.end(), data, data + bytes);
  }
  lock.unlock();
  work_cv_.notify_one();
}

void WriteQueue::Loop() {
  std::unique_lock<std::mutex> lock(mu_);
  while (true) {
    work_cv_.wait(lock, [&] { return stop_ || !incoming_.jobs.empty(); });
    if (incoming_.jobs.empty()) return;  // stop_, nothing left
    std::swap(incoming_, working_);      // no allocation: both keep their capacity
    busy_ = true;
    const bool failed = static_cast<bool>(error_);
    lock.unlock();
    idle_cv_.notify_all();  // a caller waiting for room may go on
    std::exception_ptr error;
    if (!failed) {
      try {
        for (const Job& job : working_.jobs) Run(job, working_.bytes.data() + job.data);
      } catch (...) {
        error = std::current_exception();
      }
    }
    working_.jobs.clear();
    working_.bytes.clear();
    lock.lock();
    if (error && !error_) error_ = error;
    busy_ = false;
    idle_cv_.notify_all();
  }
}

void WriteQueue::SetExtent(h5::Dataset* ds, int rank, const hsize_t* dims) {
  Job j;
  j.kind = Job::Kind::kExtent;
  j.ds = ds;
  j.rank = rank;
  std::copy(dims, dims + rank, j.at.begin());
  Enqueue(j, nullptr, 0);
}

void WriteQueue::WriteChunk(ChunkCodec* codec, h5::Dataset* ds, int rank, const hsize_t* offset,
                            const unsigned char* data, std::size_t count) {
  Job j;
  j.kind = Job::Kind::kChunk;
  j.codec = codec;
  j.ds = ds;
  j.rank = rank;
  j.count = count;
  std::copy(offset, offset + rank, j.at.begin());
  Enqueue(j, data, count * codec->mem_bytes());
}

void WriteQueue::FlushFile(h5::File* file, std::int64_t frames) {
  Job j;
  j.kind = Job::Kind::kFlush;
  j.file = file;
  j.frames = frames;
  Enqueue(j, nullptr, 0);
}

void WriteQueue::Call(void (*fn)(void*), void* arg) {
  Job j;
  j.kind = Job::Kind::kCall;
  j.fn = fn;
  j.arg = arg;
  Enqueue(j, nullptr, 0);
}

void WriteQueue::Drain() {
  std::unique_lock<std::mutex> lock(mu_);
  if (background_) idle_cv_.wait(lock, [&] { return incoming_.jobs.empty() && !busy_; });
  ThrowIfFailed();
}

}  // namespace arthrosim::io::detail
