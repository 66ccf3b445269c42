// RunWriter -> RunReader round trip, the same file checked by h5py, determinism, bad input.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <tuple>

#include "arthrosim/core/error.h"
#include "arthrosim/io/hdf5.h"
#include "arthrosim/io/hdf5_layout.h"
#include "arthrosim/io/run_reader.h"
#include "arthrosim/io/run_writer.h"
#include "arthrosim/io/xdmf.h"
#include "run_fixture.h"

namespace arthrosim::io {
namespace {

using testing::MakeFrame;
using testing::MakeModel;
using testing::TestDir;

constexpr int kFrames = 10;

void WriteRun(const std::string& path, const Model& model, int frames,
              RunWriterOptions options = {}) {
  RunWriter w(path, model, MakeFrame(model, 0), options);
  for (int f = 1; f < frames; ++f) w.Append(MakeFrame(model, f));
  w.Close();
}

// Exact storage (no quantum, no tolerance): every frame reads back bit for bit.
TEST(RunIo, ExactPositionsRoundTripBitIdentical) {
  const Model model = MakeModel();
  const std::string path = TestDir("roundtrip_exact") + "/run.h5";
  RunWriterOptions exact;
  exact.position_quantum_mm = 0;
  exact.position_tolerance_mm = 0;
  WriteRun(path, model, kFrames, exact);
  const RunReader r(path);
  ASSERT_EQ(r.frame_count(), kFrames);
  for (int f = 0; f < kFrames; ++f) {
    const State want = MakeFrame(model, f);
    const State got = r.Frame(f);
    EXPECT_TRUE(BitwiseEqual(got, want)) << "frame " << f;
    EXPECT_EQ(HashState(got), HashState(want)) << "frame " << f;
  }
}

// The default stores positions quantised and held within a tolerance: every coordinate read
// back is within the stated bound, some differ (the storage is lossy), and the rest of the
// State is bit-identical.
TEST(RunIo, DefaultPositionsWithinTheirBound) {
  const Model model = MakeModel();
  const std::string path = TestDir("roundtrip_bound") + "/run.h5";
  WriteRun(path, model, kFrames);
  const RunReader r(path);
  double worst = 0;
  for (int f = 0; f < kFrames; ++f) {
    const State want = MakeFrame(model, f);
    const State got = r.Frame(f);
    worst = std::max(worst, testing::MaxPositionError(got, want));
    EXPECT_TRUE(testing::EqualWithinPositionBound(got, want)) << "frame " << f;
  }
  EXPECT_LE(worst, testing::kPositionBoundMm);
  EXPECT_GT(worst, 0.0);
}

// Tissue creeping by 0.7 um per frame: nodes are held (the error grows up to the tolerance) and
// rewritten once beyond it, so every frame read back stays within the bound.
TEST(RunIo, SlowDriftIsHeldWithinTheBound) {
  const Model model = MakeModel();
  const std::string path = TestDir("drift") + "/run.h5";
  std::vector<State> frames;
  {
    RunWriter w(path, model, MakeFrame(model, 0));
    for (int k = 1; k <= 40; ++k) {
      State s = MakeFrame(model, 1);
      s.step = 2 + k;
      s.time_s = 0.01 * static_cast<double>(s.step);
      s.soft_bodies[0].x.array() += 0.0007 * k;
      s.threads[0].x.array() -= 0.0007 * k;
      w.Append(s);
      frames.push_back(s);
    }
  }
  const RunReader r(path);
  double worst = 0;
  for (int k = 1; k <= 40; ++k) {
    const double e = testing::MaxPositionError(r.Frame(k), frames[static_cast<std::size_t>(k - 1)]);
    EXPECT_LE(e, testing::kPositionBoundMm) << "frame " << k;
    worst = std::max(worst, e);
  }
  EXPECT_GT(worst, 0.8 * testing::kPositionBoundMm);  // held, not rewritten every frame
}

// A node is rewritten once it moved beyond the tolerance; below it the stored value holds.
TEST(RunIo, PositionsHeldWithinToleranceThenRewritten) {
  Points x(3, 2);
  x << 1.0, 2.0, 0.0, 0.0, 0.0, 0.0;
  std::vector<double> held;
  layout::HoldPositions(x, 1.0 / 1024, 0.005, &held);
  EXPECT_EQ(held[0], 1.0);
  x(0, 0) = 1.004;  // within the tolerance: held
  x(0, 1) = 2.006;  // beyond: rewritten to the nearest multiple of 2^-10
  layout::HoldPositions(x, 1.0 / 1024, 0.005, &held);
  EXPECT_EQ(held[0], 1.0);
  EXPECT_EQ(held[3], std::nearbyint(2.006 * 1024) / 1024);
  EXPECT_LE(std::abs(held[3] - 2.006), 0.5 / 1024);
}

TEST(RunIo, RoundTripMatchesTheFrames) {
  const Model model = MakeModel();
  const std::string path = TestDir("roundtrip") + "/run.h5";
  WriteRun(path, model, kFrames);

  const RunReader r(path);
  ASSERT_EQ(r.frame_count(), kFrames);
  EXPECT_EQ(r.info().scenario_name, "io-synthetic");
  EXPECT_EQ(r.info().scenario_yaml, model.scenario_text);
  EXPECT_EQ(r.info().scenario_sha256, model.scenario_sha256);
  EXPECT_EQ(r.info().dt_s, 0.01);
  EXPECT_EQ(r.info().soft_bodies, (std::vector<std::string>{"cuff", "biceps"}));  // Model order
  EXPECT_EQ(r.info().instruments, (std::vector<std::string>{"grasper", "burr", "scissors"}));
  State got;
  for (int f = 0; f < kFrames; ++f) {
    const State want = MakeFrame(model, f);
    r.ReadFrame(f, got);  // buffers reused across frames of different sizes
    EXPECT_TRUE(testing::EqualWithinPositionBound(got, want)) << "frame " << f;
    EXPECT_EQ(r.step(f), 2 * f);
  }
  // Spot checks that do not rely on BitwiseEqual.
  const State s7 = r.Frame(7);
  EXPECT_EQ(s7.soft_bodies[0].x.cols(), 9);
  EXPECT_EQ(s7.soft_bodies[0].tets.size(), 9u);
  EXPECT_EQ(s7.soft_bodies[0].tet_alive[0], 0);
  EXPECT_EQ(s7.bones[0].surface.tris.size(), 6u);
  EXPECT_EQ(s7.constraints.size(), 2u);
  EXPECT_EQ(s7.events.size(), 1u);
  EXPECT_EQ(s7.events[0].kind, "reshape");
  EXPECT_EQ(r.EventsUpTo(9).size(), 6u);
  EXPECT_EQ(r.EventsUpTo(3).size(), 3u);
  EXPECT_THROW(r.Frame(kFrames), std::out_of_range);
  EXPECT_THROW(r.Frame(-1), std::out_of_range);
}

TEST(RunIo, PythonH5pyReadsTheLayout) {
  ASSERT_TRUE(testing::HavePythonH5py()) << "python3-h5py is required by the io tests";
  const Model model = MakeModel();
  const std::string path = TestDir("h5py") + "/run.h5";
  WriteRun(path, model, kFrames);
  EXPECT_EQ(testing::RunPython("check_run.py", path + " --frames " + std::to_string(kFrames)), 0);
}

TEST(RunIo, SameFramesGiveIdenticalDatasets) {
  ASSERT_TRUE(testing::HavePythonH5py()) << "python3-h5py is required by the io tests";
  const Model model = MakeModel();
  const std::string a = TestDir("determinism_a") + "/run.h5";
  const std::string b = TestDir("determinism_b") + "/run.h5";
  WriteRun(a, model, kFrames);
  WriteRun(b, model, kFrames);
  EXPECT_EQ(testing::RunPython("compare_runs.py", a + " " + b), 0);
  // A different frame must be detected by the same comparison (the check can fail): a node
  // moved beyond the positions' stored bound (5 um), and one ulp of an exactly stored value.
  const std::string c = TestDir("determinism_c") + "/run.h5";
  {
    RunWriter w(c, model, MakeFrame(model, 0));
    for (int f = 1; f < kFrames; ++f) {
      State s = MakeFrame(model, f);
      if (f == 5) s.soft_bodies[0].x(1, 3) += 0.01;
      w.Append(s);
    }
  }
  EXPECT_NE(testing::RunPython("compare_runs.py", a + " " + c + " --quiet"), 0);
  const std::string d = TestDir("determinism_d") + "/run.h5";
  {
    RunWriter w(d, model, MakeFrame(model, 0));
    for (int f = 1; f < kFrames; ++f) {
      State s = MakeFrame(model, f);
      if (f == 5) s.soft_bodies[0].removed_volume_mm3 = std::nextafter(1.0, 2.0);
      w.Append(s);
    }
  }
  EXPECT_NE(testing::RunPython("compare_runs.py", a + " " + d + " --quiet"), 0);
  // And the sidecars of equal runs are equal text.
  auto slurp = [](const std::string& p) {
    std::ifstream in(p);
    return std::string((std::istreambuf_iterator<char>(in)), {});
  };
  const std::string ta = slurp(XdmfPathFor(a)), tb = slurp(XdmfPathFor(b));
  EXPECT_FALSE(ta.empty());
  EXPECT_EQ(ta, tb);
}

// Frames are buffered and written in blocks: the block size (whole blocks, blocks cut by a row
// shape change at the frame-6 split, blocks cut by a flush every 5 frames, a byte budget) must
// not change a single dataset, chunk layout, filter or the sidecar.
// The writer thread (RunWriterOptions::background_writer) changes when chunks are compressed and
// stored, not what is stored or where: a run written with it is the same file byte for byte as
// one written with every job inside Append, but for its creation time in /meta (the same
// length, and the checksum of the header holding it), and the same sidecar. Over 400 frames: 80
// flushes, 2 checkpoints, the tet splits and node growth of the test model.
TEST(RunIo, WriterThreadWritesTheSameFile) {
  const Model model = MakeModel();
  constexpr int kFrames = 400;
  auto write = [&](const std::string& name, bool background) {
    const std::string path = TestDir(name) + "/run.h5";
    RunWriterOptions options;
    options.background_writer = background;
    RunWriter w(path, model, MakeFrame(model, 0), options);
    for (int f = 1; f < kFrames; ++f) w.Append(MakeFrame(model, f));
    w.Close();
    return path;
  };
  const std::string on = write("thread_on", true);
  const std::string off = write("thread_off", false);
  auto slurp = [](const std::string& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), {});
  };
  auto created = [](const std::string& p) {
    return h5::File::OpenReadOnly(p, false)
        .root()
        .OpenGroup(layout::kMeta)
        .AttrString("created_utc");
  };
  std::string a = slurp(on);
  const std::string b = slurp(off);
  ASSERT_EQ(a.size(), b.size());
  const std::string ta = created(on), tb = created(off);
  ASSERT_EQ(ta.size(), tb.size());
  const std::size_t at = a.find(ta);
  ASSERT_NE(at, std::string::npos);
  a.replace(at, ta.size(), tb);
  std::size_t differ = 0;
  for (std::size_t i = 0; i < a.size(); ++i) differ += a[i] != b[i] ? 1 : 0;
  EXPECT_LE(differ, 4u) << "bytes differing besides the creation time (4: a header checksum)";
  EXPECT_EQ(slurp(XdmfPathFor(on)), slurp(XdmfPathFor(off)));
  const RunReader r(on);
  ASSERT_EQ(r.frame_count(), kFrames);
  EXPECT_TRUE(
      testing::EqualWithinPositionBound(r.Frame(kFrames - 1), MakeFrame(model, kFrames - 1)));
}

