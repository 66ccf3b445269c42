// The anatomic shoulder (scenarios/rotator_cuff_repair_anatomic.yaml, tools/anatomic_shoulder.py):
// its meshes are valid closed surfaces with the physical groups scoring and rendering need, every
// landmark lies on (bone) or in (soft tissue) the body it names, and the first 10.4 s of the tour
// (diagnostic view, subacromial view, burr onto the spur) run on it with the scope outside bone
// and no soft-body node pushed into bone; the subacromial bursa lies between the acromion and the
// tendon without penetrating either, stays there at rest, and a shaver pass removes its volume.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

#include "arthrosim/collision/tool_bone_query.h"
#include "arthrosim/input/script_source.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/mesh/mesh_io.h"
#include "arthrosim/mesh/mesh_validate.h"
#include "arthrosim/mesh/surface.h"
#include "arthrosim/sim/step.h"

namespace arthrosim::sim {
namespace {

const std::string kSource = ARTHROSIM_SOURCE_DIR;
const std::string kScene = kSource + "/scenarios/rotator_cuff_repair_anatomic.yaml";

const Model& Anatomic() {
  static const Model model = io::LoadScenario(kScene);
  return model;
}

// Closest distance from p to triangle abc (Ericson, Real-Time Collision Detection 5.1.5), mm.
double PointTriangleDistance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return (p - a).norm();
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return (p - b).norm();
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return (p - (a + d1 / (d1 - d3) * ab)).norm();
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return (p - c).norm();
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return (p - (a + d2 / (d2 - d6) * ac)).norm();
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    return (p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b))).norm();
  }
  const double denom = 1.0 / (va + vb + vc);
  return (p - (a + ab * (vb * denom) + ac * (vc * denom))).norm();
}

double SurfaceDistance(const Vec3& p, const mesh::TriMesh& m) {
  double best = std::numeric_limits<double>::infinity();
  for (const mesh::Tri& t : m.tris) {
    best = std::min(
        best, PointTriangleDistance(p, m.nodes.col(t[0]), m.nodes.col(t[1]), m.nodes.col(t[2])));
  }
  return best;
}

// Whether p lies in one of the (positively oriented) tets of m.
bool InsideTets(const Vec3& p, const mesh::TetMesh& m) {
  for (const mesh::Tet& t : m.tets) {
    const Vec3 a = m.nodes.col(t[0]), b = m.nodes.col(t[1]), c = m.nodes.col(t[2]),
               d = m.nodes.col(t[3]);
    const double v = (b - a).dot((c - a).cross(d - a));
    const double l0 = (b - p).dot((c - p).cross(d - p)) / v;
    const double l1 = (a - p).dot((d - p).cross(c - p)) / v;
    const double l2 = (a - p).dot((b - p).cross(d - p)) / v;
    const double l3 = 1.0 - l0 - l1 - l2;
    if (l0 >= 0 && l1 >= 0 && l2 >= 0 && l3 >= 0) return true;
  }
  return false;
}

TEST(AnatomicScene, RigidMeshesAreClosedOutwardAndCarryTheirGroups) {
  const Model& m = Anatomic();
  for (const char* name : {"humerus", "acromion", "glenoid", "coracoacromial_ligament"}) {
    const int i = m.FindBone(name);
    ASSERT_GE(i, 0) << name;
    mesh::TriMesh s = m.bones[static_cast<std::size_t>(i)].surface;
    const mesh::TriQualityReport r = mesh::OrientAndCheck(&s, name);
    EXPECT_TRUE(r.closed) << name;
    EXPECT_TRUE(r.consistently_oriented) << name;
    EXPECT_FALSE(r.flipped) << name;
    EXPECT_TRUE(r.degenerate.empty()) << name;
    EXPECT_GT(r.enclosed_volume, 0) << name;
  }
  // The groups the generator writes: cartilage on the humerus (burring it is collateral damage),
  // labrum / tubercle / coracoid on the glenoid, each with triangles.
  const auto count = [](const mesh::MeshData& d, const std::string& group) {
    int tag = -1;
    for (const auto& g : d.groups) tag = g.name == group ? g.tag : tag;
    return static_cast<int>(std::count(d.tri_physical.begin(), d.tri_physical.end(), tag));
  };
  const std::string dir = kSource + "/scenarios/meshes/anatomic/";
  const mesh::MeshData hum = mesh::ReadMesh(dir + "humerus.msh");
  EXPECT_GT(count(hum, "cartilage"), 500);
  EXPECT_GT(count(hum, "footprint"), 100);
  const mesh::MeshData gl = mesh::ReadMesh(dir + "glenoid.msh");
  for (const char* g : {"labrum", "supraglenoid_tubercle", "coracoid"}) EXPECT_GT(count(gl, g), 5);
}

