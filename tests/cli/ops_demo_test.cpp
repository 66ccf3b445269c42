// The cutting and shaving demonstrations (trajectories/ops/*.yaml) run on the shoulder scene with
// the arthrosim binary (by the fixture tests Run.ops_<name>); each outcome is checked from the run
// file alone (plus the scenario, for landmark positions and fixed regions): pieces, volumes, events
// and where they happened.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <numeric>
#include <string>
#include <vector>

#include "arthrosim/io/run_reader.h"
#include "arthrosim/io/scenario_loader.h"
#include "run_state_util.h"

namespace arthrosim {
namespace {

using testing::ComponentOf;

const std::string kSource = ARTHROSIM_SOURCE_DIR;

// The run of trajectories/ops/<name>.yaml on the shoulder scene, made once by the fixture test
// Run.ops_<name> (tests/cli/CMakeLists.txt) and shared with its golden comparison.
std::string RunDemo(const std::string& name) {
  const std::string run = std::string(ARTHROSIM_BINARY_DIR) + "/test_runs/ops_" + name + ".h5";
  EXPECT_TRUE(std::filesystem::exists(run)) << run << ": run by the CTest Run.ops_" << name;
  return run;
}

int Index(const std::vector<std::string>& names, const std::string& name) {
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (names[i] == name) return static_cast<int>(i);
  }
  return -1;
}

const Model& Shoulder() {
  static const Model model = io::LoadScenario(kSource + "/scenarios/rotator_cuff_repair.yaml");
  return model;
}

Vec3 LandmarkMm(const std::string& name) {
  const int i = Shoulder().FindLandmark(name);
  EXPECT_GE(i, 0) << name;
  return i < 0 ? Vec3::Zero() : Shoulder().landmarks[static_cast<std::size_t>(i)].position_mm;
}

int Components(const SoftBodyState& b) {
  const std::vector<int> label = ComponentOf(b);
  int count = 0;
  for (std::size_t i = 0; i < label.size(); ++i) count += label[i] == static_cast<int>(i) ? 1 : 0;
  return count;
}

int CountEvents(const std::vector<Event>& events, const std::string& kind,
                const std::string& body) {
  int n = 0;
  for (const Event& e : events) n += e.kind == kind && e.body == body ? 1 : 0;
  return n;
}

// The value of `key=` in an event detail (0 when absent).
double DetailValue(const Event& e, const std::string& key) {
  const std::size_t at = e.detail.find(key + "=");
  return at == std::string::npos ? 0.0 : std::atof(e.detail.c_str() + at + key.size() + 1);
}

// Largest distance from `at` to an event of `kind` on `body`, mm.
double FarthestEvent(const std::vector<Event>& events, const std::string& kind,
                     const std::string& body, const Vec3& at) {
  double far = 0;
  for (const Event& e : events) {
    if (e.kind == kind && e.body == body) far = std::max(far, (e.position_mm - at).norm());
  }
  return far;
}

// The run file stores positions, not rest positions or velocities (docs/hdf5-layout.md): tets are
// located by their centroid at frame 0 and measured by their volume at a frame.
Vec3 Centroid(const Points& x, const mesh::Tet& q) {
  return (x.col(q[0]) + x.col(q[1]) + x.col(q[2]) + x.col(q[3])) / 4.0;
}

double Volume(const Points& x, const mesh::Tet& q) {
  const Vec3 a = x.col(q[0]);
  return std::abs((x.col(q[1]) - a).cross(x.col(q[2]) - a).dot(x.col(q[3]) - a)) / 6.0;
}

// Volume of the alive tets of `now` split by where the tet's centroid was at frame 0 (within
// `radius_mm` of `at` or not), mm^3.
struct SplitVolume {
  double near_mm3 = 0, far_mm3 = 0;
};
SplitVolume VolumeAround(const SoftBodyState& start, const SoftBodyState& now, const Vec3& at,
                         double radius_mm) {
  SplitVolume v;
  for (std::size_t t = 0; t < now.tets.size(); ++t) {
    if (!now.tet_alive[t]) continue;
    const bool near =
        t < start.tets.size() && (Centroid(start.x, start.tets[t]) - at).norm() <= radius_mm;
    (near ? v.near_mm3 : v.far_mm3) += Volume(now.x, now.tets[t]);
  }
  return v;
}

// Largest node speed between frames k-1 and k, mm/s.
double MaxSpeedMmS(const io::RunReader& run, std::int64_t k, int body) {
  const Points a = run.Frame(k - 1).soft_bodies[static_cast<std::size_t>(body)].x;
  const Points b = run.Frame(k).soft_bodies[static_cast<std::size_t>(body)].x;
  double m = 0;
  for (int i = 0; i < b.cols(); ++i) m = std::max(m, (b.col(i) - a.col(i)).norm());
  return m / (run.time(k) - run.time(k - 1));
}

// Biceps tenotomy: the cut happens at biceps_cut_site, only the biceps is cut, and the tendon ends
// in two pieces, each still held by one of its fixed ends.
TEST(OpsDemo, ScissorsCutTheBicepsInTwo) {
  const io::RunReader run(RunDemo("scissors"));
  const std::int64_t last = run.frame_count() - 1;
  ASSERT_GT(last, 0);
  const int biceps = Index(run.info().soft_bodies, "biceps_tendon");
  ASSERT_GE(biceps, 0);
  const State s0 = run.Frame(0);
  const SoftBodyState& start = s0.soft_bodies[static_cast<std::size_t>(biceps)];
  EXPECT_EQ(Components(start), 1);
  const State s = run.Frame(last);
  const SoftBodyState& b = s.soft_bodies[static_cast<std::size_t>(biceps)];
  EXPECT_EQ(Components(b), 2);
  const std::vector<Event> events = run.EventsUpTo(last);
  EXPECT_GE(CountEvents(events, "cut", "biceps_tendon"), 1);
  // Only the biceps was cut.
  EXPECT_EQ(CountEvents(events, "cut", "supraspinatus_tendon"), 0);
  EXPECT_EQ(CountEvents(events, "cut", "supraspinatus_muscle"), 0);
  // Where: every cut event and every removed tet near biceps_cut_site.
  const Vec3 site = LandmarkMm("biceps_cut_site");
  const double event_far = FarthestEvent(events, "cut", "biceps_tendon", site);
  const mesh::TetMesh& rest = Shoulder().soft_bodies[static_cast<std::size_t>(biceps)].rest_mesh;
  double tet_far = 0, removed_rest = 0, event_volume = 0;
  for (std::size_t t = 0; t < start.tets.size(); ++t) {
    if (b.tet_alive[t]) continue;
    tet_far = std::max(tet_far, (Centroid(start.x, start.tets[t]) - site).norm());
    removed_rest += Volume(rest.nodes, rest.tets[t]);
  }
  for (const Event& e : events) event_volume += e.kind == "cut" ? DetailValue(e, "volume_mm3") : 0;
  std::printf(
      "scissors: %d cuts, farthest cut event %.2f mm and removed tet %.2f mm from "
      "biceps_cut_site, removed %.3f mm^3 (events %.3f)\n",
      CountEvents(events, "cut", "biceps_tendon"), event_far, tet_far, b.removed_volume_mm3,
      event_volume);
  EXPECT_LT(event_far, 6.0);
  EXPECT_LT(tet_far, 7.0);
  EXPECT_NEAR(b.removed_volume_mm3, removed_rest, 1e-9 * removed_rest);
  EXPECT_NEAR(b.removed_volume_mm3, event_volume, 1e-6 * event_volume);
  // Each piece holds the nodes of exactly one fixed end.
  const std::vector<int> label = ComponentOf(b);
  std::vector<int> piece_of_end;
  for (const char* end : {"biceps_ends_proximal", "biceps_ends_distal"}) {
    const Region& r = Shoulder().regions[static_cast<std::size_t>(Shoulder().FindRegion(end))];
    std::vector<int> pieces;
    for (std::int32_t n : r.nodes) pieces.push_back(label[static_cast<std::size_t>(n)]);
    std::sort(pieces.begin(), pieces.end());
    pieces.erase(std::unique(pieces.begin(), pieces.end()), pieces.end());
    ASSERT_EQ(pieces.size(), 1u) << end;
    EXPECT_GE(pieces[0], 0) << end;
    piece_of_end.push_back(pieces[0]);
  }
  EXPECT_NE(piece_of_end[0], piece_of_end[1]);
  // The stumps part: the nearest nodes of the two pieces are apart.
  double gap = 1e300;
  for (int i = 0; i < b.x.cols(); ++i) {
    for (int j = 0; j < b.x.cols(); ++j) {
      if (label[static_cast<std::size_t>(i)] != piece_of_end[0] ||
          label[static_cast<std::size_t>(j)] != piece_of_end[1])
        continue;
      gap = std::min(gap, (b.x.col(i) - b.x.col(j)).norm());
    }
  }
  std::printf("scissors: stump gap %.3f mm, max speed %.3g mm/s\n", gap,
              MaxSpeedMmS(run, last, biceps));
  EXPECT_GT(gap, 0.5);
  EXPECT_TRUE(b.x.allFinite());
}

// Cutting a suture limb near the anchor: the limb lying nearest the blades (suture_b) is cut once,
// a bone-side prefix from the anchored node 0 stays where it was, the rest of the limb is gone,
// and the other limb is whole.
TEST(OpsDemo, CutterCutsASutureLimbLeavingTheAnchoredPart) {
  const io::RunReader run(RunDemo("cutter"));
  const std::int64_t last = run.frame_count() - 1;
  const int thread = Index(run.info().threads, "suture_b");
  ASSERT_GE(thread, 0);
  const std::vector<Event> events = run.EventsUpTo(last);
  ASSERT_EQ(CountEvents(events, "thread_cut", "suture_b"), 1);
  EXPECT_EQ(CountEvents(events, "thread_cut", "suture_a"), 0);
  std::int64_t cut_step = 0;
  for (const Event& e : events) cut_step = e.kind == "thread_cut" ? e.step : cut_step;
  const double cut_from_anchor =
      FarthestEvent(events, "thread_cut", "suture_b", LandmarkMm("anchor_site_1"));
  const State s = run.Frame(last);
  const ThreadState& t = s.threads[static_cast<std::size_t>(thread)];
  // A prefix from the anchored node 0 stays, everything after it is gone.
  std::size_t alive = 0;
  while (alive < t.node_alive.size() && t.node_alive[alive]) ++alive;
  EXPECT_GE(alive, 2u);
  EXPECT_LT(alive, t.node_alive.size());
  for (std::size_t n = alive; n < t.node_alive.size(); ++n) EXPECT_EQ(t.node_alive[n], 0) << n;
  // The anchored node does not move once the limb is cut.
  const Vec3 held = run.Frame(cut_step - 1).threads[static_cast<std::size_t>(thread)].x.col(0);
  const double drift = (t.x.col(0) - held).norm();
  std::printf(
      "cutter: cut at step %lld, %.2f mm from anchor_site_1, %zu of %zu nodes stay, "
      "anchored node moved %.3g mm after the cut\n",
      static_cast<long long>(cut_step), cut_from_anchor, alive, t.node_alive.size(), drift);
  EXPECT_LT(cut_from_anchor, 12.0);
  EXPECT_LT(drift, 0.1);
  EXPECT_TRUE(t.x.allFinite());
  // suture_a is untouched.
  for (std::uint8_t a : s.threads[1 - static_cast<std::size_t>(thread)].node_alive) {
    EXPECT_EQ(a, 1);
  }
}

// A demonstration on the supraspinatus tendon's edge read back: its `kind` events on the tendon,
// how far from tear_edge_center the farthest one was, and the tendon at frame 0 and at the end.
struct EdgeDemo {
  EdgeDemo(const std::string& name, const std::string& kind)
      : run(RunDemo(name)),
        last(run.frame_count() - 1),
        tendon(Index(run.info().soft_bodies, "supraspinatus_tendon")),
        events(run.EventsUpTo(last)),
        edge(LandmarkMm("tear_edge_center")),
        event_count(CountEvents(events, kind, "supraspinatus_tendon")),
        event_far(FarthestEvent(events, kind, "supraspinatus_tendon", edge)) {
    EXPECT_GE(event_count, 5) << name;
    EXPECT_GE(tendon, 0);
    if (tendon < 0) return;
    start = run.Frame(0).soft_bodies[static_cast<std::size_t>(tendon)];
    end = run.Frame(last);
  }
  /// The tendon at the end.
  const SoftBodyState& Tendon() const { return end.soft_bodies[static_cast<std::size_t>(tendon)]; }

