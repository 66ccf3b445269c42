// End-to-end tests of the arthrosim binary: exit codes, error messages, determinism of the HDF5
// output across thread counts, and a SIGKILLed run leaving a readable file.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include "cli_test_util.h"

namespace {

namespace fs = std::filesystem;

const std::string kBinary = std::string(ARTHROSIM_BINARY_DIR) + "/src/cli/arthrosim";
const std::string kSource = ARTHROSIM_SOURCE_DIR;
const std::string kSmall = kSource + "/tests/testdata/scenes/small.yaml";

std::string Python() { return fs::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3"; }

struct Result {
  int exit_code = -1;
  std::string output;  // stdout + stderr
};

Result Exec(const std::string& args) {
  Result r;
  FILE* pipe = popen((kBinary + " " + args + " 2>&1").c_str(), "r");
  if (!pipe) return r;
  std::array<char, 4096> buf{};
  while (std::fgets(buf.data(), buf.size(), pipe)) r.output += buf.data();
  const int status = pclose(pipe);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

class CliTest : public arthrosim::testing::TempDirTest {
 protected:
  CliTest() : TempDirTest("arthrosim_cli_") {}
};

TEST_F(CliTest, ValidateAcceptsTheShippedScenarios) {
  for (const char* s : {"scenarios/rotator_cuff_repair.yaml", "scenarios/bench_full.yaml"}) {
    const Result r = Exec("validate " + kSource + "/" + s);
    EXPECT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("ok"), std::string::npos) << r.output;
  }
}

TEST_F(CliTest, BadScenarioExitsWithTwoAndNamesFileLineField) {
  std::ifstream in(kSmall);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  text.replace(text.find("poisson_ratio: 0.3"), 18, "poisson_ratio: 0.7");
  fs::copy(fs::path(kSmall).parent_path() / "block.vtk", dir_ / "block.vtk");
  fs::copy(fs::path(kSmall).parent_path() / "bone.obj", dir_ / "bone.obj");
  std::ofstream(P("bad.yaml")) << text;
  const Result r = Exec("validate " + P("bad.yaml"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find(P("bad.yaml") + ":8: field 'materials.soft.poisson_ratio'"),
            std::string::npos)
      << r.output;
  // run refuses it the same way and writes no output file
  const Result run = Exec("run " + P("bad.yaml") + " --quiet --out " + P("x.h5"));
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_FALSE(fs::exists(P("x.h5")));
}

TEST_F(CliTest, UsageErrorsExitWithTwo) {
  EXPECT_EQ(Exec("").exit_code, 2);
  EXPECT_EQ(Exec("run").exit_code, 2);
  EXPECT_EQ(Exec("run " + kSmall + " --steps 3 --duration 1").exit_code, 2);
  EXPECT_EQ(
      Exec("run " + kSmall + " --trajectory nowhere.csv --quiet --out " + P("y.h5")).exit_code, 2);
  EXPECT_EQ(Exec("info " + P("missing.yaml")).exit_code, 2);
}

TEST_F(CliTest, RunIsByteIdenticalForOneAndTwoThreads) {
  const Result a = Exec("run " + kSmall + " --steps 15 --threads 1 --quiet --out " + P("a.h5"));
  const Result b = Exec("run " + kSmall + " --steps 15 --threads 2 --quiet --out " + P("b.h5"));
  ASSERT_EQ(a.exit_code, 0) << a.output;
  ASSERT_EQ(b.exit_code, 0) << b.output;
  const std::string cmp =
      Python() + " " + kSource + "/tests/io/compare_runs.py " + P("a.h5") + " " + P("b.h5");
  EXPECT_EQ(std::system(cmp.c_str()), 0) << cmp;
  // and a different run does differ, so the comparison can fail
  const Result c = Exec("run " + kSmall + " --steps 16 --quiet --out " + P("c.h5"));
  ASSERT_EQ(c.exit_code, 0) << c.output;
  const std::string cmp2 = Python() + " " + kSource + "/tests/io/compare_runs.py " + P("a.h5") +
                           " " + P("c.h5") + " --quiet";
  EXPECT_NE(std::system(cmp2.c_str()), 0);
}

// The run's summary counts the thread solves that stopped unconverged (one or more solves per
// step on a scene with a thread: the small scene has one).
TEST_F(CliTest, RunReportsUnconvergedThreadSolves) {
  const Result r = Exec("run " + kSmall + " --steps 15 --out " + P("t.h5"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string key = "thread solves unconverged: ";
  const std::size_t at = r.output.find(key);
  ASSERT_NE(at, std::string::npos) << r.output;
  long long unconverged = -1, solves = -1;
  ASSERT_EQ(std::sscanf(r.output.c_str() + at + key.size(), "%lld of %lld", &unconverged, &solves),
            2)
      << r.output;
  EXPECT_GE(solves, 15) << r.output;
  EXPECT_GE(unconverged, 0);
  EXPECT_LE(unconverged, solves);
}

TEST_F(CliTest, InfoSummarisesARun) {
  ASSERT_EQ(Exec("run " + kSmall + " --steps 5 --quiet --out " + P("r.h5")).exit_code, 0);
  const Result r = Exec("info " + P("r.h5"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("frames: 6"), std::string::npos) << r.output;
}

// A step that diverges even in substeps (docs/numerical-guards.md) stops the run with exit 3,
// a message naming the step and the node, and a closed file holding every step before it.
TEST_F(CliTest, DivergedRunStopsWithExitThreeAndAReadableFile) {
  const std::string scenario = kSource + "/tests/testdata/scenes/small_diverge.yaml";
  const Result r = Exec("run " + scenario + " --steps 50 --quiet --out " + P("d.h5"));
  EXPECT_EQ(r.exit_code, 3) << r.output;
  EXPECT_NE(r.output.find("error: step 4 (t = 0.0800 s): the deformable solve diverged (soft "
                          "body 'block' node "),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("holds 4 frames up to step 3"), std::string::npos) << r.output;
  const Result info = Exec("info " + P("d.h5"));
  EXPECT_EQ(info.exit_code, 0) << info.output;
  EXPECT_NE(info.output.find("frames: 4 (steps 0 .. 3)"), std::string::npos) << info.output;
}

TEST_F(CliTest, KilledRunLeavesAReadableFile) {
  const std::string out = P("killed.h5");
  // a long run (flushes every 0.1 simulated s in this scenario)
  const pid_t pid = arthrosim::testing::SpawnRun(kBinary, kSmall, "1000000", out);
  ASSERT_GE(pid, 0);
  // wait until some frames are durable, then kill -9
  std::this_thread::sleep_for(std::chrono::milliseconds(2500));
  kill(pid, SIGKILL);
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status));
  const std::string check = Python() + " -c \"import h5py,sys; f=h5py.File('" + out +
                            "','r',swmr=True); n=f['time'].shape[0]; "
                            "p=f['bodies/block/positions_offset'][:n]; sys.exit(0 if n>5 and "
                            "p.shape[0]==n and (f['time'][1:n]>f['time'][:n-1]).all() else 1)\"";
  EXPECT_EQ(std::system(check.c_str()), 0) << check;
  // Its ParaView sidecar can be rebuilt from the file: frames listed 0.2 s apart (10 steps here),
  // the last stored frame included.
  const Result x = Exec("info " + out + " --write-xdmf");
  EXPECT_EQ(x.exit_code, 0) << x.output;
  std::ifstream xmf(P("killed.xmf"));
  const std::string text((std::istreambuf_iterator<char>(xmf)), {});
  std::size_t frames = 0;
  for (std::size_t p = text.find("<Time "); p != std::string::npos; p = text.find("<Time ", p + 1))
    ++frames;
  EXPECT_GT(frames, 5u) << x.output;
  const std::size_t at = x.output.find("frames: ");
  ASSERT_NE(at, std::string::npos) << x.output;
  const long stored = std::stol(x.output.substr(at + 8));
  EXPECT_EQ(frames, static_cast<std::size_t>((stored - 2) / 10 + 2)) << x.output;
  EXPECT_NE(text.find("Name=\"frame" + std::to_string(stored - 1) + "\""), std::string::npos);
}

// --igtl-device mappings are checked before the scenario is loaded: a bad target, or a mapping
// without live input, exits 2 naming the option and writes nothing.
TEST_F(CliTest, IgtlDeviceMappingIsChecked) {
  const std::string tail = " --steps 1 --quiet --out " + P("x.h5");
  Result r = Exec("run " + kSmall +
                  " --trajectory igtl:127.0.0.1:0 --igtl-device StylusToTracker=hand" + tail);
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--igtl-device: 'StylusToTracker=hand': unknown target 'hand' (slot0, "
                          "slot1, scope, ignore)"),
            std::string::npos)
      << r.output;
  r = Exec("serve " + kSmall + " --igtl-device StylusToTracker --quiet --out " + P("x.h5"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("expected NAME=slot0|slot1|scope|ignore"), std::string::npos) << r.output;
  r = Exec("run " + kSmall + " --igtl-device StylusToTracker=slot0" + tail);
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("needs --trajectory igtl"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(P("x.h5")));
}

// A live session over OpenIGTLink (arthrosim serve + the streaming client), recorded with
// --record, replays with `run --trajectory` to byte-identical HDF5 datasets; forces come back.
// `run --trajectory igtl:...` is live as `serve` is: it ends with the device's session (a
// 1.5 s session: 75 steps), not 180 000 steps later.
TEST_F(CliTest, RunWithLiveInputEndsWithTheSession) {
  const std::string client = std::string(ARTHROSIM_BINARY_DIR) + "/src/input/igtl_stream_client";
  if (!fs::exists(client)) GTEST_SKIP() << "built without OpenIGTLink";
  const std::string port = std::to_string(20000 + (getpid() + 7919) % 20000);
  const std::string live = P("live.h5");
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    const std::string spec = "igtl:127.0.0.1:" + port;
    execl(kBinary.c_str(), kBinary.c_str(), "run", kSmall.c_str(), "--trajectory", spec.c_str(),
          "--out", live.c_str(), "--quiet", static_cast<char*>(nullptr));
    _exit(127);
  }
  const std::string stream = client + " " + kSource +
                             "/tests/testdata/scenes/small_session.csv --port " + port + " > " +
                             P("client.log") + " 2>&1";
  ASSERT_NO_FATAL_FAILURE(arthrosim::testing::StreamThenWaitForServer(stream, pid));
  const Result info = Exec("info " + live);
  EXPECT_EQ(info.exit_code, 0) << info.output;
  const std::size_t at = info.output.find("frames: ");
  ASSERT_NE(at, std::string::npos) << info.output;
  const long frames = std::stol(info.output.substr(at + 8));
  EXPECT_GT(frames, 50) << info.output;
  EXPECT_LT(frames, 200) << info.output;
}

TEST_F(CliTest, ServeRecordReplayReproducesTheLiveRun) {
  const std::string client = std::string(ARTHROSIM_BINARY_DIR) + "/src/input/igtl_stream_client";
  if (!fs::exists(client)) GTEST_SKIP() << "built without OpenIGTLink";
  const std::string port = std::to_string(20000 + getpid() % 20000);
  const std::string live = P("live.h5"), rec = P("rec.csv");
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    execl(kBinary.c_str(), kBinary.c_str(), "serve", kSmall.c_str(), "--port", port.c_str(),
          "--record", rec.c_str(), "--out", live.c_str(), "--quiet", static_cast<char*>(nullptr));
    _exit(127);
  }
  // the client retries until the server listens
  const std::string stream = client + " " + kSource +
                             "/tests/testdata/scenes/small_session.csv --port " + port +
                             " --forces " + P("forces.csv") + " > " + P("client.log") + " 2>&1";
  ASSERT_NO_FATAL_FAILURE(arthrosim::testing::StreamThenWaitForServer(stream, pid));

  const Result replay =
      Exec("run " + kSmall + " --trajectory " + rec + " --quiet --out " + P("replay.h5"));
  ASSERT_EQ(replay.exit_code, 0) << replay.output;
  const std::string cmp = Python() + " " + kSource + "/tests/io/compare_runs.py " + live + " " +
                          P("replay.h5") + " --ignore-event realtime_lag";
  EXPECT_EQ(std::system(cmp.c_str()), 0) << cmp;

  // the grasper pressed on the block: some force message is non-zero
  std::ifstream forces(P("forces.csv"));
  std::string line;
  int rows = 0;
  double max_force = 0;
  std::getline(forces, line);  // header
  while (std::getline(forces, line)) {
    ++rows;
    double t, fx, fy, fz;
    int slot;
    if (std::sscanf(line.c_str(), "%lf,%d,%lf,%lf,%lf", &t, &slot, &fx, &fy, &fz) == 5) {
      max_force = std::max(max_force, std::sqrt(fx * fx + fy * fy + fz * fz));
    }
  }
  EXPECT_GT(rows, 10);
  EXPECT_GT(max_force, 0.0);
}

}  // namespace