TEST(RunIo, BlockSizeDoesNotChangeTheFile) {
  ASSERT_TRUE(testing::HavePythonH5py()) << "python3-h5py is required by the io tests";
  const Model model = MakeModel();
  constexpr int kLong = 23;
  auto write = [&](const std::string& name, std::int64_t block_frames, std::size_t block_bytes) {
    const std::string path = TestDir(name) + "/run.h5";
    RunWriterOptions options;
    options.block_frames = block_frames;
    options.block_bytes = block_bytes;
    RunWriter w(path, model, MakeFrame(model, 0), options);
    for (int f = 1; f < kLong; ++f) {
      State s = MakeFrame(model, f);
      if (f == 3) w.RecordEvents(s);  // recorded early: Append must not record them again
      if (f == 12) {                  // events of a step between two frames
        State between = MakeFrame(model, 3);
        between.step = s.step - 1;
        w.RecordEvents(between);
      }
      w.Append(s);
      EXPECT_EQ(w.frames(), f + 1);
    }
    w.Close();
    return path;
  };
  const std::string one = write("block_1", 1, std::size_t{16} << 20);
  auto slurp = [](const std::string& p) {
    std::ifstream in(p);
    return std::string((std::istreambuf_iterator<char>(in)), {});
  };
  for (const auto& [name, frames, bytes] :
       {std::tuple<const char*, std::int64_t, std::size_t>{"block_3", 3, std::size_t{16} << 20},
        {"block_4", 4, std::size_t{16} << 20},
        {"block_64", 64, std::size_t{16} << 20},
        {"block_bytes", 64, 700}}) {
    const std::string other = write(name, frames, bytes);
    EXPECT_EQ(testing::RunPython("compare_runs.py", one + " " + other), 0) << name;
    EXPECT_EQ(slurp(XdmfPathFor(one)), slurp(XdmfPathFor(other))) << name;
    const RunReader r(other);
    ASSERT_EQ(r.frame_count(), kLong) << name;
    EXPECT_TRUE(testing::EqualWithinPositionBound(r.Frame(6), MakeFrame(model, 6))) << name;
    EXPECT_TRUE(testing::EqualWithinPositionBound(r.Frame(kLong - 1), MakeFrame(model, kLong - 1)))
        << name;
  }
  EXPECT_THROW(
      {
        RunWriterOptions bad;
        bad.block_frames = 0;
        RunWriter w(TestDir("block_0") + "/run.h5", model, MakeFrame(model, 0), bad);
      },
      std::invalid_argument);
}

