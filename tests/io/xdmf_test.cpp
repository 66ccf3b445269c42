// The run.xmf sidecar: hyperslab arithmetic against the HDF5 file, regeneration from the file,
// skipping of empty meshes, atomic replacement.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "arthrosim/io/run_writer.h"
#include "arthrosim/io/xdmf.h"
#include "run_fixture.h"

namespace arthrosim::io {
namespace {

using testing::MakeFrame;
using testing::MakeModel;

std::string Slurp(const std::string& path) {
  std::ifstream in(path);
  return std::string((std::istreambuf_iterator<char>(in)), {});
}

int Count(const std::string& text, const std::string& what) {
  int n = 0;
  for (std::size_t p = text.find(what); p != std::string::npos; p = text.find(what, p + 1)) ++n;
  return n;
}

TEST(Xdmf, SidecarMatchesTheAliveElementsOfEveryFrame) {
  ASSERT_TRUE(testing::HavePythonH5py()) << "python3-h5py is required by the io tests";
  const Model model = MakeModel();
  const std::string path = testing::TestDir("xdmf") + "/run.h5";
  {
    RunWriter w(path, model, MakeFrame(model, 0));
    for (int f = 1; f < 10; ++f) w.Append(MakeFrame(model, f));
  }
  const std::string xmf = XdmfPathFor(path);
  EXPECT_EQ(testing::RunPython("check_xdmf.py", xmf + " " + path), 0);
  const std::string text = Slurp(xmf);
  EXPECT_EQ(Count(text, "<Time "), 10);
  EXPECT_EQ(Count(text, "Name=\"body:cuff\""), 10);
  EXPECT_NE(text.find(">run.h5:/bodies/cuff/alive_elements<"), std::string::npos);  // relative
  // Frames 6..9 show 7 alive cube tets: 5 - 1 removed + 4 split - 1 split parent.
  EXPECT_EQ(Count(text, "TopologyType=\"Tetrahedron\" NumberOfElements=\"7\""), 4);
  // The sidecar can be rebuilt from the file's own offset/count arrays (e.g. after a crash).
  EXPECT_EQ(XdmfText(XdmfRunFromFile(path)), text);
}

TEST(Xdmf, SidecarIsRewrittenAtEveryFlush) {
  const Model model = MakeModel();
  const std::string path = testing::TestDir("xdmf_flush") + "/run.h5";
  RunWriter w(path, model, MakeFrame(model, 0));
  EXPECT_EQ(Count(Slurp(w.xdmf_path()), "<Time "), 1);
  w.Append(MakeFrame(model, 1));
  w.Append(MakeFrame(model, 2));
  EXPECT_EQ(Count(Slurp(w.xdmf_path()), "<Time "), 1);  // 0.04 s < flush interval 0.1 s
  w.Flush();
  EXPECT_EQ(Count(Slurp(w.xdmf_path()), "<Time "), 3);
  EXPECT_FALSE(std::filesystem::exists(w.xdmf_path() + ".tmp"));
  w.Close();
}

// A long session must not rewrite the whole sidecar at every flush (O(frames^2) bytes): past
// xdmf_every_flush_frames it is rewritten only once it lags by the growth fraction, never lags
// more, and is complete after Close.
TEST(Xdmf, SidecarRewritesAreAmortizedOnLongRuns) {
  const Model model = MakeModel();
  const std::string path = testing::TestDir("xdmf_long") + "/run.h5";
  RunWriterOptions options;
  options.xdmf_every_flush_frames = 10;
  options.xdmf_growth = 0.25;
  RunWriter w(path, model, MakeFrame(model, 0), options);
  int rewrites = 0, last = 1;
  for (int f = 1; f < 120; ++f) {
    w.Append(MakeFrame(model, f));
    w.Flush();
    const int in_sidecar = Count(Slurp(w.xdmf_path()), "<Time ");
    const int frames = f + 1;
    EXPECT_LE(in_sidecar, frames);
    if (frames <= 10) {
      EXPECT_EQ(in_sidecar, frames);  // short runs: every flush
    }
    EXPECT_GE(1.25 * in_sidecar + 1, frames) << "frame " << f;  // lags by at most 25 %
    if (in_sidecar != last) ++rewrites;
    last = in_sidecar;
  }
  EXPECT_LE(rewrites, 10 + 12);  // 10 early ones, then growth by 1.25 up to 120 frames
  EXPECT_GT(rewrites, 10);
  w.Close();
  EXPECT_EQ(Count(Slurp(w.xdmf_path()), "<Time "), 120);
}

TEST(Xdmf, EmptyMeshesAreLeftOutAndNamesEscaped) {
  XdmfRun run;
  run.h5_name = "a&b.h5";
  run.times = {0.0, 0.5};
  XdmfMesh m;
  m.name = "body:<x>";
  m.cells = {"/bodies/x/alive_elements", 3, 4, false, 4, {0, 3}, {3, 0}};
  m.points = {"/bodies/x/xdmf_points", 10, 3, true, 4, {0, 5}, {5, 5}};
  run.meshes.push_back(m);
  const std::string text = XdmfText(run);
  EXPECT_EQ(Count(text, "<Time "), 2);
  EXPECT_EQ(Count(text, "Name=\"body:&lt;x&gt;\""), 1);  // frame 1 has no cells
  EXPECT_NE(text.find("<DataItem Dimensions=\"3 2\" Format=\"XML\">0 0 1 1 3 4</DataItem>"),
            std::string::npos);
  EXPECT_NE(text.find(">a&amp;b.h5:/bodies/x/xdmf_points<"), std::string::npos);
  EXPECT_NE(text.find("<Time Value=\"0.5\"/>"), std::string::npos);
}

TEST(Xdmf, PathsAndAtomicWrites) {
  EXPECT_EQ(XdmfPathFor("out/run.h5"), "out/run.xmf");
  EXPECT_EQ(XdmfPathFor("run"), "run.xmf");
  const std::string dir = testing::TestDir("xdmf_atomic");
  WriteFileAtomically(dir + "/a.xmf", "one");
  WriteFileAtomically(dir + "/a.xmf", "two");
  EXPECT_EQ(Slurp(dir + "/a.xmf"), "two");
  EXPECT_THROW(WriteFileAtomically(dir + "/missing/a.xmf", "x"), std::runtime_error);
  EXPECT_FALSE(std::filesystem::exists(dir + "/missing/a.xmf.tmp"));
}

}  // namespace
}  // namespace arthrosim::io
