// The run file keeps almost no lost space: under SWMR, HDF5 never reuses the file space of a
// compressed chunk that a flush wrote part-filled and a later flush rewrote elsewhere, nor of
// the B-tree nodes indexing datasets with two unlimited dimensions, so the writer stores whole
// chunks at flushes and bounds the node dimensions (docs/hdf5-layout.md, "Writing in chunks").
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <string>

#include "arthrosim/io/run_reader.h"
#include "arthrosim/io/run_writer.h"
#include "run_fixture.h"

namespace arthrosim::io {
namespace {

using testing::MakeFrame;
using testing::MakeModel;

// "Unaccounted space" of `h5stat -S` (hdf5-tools): file space that neither metadata, data
// nor a free-space manager accounts for. -1 when h5stat is not installed.
long long UnaccountedBytes(const std::string& path) {
  FILE* p = popen(("h5stat -S '" + path + "' 2>/dev/null").c_str(), "r");
  if (p == nullptr) return -1;
  long long bytes = -1;
  char line[256];
  while (std::fgets(line, sizeof line, p) != nullptr) {
    std::sscanf(line, " Unaccounted space: %lld", &bytes);
  }
  pclose(p);
  return bytes;
}

// 3 000 frames flushed every 25 frames (120 flushes, each with new positions, node masks...):
// the file's bytes beyond its stored data stay at the metadata's size, a fraction of the data.
// When flushes stored part-filled chunks that the next flush stored again elsewhere, or node
// masks growing in two dimensions were indexed by B-trees, that lost space was most of the file.
TEST(RunSize, FlushesLeaveNoLostSpace) {
  Model model = MakeModel();
  model.options.flush_interval_s = 0.5;
  const std::string path = testing::TestDir("size") + "/run.h5";
  {
    RunWriter w(path, model, MakeFrame(model, 0));
    for (int f = 1; f < 3000; ++f) {
      State s = MakeFrame(model, 10 + f % 10);  // after the splits; moves on every frame
      s.step = 2 * f;
      s.time_s = 0.02 * f;
      w.Append(s);
    }
    w.Close();
  }
  const auto file = static_cast<long long>(std::filesystem::file_size(path));
  const long long lost = UnaccountedBytes(path);
  if (lost < 0) GTEST_SKIP() << "h5stat (hdf5-tools) is not installed";
  std::printf("run file %lld bytes, %lld of them lost (h5stat -S: unaccounted space)\n", file,
              lost);
  EXPECT_LT(lost, file / 20) << "bytes lost of a " << file << "-byte file";
  EXPECT_EQ(RunReader(path).frame_count(), 3000);
}

}  // namespace
}  // namespace arthrosim::io
