// A steady-state RunWriter::Append makes no C++ heap allocation (project convention): the
// global operator new is counted in this test binary while frames are appended, including the
// Append that writes a whole buffered block to the file. (HDF5 itself allocates with malloc in
// C; that is not counted, and is per block, not per frame.)
#include <gtest/gtest.h>

#include <cstdlib>
#include <new>

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
  model.options.flush_interval_s = 1e9;  // flushes rewrite the .xmf text: not a per-frame cost
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

}  // namespace
}  // namespace arthrosim::io
