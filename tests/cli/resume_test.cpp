// Checkpoints and resume through the arthrosim binary (docs/hdf5-layout.md, "Checkpoints"):
// a run killed with SIGKILL at seeded random steps and resumed with `run --resume` ends in the
// State of the uninterrupted run (hashes, every checkpoint after the resume point too), for one
// and two threads; SIGINT leaves a closed file with a checkpoint of its last step; `run --from
// RUN --at T` continues from the checkpoint at or before T exactly as the uninterrupted run did.
// The small scene is driven by a script with a force-profile push (its controller integrates
// the fed-back force: input state a checkpoint must carry) and seeded trainee noise.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "arthrosim/core/state.h"
#include "arthrosim/io/hdf5.h"
#include "arthrosim/io/run_checkpoint.h"
#include "arthrosim/io/run_reader.h"
#include "arthrosim/io/scenario_loader.h"
#include "cli_test_util.h"

namespace {

namespace fs = std::filesystem;
using arthrosim::io::CheckpointEntry;
using arthrosim::io::RunCheckpoints;

const std::string kBinary = std::string(ARTHROSIM_BINARY_DIR) + "/src/cli/arthrosim";
const std::string kScenes = std::string(ARTHROSIM_SOURCE_DIR) + "/tests/testdata/scenes";
const std::string kScene = kScenes + "/small_resume.yaml";
const std::string kScript = kScenes + "/small_push.yaml";

// 20 kill-and-resume trials (the number) in Release; a few under the sanitizers, where
// each process costs ~10 times more.
#if defined(__SANITIZE_ADDRESS__)
constexpr int kTrials = 3;
#else
constexpr int kTrials = 20;
#endif

struct Result {
  int exit_code = -1;  // the shell's: 128 + n when the binary died of signal n
  std::string output;
};

Result Exec(const std::string& args, const std::string& env = "") {
  Result r;
  FILE* pipe = popen((env + " " + kBinary + " " + args + " 2>&1").c_str(), "r");
  if (!pipe) return r;
  std::array<char, 4096> buf{};
  while (std::fgets(buf.data(), buf.size(), pipe)) r.output += buf.data();
  const int status = pclose(pipe);
  r.exit_code = WIFEXITED(status)     ? WEXITSTATUS(status)
                : WIFSIGNALED(status) ? 128 + WTERMSIG(status)
                                      : -1;
  return r;
}

std::string KillAt(std::int64_t step, const char* signal = "KILL") {
  return "ARTHROSIM_FAULT_KILL_AT_STEP=" + std::to_string(step) +
         " ARTHROSIM_FAULT_SIGNAL=" + signal;
}

/// The checkpoint of `cp` at `step`, or nullptr.
const CheckpointEntry* At(const RunCheckpoints& cp, std::int64_t step) {
  for (const CheckpointEntry& e : cp.entries()) {
    if (e.step == step) return &e;
  }
  return nullptr;
}

/// Every checkpoint of `part` equals the one `full` has at the same step (and full has one),
/// except a first or last one off the schedule (a run interrupted there, or resumed from it).
void ExpectCheckpointsMatch(const RunCheckpoints& part, const RunCheckpoints& full,
                            const std::string& what) {
  for (const CheckpointEntry& e : part.entries()) {
    const CheckpointEntry* f = At(full, e.step);
    const bool end = &e == &part.entries().front() || &e == &part.entries().back();
    if (f == nullptr && end) continue;
    ASSERT_NE(f, nullptr) << what << ": the uninterrupted run has no checkpoint at step " << e.step;
    EXPECT_EQ(e.state_hash, f->state_hash) << what << ": State differs at step " << e.step;
  }
}

bool SameBits(const arthrosim::Pose& a, const arthrosim::Pose& b) {
  return std::memcmp(a.position_mm.data(), b.position_mm.data(), 3 * sizeof(double)) == 0 &&
         std::memcmp(a.orientation.coeffs().data(), b.orientation.coeffs().data(),
                     4 * sizeof(double)) == 0;
}

/// Every frame of `part` equals the frame of `full` at the same step in what frames store
/// exactly: both tool slots (instrument, proxy and handle pose, jaw, buttons, forces), the
/// camera, the random stream and the constraint count; soft-body positions within twice the
/// stored positions' 5 um bound (each file holds its own quantised copy).
void ExpectFramesMatch(const std::string& part, const std::string& full, const std::string& what) {
  const arthrosim::io::RunReader p(part), f(full);
  std::int64_t k = 0;
  for (std::int64_t i = 0; i < p.frame_count(); ++i) {
    while (k < f.frame_count() && f.step(k) < p.step(i)) ++k;
    ASSERT_LT(k, f.frame_count()) << what;
    ASSERT_EQ(f.step(k), p.step(i)) << what;
    const arthrosim::State a = p.Frame(i), b = f.Frame(k);
    for (std::size_t t = 0; t < a.tools.size(); ++t) {
      const arthrosim::ToolState &x = a.tools[t], &y = b.tools[t];
      EXPECT_TRUE(x.instrument == y.instrument && SameBits(x.pose, y.pose) &&
                  SameBits(x.handle_pose, y.handle_pose) && x.jaw == y.jaw &&
                  x.buttons == y.buttons && x.force_n == y.force_n)
          << what << ": tool slot " << t << " differs at step " << p.step(i);
    }
    EXPECT_TRUE(SameBits(a.camera.pose, b.camera.pose)) << what << ": camera, step " << p.step(i);
    EXPECT_EQ(a.rng_state, b.rng_state) << what;
    EXPECT_EQ(a.constraints.size(), b.constraints.size()) << what << ", step " << p.step(i);
    for (std::size_t s = 0; s < a.soft_bodies.size(); ++s) {
      ASSERT_EQ(a.soft_bodies[s].x.cols(), b.soft_bodies[s].x.cols()) << what;
      EXPECT_LE((a.soft_bodies[s].x - b.soft_bodies[s].x).cwiseAbs().maxCoeff(), 0.0101)
          << what << ": body " << s << " at step " << p.step(i);
    }
  }
}

class ResumeTest : public arthrosim::testing::TempDirTest {
 protected:
  ResumeTest() : TempDirTest("arthrosim_resume_") {}
  /// The scripted run of the small scene, with trainee noise, into `out`.
  std::string RunArgs(const std::string& out, int threads = 1) const {
    return "run " + kScene + " --trajectory " + kScript + " --noise-scale 1 --quiet --threads " +
           std::to_string(threads) + " --out " + out;
  }
};

TEST_F(ResumeTest, KilledAtSeededStepsResumesToTheUninterruptedState) {
  const Result full = Exec(RunArgs(P("full.h5")));
  ASSERT_EQ(full.exit_code, 0) << full.output;
  const RunCheckpoints full_cp(P("full.h5"));
  ASSERT_GE(full_cp.entries().size(), 5u);
  const CheckpointEntry end = full_cp.entries().back();
  ASSERT_GT(end.step, 100);
  // The same run on two threads ends in the same State.
  const Result two = Exec(RunArgs(P("two.h5"), 2));
  ASSERT_EQ(two.exit_code, 0) << two.output;
  EXPECT_EQ(RunCheckpoints(P("two.h5")).entries().back().state_hash, end.state_hash);

  // Seeded random kill steps, plus one a few steps after a checkpoint taken while the force push
  // is integrating (its controller is mid-way: the resumed frames depend on it).
  const arthrosim::Model model = arthrosim::io::LoadScenario(kScene);
  std::int64_t mid_push = -1;
  for (std::size_t i = 0; i < full_cp.entries().size() && mid_push < 0; ++i) {
    const arthrosim::State s = full_cp.Read(i, model);
    const arthrosim::ScriptPushState& p = s.script_push[0];
    // Integrating at this step, in contact (short of max_depth: 8 mm in small_push.yaml).
    if (p.action >= 0 && p.t_prev_s == s.time_s && p.depth_mm > 0 && p.depth_mm < 7.9) {
      mid_push = s.step;
    }
  }
  ASSERT_GT(mid_push, 0) << "no checkpoint falls inside the force push while it presses on the "
                            "block: the test lost its point";
  std::mt19937_64 rng(20261125);
  std::uniform_int_distribution<std::int64_t> pick(1, end.step - 1);
  std::vector<std::int64_t> kill_steps;
  for (int trial = 0; trial < kTrials; ++trial) kill_steps.push_back(pick(rng));
  kill_steps.push_back(mid_push + 3);
  for (std::size_t trial = 0; trial < kill_steps.size(); ++trial) {
    const std::int64_t kill_step = kill_steps[trial];
    const std::string killed = P("killed" + std::to_string(trial) + ".h5");
    const std::string resumed = P("resumed" + std::to_string(trial) + ".h5");
    const Result k = Exec(RunArgs(killed), KillAt(kill_step));
    ASSERT_EQ(k.exit_code, 128 + SIGKILL) << "trial " << trial << ": " << k.output;
    const RunCheckpoints killed_cp(killed);
    ASSERT_FALSE(killed_cp.entries().empty());
    const CheckpointEntry from = killed_cp.entries().back();
    EXPECT_LE(from.step, kill_step);
    ExpectCheckpointsMatch(killed_cp, full_cp, "killed run");

    const int threads = 1 + static_cast<int>(trial % 2);
    const Result r = Exec("run --resume " + killed + " --quiet --threads " +
                          std::to_string(threads) + " --out " + resumed);
    ASSERT_EQ(r.exit_code, 0) << "trial " << trial << " (killed after step " << kill_step
                              << "): " << r.output;
    const RunCheckpoints resumed_cp(resumed);
    EXPECT_EQ(resumed_cp.origin().parent, fs::path(killed).lexically_normal().string());
    EXPECT_EQ(resumed_cp.origin().parent_step, from.step);
    ASSERT_EQ(resumed_cp.entries().front().step, from.step);
    ASSERT_EQ(resumed_cp.entries().back().step, end.step) << "trial " << trial;
    EXPECT_EQ(resumed_cp.entries().back().state_hash, end.state_hash)
        << "trial " << trial << ": killed after step " << kill_step << ", resumed from step "
        << from.step << " on " << threads << " thread(s)";
    ExpectCheckpointsMatch(resumed_cp, full_cp, "resumed run, trial " + std::to_string(trial));
    ExpectFramesMatch(resumed, P("full.h5"), "trial " + std::to_string(trial));
    fs::remove(killed);
    fs::remove(resumed);
  }
  // Bit for bit, not only by hash: the final States themselves.
  const RunCheckpoints two_cp(P("two.h5"));
  EXPECT_TRUE(arthrosim::BitwiseEqual(two_cp.Read(two_cp.entries().size() - 1, model),
                                      full_cp.Read(full_cp.entries().size() - 1, model)));
}

TEST_F(ResumeTest, SigintLeavesAClosedFileWithACheckpointOfItsLastStep) {
  // An external SIGINT during a long run: exit 130, a properly closed file (a plain, non-SWMR
  // open succeeds) whose last checkpoint is the last frame's step.
  const std::string out = P("sigint.h5");
  const pid_t pid = arthrosim::testing::SpawnRun(kBinary, kScene, "10000000", out);
  ASSERT_GE(pid, 0);
  // Once a few frames are flushed the run is stepping (its handler is installed).
  for (int i = 0; i < 600; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    try {
      if (arthrosim::io::RunReader(out).frame_count() > 10) break;
    } catch (const std::exception&) {  // not created yet
    }
  }
  kill(pid, SIGINT);
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130);
  EXPECT_NO_THROW({ auto f = arthrosim::io::h5::File::OpenReadOnly(out, false); })
      << "the interrupted run's file was not closed";
  const arthrosim::io::RunReader reader(out);
  ASSERT_GT(reader.frame_count(), 1);
  const RunCheckpoints cp(out);
  ASSERT_FALSE(cp.entries().empty());
  EXPECT_EQ(cp.entries().back().step, reader.step(reader.frame_count() - 1));