  const io::RunReader run;
  const std::int64_t last;
  const int tendon;
  const std::vector<Event> events;
  const Vec3 edge;
  const int event_count;
  const double event_far;
  SoftBodyState start;
  State end;
};

// Debridement of the tendon edge: material goes at tear_edge_center only (the volume of the
// tendon's tets within 10 mm of it falls by what was booked as removed, within 2 %; elsewhere it
// changes by less than 1 % of that), and the tendon is finite and at rest afterwards.
TEST(OpsDemo, ShaverDebridesTheTendonEdge) {
  const EdgeDemo demo("shaver", "shave");
  ASSERT_GE(demo.tendon, 0);
  const auto& [run, last, tendon, events, edge, event_count, event_far, start, s] = demo;
  const SoftBodyState& b = demo.Tendon();
  constexpr double kRegionMm = 10.0;
  const SplitVolume before = VolumeAround(start, start, edge, kRegionMm);
  const SplitVolume after = VolumeAround(start, b, edge, kRegionMm);
  std::printf(
      "shaver: %d shaves, farthest %.2f mm from tear_edge_center; volume within "
      "%.0f mm %.3f -> %.3f mm^3 (removed %.3f), elsewhere %.6f -> %.6f mm^3; "
      "max speed %.3g mm/s\n",
      event_count, event_far, kRegionMm, before.near_mm3, after.near_mm3, b.removed_volume_mm3,
      before.far_mm3, after.far_mm3, MaxSpeedMmS(run, last, tendon));
  EXPECT_LT(event_far, 6.0);
  EXPECT_GT(b.removed_volume_mm3, 0.5);
  EXPECT_NEAR(before.near_mm3 - after.near_mm3, b.removed_volume_mm3, 0.02 * b.removed_volume_mm3);
  EXPECT_NEAR(after.far_mm3, before.far_mm3, 0.01 * b.removed_volume_mm3);
  for (const SoftBodyState& body : s.soft_bodies) EXPECT_TRUE(body.x.allFinite());
  EXPECT_LT(MaxSpeedMmS(run, last, tendon), 50.0);
}

// Cautery along the tendon edge: marks and trimming at tear_edge_center, nowhere else (marks are
// located where their nodes were at frame 0, so a tendon dragged along by the probe fails).
TEST(OpsDemo, ElectrocauteryMarksAndTrimsTheTendon) {
  const EdgeDemo demo("electrocautery", "cauterize");
  ASSERT_GE(demo.tendon, 0);
  const auto& [run, last, tendon, events, edge, event_count, event_far, start, s] = demo;
  const SoftBodyState& b = demo.Tendon();
  int marked = 0;
  double mark_far = 0;
  for (std::size_t n = 0; n < b.cauterized.size(); ++n) {
    if (!b.cauterized[n]) continue;
    ++marked;
    mark_far = std::max(mark_far, (start.x.col(static_cast<int>(n)) - edge).norm());
  }
  std::printf(
      "electrocautery: %d events, farthest %.2f mm from tear_edge_center; %d nodes "
      "marked, farthest %.2f mm; removed %.3f mm^3\n",
      event_count, event_far, marked, mark_far, b.removed_volume_mm3);
  EXPECT_LT(event_far, 8.0);  // the sweep runs 6 mm either side of the landmark
  EXPECT_GE(marked, 5);
  EXPECT_LT(mark_far, 8.0);
  EXPECT_GT(b.removed_volume_mm3, 1.0);
  const SplitVolume before = VolumeAround(start, start, edge, 10.0);
  const SplitVolume after = VolumeAround(start, b, edge, 10.0);
  std::printf("electrocautery: volume within 10 mm %.3f -> %.3f mm^3, elsewhere %.6f -> %.6f\n",
              before.near_mm3, after.near_mm3, before.far_mm3, after.far_mm3);
  EXPECT_NEAR(before.near_mm3 - after.near_mm3, b.removed_volume_mm3, 0.02 * b.removed_volume_mm3);
  EXPECT_NEAR(after.far_mm3, before.far_mm3, 0.01 * b.removed_volume_mm3);
  // No other body is marked.
  for (std::size_t i = 0; i < s.soft_bodies.size(); ++i) {
    if (static_cast<int>(i) == tendon) continue;
    for (std::uint8_t m : s.soft_bodies[i].cauterized) EXPECT_EQ(m, 0) << i;
  }
}

}  // namespace
}  // namespace arthrosim