TEST(AnatomicScene, SoftBodiesStayNearThePapersSizes) {
  const Model& m = Anatomic();
  const auto& muscle =
      m.soft_bodies[static_cast<std::size_t>(m.FindSoftBody("supraspinatus_muscle"))];
  const auto& tendon =
      m.soft_bodies[static_cast<std::size_t>(m.FindSoftBody("supraspinatus_tendon"))];
  // paper: muscle 627 nodes / 2026 tets, tendon 398 / 1261
  EXPECT_NEAR(muscle.rest_mesh.nodes.cols(), 627, 40);
  EXPECT_NEAR(static_cast<double>(muscle.rest_mesh.tets.size()), 2026, 120);
  EXPECT_NEAR(tendon.rest_mesh.nodes.cols(), 398, 40);
  EXPECT_NEAR(static_cast<double>(tendon.rest_mesh.tets.size()), 1261, 120);
}

TEST(AnatomicScene, EveryLandmarkLiesOnOrInTheBodyItNames) {
  const Model& m = Anatomic();
  int checked = 0;
  for (const Landmark& l : m.landmarks) {
    if (l.body.empty()) continue;
    const int bone = m.FindBone(l.body);
    const int soft = m.FindSoftBody(l.body);
    ASSERT_TRUE(bone >= 0 || soft >= 0) << l.name << ": no body " << l.body;
    if (bone >= 0) {
      const double d =
          SurfaceDistance(l.position_mm, m.bones[static_cast<std::size_t>(bone)].surface);
      EXPECT_LT(d, 0.6) << l.name << " is " << d << " mm from " << l.body;
    } else {
      EXPECT_TRUE(
          InsideTets(l.position_mm, m.soft_bodies[static_cast<std::size_t>(soft)].rest_mesh))
          << l.name << " not inside " << l.body;
    }
    ++checked;
  }
  EXPECT_GE(checked, 11);
  // The free points the scope and instruments aim at lie outside every bone.
  collision::BoneQueryWorld bones;
  const State s = MakeInitialState(m);
  collision::SyncBoneQuery(s, &bones);
  for (const Landmark& l : m.landmarks) {
    if (l.body.empty()) {
      EXPECT_GT(collision::PointBoneSignedDistance(l.position_mm, &bones), 0.0) << l.name;
    }
  }
}

TEST(AnatomicScene, TheTourRunsOnItsFirstTenSeconds) {
  const Model& m = Anatomic();
  input::ScriptOptions o;
  o.dt_s = m.options.dt_s;
  auto script = input::ScriptSource::Open(kSource + "/trajectories/rotator_cuff_tour.yaml", m, o);
  State s = MakeInitialState(m);
  Workspace ws;
  BuildWorkspace(m, s, &ws);
  collision::BoneQueryWorld bones;
  // The bodies this scene adds (glenoid with labrum and coracoid, coracoacromial ligament) on
  // their own: the tour's scope path must not pass through them. (Its diagnostic pose is clear
  // of every bone here, 3.1 mm; its way back over the humeral head to the subacromial space
  // grazes the head by up to 2 mm between waypoints: the tour's matter, not the anatomy's.)
  Model added = m;
  added.bones.clear();
  for (const char* name : {"glenoid", "coracoacromial_ligament"}) {
    added.bones.push_back(m.bones[static_cast<std::size_t>(m.FindBone(name))]);
  }
  collision::BoneQueryWorld added_bones;
  collision::SyncBoneQuery(MakeInitialState(added), &added_bones);
  double scope_clearance = std::numeric_limits<double>::infinity();
  double scope_clearance_all = std::numeric_limits<double>::infinity();
  double deepest = 0;
  const int steps = static_cast<int>(10.4 / m.options.dt_s + 0.5);
  for (int k = 0; k < steps; ++k) {
    InputFrame f;
    script->Frame(k, k * m.options.dt_s, &f);
    Step(m, f, &s, &ws);
    FeedbackFrame fb;
    for (std::size_t i = 0; i < s.tools.size() && i < fb.force_n.size(); ++i) {
      fb.force_n[i] = s.tools[i].force_n;
    }
    script->Feedback(fb);
    collision::SyncBoneQuery(s, &bones);
    const Vec3& eye = s.camera.pose.position_mm;
    scope_clearance =
        std::min(scope_clearance, collision::PointBoneSignedDistance(eye, &added_bones));
    scope_clearance_all =
        std::min(scope_clearance_all, collision::PointBoneSignedDistance(eye, &bones));
    for (const SoftBodyState& b : s.soft_bodies) {
      ASSERT_TRUE(b.x.allFinite()) << "step " << k;
      if (k + 1 < steps) continue;
      for (Eigen::Index i = 0; i < b.x.cols(); ++i) {
        deepest = std::max(deepest, -collision::PointBoneSignedDistance(b.x.col(i), &bones));
      }
    }
  }
  std::printf(
      "tour 0-10.4 s on the anatomic scene: scope at least %.2f mm outside the glenoid and the "
      "coracoacromial ligament (%.2f mm from any bone); deepest soft node %.3f mm inside bone\n",
      scope_clearance, scope_clearance_all, deepest);
  EXPECT_GT(scope_clearance, 0.0);
  EXPECT_LT(deepest, 0.5);
}

