// Tissue-tissue and bone tip-tissue contacts through sim::Step (real FEM, dt = 20 ms): two soft
// blocks pressed together stay apart, joined blocks get no contact at their interface, and a
// coarse tissue sheet falling onto a sharp bone tip is held by it. Each test also runs without
// the new contacts to show that it can fail.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <utility>

#include "arthrosim/collision/bench_scene.h"
#include "arthrosim/collision/collision_mesh.h"
#include "arthrosim/collision/proximity.h"
#include "arthrosim/core/units.h"
#include "arthrosim/physics/bone_surface.h"
#include "arthrosim/sim/step.h"
#include "signed_distance.h"
#include "test_instruments.h"

namespace arthrosim::collision {
namespace {

using Kind = ConstraintEnd::Kind;

const Quat kDown(Eigen::AngleAxisd(units::kPi, Vec3::UnitX()));  // tool +z -> world -z

Material Muscle() {
  Material m;
  m.name = "muscle";
  m.young_modulus_pa = 25000;
  m.poisson_ratio = 0.45;
  m.density_kg_m3 = 1060;
  m.rayleigh_mass = 0.1;
  m.rayleigh_stiffness = 0.001;
  return m;
}

// A box of tissue named `name`; nodes selected by `fixed(p)` are held.
template <class Fixed>
SoftBodyModel Block(const char* name, const Vec3& lo, const Vec3& hi, int nx, int ny, int nz,
                    const Fixed& fixed) {
  SoftBodyModel b;
  b.name = name;
  b.rest_mesh = BoxTets(lo, hi, nx, ny, nz);
  b.material = Muscle();
  for (Eigen::Index i = 0; i < b.rest_mesh.nodes.cols(); ++i) {
    if (fixed(Vec3(b.rest_mesh.nodes.col(i)))) b.fixed_nodes.push_back(static_cast<int>(i));
  }
  return b;
}

using testing::SignedDistance;

bool AllFinite(const State& s) {
  for (const SoftBodyState& b : s.soft_bodies) {
    if (!b.x.allFinite() || !b.v.allFinite()) return false;
  }
  return true;
}

// ---- Two soft blocks pressed together -------------------------------------------------------

struct PressResult {
  double deepest = 0;     ///< largest penetration of a surface vertex into the other block, mm
  double final_gap = 0;   ///< mean gap between the blocks at the end (rest), mm
  double tool_force = 0;  ///< final punch force, N
  bool finite = true;
};

// A lower block (10 x 10 x 5 mm, base held) and a free upper block (6 x 6 x 5 mm, centred)
// resting 0.05 mm above it; a flat punch (a 50 m burr sphere) comes down on the upper block's top
// face and presses it 1 mm (at 1 mm/s, then held for 0.5 s: quasi-static, as the solver's contact
// set is fixed at the start of each step). Muscle E 25 kPa, 2 mm elements, vertex grids of the
// facing faces coincident (vertex on vertex: the least favourable case for a vertex-triangle
// test).
PressResult PressBlocks(bool tissue_contacts) {
  Model model;
  model.options.gravity_mm_s2 = Vec3::Zero();
  model.soft_bodies.push_back(Block("lower", Vec3(-5, -5, 0), Vec3(5, 5, 5), 5, 5, 2,
                                    [](const Vec3& p) { return p.z() == 0; }));
  const double gap0 = 0.05;
  model.soft_bodies.push_back(Block("upper", Vec3(-3, -3, 5 + gap0), Vec3(3, 3, 10 + gap0), 3, 3, 2,
                                    [](const Vec3&) { return false; }));
  model.instruments.push_back(testing::TipInstrument("punch", InstrumentKind::kBurr, 5e4));
  State state = MakeInitialState(model);
  sim::Workspace ws;
  sim::BuildWorkspace(model, state, &ws);
  ws.collision_params.tissue_tissue_contacts = tissue_contacts;
  PressResult r;
  const double top = 10 + gap0;
  for (int step = 0; step < 75; ++step) {
    InputFrame in;
    in.tools[0].instrument = 0;
    in.tools[0].pose.orientation = kDown;
    const double push = std::min(0.02 * (step + 1), 1.0);
    // The skin (0.1 mm) keeps the tissue below the punch: push 0 just touches.
    in.tools[0].pose.position_mm = Vec3(0, 0, top + 0.1 - push);
    sim::Step(model, in, &state, &ws);
    r.finite = r.finite && AllFinite(state);
    if (!r.finite) break;
    // Every vertex of the facing faces against the other block's deformed surface.
    for (int a = 0; a < 2; ++a) {
      const SoftBodyState& sa = state.soft_bodies[a];
      const Points& rest = model.soft_bodies[a].rest_mesh.nodes;
      for (Eigen::Index v = 0; v < rest.cols(); ++v) {
        if (std::abs(rest(2, v) - 5) > 0.1) continue;
        const double d = SignedDistance(state.soft_bodies[1 - a], sa.x.col(v));
        r.deepest = std::max(r.deepest, -d);
      }
    }
  }
  // Mean gap between the facing faces at the end.
  double lower_top = 0, upper_bottom = 0;
  int nl = 0, nu = 0;
  for (Eigen::Index i = 0; i < model.soft_bodies[0].rest_mesh.nodes.cols(); ++i) {
    if (model.soft_bodies[0].rest_mesh.nodes(2, i) == 5) {
      lower_top += state.soft_bodies[0].x(2, i);
      ++nl;
    }
  }
  for (Eigen::Index i = 0; i < model.soft_bodies[1].rest_mesh.nodes.cols(); ++i) {
    if (model.soft_bodies[1].rest_mesh.nodes(2, i) == 5 + gap0) {
      upper_bottom += state.soft_bodies[1].x(2, i);
      ++nu;
    }
  }
  r.final_gap = upper_bottom / nu - lower_top / nl;
  r.tool_force = state.tools[0].force_n.norm();
  return r;
}

// Pressed together by 1 mm (~0.1 N: the upper block's E A / h is 0.18 N/mm, in series with the
// lower block's indentation), the blocks must stay apart: no facing vertex more than 0.1 mm
// inside the other block at any step, a positive gap below the 0.1 mm skin plus the per-step
// motion at rest, finite state throughout. Without tissue-tissue contacts the free upper block is
// pushed 1 mm into the lower one.
TEST(TissueContact, TwoSoftBlocksPressedTogetherStayApart) {
  const PressResult with = PressBlocks(true);
  std::printf("with contacts: deepest %.4f mm, final gap %.4f mm, punch force %.4f N\n",
              with.deepest, with.final_gap, with.tool_force);
  EXPECT_TRUE(with.finite);
  EXPECT_LE(with.deepest, 0.1);
  EXPECT_GT(with.final_gap, 0.0);
  EXPECT_LT(with.final_gap, 0.25);
  EXPECT_GT(with.tool_force, 0.1);  // the lower block pushes back through the upper one
  const PressResult without = PressBlocks(false);
  std::printf("without: deepest %.4f mm, final gap %.4f mm\n", without.deepest, without.final_gap);
  EXPECT_GT(without.deepest, 0.5);  // the test can fail
}

// ---- Joined bodies: no contact at the interface ---------------------------------------------

// Two blocks joined at a shared face (coincident nodes, merged by physics) sag under gravity
// for 0.5 s with the lower base held: the interface (distance 0 everywhere) must produce no
// tissue-tissue contact. The same two blocks not joined do get contacts there (each face lies
// on the other: the test can fail).
TEST(TissueContact, JoinedInterfaceProducesNoContact) {
  for (const bool joined : {true, false}) {
    Model model;
    model.soft_bodies.push_back(Block("muscle", Vec3(-5, -5, 0), Vec3(5, 5, 4), 5, 5, 2,
                                      [](const Vec3& p) { return p.z() == 0; }));
    model.soft_bodies.push_back(Block("tendon", Vec3(-5, -5, 4), Vec3(5, 5, 6), 5, 5, 1,
                                      [](const Vec3&) { return false; }));
    if (joined) model.joins.push_back(Join{"muscle", "tendon", 1e-6});
    State state = MakeInitialState(model);
    sim::Workspace ws;
    sim::BuildWorkspace(model, state, &ws);
    std::size_t tissue_contacts = 0;
    for (int step = 0; step < 25; ++step) {
      sim::Step(model, InputFrame{}, &state, &ws);
      ASSERT_TRUE(AllFinite(state));
      for (std::size_t i = 0; i < ws.contacts.contacts.size(); ++i) {
        if (ws.contacts.obstacle_kind[i] == Kind::kSoftBody) ++tissue_contacts;
      }
    }
    std::printf("%s: %zu tissue-tissue contacts over 25 steps\n", joined ? "joined" : "not joined",
                tissue_contacts);
    if (joined) {
      EXPECT_EQ(tissue_contacts, 0u);
    } else {
      EXPECT_GT(tissue_contacts, 25u * 36u);  // at least every interface vertex, every step
    }
  }
}

// ---- A coarse tissue sheet lowered onto a sharp bone tip -------------------------------------

// A narrow bone spike (square pyramid, 4 mm base 30 mm below its tip) under a 20 x 20 x 2 mm
// sheet of 5 mm elements (muscle, border held, under gravity) that has been lowered onto it: the
// tip pokes 0.2 mm into the sheet's lower face, inside a triangle, 2.9 mm from the nearest sheet
// vertex (so the tissue-bone vertex contacts cannot see it). Over 0.4 s the sheet must be pushed
// off the tip and stay there: from step 5 on the tip is at most 0.1 mm inside the sheet and at
// the end it is outside. Returns the signed distance of the tip from the sheet at the end, and
// the deepest penetration from step 5 on (mm).
std::pair<double, double> SheetOnSpike(bool bone_tips) {
  Model model;
  model.soft_bodies.push_back(
      Block("sheet", Vec3(-10, -10, 0), Vec3(10, 10, 2), 4, 4, 1,
            [](const Vec3& p) { return std::abs(p.x()) == 10 || std::abs(p.y()) == 10; }));
  const Vec3 tip(2.5, 1.5, 0.2);
  mesh::TriMesh spike;
  spike.nodes.resize(3, 5);
  spike.nodes.col(0) = tip;
  const double h = 30, w = 2;
  spike.nodes.col(1) = tip + Vec3(-w, -w, -h);
  spike.nodes.col(2) = tip + Vec3(w, -w, -h);
  spike.nodes.col(3) = tip + Vec3(w, w, -h);
  spike.nodes.col(4) = tip + Vec3(-w, w, -h);
  spike.tris = {{0, 1, 2}, {0, 2, 3}, {0, 3, 4}, {0, 4, 1}, {1, 4, 3}, {1, 3, 2}};
  model.bones.push_back(BoneModel{"spur", "", spike, 1, {}, {}});
  State state = MakeInitialState(model);
  sim::Workspace ws;
  sim::BuildWorkspace(model, state, &ws);
  ws.collision_params.bone_tip_contacts = bone_tips;
  EXPECT_EQ(ws.collision.bones[0].salient.size(), 5u);  // the tip and the four base corners
  double deepest = -1e9;
  for (int step = 0; step < 20; ++step) {
    sim::Step(model, InputFrame{}, &state, &ws);
    EXPECT_TRUE(AllFinite(state));
    if (step >= 5) deepest = std::max(deepest, -SignedDistance(state.soft_bodies[0], tip));
  }
  const double end = SignedDistance(state.soft_bodies[0], tip);
  std::printf("bone tips %s: tip %.4f mm from the sheet at the end, deepest %.4f mm\n",
              bone_tips ? "on" : "off", end, deepest);
  return {end, deepest};
}

TEST(TissueContact, SheetLoweredOntoABoneTipIsPushedOffIt) {
  const auto [end, deepest] = SheetOnSpike(true);
  EXPECT_GT(end, 0.0);
  EXPECT_LE(deepest, 0.1);
  EXPECT_LT(SheetOnSpike(false).first, -0.15);  // without: the tip stays inside the sheet
}

// The collision world keeps a bone's tree while the bone's revision is unchanged: a burr cut
// (which raises it) rebuilds that tree, and the contacts then equal a fresh world's.
TEST(BoneRevision, CarvedBoneRebuildsItsTreeAndMatchesAFreshWorld) {
  const Model model = MakeBenchmarkModel();
  State state = MakeInitialState(model);
  const CollisionParams params;
  CollisionWorld world;
  CollisionOutput out;
  Detect(model, state, state.tools, params, &world, &out);
  const int built = world.rebuilds;
  Detect(model, state, state.tools, params, &world, &out);
  EXPECT_EQ(world.rebuilds, built);  // nothing changed: refit only
  BoneState& bone = state.bones[0];
  const std::uint64_t before = bone.revision;
  const Vec3 spot = bone.surface.nodes.col(0);
  const double removed = physics::CarveSphere(&bone, spot, 2.0, 0.5);
  ASSERT_NE(removed, 0.0);  // the surface changed
  EXPECT_GT(bone.revision, before);
  Detect(model, state, state.tools, params, &world, &out);
  EXPECT_EQ(world.rebuilds, built + 1);  // that bone only
  CollisionWorld fresh;
  CollisionOutput again;
  Detect(model, state, state.tools, params, &fresh, &again);
  ASSERT_EQ(out.contacts.size(), again.contacts.size());
  for (std::size_t k = 0; k < out.contacts.size(); ++k) {
    EXPECT_EQ(out.contacts[k].nodes, again.contacts[k].nodes);
    EXPECT_EQ(out.contacts[k].offset_mm, again.contacts[k].offset_mm);
  }
}

}  // namespace
}  // namespace arthrosim::collision