  // SIGINT (and SIGTERM) at a given step: the scripted run resumes to the uninterrupted State.
  ASSERT_EQ(Exec(RunArgs(P("full.h5"))).exit_code, 0);
  const RunCheckpoints full_cp(P("full.h5"));
  for (const char* signal : {"INT", "TERM"}) {
    const std::int64_t step = std::string(signal) == "INT" ? 77 : 101;
    const std::string part = P(std::string("part_") + signal + ".h5");
    const Result k = Exec(RunArgs(part), KillAt(step, signal));
    ASSERT_EQ(k.exit_code, 130) << k.output;
    EXPECT_NE(k.output.find("arthrosim run --resume " + part), std::string::npos) << k.output;
    const RunCheckpoints part_cp(part);
    ASSERT_EQ(part_cp.entries().back().step, step);
    const std::string rest = P(std::string("rest_") + signal + ".h5");
    const Result r = Exec("run --resume " + part + " --quiet --out " + rest);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const RunCheckpoints rest_cp(rest);
    EXPECT_EQ(rest_cp.entries().front().step, step);
    EXPECT_EQ(rest_cp.entries().back().state_hash, full_cp.entries().back().state_hash) << signal;
    ExpectCheckpointsMatch(rest_cp, full_cp, std::string("resumed after SIG") + signal);
  }
}

