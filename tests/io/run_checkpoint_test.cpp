// Checkpoints (core/state_bytes.h, /checkpoints of the run file, io::RunCheckpoints): a State
// comes back bit for bit, every field of the State field table included (also those the frames
// do not store), on the schedule of output.checkpoint_every; damaged bytes are refused.
#include <gtest/gtest.h>

#include <filesystem>

#include "arthrosim/core/error.h"
#include "arthrosim/core/state_bytes.h"
#include "arthrosim/core/state_fields.h"
#include "arthrosim/io/hdf5.h"
#include "arthrosim/io/run_checkpoint.h"
#include "arthrosim/io/run_writer.h"
#include "run_fixture.h"

namespace arthrosim::io {
namespace {

using testing::MakeFrame;
using testing::MakeModel;

/// Frame f of the synthetic run with every field set, those the frames do not store too.
State FullFrame(const Model& model, int f) {
  State s = MakeFrame(model, f);
  for (SoftBodyState& b : s.soft_bodies) {
    b.v = 0.5 * b.x;
    b.v.array() += 1.0 + f;
    b.x_rest = b.x;
    b.x_rest.array() -= 0.125;
    b.dv_warm = 1e-3 * b.x;
    b.x_factor = b.x.leftCols(b.x.cols() / 2);
  }
  for (ThreadState& t : s.threads) {
    t.v = -0.25 * t.x;
    t.v.array() += f;
  }
  for (BoneState& b : s.bones) b.revision = 7 + static_cast<std::uint64_t>(f);
  s.script_push[0] = ScriptPushState{3, 0.75 + f, 0.02 * f};
  s.script_push[1] = ScriptPushState{-1, 0, 0};
  return s;
}

// Every field set (those the frames do not store too): decode(encode(s)) is s bit for bit.
TEST(StateBytes, RoundTripIsBitForBitWithEveryField) {
  const Model model = MakeModel();
  const State reference = MakeInitialState(model);
  for (int f : {0, 3, 7, 9}) {
    const State s = FullFrame(model, f);
    std::vector<std::uint8_t> bytes;
    EncodeState(s, reference, &bytes);
    State back;
    DecodeState(bytes, reference, &back);
    EXPECT_TRUE(BitwiseEqual(back, s)) << "frame " << f;
    EXPECT_EQ(HashState(back), HashState(s));
    // Derived fields (not part of the hash) come back too.
    ASSERT_EQ(back.bones.size(), s.bones.size());
    EXPECT_EQ(back.bones[0].revision, s.bones[0].revision);
    EXPECT_EQ(back.script_push[0].depth_mm, s.script_push[0].depth_mm);
    EXPECT_EQ(back.soft_bodies[0].x_factor.cols(), s.soft_bodies[0].x_factor.cols());
  }
}

TEST(StateBytes, RestIsCheapAndDamageIsRefused) {
  const Model model = MakeModel();
  const State reference = MakeInitialState(model);
  std::vector<std::uint8_t> bytes;
  EncodeState(reference, reference, &bytes);
  // The initial state relative to itself: all data bytes are zero.
  std::size_t nonzero = 0;
  for (std::uint8_t b : bytes) nonzero += b != 0;
  EXPECT_LT(nonzero, bytes.size() / 2);
  State back;
  std::vector<std::uint8_t> cut(bytes.begin(), bytes.end() - 5);
  EXPECT_THROW(DecodeState(cut, reference, &back), std::runtime_error);
  std::vector<std::uint8_t> longer = bytes;
  longer.push_back(0);
  EXPECT_THROW(DecodeState(longer, reference, &back), std::runtime_error);
  EXPECT_NE(StateLayoutSignature(), 0u);
}

TEST(RunCheckpoint, WriterKeepsExactStatesOnItsSchedule) {
  Model model = MakeModel();                // dt 0.01 s, a frame every 2 steps
  model.options.checkpoint_every_s = 0.05;  // every 5 steps: the first frame of each interval
  const std::string path = testing::TestDir("checkpoints") + "/run.h5";
  std::vector<State> frames;
  for (int f = 0; f < 10; ++f) frames.push_back(FullFrame(model, f));
  {
    RunWriter w(path, model, frames[0]);
    for (int f = 1; f < 10; ++f) w.Append(frames[static_cast<std::size_t>(f)]);
    State last = frames.back();  // a final state between frames (output.every = 2)
    last.step += 1;
    last.time_s += 0.01;
    w.WriteCheckpoint(last);
    w.WriteCheckpoint(last);  // the same step again: nothing new
    frames.push_back(last);
    w.Close();
  }
  const RunCheckpoints cp(path);
  // Steps 0, 2, ..., 18: intervals of 5 steps start being due at steps 0, 6, 10, 16; then 19.
  const std::vector<std::int64_t> want_steps{0, 6, 10, 16, 19};
  const std::vector<std::size_t> want_frame{0, 3, 5, 8, 10};
  ASSERT_EQ(cp.entries().size(), want_steps.size());
  for (std::size_t i = 0; i < want_steps.size(); ++i) {
    const CheckpointEntry& e = cp.entries()[i];
    EXPECT_EQ(e.step, want_steps[i]);
    EXPECT_EQ(e.frame, i + 1 < want_steps.size() ? static_cast<std::int64_t>(want_frame[i]) : -1);
    const State s = cp.Read(i, model);
    EXPECT_TRUE(BitwiseEqual(s, frames[want_frame[i]])) << "checkpoint " << i;
    EXPECT_EQ(s.bones[0].revision, frames[want_frame[i]].bones[0].revision);
  }
  EXPECT_EQ(cp.AtOrBefore(0.12), 2);
  EXPECT_EQ(cp.AtOrBefore(0.1), 2);
  EXPECT_EQ(cp.AtOrBefore(0.0999), 1);
  EXPECT_EQ(cp.AtOrBefore(100), 4);
  EXPECT_EQ(cp.BuildMismatch(), "");
  EXPECT_EQ(cp.origin().trajectory, "none");
  EXPECT_EQ(cp.origin().parent, "");
}

TEST(RunCheckpoint, AnotherScenarioDoesNotDecodeToTheRecordedState) {
  Model model = MakeModel();
  const std::string path = testing::TestDir("checkpoints_other") + "/run.h5";
  {
    RunWriter w(path, model, FullFrame(model, 0));
    w.Append(FullFrame(model, 1));
    w.WriteCheckpoint(FullFrame(model, 1));
    w.Close();
  }
  const RunCheckpoints cp(path);
  ASSERT_EQ(cp.entries().size(), 2u);
  Model other = model;  // the meshes moved since the run: the reference differs
  other.soft_bodies[0].rest_mesh.nodes.array() += 1.0;
  EXPECT_THROW((void)cp.Read(1, other), InputError);
  EXPECT_NO_THROW((void)cp.Read(1, model));
}

TEST(RunCheckpoint, OffWritesNone) {
  const Model model = MakeModel();
  const std::string path = testing::TestDir("checkpoints_off") + "/run.h5";
  RunWriterOptions options;
  options.checkpoints = false;
  {
    RunWriter w(path, model, FullFrame(model, 0), options);
    w.Append(FullFrame(model, 1));
    w.WriteCheckpoint(FullFrame(model, 1));
    EXPECT_EQ(w.checkpoints(), 0);
    w.Close();
  }
  EXPECT_TRUE(RunCheckpoints(path).entries().empty());
}

}  // namespace
}  // namespace arthrosim::io