TEST(RunIo, BadPathsGiveClearErrors) {
  const Model model = MakeModel();
  const State s0 = MakeFrame(model, 0);
  try {
    RunWriter w("/nonexistent-dir-arthrosim/run.h5", model, s0);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "output_file");
    EXPECT_NE(std::string(e.what()).find("does not exist"), std::string::npos) << e.what();
  }
  const std::string dir = TestDir("badpath");
  EXPECT_THROW(RunWriter(dir, model, s0), InputError);  // a directory
  std::filesystem::permissions(
      dir, std::filesystem::perms::owner_read | std::filesystem::perms::owner_exec);
  if (::geteuid() != 0) {  // root ignores permissions
    EXPECT_THROW(RunWriter(dir + "/run.h5", model, s0), InputError);
  }
  std::filesystem::permissions(dir, std::filesystem::perms::owner_all);

  EXPECT_THROW(RunReader(dir + "/missing.h5"), InputError);
  const std::string text = dir + "/not-hdf5.h5";
  std::ofstream(text) << "hello\n";
  EXPECT_THROW(RunReader{text}, InputError);
  {  // HDF5, but not a run file
    h5::File f = h5::File::Create(dir + "/other.h5");
    f.Close();
  }
  try {
    RunReader r(dir + "/other.h5");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not an arthrosim run file"), std::string::npos);
  }
}