TEST_F(ResumeTest, FromAtContinuesFromTheCheckpointAtOrBeforeT) {
  ASSERT_EQ(Exec(RunArgs(P("full.h5"))).exit_code, 0);
  const RunCheckpoints full_cp(P("full.h5"));
  // Checkpoints every 0.3 s: T = 1.0 s starts at the one of 0.9 s (step 45).
  const std::int64_t i = full_cp.AtOrBefore(1.0);
  ASSERT_GE(i, 0);
  const CheckpointEntry start = full_cp.entries()[static_cast<std::size_t>(i)];
  EXPECT_EQ(start.step, 45);
  const Result r = Exec("run --from " + P("full.h5") + " --at 1.0 --quiet --out " + P("from.h5"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const RunCheckpoints from_cp(P("from.h5"));
  EXPECT_EQ(from_cp.origin().parent, P("full.h5"));
  EXPECT_EQ(from_cp.origin().parent_step, start.step);
  EXPECT_DOUBLE_EQ(from_cp.origin().parent_time_s, start.time_s);
  EXPECT_EQ(from_cp.origin().parent_state_hash, start.state_hash);
  ASSERT_EQ(from_cp.entries().front().step, start.step);
  EXPECT_EQ(from_cp.entries().front().state_hash, start.state_hash);
  EXPECT_EQ(from_cp.entries().back().step, full_cp.entries().back().step);
  EXPECT_EQ(from_cp.entries().back().state_hash, full_cp.entries().back().state_hash);
  ExpectCheckpointsMatch(from_cp, full_cp, "--from --at 1.0");
  // Its frames start at the checkpoint: frame 0 is step 45, one frame per step after it.
  const arthrosim::io::RunReader reader(P("from.h5"));
  EXPECT_EQ(reader.step(0), start.step);
  EXPECT_EQ(reader.step(reader.frame_count() - 1), full_cp.entries().back().step);

  // --steps runs that many steps from the checkpoint (0.3 s: step 15, to step 45, where the
  // uninterrupted run has a checkpoint); the default file name records the checkpoint's time.
  const Result s = Exec("run --from " + P("full.h5") + " --at 0.3 --steps 30 --quiet");
  ASSERT_EQ(s.exit_code, 0) << s.output;
  const RunCheckpoints short_cp(P("full.from_0.3s.h5"));
  EXPECT_EQ(short_cp.entries().front().step, 15);
  ASSERT_EQ(short_cp.entries().back().step, 45);
  EXPECT_EQ(short_cp.entries().back().state_hash, start.state_hash);
}

// A run started with a relative scenario path can be continued, scored and rendered from
// another directory: the run file records the scenario's absolute path too, and its meshes are
// read relative to it when the path as given does not exist from there.
TEST_F(ResumeTest, FromAtWorksFromAnotherDirectory) {
  fs::create_directories(dir_ / "scenes");
  for (const char* f : {"small_resume.yaml", "small_push.yaml", "block.vtk", "bone.obj"})
    fs::copy_file(kScenes + "/" + f, dir_ / "scenes" / f);
  fs::create_directories(dir_ / "elsewhere");
  const std::string in_dir = "cd " + dir_.string() + " && ";
  const std::string in_elsewhere = "cd " + (dir_ / "elsewhere").string() + " && ";
  ASSERT_EQ(Exec("run scenes/small_resume.yaml --trajectory scenes/small_push.yaml --steps 30 "
                 "--quiet --out full.h5",
                 in_dir)
                .exit_code,
            0);
  const RunCheckpoints full_cp(P("full.h5"));
  EXPECT_EQ(full_cp.scenario_path(), "scenes/small_resume.yaml");
  EXPECT_EQ(full_cp.scenario_path_absolute(), P("scenes/small_resume.yaml"));

  const Result from =
      Exec("run --from ../full.h5 --at 0.3 --steps 10 --quiet --out from.h5", in_elsewhere);
  ASSERT_EQ(from.exit_code, 0) << from.output;
  EXPECT_EQ(arthrosim::io::RunReader(P("elsewhere/from.h5")).step(0), 15);
  const Result frame =
      Exec("render ../full.h5 --frames frames --to 0.02 --size 64x48", in_elsewhere);
  EXPECT_EQ(frame.exit_code, 0) << frame.output;

  // Neither the path as given nor the recorded one exists: a clear error naming both.
  fs::rename(dir_ / "scenes", dir_ / "moved");
  const Result gone =
      Exec("run --from ../full.h5 --at 0.3 --steps 10 --quiet --out gone.h5", in_elsewhere);
  EXPECT_EQ(gone.exit_code, 2) << gone.output;
  EXPECT_NE(gone.output.find("/meta scenario_path"), std::string::npos) << gone.output;
  EXPECT_NE(gone.output.find(P("scenes/small_resume.yaml")), std::string::npos) << gone.output;
}

}  // namespace

// The shoulder scene with the burr carving the acromion (bone surfaces and their collision
// trees, tool proxies sliding on bone, the soft-tissue preconditioner): killed after step 330 of
// 350, resumed from the checkpoint at 5 s (step 250), it ends in the uninterrupted run's State.
// (7 s: with the sliding proxy, ops/burr.yaml carves at 2.9-4.5 s and 6.0-7.5 s, not in 5-6 s.)
// Release only: three runs of the shoulder scene (~10 s in Release) would take minutes under the
// sanitizers, which run the same code paths on the small scene above.
TEST_F(ResumeTest, ShoulderBurrRunResumesBitForBit) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "Release only (three shoulder runs)";
#endif
  const std::string src = ARTHROSIM_SOURCE_DIR;
  const std::string args = "run " + src + "/scenarios/rotator_cuff_repair.yaml --trajectory " +
                           src + "/trajectories/ops/burr.yaml --duration 7 --quiet --out ";
  ASSERT_EQ(Exec(args + P("full.h5")).exit_code, 0);
  const Result k = Exec(args + P("killed.h5"), KillAt(330));
  ASSERT_EQ(k.exit_code, 128 + SIGKILL) << k.output;
  const RunCheckpoints killed_cp(P("killed.h5"));
  ASSERT_EQ(killed_cp.entries().back().step, 250);
  const Result r =
      Exec("run --resume " + P("killed.h5") + " --threads 2 --quiet --out " + P("resumed.h5"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const RunCheckpoints full_cp(P("full.h5")), resumed_cp(P("resumed.h5"));
  ASSERT_EQ(resumed_cp.entries().back().step, 350);
  EXPECT_EQ(resumed_cp.entries().back().state_hash, full_cp.entries().back().state_hash);
  ExpectCheckpointsMatch(resumed_cp, full_cp, "shoulder burr");
  // The burr did carve bone in the resumed part.
  const arthrosim::io::RunReader reader(P("resumed.h5"));
  const arthrosim::State first = reader.Frame(0), last = reader.Frame(reader.frame_count() - 1);
  double carved = 0;
  for (std::size_t b = 0; b < last.bones.size(); ++b) {
    carved += last.bones[b].removed_volume_mm3 - first.bones[b].removed_volume_mm3;
  }
  EXPECT_GT(carved, 0.0);
}