// Where the ray from o along unit d first crosses a triangle of m (Moller-Trumbore), as the
// distance along d; infinity if it crosses none.
double RayHit(const Vec3& o, const Vec3& d, const mesh::TriMesh& m) {
  double best = std::numeric_limits<double>::infinity();
  for (const mesh::Tri& t : m.tris) {
    const Vec3 a = m.nodes.col(t[0]), e1 = m.nodes.col(t[1]) - a, e2 = m.nodes.col(t[2]) - a;
    const Vec3 p = d.cross(e2);
    const double det = e1.dot(p);
    if (std::abs(det) < 1e-12) continue;
    const Vec3 s = o - a;
    const double u = s.dot(p) / det;
    const Vec3 q = s.cross(e1);
    const double v = d.dot(q) / det;
    const double h = e2.dot(q) / det;
    if (u >= 0 && v >= 0 && u + v <= 1 && h > 0) best = std::min(best, h);
  }
  return best;
}

int CountInside(const Points& pts, const mesh::TetMesh& m) {
  int n = 0;
  for (Eigen::Index i = 0; i < pts.cols(); ++i) n += InsideTets(pts.col(i), m) ? 1 : 0;
  return n;
}

TEST(AnatomicScene, TheBursaLiesBetweenAcromionAndTendonWithoutPenetration) {
  const Model& m = Anatomic();
  const int b = m.FindSoftBody("subacromial_bursa");
  ASSERT_GE(b, 0);
  const mesh::TetMesh& bursa = m.soft_bodies[static_cast<std::size_t>(b)].rest_mesh;
  const mesh::TetMesh& tendon =
      m.soft_bodies[static_cast<std::size_t>(m.FindSoftBody("supraspinatus_tendon"))].rest_mesh;
  const mesh::TriMesh& acromion = m.bones[static_cast<std::size_t>(m.FindBone("acromion"))].surface;
  // small: a few hundred tets beside the cuff's 3 300
  EXPECT_GE(bursa.tets.size(), 200u);
  EXPECT_LE(bursa.tets.size(), 1000u);
  // no bursa node in a bone or in the tendon, no tendon node in the bursa
  collision::BoneQueryWorld bones;
  collision::SyncBoneQuery(MakeInitialState(m), &bones);
  double to_bone = std::numeric_limits<double>::infinity();
  for (Eigen::Index i = 0; i < bursa.nodes.cols(); ++i)
    to_bone = std::min(to_bone, collision::PointBoneSignedDistance(bursa.nodes.col(i), &bones));
  EXPECT_GT(to_bone, 0.5);
  EXPECT_EQ(CountInside(bursa.nodes, tendon), 0);
  EXPECT_EQ(CountInside(tendon.nodes, bursa), 0);
  // between them: straight up from more than half of the bursa nodes the acromion lies within
  // 6 mm (the rest are medial of x = -6, past the acromion's medial edge), straight down from
  // every one the tendon's bursal surface within 3 mm
  const mesh::TriMesh tendon_surface = mesh::BoundaryTriMesh(tendon);
  int under_acromion = 0, over_tendon = 0;
  double up_max = 0, down_max = 0;
  for (Eigen::Index i = 0; i < bursa.nodes.cols(); ++i) {
    const Vec3 p = bursa.nodes.col(i);
    const double up = RayHit(p, Vec3::UnitZ(), acromion);
    const double down = RayHit(p, -Vec3::UnitZ(), tendon_surface);
    if (up < 6.0) {
      ++under_acromion;
      up_max = std::max(up_max, up);
    }
    if (down < 3.0) {
      ++over_tendon;
      down_max = std::max(down_max, down);
    }
  }
  std::printf(
      "bursa: %d nodes / %zu tets, %.2f mm from bone; nodes under the acromion %d, over "
      "the tendon %d (of %d)\n",
      static_cast<int>(bursa.nodes.cols()), bursa.tets.size(), to_bone, under_acromion, over_tendon,
      static_cast<int>(bursa.nodes.cols()));
  EXPECT_GT(under_acromion, bursa.nodes.cols() / 2);
  EXPECT_EQ(over_tendon, bursa.nodes.cols());
  // and it stays there: one second from rest under gravity, nothing pushed into bone or tendon
  State s = MakeInitialState(m);
  Workspace ws;
  BuildWorkspace(m, s, &ws);
  InputFrame idle;
  idle.camera.pose = m.camera.initial_pose;
  for (int k = 0; k < 50; ++k) Step(m, idle, &s, &ws);
  const Points& x = s.soft_bodies[static_cast<std::size_t>(b)].x;
  ASSERT_TRUE(x.allFinite());
  const double moved = (x - bursa.nodes).colwise().norm().maxCoeff();
  std::printf("bursa after 1 s at rest: largest node move %.3f mm\n", moved);
  EXPECT_LT(moved, 1.0);
  collision::SyncBoneQuery(s, &bones);
  for (Eigen::Index i = 0; i < x.cols(); ++i)
    EXPECT_GT(collision::PointBoneSignedDistance(x.col(i), &bones), 0.0) << "node " << i;
}

