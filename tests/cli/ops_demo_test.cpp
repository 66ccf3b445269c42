// The cutting and shaving demonstrations (trajectories/ops/*.yaml) run on the shoulder scene with
// the arthrosim binary; each outcome is checked from the run file alone. Disabled: the
// trajectories have not yet been tuned against the scene (tool poses, bite positions), so these
// checks are expected to fail until they are; run them with --gtest_also_run_disabled_tests.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <functional>
#include <numeric>
#include <string>

#include "arthrosim/io/run_reader.h"

namespace arthrosim {
namespace {

const std::string kBinary = std::string(ARTHROSIM_BINARY_DIR) + "/src/cli/arthrosim";
const std::string kSource = ARTHROSIM_SOURCE_DIR;

// Runs trajectories/ops/<name>.yaml on the shoulder scene; returns the run file.
std::string RunDemo(const std::string& name) {
  const std::string out =
      (std::filesystem::temp_directory_path() / ("arthrosim_ops_" + name + ".h5")).string();
  const std::string cmd = kBinary + " run " + kSource + "/scenarios/rotator_cuff_repair.yaml" +
                          " --trajectory " + kSource + "/trajectories/ops/" + name + ".yaml" +
                          " --out " + out + " > /dev/null";
  EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
  return out;
}

int Index(const std::vector<std::string>& names, const std::string& name) {
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (names[i] == name) return static_cast<int>(i);
  }
  return -1;
}

// Connected components of the alive tets (sharing a node connects).
int Components(const SoftBodyState& b) {
  std::vector<int> parent(static_cast<std::size_t>(b.x.cols()));
  std::iota(parent.begin(), parent.end(), 0);
  std::function<int(int)> find = [&](int i) {
    while (parent[static_cast<std::size_t>(i)] != i) i = parent[static_cast<std::size_t>(i)];
    return i;
  };
  std::vector<std::uint8_t> used(parent.size(), 0);
  for (std::size_t t = 0; t < b.tets.size(); ++t) {
    if (!b.tet_alive[t]) continue;
    for (std::int32_t n : b.tets[t]) {
      used[static_cast<std::size_t>(n)] = 1;
      parent[static_cast<std::size_t>(find(n))] = find(b.tets[t][0]);
    }
  }
  int count = 0;
  for (std::size_t i = 0; i < parent.size(); ++i) {
    if (used[i] && find(static_cast<int>(i)) == static_cast<int>(i)) ++count;
  }
  return count;
}

int CountEvents(const std::vector<Event>& events, const std::string& kind,
                const std::string& body) {
  int n = 0;
  for (const Event& e : events) n += e.kind == kind && e.body == body ? 1 : 0;
  return n;
}

TEST(OpsDemo, DISABLED_ScissorsCutTheBicepsInTwo) {
  const io::RunReader run(RunDemo("scissors"));
  const std::int64_t last = run.frame_count() - 1;
  ASSERT_GT(last, 0);
  const int biceps = Index(run.info().soft_bodies, "biceps_tendon");
  ASSERT_GE(biceps, 0);
  EXPECT_EQ(Components(run.Frame(0).soft_bodies[static_cast<std::size_t>(biceps)]), 1);
  const State s = run.Frame(last);
  EXPECT_EQ(Components(s.soft_bodies[static_cast<std::size_t>(biceps)]), 2);
  const std::vector<Event> events = run.EventsUpTo(last);
  EXPECT_GE(CountEvents(events, "cut", "biceps_tendon"), 1);
  EXPECT_GT(s.soft_bodies[static_cast<std::size_t>(biceps)].removed_volume_mm3, 0);
  // Only the biceps was cut.
  EXPECT_EQ(CountEvents(events, "cut", "supraspinatus_tendon"), 0);
  EXPECT_EQ(CountEvents(events, "cut", "supraspinatus_muscle"), 0);
}

TEST(OpsDemo, DISABLED_CutterCutsASutureLimbLeavingTheAnchoredPart) {
  const io::RunReader run(RunDemo("cutter"));
  const std::int64_t last = run.frame_count() - 1;
  const int thread = Index(run.info().threads, "suture_a");
  ASSERT_GE(thread, 0);
  const std::vector<Event> events = run.EventsUpTo(last);
  ASSERT_EQ(CountEvents(events, "thread_cut", "suture_a"), 1);
  const ThreadState& t = run.Frame(last).threads[static_cast<std::size_t>(thread)];
  // A prefix from the anchored node 0 stays, everything after it is gone.
  std::size_t alive = 0;
  while (alive < t.node_alive.size() && t.node_alive[alive]) ++alive;
  EXPECT_GE(alive, 2u);
  EXPECT_LT(alive, t.node_alive.size());
  for (std::size_t n = alive; n < t.node_alive.size(); ++n) EXPECT_EQ(t.node_alive[n], 0) << n;
  // suture_b is untouched.
  for (std::uint8_t a : run.Frame(last).threads[1 - static_cast<std::size_t>(thread)].node_alive) {
    EXPECT_EQ(a, 1);
  }
}

TEST(OpsDemo, DISABLED_ShaverDebridesTheTendonEdge) {
  const io::RunReader run(RunDemo("shaver"));
  const std::int64_t last = run.frame_count() - 1;
  const int tendon = Index(run.info().soft_bodies, "supraspinatus_tendon");
  ASSERT_GE(tendon, 0);
  EXPECT_GE(CountEvents(run.EventsUpTo(last), "shave", "supraspinatus_tendon"), 5);
  const State s = run.Frame(last);
  EXPECT_GT(s.soft_bodies[static_cast<std::size_t>(tendon)].removed_volume_mm3, 0.5);
  for (const SoftBodyState& b : s.soft_bodies) EXPECT_TRUE(b.x.allFinite());
}

TEST(OpsDemo, DISABLED_ElectrocauteryMarksAndTrimsTheTendon) {
  const io::RunReader run(RunDemo("electrocautery"));
  const std::int64_t last = run.frame_count() - 1;
  const int tendon = Index(run.info().soft_bodies, "supraspinatus_tendon");
  ASSERT_GE(tendon, 0);
  EXPECT_GE(CountEvents(run.EventsUpTo(last), "cauterize", "supraspinatus_tendon"), 5);
  const SoftBodyState& b = run.Frame(last).soft_bodies[static_cast<std::size_t>(tendon)];
  int marked = 0;
  for (std::uint8_t m : b.cauterized) marked += m;
  EXPECT_GT(marked, 3);
  EXPECT_GT(b.removed_volume_mm3, 0);
}

}  // namespace
}  // namespace arthrosim
