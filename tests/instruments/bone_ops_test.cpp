// Burr, awl and anchor on a 30 x 30 x 16 mm bone box (tests/testdata/scenes/bone_ops.yaml):
// outcomes measured on the surface (volumes, moved vertices, hole shape, anchor position).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <string>

#include "arthrosim/collision/proximity.h"
#include "arthrosim/core/parallel.h"
#include "arthrosim/core/units.h"
#include "arthrosim/instruments/instruments.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/physics/bone_surface.h"
#include "arthrosim/sim/step.h"
#include "arthrosim/sim/workspace.h"

namespace arthrosim::instruments {
namespace {

constexpr double kTop = 16;  // the box's top face, z (mm)

Model BoneModelScene() {
  return io::LoadScenario(std::string(ARTHROSIM_SOURCE_DIR) +
                          "/tests/testdata/scenes/bone_ops.yaml");
}

// Tool pose with the tip at `tip` and +z (forward) along `dir`.
Pose Aim(const Vec3& tip, const Vec3& dir) {
  Pose p;
  p.position_mm = tip;
  p.orientation = Quat::FromTwoVectors(Vec3::UnitZ(), dir.normalized());
  return p;
}

// One instruments stage at the next step (the clock advanced first, as in sim::Step). The hand is
// where the tool is (no press: as with the proxy off), so the tools act at their poses.
void Act(const Model& m, State* s) {
  for (ToolState& tool : s->tools) tool.handle_pose = tool.pose;
  s->step += 1;
  s->time_s = static_cast<double>(s->step) * m.options.dt_s;
  s->events.clear();
  InstrumentScratch scratch;
  ApplyInstruments(m, StepContext{}, s, &scratch);
}

// Distance from p to the burr centre path (polyline of centres), mm.
double DistanceToPath(const Vec3& p, const std::vector<Vec3>& path) {
  double best = 1e300;
  for (std::size_t i = 0; i + 1 < path.size(); ++i) {
    best = std::min(best, std::sqrt(collision::PointSegment(p, path[i], path[i + 1]).dist2));
  }
  if (path.size() == 1) best = (p - path[0]).norm();
  return best;
}

// True when p lies on the original box surface (one coordinate on a face plane, within it).
bool OnBox(const Vec3& p) {
  const Vec3 lo(40, 0, 0), hi(70, 30, kTop);
  const bool inside =
      (p.array() >= lo.array() - 1e-9).all() && (p.array() <= hi.array() + 1e-9).all();
  bool on_face = false;
  for (int a = 0; a < 3; ++a) {
    on_face = on_face || std::abs(p[a] - lo[a]) < 1e-9 || std::abs(p[a] - hi[a]) < 1e-9;
  }
  return inside && on_face;
}

// Six times the signed volume of (a, b, c, d).
double Orient(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  return (b - a).cross(c - a).dot(d - a);
}

// Whether segment (p, q) passes through triangle (a, b, c): its ends more than 1e-9 mm on either
// side of the plane, and the line through them inside the three edges (signs of the volumes
// alone, which stay meaningful for needle triangles where barycentric coordinates do not). An end
// within 1e-9 mm of the plane is left to the distance tests (it would be in the plane up to
// rounding, where these signs are noise).
bool Crosses(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c) {
  const double area2 = (b - a).cross(c - a).norm();
  if (!(area2 > 0)) return false;
  const double h1 = Orient(a, b, c, p) / area2, h2 = Orient(a, b, c, q) / area2;
  if (!((h1 > 1e-9 && h2 < -1e-9) || (h1 < -1e-9 && h2 > 1e-9))) return false;
  const double s1 = Orient(p, q, a, b), s2 = Orient(p, q, b, c), s3 = Orient(p, q, c, a);
  return (s1 >= 0 && s2 >= 0 && s3 >= 0) || (s1 <= 0 && s2 <= 0 && s3 <= 0);
}

// Whether triangles a and b intersect or touch (closer than 1e-9 mm): an edge of one through the
// other, or a vertex-face or edge-edge distance below that (coplanar overlaps included).
// collision::TriangleTriangle is not used: it reports 0 for needle triangles (two vertices
// within 1e-5 mm) that are 2.8 um from the other triangle (checked by dense sampling).
bool Touch(const mesh::TriMesh& m, const mesh::Tri& a, const mesh::Tri& b) {
  const std::array<Vec3, 3> pa{m.nodes.col(a[0]), m.nodes.col(a[1]), m.nodes.col(a[2])};
  const std::array<Vec3, 3> pb{m.nodes.col(b[0]), m.nodes.col(b[1]), m.nodes.col(b[2])};
  constexpr double kTol2 = 1e-18;
  for (int k = 0; k < 3; ++k) {
    const int k1 = (k + 1) % 3;
    if (Crosses(pa[k], pa[k1], pb[0], pb[1], pb[2])) return true;
    if (Crosses(pb[k], pb[k1], pa[0], pa[1], pa[2])) return true;
    if (collision::PointTriangle(pa[k], pb[0], pb[1], pb[2]).dist2 < kTol2) return true;
    if (collision::PointTriangle(pb[k], pa[0], pa[1], pa[2]).dist2 < kTol2) return true;
    for (int l = 0; l < 3; ++l) {
      if (collision::SegmentSegment(pa[k], pa[k1], pb[l], pb[(l + 1) % 3]).dist2 < kTol2)
        return true;
    }
  }
  return false;
}

// Pairs of triangles without a shared vertex that intersect, among those near `center` with an
// area of at least min_area_mm2 (0: all).
int SelfIntersections(const mesh::TriMesh& m, const Vec3& center, double radius,
                      double min_area_mm2 = 0) {
  std::vector<int> near;
  for (int t = 0; t < static_cast<int>(m.tris.size()); ++t) {
    const Vec3 p0 = m.nodes.col(m.tris[t][0]), p1 = m.nodes.col(m.tris[t][1]),
               p2 = m.nodes.col(m.tris[t][2]);
    if (0.5 * (p1 - p0).cross(p2 - p0).norm() < min_area_mm2) continue;
    if (((p0 + p1 + p2) / 3.0 - center).norm() < radius) near.push_back(t);
  }
  int hits = 0;
  for (std::size_t i = 0; i < near.size(); ++i) {
    for (std::size_t j = i + 1; j < near.size(); ++j) {
      const mesh::Tri& a = m.tris[near[i]];
      const mesh::Tri& b = m.tris[near[j]];
      bool shared = false;
      for (int x : a) shared = shared || std::find(b.begin(), b.end(), x) != b.end();
      if (shared) continue;
      // Triangles whose bounding boxes are more than the tolerance apart cannot touch.
      Vec3 lo_a = m.nodes.col(a[0]), hi_a = lo_a, lo_b = m.nodes.col(b[0]), hi_b = lo_b;
      for (int k = 1; k < 3; ++k) {
        lo_a = lo_a.cwiseMin(m.nodes.col(a[k]));
        hi_a = hi_a.cwiseMax(m.nodes.col(a[k]));
        lo_b = lo_b.cwiseMin(m.nodes.col(b[k]));
        hi_b = hi_b.cwiseMax(m.nodes.col(b[k]));
      }
      if ((lo_a.array() > hi_b.array() + 1e-6).any() || (lo_b.array() > hi_a.array() + 1e-6).any())
        continue;
      if (Touch(m, a, b)) ++hits;
    }
  }
  return hits;
}

struct BurrRun {
  State state;
  std::vector<Vec3> centers;  // burr head centres used
  std::vector<std::size_t> tri_counts;
};

// Burrs with the head centre following `center(t)` for `seconds`, button 1 held.
template <class F>
BurrRun RunBurr(const Model& m, double seconds, F center) {
  BurrRun r{MakeInitialState(m), {}, {}};
  const int burr = m.FindInstrument("burr");
  const double radius = m.instruments[static_cast<std::size_t>(burr)].tip_radius_mm;
  r.state.tools[0].instrument = burr;
  r.state.tools[0].buttons = 1;
  const int steps = static_cast<int>(std::lround(seconds / m.options.dt_s));
  for (int i = 0; i < steps; ++i) {
    const Vec3 c = center(i * m.options.dt_s);
    // Burr pointing down: the head centre is one radius behind (above) the tip.
    r.state.tools[0].pose = Aim(c - Vec3(0, 0, radius), Vec3(0, 0, -1));
    r.centers.push_back(c);
    Act(m, &r.state);
    r.tri_counts.push_back(r.state.bones[0].surface.tris.size());
  }
  return r;
}

TEST(Burr, TenSecondsAtOneSpotRemovesBoneOnlyThereAndKeepsTheSurfaceClosed) {
  const Model m = BoneModelScene();
  const double v0 = physics::EnclosedVolume(m.bones[0].surface);
  // Head centre 1 mm above the top face, driven 0.3 mm/s deeper (as the proxy follows the
  // receding surface): 10 s of continuous burring at x = 47 (the spur region).
  const BurrRun r = RunBurr(m, 10.0, [](double t) { return Vec3(47, 15, kTop + 1.0 - 0.3 * t); });
  const BoneState& bone = r.state.bones[0];
  const physics::WatertightReport w = physics::CheckWatertight(bone.surface);
  EXPECT_TRUE(w.ok()) << w.boundary_edges << " " << w.nonmanifold_edges << " " << w.degenerate_tris;
  const double v1 = physics::EnclosedVolume(bone.surface);
  EXPECT_GT(bone.removed_volume_mm3, 1.0);
  EXPECT_NEAR(bone.removed_volume_mm3, v0 - v1, 1e-9 * v0);
  // Nothing outside the swept burr plus the rim moved off the original surface. The rim is the
  // smoothing ring plus one refined edge: the triangles joining carved to untouched surface
  // (their split midpoints lie on those chords, off the original faces).
  const double reach = 2.0 + m.operations.burr.smoothing_ring_mm + m.operations.burr.max_edge_mm;
  int moved_outside = 0, moved_inside = 0;
  double farthest = 0;
  for (int i = 0; i < bone.surface.nodes.cols(); ++i) {
    const Vec3 p = bone.surface.nodes.col(i);
    if (OnBox(p)) continue;
    const double d = DistanceToPath(p, r.centers);
    farthest = std::max(farthest, d);
    (d > reach + 1e-9 ? moved_outside : moved_inside) += 1;
  }
  EXPECT_EQ(moved_outside, 0) << "farthest moved vertex " << farthest << " mm from the path";
  EXPECT_GT(moved_inside, 20);
  EXPECT_EQ(SelfIntersections(bone.surface, r.centers.back(), 6.0), 0);
  // Triangle count bounded: no growth over the last 5 s at the same spot beyond 25 %.
  EXPECT_LE(r.tri_counts.back(), r.tri_counts[r.tri_counts.size() / 2] * 5 / 4);
  // All of it booked to the spur region (index 1 in the scenario), none elsewhere.
  const int spur = m.FindRegion("spur");
  EXPECT_NEAR(bone.removed_by_region_mm3[static_cast<std::size_t>(spur)], bone.removed_volume_mm3,
              1e-9 * v0);
  EXPECT_EQ(bone.removed_by_region_mm3.back(), 0.0);
}

TEST(Burr, RemovalRateFollowsHardnessAndSimulatedTimeNotStepCount) {
  Model m = BoneModelScene();
  auto depth_after = [&](double dt, double hardness) {
    Model mm = m;
    mm.options.dt_s = dt;
    mm.bones[0].hardness = hardness;
    const BurrRun r = RunBurr(mm, 1.0, [](double) { return Vec3(55, 15, kTop + 0.5); });
    double lowest = kTop;  // under the burr (not the box's bottom face)
    const mesh::TriMesh& surf = r.state.bones[0].surface;
    for (int i = 0; i < surf.nodes.cols(); ++i) {
      const Vec3 p = surf.nodes.col(i);
      if ((p - Vec3(55, 15, kTop)).norm() < 3) lowest = std::min(lowest, p.z());
    }
    return kTop - lowest;
  };
  // 1 mm/s on hardness 2: 0.5 mm in 1 s, whatever the step.
  EXPECT_NEAR(depth_after(0.02, 2.0), 0.5, 0.05);
  EXPECT_NEAR(depth_after(0.005, 2.0), 0.5, 0.05);
  EXPECT_NEAR(depth_after(0.02, 4.0), 0.25, 0.03);
}

TEST(Burr, SweptAcrossTheBoxRemovesAlongThePathOnly) {
  const Model m = BoneModelScene();
  const double v0 = physics::EnclosedVolume(m.bones[0].surface);
  const BurrRun r =
      RunBurr(m, 5.0, [](double t) { return Vec3(44 + 4.4 * t, 15, kTop + 1.2 - 0.1 * t); });
  const BoneState& bone = r.state.bones[0];
  EXPECT_TRUE(physics::CheckWatertight(bone.surface).ok());
  EXPECT_NEAR(bone.removed_volume_mm3, v0 - physics::EnclosedVolume(bone.surface), 1e-9 * v0);
  EXPECT_GT(bone.removed_volume_mm3, 1.0);
  const double reach = 2.0 + m.operations.burr.smoothing_ring_mm + m.operations.burr.max_edge_mm;
  int moved_outside = 0;
  double farthest = 0;
  for (int i = 0; i < bone.surface.nodes.cols(); ++i) {
    const Vec3 p = bone.surface.nodes.col(i);
    if (OnBox(p)) continue;
    farthest = std::max(farthest, DistanceToPath(p, r.centers));
    if (DistanceToPath(p, r.centers) > reach + 1e-9) ++moved_outside;
  }
  EXPECT_EQ(moved_outside, 0) << "farthest moved vertex " << farthest << " mm from the path";
  // The path crosses from spur (x < 55) into footprint: both regions get some.
  EXPECT_GT(bone.removed_by_region_mm3[static_cast<std::size_t>(m.FindRegion("spur"))], 0.1);
  EXPECT_GT(bone.removed_by_region_mm3[static_cast<std::size_t>(m.FindRegion("footprint"))], 0.1);
}

// Known defect, not yet fixed: a burr swept across the surface folds it through itself. Measured
// with this check: 10 171 intersecting pairs of non-degenerate triangles (>= 1e-6 mm^2) after the
// 5 s sweep, from rim vertices sliding over non-adjacent triangles (the carve's flip test only
// sees incident triangles). Undoing every move that makes a triangle touch a non-adjacent one
// brings it to 0 here, but on the shoulder scene it stalls the burr at the acromion's coarse spur
// tip (demo removal 1.18 -> 0.92 mm^3, the tip never removed), so it is not in the carve yet.
TEST(Burr, DISABLED_SweptSurfaceHasNoFoldedTriangles) {
  const Model m = BoneModelScene();
  const BurrRun r =
      RunBurr(m, 5.0, [](double t) { return Vec3(44 + 4.4 * t, 15, kTop + 1.2 - 0.1 * t); });
  EXPECT_EQ(SelfIntersections(r.state.bones[0].surface, Vec3(55, 15, kTop), 14.0, 1e-6), 0);
}

// Known defect, not yet fixed: besides the folds above, the sweep leaves collapsed zero-area
// triangles (vertices carved onto the same point of the burr sphere, then split again) lying on
// an edge of a non-adjacent triangle (204 touching pairs even with the folds undone). The fix
// needs an edge collapse of degenerate triangles in the carve.
TEST(Burr, DISABLED_SweptSurfaceHasNoSelfIntersection) {
  const Model m = BoneModelScene();
  const BurrRun r =
      RunBurr(m, 5.0, [](double t) { return Vec3(44 + 4.4 * t, 15, kTop + 1.2 - 0.1 * t); });
  EXPECT_EQ(SelfIntersections(r.state.bones[0].surface, Vec3(55, 15, kTop), 14.0), 0);
}

TEST(Burr, NothingHappensWithoutButtonOne) {
  const Model m = BoneModelScene();
  State s = MakeInitialState(m);
  s.tools[0].instrument = m.FindInstrument("burr");
  s.tools[0].pose = Aim(Vec3(55, 15, kTop - 1), Vec3(0, 0, -1));
  s.tools[0].handle_pose = s.tools[0].pose;
  State before = s;
  Act(m, &s);
  before.step = s.step;
  before.time_s = s.time_s;
  EXPECT_TRUE(BitwiseEqual(before, s));
}

// The awl driven along `dir` through the entry point `entry` on the top face: from 1 mm before
// it to `depth` past it in `steps` steps, then back out above the surface.
State DrillHole(const Model& m, const Vec3& entry, const Vec3& dir, double depth, int steps) {
  State s = MakeInitialState(m);
  s.tools[0].instrument = m.FindInstrument("awl");
  const Vec3 u = dir.normalized();
  for (int i = 0; i <= steps; ++i) {
    const double d = -1.0 + (depth + 1.0) * i / steps;
    s.tools[0].pose = Aim(entry + d * u, u);
    Act(m, &s);
  }
  s.tools[0].pose = Aim(entry - 3.0 * u, u);
  Act(m, &s);
  return s;
}

struct HoleShape {
  double depth = 0, diameter = 0, angle_deg = 0;
};

// Measured from the surface: deepest point along the commanded axis, widest moved vertex from
// the axis, and the angle between the top face and the hole's own axis (entry -> centroid of
// the vertices in the deepest fifth of the hole, which lies on the axis of a symmetric hole).
HoleShape Measure(const mesh::TriMesh& s, const Vec3& entry, const Vec3& dir) {
  const Vec3 u = dir.normalized();
  HoleShape h;
  Vec3 deepest = entry;
  double rho_max = 0;
  for (int i = 0; i < s.nodes.cols(); ++i) {
    const Vec3 p = s.nodes.col(i);
    if (OnBox(p)) continue;
    const Vec3 d = p - entry;
    const double along = d.dot(u);
    rho_max = std::max(rho_max, (d - along * u).norm());
    if (along > h.depth) {
      h.depth = along;
      deepest = p;
    }
  }
  h.diameter = 2 * rho_max;
  Vec3 sum = Vec3::Zero();
  int count = 0;
  for (int i = 0; i < s.nodes.cols(); ++i) {
    const Vec3 p = s.nodes.col(i);
    if (!OnBox(p) && (p - entry).dot(u) >= 0.8 * h.depth) {
      sum += p;
      ++count;
    }
  }
  const Vec3 bottom = count > 0 ? Vec3(sum / count) : deepest;
  h.angle_deg = std::asin((entry - bottom).normalized().z()) / units::kDegToRad;
  return h;
}

TEST(Awl, HoleMatchesTheToolAndTheCommandedAngle) {
  const Model m = BoneModelScene();
  const double radius =
      m.instruments[static_cast<std::size_t>(m.FindInstrument("awl"))].tip_radius_mm;
  for (const double angle_deg : {45.0, 60.0, 90.0}) {
    const double a = angle_deg * units::kDegToRad;
    const Vec3 dir(std::cos(a), 0, -std::sin(a));
    const Vec3 entry(52, 15, kTop);
    const State s = DrillHole(m, entry, dir, 5.0, 50);
    const HoleShape h = Measure(s.bones[0].surface, entry, dir);
    EXPECT_NEAR(h.depth, 5.0, 0.5) << angle_deg;
    EXPECT_NEAR(h.diameter, 2 * radius, 0.2 * radius) << angle_deg;
    EXPECT_NEAR(h.angle_deg, angle_deg, 2.0) << angle_deg;
    EXPECT_TRUE(physics::CheckWatertight(s.bones[0].surface).ok());
    // The record and the event agree with the measurement.
    ASSERT_EQ(s.holes.size(), 1u) << angle_deg;
    EXPECT_NEAR(s.holes[0].depth_mm, h.depth, 0.5);
    EXPECT_NEAR(s.holes[0].angle_deg, angle_deg, 1.0);
    EXPECT_NEAR((s.holes[0].entry_mm - entry).norm(), 0.0, 0.3);
    EXPECT_EQ(s.holes[0].open, 0);
    ASSERT_EQ(s.events.size(), 1u);
    EXPECT_EQ(s.events[0].kind, "hole");
    EXPECT_NE(s.events[0].detail.find("depth_mm="), std::string::npos);
  }
}

// Deepening a hole in more, smaller mallet blows refines the surface hardly more: the
// refinement saturates at the hole's footprint instead of growing with the number of pushes.
// (Refining in 3-D re-split the stretched wall at every push: 25 000 triangles after 40 pushes,
// growing linearly.) Measured: +1 692 triangles after 60 pushes, +2 166 after 240.
TEST(Awl, RefinementSaturatesWithTheNumberOfPushes) {
  const Model m = BoneModelScene();
  const Vec3 entry(55, 15, kTop);
  const Vec3 dir(1, 0, -1);
  const std::size_t before = m.bones[0].surface.tris.size();
  const std::size_t sixty = DrillHole(m, entry, dir, 6.0, 60).bones[0].surface.tris.size();
  const std::size_t more = DrillHole(m, entry, dir, 6.0, 240).bones[0].surface.tris.size();
  std::printf("triangles: %zu before, %zu after 60 pushes, %zu after 240\n", before, sixty, more);
  ASSERT_GT(sixty, before);
  EXPECT_LE(more - sixty, (sixty - before) / 2) << "60 pushes " << sixty << ", 240 " << more;
}

TEST(Awl, GlancingToolMakesNoHole) {
  const Model m = BoneModelScene();
  const double a = 15 * units::kDegToRad;  // 75 deg off the surface normal > max_angle 60
  const State s = DrillHole(m, Vec3(52, 15, kTop), Vec3(std::cos(a), 0, -std::sin(a)), 3.0, 30);
  EXPECT_TRUE(s.holes.empty());
  EXPECT_EQ(s.bones[0].removed_volume_mm3, 0.0);
}

TEST(Awl, MethodOneDisplacesTheContactVertexWithItsNeighbours) {
  Model m = BoneModelScene();
  m.operations.awl.method = 1;
  const double v0 = physics::EnclosedVolume(m.bones[0].surface);
  // Straight down onto the grid vertex (54, 16): it and its six neighbours go 2 mm down.
  const State s = DrillHole(m, Vec3(54, 16, kTop), Vec3(0, 0, -1), 2.0, 20);
  const mesh::TriMesh& surf = s.bones[0].surface;
  int down = 0;
  for (int i = 0; i < surf.nodes.cols(); ++i) {
    const Vec3 p = surf.nodes.col(i);
    if (std::abs(p.z() - (kTop - 2.0)) < 1e-9 && (p - Vec3(54, 16, p.z())).norm() < 4) ++down;
  }
  EXPECT_EQ(down, 7);
  EXPECT_TRUE(physics::CheckWatertight(surf).ok());
  EXPECT_NEAR(s.bones[0].removed_volume_mm3, v0 - physics::EnclosedVolume(surf), 1e-9 * v0);
}

// Drills a 45 deg hole 5 mm deep, then presses button 2 with the tip still in it.
State SeatAnchorAt45(const Model& m) {
  const double a = 45 * units::kDegToRad;
  const Vec3 u(std::cos(a), 0, -std::sin(a));
  const Vec3 entry(52, 15, kTop);
  State s = MakeInitialState(m);
  s.tools[0].instrument = m.FindInstrument("awl");
  for (int i = 0; i <= 40; ++i) {
    s.tools[0].pose = Aim(entry + (-1.0 + 6.0 * i / 40) * u, u);
    Act(m, &s);
  }
  s.tools[0].buttons = 2;
  Act(m, &s);
  s.tools[0].buttons = 0;
  return s;
}

TEST(Anchor, SeatsAtTheBottomOfTheHoleWithItsTwoSutures) {
  const Model m = BoneModelScene();
  const State s0 = MakeInitialState(m);
  for (const ThreadState& t : s0.threads) {  // not in the scene before the anchor
    EXPECT_TRUE(std::all_of(t.node_alive.begin(), t.node_alive.end(), [](auto a) { return !a; }));
  }
  const State s = SeatAnchorAt45(m);
  ASSERT_EQ(s.anchors.size(), 1u);
  const AnchorState& a = s.anchors[0];
  EXPECT_NEAR(a.depth_mm, 5.0, 1e-9);
  EXPECT_NEAR(a.angle_deg, 45.0, 1.0);
  const Vec3 bottom = s.holes[0].entry_mm + 5.0 * s.holes[0].axis;
  EXPECT_LT((a.position_mm - bottom).norm(), 1e-9);
  int springs = 0;
  for (const SpringConstraint& c : s.constraints) springs += c.tag == "anchor";
  EXPECT_EQ(springs, 2);
  for (const ThreadState& t : s.threads) {
    EXPECT_TRUE(std::all_of(t.node_alive.begin(), t.node_alive.end(), [](auto v) { return v; }));
    EXPECT_LT((t.x.col(0) - a.position_mm).norm(), 0.31);
  }
  bool hole_event = false, anchor_event = false;
  for (const Event& e : s.events) {
    hole_event = hole_event || e.kind == "hole";
    anchor_event = anchor_event || e.kind == "anchor";
  }
  EXPECT_TRUE(hole_event);
  EXPECT_TRUE(anchor_event);
}

// Runs the full step with the seated anchor while a spring pulls suture_a's free end with
// ~10 N; returns the largest distance of its first node from the anchor eyelet and the pull.
std::pair<double, double> PullSuture(const Model& m, int threads) {
  SetThreadCount(threads);
  State s = SeatAnchorAt45(m);
  s.tools[0].instrument = -1;
  const int t = m.FindThread("suture_a");
  const int last = static_cast<int>(s.threads[static_cast<std::size_t>(t)].x.cols()) - 1;
  Vec3 eyelet = Vec3::Zero();
  for (const SpringConstraint& c : s.constraints) {
    if (c.tag == "anchor" && c.a.index == t) eyelet = c.b.offset_mm;
  }
  const Vec3 end0 = s.threads[static_cast<std::size_t>(t)].x.col(last);
  SpringConstraint pull;
  pull.id = s.next_constraint_id++;
  pull.tag = "test_pull";
  pull.a.kind = ConstraintEnd::Kind::kThread;
  pull.a.index = t;
  pull.a.nodes = {last, -1, -1, -1};
  pull.a.weights = {1, 0, 0, 0};
  pull.b.kind = ConstraintEnd::Kind::kWorld;
  pull.b.offset_mm = end0 + Vec3(0, 0, 20);
  pull.stiffness_n_per_mm = 0.5;  // 10 N at the 20 mm stretch
  s.constraints.push_back(pull);
  sim::Workspace ws;
  sim::BuildWorkspace(m, s, &ws);
  InputFrame in;
  double worst = 0, force = 0;
  for (int i = 0; i < 100; ++i) {
    sim::Step(m, in, &s, &ws);
    const ThreadState& th = s.threads[static_cast<std::size_t>(t)];
    worst = std::max(worst, (th.x.col(0) - eyelet).norm());
    force = pull.stiffness_n_per_mm * (pull.b.offset_mm - th.x.col(last)).norm();
  }
  SetThreadCount(1);
  return {worst, force};
}

TEST(Anchor, StaysFixedWhileItsSutureIsPulledWithTenNewtons) {
  const Model m = BoneModelScene();
  const auto [worst, force] = PullSuture(m, 1);
  EXPECT_GT(force, 8.0);
  EXPECT_LT(force, 10.5);
  EXPECT_LT(worst, 0.1);
}

TEST(BoneOps, BitIdenticalWithOneAndTwoThreads) {
  const Model m = BoneModelScene();
  std::uint64_t hash[2];
  for (int k = 0; k < 2; ++k) {
    SetThreadCount(k + 1);
    BurrRun r = RunBurr(m, 1.0, [](double t) { return Vec3(47 + 5 * t, 15, kTop + 0.8); });
    State s = r.state;
    s.tools[0].instrument = m.FindInstrument("awl");
    s.tools[0].buttons = 0;
    const Vec3 u = Vec3(1, 0, -1).normalized();
    for (int i = 0; i <= 30; ++i) {
      s.tools[0].pose = Aim(Vec3(60, 15, kTop) + (-1.0 + 5.0 * i / 30) * u, u);
      Act(m, &s);
    }
    s.tools[0].buttons = 2;
    Act(m, &s);
    sim::Workspace ws;
    sim::BuildWorkspace(m, s, &ws);
    InputFrame in;
    for (int i = 0; i < 20; ++i) sim::Step(m, in, &s, &ws);
    hash[k] = HashState(s);
  }
  SetThreadCount(1);
  EXPECT_EQ(hash[0], hash[1]);
}

}  // namespace
}  // namespace arthrosim::instruments