// Runs the script on the anatomic scene to its end; the State at the end.
State RunScript(const std::string& rel, std::vector<Event>* events) {
  const Model& m = Anatomic();
  input::ScriptOptions o;
  o.dt_s = m.options.dt_s;
  auto script = input::ScriptSource::Open(kSource + "/" + rel, m, o);
  State s = MakeInitialState(m);
  Workspace ws;
  BuildWorkspace(m, s, &ws);
  const int steps = static_cast<int>(script->end_time_s() / m.options.dt_s + 0.5);
  for (int k = 0; k < steps; ++k) {
    InputFrame f;
    script->Frame(k, k * m.options.dt_s, &f);
    Step(m, f, &s, &ws);
    FeedbackFrame fb;
    for (std::size_t i = 0; i < s.tools.size() && i < fb.force_n.size(); ++i)
      fb.force_n[i] = s.tools[i].force_n;
    script->Feedback(fb);
    events->insert(events->end(), s.events.begin(), s.events.end());
  }
  return s;
}

double AliveRestVolume(const SoftBodyState& b) {
  double v = 0;
  for (std::size_t t = 0; t < b.tets.size(); ++t) {
    if (!b.tet_alive.empty() && b.tet_alive[t] == 0) continue;
    const mesh::Tet& e = b.tets[t];
    const Vec3 a = b.x_rest.col(e[0]);
    v += (b.x_rest.col(e[1]) - a).dot((b.x_rest.col(e[2]) - a).cross(b.x_rest.col(e[3]) - a)) / 6;
  }
  return v;
}

TEST(AnatomicScene, AShaverPassOverTheBursaRemovesItsVolume) {
  const Model& m = Anatomic();
  const int b = m.FindSoftBody("subacromial_bursa");
  ASSERT_GE(b, 0);
  const double v0 = AliveRestVolume(MakeInitialState(m).soft_bodies[static_cast<std::size_t>(b)]);
  std::vector<Event> events;
  const State s = RunScript("trajectories/anatomic/shaver_bursa.yaml", &events);
  const SoftBodyState& bursa = s.soft_bodies[static_cast<std::size_t>(b)];
  int shaves = 0, removed_tets = 0;
  for (const Event& e : events) {
    if (e.kind != "shave" || e.body != "subacromial_bursa") continue;
    ++shaves;
    const std::size_t at = e.detail.find("removed_tets=");
    if (at != std::string::npos) removed_tets += std::atoi(e.detail.c_str() + at + 13);
  }
  const double v1 = AliveRestVolume(bursa);
  std::printf(
      "shaver over the bursa: %d shave events, %d tets removed, removed volume %.2f mm3 "
      "(alive rest volume %.1f -> %.1f mm3)\n",
      shaves, removed_tets, bursa.removed_volume_mm3, v0, v1);
  for (const SoftBodyState& sb : s.soft_bodies) ASSERT_TRUE(sb.x.allFinite());
  EXPECT_GT(shaves, 10);
  EXPECT_GT(removed_tets, 5);
  EXPECT_GT(bursa.removed_volume_mm3, 5.0);
  EXPECT_NEAR(v0 - v1, bursa.removed_volume_mm3, 1e-6 * v0);
}

}  // namespace
}  // namespace arthrosim::sim
