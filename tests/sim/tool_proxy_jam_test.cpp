// The sliding proxy's jam escape (sim/tool_proxy.cpp, Follow and Retreat; docs/contact-model.md,
// "The burr jammed in its crater"): a burr in a tunnel carved by the burr's own carve function
// (physics::CarveSphere), the hand taken out of the bone to its side and turned, where the
// straight way leads through bone and every shortened step of the turn wedges the burr in the
// tunnel. The proxy must back out along its shaft and follow the hand round the bone, never
// through it. Shown to fail with the escape disabled (the commit that added this file says how).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <vector>

#include "arthrosim/collision/tool_bone_query.h"
#include "arthrosim/physics/bone_surface.h"
#include "arthrosim/sim/step.h"
#include "arthrosim/sim/tool_proxy.h"
#include "tool_proxy_scene.h"

namespace arthrosim::sim {
namespace {

using testing::SampledClearance;

// A closed box [lo, hi] triangulated on a grid of `h_mm` cells on every face, outward-oriented
// (a bone mesh about as fine as the scene's bones near the footprint; carving the block's two
// 40 mm triangles per face would make slivers).
mesh::TriMesh GridBox(const Vec3& lo, const Vec3& hi, double h_mm) {
  std::map<std::array<long, 3>, int> index;  // grid point (in µm) -> node
  std::vector<Vec3> nodes;
  const auto node = [&](const Vec3& p) {
    const std::array<long, 3> key{std::lround(p.x() * 1e3), std::lround(p.y() * 1e3),
                                  std::lround(p.z() * 1e3)};
    const auto [it, added] = index.emplace(key, static_cast<int>(nodes.size()));
    if (added) nodes.push_back(p);
    return it->second;
  };
  mesh::TriMesh out;
  for (int axis = 0; axis < 3; ++axis) {
    const int a = (axis + 1) % 3, b = (axis + 2) % 3;  // (a, b, axis) right-handed
    const int na = static_cast<int>(std::lround((hi[a] - lo[a]) / h_mm));
    const int nb = static_cast<int>(std::lround((hi[b] - lo[b]) / h_mm));
    for (int side = 0; side < 2; ++side) {
      const auto at = [&](int i, int j) {
        Vec3 p;
        p[axis] = side == 0 ? lo[axis] : hi[axis];
        p[a] = lo[a] + (hi[a] - lo[a]) * i / na;
        p[b] = lo[b] + (hi[b] - lo[b]) * j / nb;
        return node(p);
      };
      for (int i = 0; i < na; ++i) {
        for (int j = 0; j < nb; ++j) {
          const int p00 = at(i, j), p10 = at(i + 1, j), p11 = at(i + 1, j + 1), p01 = at(i, j + 1);
          if (side == 1) {  // counter-clockwise in (a, b): faces +axis
            out.tris.push_back({p00, p10, p11});
            out.tris.push_back({p00, p11, p01});
          } else {
            out.tris.push_back({p00, p11, p10});
            out.tris.push_back({p00, p01, p11});
          }
        }
      }
    }
  }
  out.nodes.resize(3, static_cast<Eigen::Index>(nodes.size()));
  for (std::size_t i = 0; i < nodes.size(); ++i)
    out.nodes.col(static_cast<Eigen::Index>(i)) = nodes[i];
  return out;
}

// A bone block [-10, 10] x [-10, 10] x [-20, 0] on a 1 mm grid and the 5.5 mm burr, with the
// sliding proxy (every product scene has it).
Model GridBlockModel() {
  BoneModel bone;
  bone.name = "block";
  bone.surface = GridBox(Vec3(-10, -10, -20), Vec3(10, 10, 0), 1.0);
  Model m = testing::BurrOverBone("grid_block", std::move(bone));
  m.haptics.slide = true;
  return m;
}

// The burr straight down (tool +z = world -z), turned by `turn_deg` about world y (90: tool +z =
// world -x, the shaft out along +x).
Quat BurrOrientation(double turn_deg) {
  return Quat(Eigen::AngleAxisd(turn_deg * std::numbers::pi / 180, Vec3::UnitY())) *
         Quat(Eigen::AngleAxisd(std::numbers::pi, Vec3::UnitX()));
}

InputFrame BurrAt(const Vec3& tip, const Quat& orientation) {
  InputFrame f;
  f.tools[0].instrument = 0;
  f.tools[0].pose.position_mm = tip;
  f.tools[0].pose.orientation = orientation;
  return f;
}

// Carves a vertical tunnel into the block's top face with the burr's carve function: the burr's
// head (radius r, centre r behind its tip) swept 0.25 mm at a time from 3 r above the face until
// its tip is `depth_mm` deep, removing everything within r + 0.1 mm of the head centre.
void CarveTunnel(State* s, double r, double depth_mm) {
  for (double tip_z = 3 * r; tip_z >= -depth_mm - 1e-9; tip_z -= 0.25) {
    physics::CarveSphere(&s->bones[0], Vec3(0, 0, tip_z + r), r + 0.1, 100.0);
  }
  ++s->bones[0].revision;
}

struct Sim : testing::Sim {
  using testing::Sim::Sim;
  // Signed distance of the instrument's tip point from the bones, mm (< 0 inside): the
  // clearance reaches only 4 mm into bone, a tip deep inside would read as clear.
  double TipDistanceMm() const {
    collision::BoneQueryWorld bones;
    collision::SyncBoneQuery(state, &bones);
    return collision::PointBoneSignedDistance(state.tools[0].pose.position_mm, &bones);
  }
};

// The burr 8 mm deep in its tunnel; the hand then goes to the block's side, 6 mm under its top
// face and 6 mm clear of its side face, turned 90 degrees to point at that face (the instrument
// there is clear of bone): 16 mm away, the straight way through 10 mm of bone. The proxy backs
// out of the tunnel and follows the hand over the block's edge within 12 steps (measured: it
// reaches the handle in step 8), never inside bone by more than 0.1 mm. With the escape
// disabled it stays wedged in the tunnel, 16.3 mm from the hand, for good.
TEST(ToolProxyTest, BurrJammedInItsTunnelBacksOutAndFollowsTheHandRoundTheBone) {
  Sim r(GridBlockModel());
  const double radius = r.model.instruments[0].tip_radius_mm;
  CarveTunnel(&r.state, radius, 8.0);
  ASSERT_TRUE(physics::CheckWatertight(r.state.bones[0].surface).ok());
  const Vec3 deep(0, 0, -8);
  r.Step(BurrAt(deep, BurrOrientation(0)));  // inserted in the tunnel, clear of its walls
  std::printf("jam: inserted at (%.3f, %.3f, %.3f), clearance %.4f mm\n",
              r.state.tools[0].pose.position_mm.x(), r.state.tools[0].pose.position_mm.y(),
              r.state.tools[0].pose.position_mm.z(), SampledClearance(r.model, r.state, 0));
  ASSERT_LT((r.state.tools[0].pose.position_mm - deep).norm(), 0.1);
  ASSERT_GE(SampledClearance(r.model, r.state, 0), 0.0);

  const InputFrame out = BurrAt(Vec3(16, 0, -6), BurrOrientation(90));
  {  // the instrument at the hand is clear of bone (the escape's condition)
    State at_hand = r.state;
    at_hand.tools[0].pose = out.tools[0].pose;
    ASSERT_GE(SampledClearance(r.model, at_hand, 0), 1.0);
  }
  int arrived_in = -1;
  double lowest = 1e300, lowest_tip = 1e300;
  for (int step = 1; step <= 12 && arrived_in < 0; ++step) {
    r.Step(out);
    const ToolState& t = r.state.tools[0];
    const double clearance = SampledClearance(r.model, r.state, 0);
    lowest = std::min(lowest, clearance);
    lowest_tip = std::min(lowest_tip, r.TipDistanceMm());
    std::printf(
        "jam: step %2d proxy (%.3f, %.3f, %.3f), %.3f mm from the hand, clearance %.4f mm\n", step,
        t.pose.position_mm.x(), t.pose.position_mm.y(), t.pose.position_mm.z(),
        (t.pose.position_mm - t.handle_pose.position_mm).norm(), clearance);
    if (t.pose == t.handle_pose) arrived_in = step;
  }
  EXPECT_GE(arrived_in, 1) << "the proxy never reached the hand in 12 steps";
  EXPECT_GE(lowest, -0.1);
  EXPECT_GE(lowest_tip, -0.1);
  EXPECT_GE(SampledClearance(r.model, r.state, 0), 1.0);  // clear of bone at the hand
}

// The control: the hand drawn straight out along the tunnel (no turn) takes the burr out without
// the escape, in one step.
TEST(ToolProxyTest, BurrDrawnOutAlongItsTunnelFollowsTheHand) {
  Sim r(GridBlockModel());
  CarveTunnel(&r.state, r.model.instruments[0].tip_radius_mm, 8.0);
  r.Step(BurrAt(Vec3(0, 0, -8), BurrOrientation(0)));
  r.Step(BurrAt(Vec3(0, 0, 20), BurrOrientation(0)));
  EXPECT_EQ(r.state.tools[0].pose, r.state.tools[0].handle_pose);
}

// A proxy found overlapping bone that no push-out frees (here placed so, turned 25 degrees in the
// tunnel: the shaft cuts both walls) backs out along its shaft to the first pose clear of bone,
// in the same step, and follows the hand (above the block, turned the same way) from there.
// With the escape disabled it stays where it was put, inside the tunnel's walls.
TEST(ToolProxyTest, OverlappingBurrNoPushFreesBacksOutToAClearPose) {
  Sim r(GridBlockModel());
  CarveTunnel(&r.state, r.model.instruments[0].tip_radius_mm, 8.0);
  r.Step(BurrAt(Vec3(0, 0, -8), BurrOrientation(0)));
  r.state.tools[0].pose.orientation = BurrOrientation(25);  // wedged
  const double placed = SampledClearance(r.model, r.state, 0);
  ASSERT_LT(placed, -0.5);
  const InputFrame up = BurrAt(Vec3(0, 0, 20), BurrOrientation(25));
  r.Step(up);
  const double after = SampledClearance(r.model, r.state, 0);
  std::printf(
      "overlap: placed %.3f mm into bone; after one step clearance %.4f mm, tip (%.3f, "
      "%.3f, %.3f), %.3f mm from the hand\n",
      -placed, after, r.state.tools[0].pose.position_mm.x(), r.state.tools[0].pose.position_mm.y(),
      r.state.tools[0].pose.position_mm.z(),
      (r.state.tools[0].pose.position_mm - up.tools[0].pose.position_mm).norm());
  EXPECT_GE(after, -0.1);
  EXPECT_GT(r.TipDistanceMm(), 0.0);
  for (int step = 0; step < 5; ++step) r.Step(up);
  EXPECT_EQ(r.state.tools[0].pose, r.state.tools[0].handle_pose);
}

}  // namespace
}  // namespace arthrosim::sim
