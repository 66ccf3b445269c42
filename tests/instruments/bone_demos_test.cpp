// The burr and awl demonstrations (trajectories/ops/{burr,awl}.yaml) run by the arthrosim binary
// on the shoulder scene; their outcomes are checked from the run file alone, as scoring reads it.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <string>

#include "arthrosim/io/run_reader.h"

namespace arthrosim {
namespace {

namespace fs = std::filesystem;

const std::string kBinary = std::string(ARTHROSIM_BINARY_DIR) + "/src/cli/arthrosim";
const std::string kSource = ARTHROSIM_SOURCE_DIR;
const std::string kScene = kSource + "/scenarios/rotator_cuff_repair.yaml";

// Runs the demo `name` with `threads` workers into a temporary file; returns its path.
std::string RunDemo(const std::string& name, int threads) {
  const fs::path out =
      fs::temp_directory_path() / ("arthrosim_demo_" + name + "_" + std::to_string(threads) + "_" +
                                   std::to_string(getpid()) + ".h5");  // concurrent test runs apart
  const std::string cmd = kBinary + " run " + kScene + " --trajectory " + kSource +
                          "/trajectories/ops/" + name + ".yaml --threads " +
                          std::to_string(threads) + " --quiet --out " + out.string() + " 2>&1";
  FILE* pipe = popen(cmd.c_str(), "r");
  std::string output;
  std::array<char, 4096> buf{};
  while (pipe != nullptr && std::fgets(buf.data(), buf.size(), pipe)) output += buf.data();
  const int status = pipe != nullptr ? pclose(pipe) : -1;
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << cmd << "\n" << output;
  return out.string();
}

int Count(const std::vector<Event>& events, const std::string& kind) {
  int n = 0;
  for (const Event& e : events) n += e.kind == kind;
  return n;
}

TEST(BoneDemos, BurrRemovesSpurAndFootprintBoneOnly) {
  const std::string path = RunDemo("burr", 1);
  io::RunReader run(path);
  const std::int64_t last = run.frame_count() - 1;
  ASSERT_GT(last, 0);
  const State s = run.Frame(last);
  const auto& bones = run.info().bones;
  const auto acromion = std::find(bones.begin(), bones.end(), "acromion") - bones.begin();
  const auto humerus = std::find(bones.begin(), bones.end(), "humerus") - bones.begin();
  ASSERT_LT(static_cast<std::size_t>(acromion), bones.size());
  ASSERT_LT(static_cast<std::size_t>(humerus), bones.size());
  const BoneState& ac = s.bones[static_cast<std::size_t>(acromion)];
  const BoneState& hu = s.bones[static_cast<std::size_t>(humerus)];
  EXPECT_GT(ac.removed_volume_mm3, 1.0);
  EXPECT_GT(hu.removed_volume_mm3, 0.5);
  // Region columns follow the scenario's regions list; "elsewhere" is last. The spur work is
  // booked to the acromion's spur region, the footprint pass to the footprint: nothing
  // collateral.
  ASSERT_FALSE(ac.removed_by_region_mm3.empty());
  EXPECT_NEAR(ac.removed_by_region_mm3.back(), 0.0, 1e-12);
  EXPECT_NEAR(hu.removed_by_region_mm3.back(), 0.0, 1e-12);
  double ac_booked = 0, hu_booked = 0;
  for (std::size_t r = 0; r + 1 < ac.removed_by_region_mm3.size(); ++r) {
    ac_booked = std::max(ac_booked, ac.removed_by_region_mm3[r]);
    hu_booked = std::max(hu_booked, hu.removed_by_region_mm3[r]);
  }
  EXPECT_NEAR(ac_booked, ac.removed_volume_mm3, 1e-9 * (1 + ac.removed_volume_mm3));
  EXPECT_NEAR(hu_booked, hu.removed_volume_mm3, 1e-9 * (1 + hu.removed_volume_mm3));
  EXPECT_GT(Count(run.EventsUpTo(last), "burr"), 10);
  fs::remove(path);
}

TEST(BoneDemos, AwlDrillsAt45DegreesAndSeatsTheAnchorBitIdenticallyOnOneAndTwoThreads) {
  const std::string p1 = RunDemo("awl", 1);
  const std::string p2 = RunDemo("awl", 2);
  io::RunReader a(p1), b(p2);
  ASSERT_EQ(a.frame_count(), b.frame_count());
  const std::int64_t last = a.frame_count() - 1;
  const State s = a.Frame(last);
  EXPECT_EQ(HashState(s), HashState(b.Frame(last)));
  ASSERT_EQ(s.holes.size(), 1u);
  EXPECT_NEAR(s.holes[0].angle_deg, 45.0, 3.0);
  EXPECT_NEAR(s.holes[0].depth_mm, 6.0, 0.6);
  ASSERT_EQ(s.anchors.size(), 1u);
  EXPECT_NEAR(s.anchors[0].depth_mm, s.holes[0].depth_mm, 1e-12);
  // The scene's two sutures belong to the anchor: absent at the start, hanging from it after.
  const State s0 = a.Frame(0);
  ASSERT_EQ(s0.threads.size(), 2u);
  for (std::size_t t = 0; t < s.threads.size(); ++t) {
    EXPECT_EQ(std::count(s0.threads[t].node_alive.begin(), s0.threads[t].node_alive.end(), 1), 0);
    EXPECT_EQ(std::count(s.threads[t].node_alive.begin(), s.threads[t].node_alive.end(), 0), 0);
    EXPECT_LT((s.threads[t].x.col(0) - s.anchors[0].position_mm).norm(), 0.5);
  }
  const std::vector<Event> events = a.EventsUpTo(last);
  EXPECT_EQ(Count(events, "hole"), 1);
  EXPECT_EQ(Count(events, "anchor"), 1);
  fs::remove(p1);
  fs::remove(p2);
}

}  // namespace
}  // namespace arthrosim
