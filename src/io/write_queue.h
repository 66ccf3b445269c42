#pragma once
// Private to RunWriter: the writer thread. The step thread buffers frames and cuts them into
// chunks (run_series.h); compressing those chunks, storing them, growing extents, flushing the
// file and rewriting the sidecar are jobs that a WriteQueue runs **in the order given** on one
// background thread, so that RunWriter::Append never waits for zlib or the disk (a flush of the
// shoulder scene took 5-25 ms on the step thread).
//
// The file is the same byte for byte as when every job runs at once on the calling thread
// (`background` false): HDF5 sees the same calls in the same order. The caller must make no other
// HDF5 call on the writer's file while jobs are queued (call Drain() first).
#include <hdf5.h>

#include <array>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace arthrosim::io {
namespace h5 {
class Dataset;
class File;
}  // namespace h5

namespace detail {

class ChunkCodec;

class WriteQueue {
 public:
  /// `background` false: every job runs at once on the calling thread. `max_flushes_behind`:
  /// FlushFile waits while the writer thread has more than this many flushes still to do, so
  /// that the memory of queued chunks stays bounded (about that many flush intervals of frames)
  /// however much faster than zlib and the disk the caller is.
  explicit WriteQueue(bool background = false, int max_flushes_behind = 1);
  /// Runs the jobs still queued, then stops the thread (errors are dropped: Drain() first).
  ~WriteQueue();
  WriteQueue(const WriteQueue&) = delete;
  WriteQueue& operator=(const WriteQueue&) = delete;

  /// H5Dset_extent(ds, dims[0..rank)).
  void SetExtent(h5::Dataset* ds, int rank, const hsize_t* dims);
  /// codec->Write(*ds, offset, data, count): `count` elements in the codec's memory type, copied
  /// here (the caller may reuse `data` at once); offset has the dataset's rank.
  void WriteChunk(ChunkCodec* codec, h5::Dataset* ds, int rank, const hsize_t* offset,
                  const unsigned char* data, std::size_t count);
  /// file->Flush(); then durable_frames() = frames (frames < 0: left as it is). With frames >= 0,
  /// waits first while more than `max_flushes_behind` such flushes are queued.
  void FlushFile(h5::File* file, std::int64_t frames);
  /// fn(arg) on the writer thread, in order (arg must outlive the job).
  void Call(void (*fn)(void*), void* arg);
  /// Waits until every job queued so far has run; rethrows the first error a job threw (and
  /// again on every later call: a failed writer stays failed).
  void Drain();

  /// Frames made durable by the last flush job that finished.
  std::int64_t durable_frames() const { return durable_.load(std::memory_order_acquire); }
  bool background() const { return background_; }

 private:
  struct Job {
    enum class Kind : std::uint8_t { kExtent, kChunk, kFlush, kCall } kind = Kind::kCall;
    int rank = 0;
    std::array<hsize_t, 4> at{};  // chunk offset or extent
    h5::Dataset* ds = nullptr;
    ChunkCodec* codec = nullptr;
    h5::File* file = nullptr;
    std::size_t data = 0, count = 0;  // first byte in the batch's bytes; elements
    std::int64_t frames = -1;
    void (*fn)(void*) = nullptr;
    void* arg = nullptr;
  };
  struct Batch {
    std::vector<Job> jobs;
    std::vector<unsigned char> bytes;
  };

  void Run(const Job& job, const unsigned char* data);
  void Enqueue(const Job& job, const unsigned char* data, std::size_t bytes);
  void Loop();
  void ThrowIfFailed();  // with mu_ held

  bool background_;
  int max_flushes_behind_;
  std::int64_t flushes_queued_ = 0;            // by the caller
  std::atomic<std::int64_t> flushes_done_{0};  // by the writer thread
  std::atomic<std::int64_t> durable_{0};
  std::mutex mu_;
  std::condition_variable work_cv_, idle_cv_;
  Batch incoming_, working_;  // incoming_: filled by the caller; working_: the thread's
  bool busy_ = false, stop_ = false;
  std::exception_ptr error_;
  std::thread thread_;  // last: started once the rest exists
};

}  // namespace detail
}  // namespace arthrosim::io
