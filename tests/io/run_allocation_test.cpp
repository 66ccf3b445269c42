// A steady-state RunWriter::Append makes no C++ heap allocation (project convention): the
// global operator new is counted in this test binary while frames are appended, including the
// Append that writes a whole buffered block to the file. (HDF5 itself allocates with malloc in
// C; that is not counted, and is per block, not per frame.)
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <new>
#include <string>

#include "../support/counting_new.h"
#include "arthrosim/io/run_reader.h"
#include "arthrosim/io/run_writer.h"
#include "run_fixture.h"

namespace arthrosim::io {
namespace {

using testing::MakeFrame;
using testing::MakeModel;

TEST(RunAllocation, SteadyStateAppendDoesNotAllocate) {
  if (!test_support::kCountingNew)
    GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  Model model = MakeModel();
  model.options.flush_interval_s = 1e9;    // flushes rewrite the .xmf text: not a per-frame cost
  model.options.checkpoint_every_s = 1e9;  // a checkpoint flushes too
  const std::string path = testing::TestDir("allocation") + "/run.h5";
  RunWriterOptions options;
  options.block_frames = 64;
  // The mirrors kept for the .xmf (times, frame numbers, block offsets/counts of the listed
  // frames) are std::vectors that double their capacity at powers of two: with every frame
  // listed, frames 129..255 (sizes 130..256) fit in 256 slots, so the window below sees no
  // mirror growth. It includes the block written at 192 frames.
  options.xdmf_interval_s = 0;
  constexpr int kFirst = 129, kEnd = 256;
  std::vector<State> frames;
  for (int f = kFirst; f < kEnd; ++f) frames.push_back(MakeFrame(model, f));

  RunWriter w(path, model, MakeFrame(model, 0), options);
  for (int f = 1; f < kFirst; ++f) w.Append(MakeFrame(model, f));  // growth, events, 2 blocks
  const long before = test_support::AllocationCount();
  for (const State& s : frames) w.Append(s);
  const long allocations = test_support::AllocationCount() - before;
  EXPECT_EQ(allocations, 0) << "over " << frames.size() << " appends";
  // The counter does count: building one frame allocates.
  const long probe = test_support::AllocationCount();
  (void)MakeFrame(model, 1);
  EXPECT_GT(test_support::AllocationCount(), probe);

  w.Close();
  const RunReader r(path);
  ASSERT_EQ(r.frame_count(), kEnd);
  EXPECT_TRUE(testing::EqualWithinPositionBound(r.Frame(kEnd - 1), frames.back()));
  EXPECT_TRUE(testing::EqualWithinPositionBound(r.Frame(192), frames[192 - kFirst]));
}

// Resident memory of this process, kB (VmRSS of /proc/self/status; 0 if unavailable).
long ResidentKb() {
  std::ifstream in("/proc/self/status");
  std::string key;
  long kb = 0;
  while (in >> key) {
    if (key == "VmRSS:") {
      in >> kb;
      return kb;
    }
    in.ignore(1 << 10, '\n');
  }
  return 0;
}

// The writer's memory does not grow with the frames written: from frame 2 000 to 20 000 (40 to
// 400 simulated seconds at 50 frames per second, a flush every simulated second)
// resident memory grows by less than 1 MB. Measured (run alone, as ctest runs it): +0.4 MB,
// of which ~0.2 MB is the sidecar's listing (5 frames per simulated second, by design:
// docs/hdf5-layout.md). It grew by +2.0 MB, still growing at 80 000 frames, while the
// writer's HDF5 metadata cache was 2 MiB: the chunk-index blocks of every dataset stayed in it
// (massif: H5EA data blocks and their images), so it is now 256 KiB, and HDF5's own free lists
// are bounded (hdf5.cpp, FixMetadataCache). It grew by ~26 MB while chunks went through
// H5Dwrite, which under SWMR keeps every chunk it wrote in memory (HDF5 1.10.8; chunks are now
// stored with H5Dwrite_chunk, run_series.h). The writer thread holds at most about one flush
// interval of queued chunks (RunWriterOptions::max_flushes_behind), however fast this loop is.
TEST(RunMemory, WriterMemoryDoesNotGrowWithFrames) {
#if defined(__SANITIZE_ADDRESS__)
  // ASan's quarantine keeps freed blocks resident (+5 MB per 2 000 frames here): RSS says
  // nothing about the writer under it. The Release suite runs this check.
  GTEST_SKIP() << "resident memory is not the writer's under AddressSanitizer";
#endif
  Model model = MakeModel();
  model.options.flush_interval_s = 1.0;
  const std::string path = testing::TestDir("memory") + "/run.h5";
  std::vector<State> frames;
  for (int f = 10; f < 20; ++f) frames.push_back(MakeFrame(model, f));  // after the splits
  RunWriter w(path, model, MakeFrame(model, 0));
  for (int f = 1; f < 10; ++f) w.Append(MakeFrame(model, f));
  long at_2000 = 0;
  for (int f = 10; f < 20000; ++f) {
    State& s = frames[static_cast<std::size_t>(f % 10)];
    s.step = 2 * f;
    s.time_s = 0.02 * f;
    w.Append(s);
    if (f == 2000) at_2000 = ResidentKb();
    if (f % 2000 == 0) std::printf("frame %d: %ld kB\n", f, ResidentKb());
  }
  const long at_20000 = ResidentKb();
  if (at_2000 == 0) GTEST_SKIP() << "no /proc/self/status";
  EXPECT_LT(at_20000 - at_2000, 1024)
      << at_2000 << " kB at frame 2000, " << at_20000 << " kB at frame 20000";
  w.Close();
}

}  // namespace
}  // namespace arthrosim::io
