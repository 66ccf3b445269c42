// The run.xmf sidecar: hyperslab arithmetic against the HDF5 file, regeneration from the file,
// skipping of empty meshes, atomic replacement.
#include <gtest/gtest.h>

#include <cstdlib>
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
  RunWriterOptions every_frame;
  every_frame.xdmf_interval_s = 0;
  {
    RunWriter w(path, model, MakeFrame(model, 0), every_frame);
    for (int f = 1; f < 10; ++f) w.Append(MakeFrame(model, f));
  }
  const std::string xmf = XdmfPathFor(path);
  EXPECT_EQ(testing::RunPython("check_xdmf.py", xmf + " " + path), 0);
  // The legacy reader's form selects the same rows.
  const std::string xmf2 = XdmfPathFor(path, XdmfDialect::kXdmf2);
  WriteFileAtomically(xmf2, XdmfText(XdmfRunFromFile(path, 0), XdmfDialect::kXdmf2));
  EXPECT_EQ(testing::RunPython("check_xdmf.py", xmf2 + " " + path), 0);
  const std::string text = Slurp(xmf);
  EXPECT_EQ(Count(text, "<Time "), 10);
  EXPECT_EQ(Count(text, "Name=\"body:cuff\""), 10);
  EXPECT_NE(text.find(">run.h5:/bodies/cuff/alive_elements|"), std::string::npos);  // relative
  // Frames 6..9 show 7 alive cube tets: 5 - 1 removed + 4 split - 1 split parent.
  EXPECT_EQ(Count(text, "TopologyType=\"Tetrahedron\" NumberOfElements=\"7\""), 4);
  // The sidecar can be rebuilt from the file's own offset/count arrays (e.g. after a crash).
  EXPECT_EQ(XdmfText(XdmfRunFromFile(path, 0)), text);
}

// The sidecars in ParaView itself (pvpython, Debian package paraview): Xdmf3ReaderS and
// Xdmf3ReaderT load run.xmf, the legacy XDMFReader run.xdmf2.xmf, with every frame's point and
// cell counts, across the removed tet (frame 3), the split (6) and the thread cut (5).
TEST(Xdmf, ParaViewReadersLoadEveryFrame) {
  if (std::system("command -v pvpython >/dev/null 2>&1") != 0) {
    GTEST_SKIP() << "pvpython not found (apt-get install paraview): ParaView readers not checked";
  }
  const Model model = MakeModel();
  const std::string dir = testing::TestDir("xdmf_paraview");
  const std::string path = dir + "/run.h5";
  RunWriterOptions every_frame;
  every_frame.xdmf_interval_s = 0;
  {
    RunWriter w(path, model, MakeFrame(model, 0), every_frame);
    for (int f = 1; f < 10; ++f) w.Append(MakeFrame(model, f));
  }
  const std::string xmf2 = XdmfPathFor(path, XdmfDialect::kXdmf2);
  WriteFileAtomically(xmf2, XdmfText(XdmfRunFromFile(path, 0), XdmfDialect::kXdmf2));
  const std::string log = dir + "/pvpython.log";
  const std::string cmd = std::string("pvpython ") + ARTHROSIM_SOURCE_DIR +
                          "/tests/io/check_paraview.py " + path + " " + XdmfPathFor(path) + " " +
                          xmf2 + " >" + log + " 2>&1";
  const int status = std::system(cmd.c_str());
  EXPECT_EQ(status, 0) << Slurp(log);
}

// The writer lists frames as they come (memory bounded by the listed frames): its sidecar is the
// one rebuilt from the file with the same interval, the last frame included.
TEST(Xdmf, WrittenSidecarListsTheFramesARebuildLists) {
  const Model model = MakeModel();
  const std::string path = testing::TestDir("xdmf_listed") + "/run.h5";
  {
    RunWriter w(path, model, MakeFrame(model, 0));
    for (int f = 1; f < 28; ++f) w.Append(MakeFrame(model, f));
  }
  const std::string text = Slurp(XdmfPathFor(path));
  EXPECT_EQ(Count(text, "<Time "), 4);  // frames 0, 10, 20 (0.2 s apart) and the last, 27
  EXPECT_NE(text.find("Name=\"frame27\""), std::string::npos);
  EXPECT_EQ(XdmfText(XdmfRunFromFile(path)), text);
}