TEST(RunIo, BadNamesLeaveNoFile) {
  Model model = MakeModel();
  model.soft_bodies[1].name = "a/b";
  const std::string path = TestDir("badname") + "/run.h5";
  EXPECT_THROW(RunWriter(path, model, MakeFrame(model, 0)), InputError);
  EXPECT_FALSE(std::filesystem::exists(path));
  model = MakeModel();
  model.instruments[2].name = "grasper";
  EXPECT_THROW(RunWriter(path, model, MakeFrame(model, 0)), InputError);
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(RunIo, BadStatesAreRejectedBeforeWritingAndTheFileStaysReadable) {
  const Model model = MakeModel();
  const std::string path = TestDir("badstate") + "/run.h5";
  {
    RunWriter w(path, model, MakeFrame(model, 0));
    w.Append(MakeFrame(model, 1));
    EXPECT_THROW(w.Append(MakeFrame(model, 1)), std::invalid_argument);  // step not increasing
    State s = MakeFrame(model, 2);
    s.soft_bodies.pop_back();
    EXPECT_THROW(w.Append(s), std::invalid_argument);
    s = MakeFrame(model, 2);
    s.soft_bodies[0].tets[1][0] = 7;  // changed in place
    EXPECT_THROW(w.Append(s), std::invalid_argument);
    s = MakeFrame(model, 2);
    s.soft_bodies[0].tets[1][0] = 99;  // out of range
    EXPECT_THROW(w.Append(s), std::invalid_argument);
    s = MakeFrame(model, 2);
    s.tools[1].instrument = 0;  // grasper in both slots
    EXPECT_THROW(w.Append(s), std::invalid_argument);
    s.tools[1].instrument = 3;
    EXPECT_THROW(w.Append(s), std::invalid_argument);
    w.Append(MakeFrame(model, 2));
    EXPECT_EQ(w.frames(), 3);
    w.Close();
    EXPECT_THROW(w.Append(MakeFrame(model, 3)), std::logic_error);
  }
  const RunReader r(path);
  ASSERT_EQ(r.frame_count(), 3);
  EXPECT_TRUE(testing::EqualWithinPositionBound(r.Frame(2), MakeFrame(model, 2)));
}

TEST(RunIo, EventsBetweenFramesAreKept) {
  const Model model = MakeModel();
  const std::string path = TestDir("events") + "/run.h5";
  {
    RunWriter w(path, model, MakeFrame(model, 0));
    State between = MakeFrame(model, 1);
    between.step = 1;  // a step that is not written as a frame
    between.events = {Event{1, 0.01, "contact_end", "burr", "cuff", "", Vec3(1, 2, 3)}};
    w.RecordEvents(between);
    w.RecordEvents(between);  // same step twice: recorded once
    State s = MakeFrame(model, 1);
    s.events = {Event{2, 0.02, "contact_start", "burr", "cuff", "", Vec3(4, 5, 6)}};
    w.RecordEvents(s);
    w.Append(s);  // its events were recorded already: not twice
  }
  const RunReader r(path);
  const State f1 = r.Frame(1);
  ASSERT_EQ(f1.events.size(), 2u);
  EXPECT_EQ(f1.events[0].kind, "contact_end");
  EXPECT_EQ(f1.events[0].step, 1);
  EXPECT_EQ(f1.events[1].kind, "contact_start");
  EXPECT_EQ(f1.events[1].position_mm, Vec3(4, 5, 6));
}

TEST(RunIo, LongEventTextIsCutAtACharacterBoundary) {
  const Model model = MakeModel();
  const std::string path = TestDir("longtext") + "/run.h5";
  std::string detail;
  for (int i = 0; i < 150; ++i) detail += "\xc3\xa9";  // 300 bytes of 'e acute'
  {
    RunWriter w(path, model, MakeFrame(model, 0));
    State s = MakeFrame(model, 1);
    s.events = {Event{2, 0.02, "note", "", "", detail, Vec3::Zero()}};
    w.Append(s);
  }
  const RunReader r(path);
  const std::string got = r.Frame(1).events.at(0).detail;
  EXPECT_EQ(got.size(), 192u);  // 96 whole characters of 2 bytes
  EXPECT_EQ(got, detail.substr(0, 192));
}

TEST(RunIo, SummaryNamesCountsAndBounds) {
  const Model model = MakeModel();
  const std::string path = TestDir("summary") + "/run.h5";
  WriteRun(path, model, kFrames);
  const std::string s = Summarize(path);
  EXPECT_NE(s.find("frames: 10 (steps 0 .. 18)"), std::string::npos) << s;
  EXPECT_NE(s.find("body 'cuff': 9 nodes, 9 elements (7 alive)"), std::string::npos) << s;
  EXPECT_NE(s.find("bone 'humerus': 5 vertices, 6 triangles"), std::string::npos) << s;
  EXPECT_NE(s.find("thread 'suture': 6 nodes (5 alive)"), std::string::npos) << s;
  EXPECT_NE(s.find("events: 6 (contact_start 1, cut 1, grasp 1, insert 1, remove 1, reshape 1)"),
            std::string::npos)
      << s;
  // Frame 9: cube node 0 at (0.9, 0, -4.05); biceps unmoved.
  EXPECT_NE(s.find("bounds [0.900, 0.000, -4.050]"), std::string::npos) << s;
}

}  // namespace
}  // namespace arthrosim::io
