// The grasping demonstrations (trajectories/ops/{grasper,retriever,hook}.yaml) run by the
// arthrosim binary on the shoulder scene; each outcome is checked from the run file alone (the
// scenario only for its region and landmark definitions), as scoring reads it.

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "arthrosim/io/run_reader.h"
#include "arthrosim/io/scenario_loader.h"
#include "run_state_util.h"

namespace arthrosim {
namespace {

using testing::EndAt;

const std::string kSource = ARTHROSIM_SOURCE_DIR;
const std::string kScene = kSource + "/scenarios/rotator_cuff_repair.yaml";

// The run of trajectories/ops/<name>.yaml on the shoulder scene, made once by the fixture test
// Run.ops_<name> (tests/cli/CMakeLists.txt) and shared with its golden comparison.
std::string RunDemo(const std::string& name) {
  const std::string run = std::string(ARTHROSIM_BINARY_DIR) + "/test_runs/ops_" + name + ".h5";
  EXPECT_TRUE(std::filesystem::exists(run)) << run << ": run by the CTest Run.ops_" << name;
  return run;
}

// A demonstration's run file, open for reading (it stays in test_runs/: the golden comparison
// Golden.ops_<name> reads it too, possibly after this test).
struct DemoRun {
  explicit DemoRun(const std::string& name)
      : path(RunDemo(name)), run(path), last(run.frame_count() - 1) {}
  const std::string path;
  const io::RunReader run;
  const std::int64_t last;  ///< the last frame
};

std::vector<Event> OfKind(const std::vector<Event>& events, const std::string& kind) {
  std::vector<Event> out;
  for (const Event& e : events)
    if (e.kind == kind) out.push_back(e);
  return out;
}

const SpringConstraint* Tagged(const State& s, const std::string& tag) {
  for (const SpringConstraint& c : s.constraints)
    if (c.tag == tag) return &c;
  return nullptr;
}

// How far the tool of slot 0 moved from frame a to frame b.
Vec3 ToolMoved(const State& a, const State& b) {
  return b.tools[0].pose.position_mm - a.tools[0].pose.position_mm;
}

// From frame a to frame b the tool moved `distance_mm` (within 1 mm) and `moved` came along its
// direction by as much (within 1 mm): `what` happened.
void ExpectDrawnAlong(const State& a, const State& b, const Vec3& moved, double distance_mm,
                      const char* what) {
  const Vec3 tool_moved = ToolMoved(a, b);
  EXPECT_NEAR(tool_moved.norm(), distance_mm, 1.0);
  EXPECT_NEAR(moved.dot(tool_moved.normalized()), tool_moved.norm(), 1.0) << what;
}

Vec3 Centroid(const Points& x, const std::vector<std::int32_t>& nodes) {
  Vec3 c = Vec3::Zero();
  for (const std::int32_t n : nodes) c += x.col(n);
  return c / static_cast<double>(nodes.size());
}

TEST(GraspDemos, GrasperReducesTheTearEdgeTowardTheFootprint) {
  const Model model = io::LoadScenario(kScene);
  const DemoRun demo("grasper");
  const auto& [path, run, last] = demo;
  ASSERT_GT(last, 0);
  const std::vector<Event> events = run.EventsUpTo(last);
  const std::vector<Event> grasps = OfKind(events, "grasp");
  const std::vector<Event> releases = OfKind(events, "release");
  ASSERT_EQ(grasps.size(), 1u);
  EXPECT_EQ(grasps[0].body, "supraspinatus_tendon");
  ASSERT_EQ(releases.size(), 1u);
  EXPECT_NE(releases[0].detail.find("reason=jaw_open"), std::string::npos) << releases[0].detail;
  // While held, the grasped tissue point follows the tool within 1 mm.
  const int tendon = model.FindSoftBody("supraspinatus_tendon");
  const Region& edge = model.regions[static_cast<std::size_t>(model.FindRegion("tendon_edge"))];
  const Vec3 footprint =
      model.landmarks[static_cast<std::size_t>(model.FindLandmark("footprint_center"))].position_mm;
  int held_frames = 0;
  double worst_mm = 0;
  std::int64_t last_held = -1;
  for (std::int64_t k = 0; k <= last; ++k) {
    const State s = run.Frame(k);
    const SpringConstraint* c = Tagged(s, "grasp");
    if (c == nullptr) continue;
    ++held_frames;
    last_held = k;
    worst_mm = std::max(worst_mm, (EndAt(s, c->a) - EndAt(s, c->b)).norm());
  }
  EXPECT_GT(held_frames, 50);
  EXPECT_LT(worst_mm, 1.0);
  // The torn edge (region centroid) came at least 4 mm closer to the footprint centre.
  const State first = run.Frame(0), held = run.Frame(last_held);
  const Points& x0 = first.soft_bodies[static_cast<std::size_t>(tendon)].x;
  const Points& x1 = held.soft_bodies[static_cast<std::size_t>(tendon)].x;
  const double before_mm = (Centroid(x0, edge.nodes) - footprint).norm();
  const double after_mm = (Centroid(x1, edge.nodes) - footprint).norm();
  EXPECT_GT(before_mm - after_mm, 4.0) << before_mm << " -> " << after_mm;
  EXPECT_TRUE(x1.allFinite());
}

TEST(GraspDemos, RetrieverDrawsALimbOutByTheCommandedDistance) {
  const DemoRun demo("retriever");
  const auto& [path, run, last] = demo;
  ASSERT_GT(last, 0);
  const std::vector<Event> grasps = OfKind(run.EventsUpTo(last), "grasp");
  ASSERT_EQ(grasps.size(), 1u);
  EXPECT_EQ(grasps[0].body.rfind("suture_", 0), 0u) << grasps[0].body;
  // The pull: from the first held frame to the first frame of the hold that follows it (the
  // tool still), the tool drew back 15 mm (the script's push) and the node came with it.
  std::int64_t k0 = -1, k1 = -1;
  for (std::int64_t k = 0; k < last && k1 < 0; ++k) {
    const State s = run.Frame(k), next = run.Frame(k + 1);
    if (Tagged(s, "grasp") == nullptr) continue;
    if (k0 < 0) k0 = k;
    if (k > k0 + 10 && (s.tools[0].pose.position_mm - next.tools[0].pose.position_mm).norm() < 1e-9)
      k1 = k;
  }
  ASSERT_GE(k0, 0);
  ASSERT_GT(k1, k0);
  const State a = run.Frame(k0), b = run.Frame(k1);
  const SpringConstraint* c = Tagged(b, "grasp");
  ASSERT_NE(c, nullptr) << "still held at the end of the pull";
  const Vec3 node_moved = EndAt(b, c->b) - EndAt(a, c->b);
  ExpectDrawnAlong(a, b, node_moved, 15.0, "the node drawn by the commanded distance");
  EXPECT_LT((node_moved - ToolMoved(a, b)).norm(), 1.5);
}

TEST(GraspDemos, HookPullsALoopOfALimbOutByTheCommandedDistance) {
  const DemoRun demo("hook");
  const auto& [path, run, last] = demo;
  ASSERT_GT(last, 0);
  const std::vector<Event> events = run.EventsUpTo(last);
  const std::vector<Event> catches = OfKind(events, "hook_catch");
  ASSERT_EQ(catches.size(), 1u);
  EXPECT_EQ(catches[0].body, "suture_a");
  // From the frame of the snag (the hook turning in place) to the first frame of the hold after
  // the 10 mm draw: the thread point in the bend moved with the hook.
  std::int64_t k0 = -1, k1 = -1;
  Vec3 tip0 = Vec3::Zero();
  for (std::int64_t k = 0; k < last && k1 < 0; ++k) {
    const State s = run.Frame(k), next = run.Frame(k + 1);
    if (Tagged(s, "hook") == nullptr) continue;
    if (k0 < 0) k0 = k, tip0 = s.tools[0].pose.position_mm;
    const Vec3 tip = s.tools[0].pose.position_mm;
    if ((tip - tip0).norm() > 5 && (tip - next.tools[0].pose.position_mm).norm() < 1e-9) k1 = k;
  }
  ASSERT_GE(k0, 0);
  ASSERT_GT(k1, k0);
  const State a = run.Frame(k0), b = run.Frame(k1);
  const SpringConstraint* c0 = Tagged(a, "hook");
  const SpringConstraint* c1 = Tagged(b, "hook");
  ASSERT_NE(c1, nullptr) << "still held at the end of the draw";
  const Vec3 thread_moved = EndAt(b, c1->b) - EndAt(a, c0->b);
  ExpectDrawnAlong(a, b, thread_moved, 10.0, "the loop came out by the commanded distance");
  EXPECT_LT((EndAt(b, c1->a) - EndAt(b, c1->b)).norm(), 3.0);
  EXPECT_TRUE(b.threads[0].x.allFinite());
}

}  // namespace
}  // namespace arthrosim