// ParaView needs no 50 frames per second: by default frames are listed 0.2 s apart, the first
// and the last always.
TEST(Xdmf, FramesAreListedAtTheInterval) {
  XdmfRun run;
  run.h5_name = "run.h5";
  XdmfMesh m;
  m.name = "body:x";
  m.cells = {"/bodies/x/alive_elements", 3, 4, false, 4, {}, {}};
  m.points = {"/bodies/x/positions", 5, 3, true, 8, {}, {}};
  for (int f = 0; f < 53; ++f) {
    run.times.push_back(0.02 * f);
    m.cells.offset.push_back(0), m.cells.count.push_back(3);
    m.points.offset.push_back(0), m.points.count.push_back(5);
  }
  run.meshes.push_back(m);
  const std::string text = XdmfText(run);
  EXPECT_EQ(Count(text, "<Time "), 7);  // frames 0, 10, ..., 50 and the last, 52
  EXPECT_NE(text.find("Name=\"frame50\""), std::string::npos);
  EXPECT_NE(text.find("Name=\"frame52\""), std::string::npos);
  EXPECT_EQ(text.find("Name=\"frame51\""), std::string::npos);
  run.interval_s = 0;
  EXPECT_EQ(Count(XdmfText(run), "<Time "), 53);
}

TEST(Xdmf, SidecarIsRewrittenAtEveryFlush) {
  const Model model = MakeModel();
  const std::string path = testing::TestDir("xdmf_flush") + "/run.h5";
  RunWriterOptions every_frame;
  every_frame.xdmf_interval_s = 0;
  RunWriter w(path, model, MakeFrame(model, 0), every_frame);
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
  options.xdmf_interval_s = 0;
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
  run.interval_s = 0;
  XdmfMesh m;
  m.name = "body:<x>";
  m.cells = {"/bodies/x/alive_elements", 3, 4, false, 4, {0, 3}, {3, 0}};
  m.points = {"/bodies/x/xdmf_points", 10, 3, true, 4, {0, 5}, {5, 5}};
  run.meshes.push_back(m);
  const std::string text = XdmfText(run);
  EXPECT_EQ(Count(text, "<Time "), 2);
  EXPECT_EQ(Count(text, "Name=\"body:&lt;x&gt;\""), 1);  // frame 1 has no cells
  EXPECT_NE(text.find(">a&amp;b.h5:/bodies/x/alive_elements|0 0:1 1:3 4:3 4</DataItem>"),
            std::string::npos);
  EXPECT_NE(text.find(">a&amp;b.h5:/bodies/x/xdmf_points|0 0:1 1:5 3:10 3<"), std::string::npos);
  const std::string legacy = XdmfText(run, XdmfDialect::kXdmf2);
  EXPECT_NE(legacy.find("<DataItem Dimensions=\"3 2\" Format=\"XML\">0 0 1 1 3 4</DataItem>"),
            std::string::npos);
  EXPECT_NE(legacy.find(">a&amp;b.h5:/bodies/x/xdmf_points<"), std::string::npos);
  EXPECT_NE(text.find("<Time Value=\"0.5\"/>"), std::string::npos);
}

TEST(Xdmf, PathsAndAtomicWrites) {
  EXPECT_EQ(XdmfPathFor("out/run.h5"), "out/run.xmf");
  EXPECT_EQ(XdmfPathFor("run"), "run.xmf");
  EXPECT_EQ(XdmfPathFor("out/run.h5", XdmfDialect::kXdmf2), "out/run.xdmf2.xmf");
  const std::string dir = testing::TestDir("xdmf_atomic");
  WriteFileAtomically(dir + "/a.xmf", "one");
  WriteFileAtomically(dir + "/a.xmf", "two");
  EXPECT_EQ(Slurp(dir + "/a.xmf"), "two");
  EXPECT_THROW(WriteFileAtomically(dir + "/missing/a.xmf", "x"), std::runtime_error);
  EXPECT_FALSE(std::filesystem::exists(dir + "/missing/a.xmf.tmp"));
}

}  // namespace
}  // namespace arthrosim::io
