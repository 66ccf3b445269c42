// Contact generation: no tunnelling of fast tools, determinism, order independence, hand-computed
// reactions, thread-tissue rules, events and tool forces.
#include "arthrosim/collision/contact_generation.h"

#include <gtest/gtest.h>

#include <cmath>

#include "arthrosim/collision/bench_scene.h"
#include "arthrosim/core/parallel.h"
#include "arthrosim/core/units.h"
#include "test_instruments.h"

namespace arthrosim::collision {
namespace {

using physics::PointContact;

const Quat kDown(Eigen::AngleAxisd(units::kPi, Vec3::UnitX()));  // tool +z -> world -z

SoftBodyModel Block(const char* name, const Vec3& lo, const Vec3& hi, int nx, int ny, int nz) {
  SoftBodyModel b;
  b.name = name;
  b.rest_mesh = BoxTets(lo, hi, nx, ny, nz);
  return b;
}

// A closed box surface (12 triangles) as a bone.
BoneModel BoxBone(const Vec3& lo, const Vec3& hi) {
  const mesh::TetMesh cube = BoxTets(lo, hi, 1, 1, 1);
  return BoneModel{"bone", "", mesh::TriMesh{cube.nodes, BoundaryTriangles(cube.tets, {})},
                   1,      {}, {}};
}

// Stand-in for the solvers: Gauss-Seidel projection of the contact points onto their planes
// (infinitely stiff penalty, no elasticity). Fixed nodes do not move.
void Project(const Model& model, const physics::ContactSet& contacts, State* state) {
  for (int it = 0; it < 50; ++it) {
    for (const PointContact& c : contacts) {
      if (c.target != PointContact::Target::kSoftBody) continue;
      Points& x = state->soft_bodies[c.index].x;
      const auto& fixed = model.soft_bodies[c.index].fixed_nodes;
      Vec3 p = Vec3::Zero();
      double w2 = 0;
      for (int k = 0; k < 4; ++k) {
        if (c.nodes[k] < 0) continue;
        p += c.weights[k] * x.col(c.nodes[k]);
        if (!std::binary_search(fixed.begin(), fixed.end(), c.nodes[k]))
          w2 += c.weights[k] * c.weights[k];
      }
      const double viol = c.offset_mm - c.normal.dot(p);
      if (viol <= 0 || w2 == 0) continue;
      for (int k = 0; k < 4; ++k) {
        if (c.nodes[k] < 0 || std::binary_search(fixed.begin(), fixed.end(), c.nodes[k])) continue;
        x.col(c.nodes[k]) += c.weights[k] * viol / w2 * c.normal;
      }
    }
  }
}

Model Membrane(InstrumentKind kind) {
  Model m;
  m.soft_bodies.push_back(Block("membrane", Vec3(-10, -10, 0), Vec3(10, 10, 2), 10, 10, 1));
  const Points& n = m.soft_bodies[0].rest_mesh.nodes;
  for (Eigen::Index i = 0; i < n.cols(); ++i) {
    if (std::abs(n(0, i)) == 10 || std::abs(n(1, i)) == 10) {
      m.soft_bodies[0].fixed_nodes.push_back(static_cast<int>(i));
    }
  }
  InstrumentModel tool;
  tool.name = "tool";
  tool.kind = kind;
  m.instruments.push_back(tool);
  return m;
}

// Scissors (closed) with the blades horizontal, moved down face-first at 100 mm/s, dt = 20 ms
// (2 mm per step, 8x the blade half-thickness) through a 2 mm membrane. Returns the largest
// height of a top-surface vertex above the blades' lower face, among vertices under the blades.
double BladeThroughMembrane(bool sweep) {
  const Model model = Membrane(InstrumentKind::kScissors);
  State state = MakeInitialState(model);
  const Points rest = state.soft_bodies[0].x;
  CollisionParams params;
  CollisionWorld world;
  CollisionOutput out;
  state.tools[0].instrument = 0;
  state.tools[0].jaw = 1.0;
  // Blade plane (tool x-z) horizontal: tool y -> world z, tool z -> world -y.
  state.tools[0].pose.orientation = Quat(Eigen::AngleAxisd(0.5 * units::kPi, Vec3::UnitX()));
  const Vec3 start(0.1, -4.0, 5.0);
  double worst = -1e9;
  int touching_steps = 0;
  for (int step = 0; step < 12; ++step) {
    const auto prev = state.tools;
    state.tools[0].pose.position_mm = start - Vec3(0, 0, 2.0 * step);
    Detect(model, state, sweep && step > 0 ? prev : state.tools, params, &world, &out);
    Project(model, out.contacts, &state);
    if (!out.contacts.empty()) ++touching_steps;
    const double blade_z = state.tools[0].pose.position_mm.z();
    const auto prims = ToolPrimitivesWorld(model, state.tools[0]);
    for (Eigen::Index i = 0; i < rest.cols(); ++i) {
      if (rest(2, i) != 2.0) continue;  // top surface
      const Vec3 p = state.soft_bodies[0].x.col(i);
      // Under the closed blades: |x| below the blade half-width at that point (margin 0.2 mm).
      const double along = p.y() - start.y();  // 0 at the tip, 8 at the hinge
      if (along < 0.2 || along > 7.8) continue;
      if (std::abs(p.x() - start.x()) > 1.8 * along / 8.0 - 0.2) continue;
      if (blade_z < 2.0 + 0.5) worst = std::max(worst, p.z() - (blade_z - 0.25));
    }
  }
  if (sweep) {
    EXPECT_EQ(touching_steps, 12);  // every step (the shaft is within reach at once)
  }
  return worst;
}

TEST(ContactGeneration, FastBladeNeverPassesThroughAMembrane) {
  // With the sweep the surface stays below the blade's lower face (skin 0.1 mm below it).
  EXPECT_LE(BladeThroughMembrane(true), -0.1 + 1e-9);
  // Control: without the sweep the same motion tunnels (vertices end above the blade), so the
  // check above can fail.
  EXPECT_GT(BladeThroughMembrane(false), 0.5);
}

void ExpectSameContacts(const CollisionOutput& a, const CollisionOutput& b) {
  ASSERT_EQ(a.contacts.size(), b.contacts.size());
  for (std::size_t i = 0; i < a.contacts.size(); ++i) {
    const PointContact &p = a.contacts[i], &q = b.contacts[i];
    EXPECT_EQ(p.target, q.target);
    EXPECT_EQ(p.index, q.index);
    EXPECT_EQ(p.nodes, q.nodes) << i;
    EXPECT_EQ(p.weights, q.weights) << i;
    EXPECT_EQ(p.normal, q.normal) << i;
    EXPECT_EQ(p.offset_mm, q.offset_mm) << i;
    EXPECT_EQ(p.stiffness_n_per_mm, q.stiffness_n_per_mm);
    EXPECT_EQ(p.tool_slot, q.tool_slot);
    EXPECT_EQ(p.obstacle_id, q.obstacle_id);
    EXPECT_EQ(a.obstacle_kind[i], b.obstacle_kind[i]);
  }
  for (int s = 0; s < kToolSlots; ++s) EXPECT_EQ(a.bone_force_n[s], b.bone_force_n[s]);
}

// Detect with the tools in place, through the cached `world`; the contacts must equal those a
// fresh world (what a restored run would build) finds.
void DetectAsAFreshWorldWould(const Model& model, const State& state, const CollisionParams& params,
                              CollisionWorld* world, CollisionOutput* out) {
  Detect(model, state, state.tools, params, world, out);
  CollisionWorld fresh;
  CollisionOutput again;
  Detect(model, state, state.tools, params, &fresh, &again);
  ExpectSameContacts(*out, again);
}

// The node positions of every soft body.
std::vector<Points> Positions(const State& state) {
  std::vector<Points> x;
  for (const SoftBodyState& b : state.soft_bodies) x.push_back(b.x);
  return x;
}

void PlaceTools(State* state, double x) {
  for (int slot = 0; slot < kToolSlots; ++slot) {
    state->tools[slot].instrument = slot;
    state->tools[slot].pose.orientation = kDown;
    state->tools[slot].pose.position_mm = Vec3(slot == 0 ? x : -x, slot == 0 ? -4.2 : 3.9, 29.0);
    state->tools[slot].jaw = 0.4;
  }
}

TEST(ContactGeneration, ContactsDoNotDependOnInputOrder) {
  const Model model = MakeBenchmarkModel();
  State state = MakeInitialState(model);
  PlaceTools(&state, 1.3);
  CollisionParams params;
  CollisionWorld w1, w2;
  CollisionOutput o1, o2;
  Detect(model, state, state.tools, params, &w1, &o1);
  EXPECT_GT(o1.contacts.size(), 50u);
  // Same scene with reversed tets (nodes rotated by an even permutation) and reversed, rotated
  // bone triangles.
  Model shuffled = model;
  for (SoftBodyModel& b : shuffled.soft_bodies) {
    std::reverse(b.rest_mesh.tets.begin(), b.rest_mesh.tets.end());
    for (mesh::Tet& t : b.rest_mesh.tets) {
      const mesh::Tet o = t;
      t = {o[1], o[2], o[0], o[3]};
    }
  }
  for (BoneModel& b : shuffled.bones) {
    std::reverse(b.surface.tris.begin(), b.surface.tris.end());
    for (mesh::Tri& t : b.surface.tris) {
      const mesh::Tri o = t;
      t = {o[2], o[0], o[1]};
    }
  }
  State s2 = MakeInitialState(shuffled);
  s2.tools = state.tools;
  Detect(shuffled, s2, s2.tools, params, &w2, &o2);
  ExpectSameContacts(o1, o2);
}

TEST(ContactGeneration, RefitWorldEqualsFreshWorldAfterSteps) {
  const Model model = MakeBenchmarkModel();
  State state = MakeInitialState(model);
  const Points rest = state.soft_bodies[0].x;
  CollisionParams params;
  CollisionWorld world;
  CollisionOutput out;
  for (int step = 0; step < 6; ++step) {
    const auto prev = state.tools;
    PlaceTools(&state, -6.0 + 2.0 * step);
    for (Eigen::Index i = 0; i < rest.cols(); ++i) {
      state.soft_bodies[0].x(2, i) = rest(2, i) + 0.4 * std::sin(0.3 * rest(0, i) + step);
    }
    Detect(model, state, step == 0 ? state.tools : prev, params, &world, &out);
    if (step == 5) {
      CollisionWorld fresh;  // what a restored run would build
      CollisionOutput again;
      Detect(model, state, prev, params, &fresh, &again);
      ExpectSameContacts(out, again);
    }
  }
  EXPECT_EQ(world.rebuilds, 4);  // 2 soft + 2 bones, once: refit afterwards
}

// The stage runs its tasks (tool slots, threads, bodies) on worker threads when there are any:
// over the benchmark workload (two tools crossing a thread on the cuff, tissue on bone, tissue
// on tissue) every step's output is the same for 1, 2 and 3 threads, bone touches included.
TEST(ContactGeneration, ContactsDoNotDependOnThreadCount) {
  const Model model = MakeBenchmarkModel();
  std::vector<CollisionOutput> one;
  BenchmarkCollision(model, 30, [&](int, const CollisionOutput& out) { one.push_back(out); });
  std::size_t total = 0;
  for (const CollisionOutput& o : one) total += o.contacts.size();
  EXPECT_GT(total, 30u * 100u);
  for (int threads : {2, 3}) {
    SetThreadCount(threads);
    BenchmarkCollision(model, 30, [&](int step, const CollisionOutput& out) {
      ExpectSameContacts(one[static_cast<std::size_t>(step)], out);
      ASSERT_EQ(one[static_cast<std::size_t>(step)].bone_touches.size(), out.bone_touches.size());
      for (int s = 0; s < kToolSlots; ++s) {
        EXPECT_EQ(one[static_cast<std::size_t>(step)].substeps[s], out.substeps[s]);
      }
    });
    SetThreadCount(1);
  }
}

// Tissue-bone searches are skipped for vertices still within a proven out-of-reach bound of an
// earlier search: at every step of a slow wave (vertices moving 0.02-0.1 mm per step, so bounds
// hold for several steps and then expire) the contacts equal a fresh world's, and the skip is
// really used.
TEST(ContactGeneration, TissueBoneOutOfReachBoundsNeverChangeContacts) {
  const Model model = MakeBenchmarkModel();
  State state = MakeInitialState(model);
  const std::vector<Points> rest = Positions(state);
  CollisionParams params;
  CollisionWorld world;
  CollisionOutput out;
  int bounded = 0, bone_contacts = 0;
  for (int step = 0; step < 40; ++step) {
    for (std::size_t b = 0; b < rest.size(); ++b) {
      for (Eigen::Index i = 0; i < rest[b].cols(); ++i) {
        state.soft_bodies[b].x(2, i) = rest[b](2, i) - 0.8 * std::sin(0.05 * step) +
                                       0.1 * std::sin(0.3 * rest[b](0, i) + 0.2 * step);
      }
    }
    DetectAsAFreshWorldWould(model, state, params, &world, &out);
    for (const auto& e : world.soft) {
      for (const NearBoneCache& c : e.near_bone) {
        for (double m : c.far_margin) bounded += m > 0;
      }
    }
    for (ConstraintEnd::Kind k : out.obstacle_kind)
      bone_contacts += k == ConstraintEnd::Kind::kBone;
  }
  std::printf("bounded vertex-steps %d, bone contacts %d\n", bounded, bone_contacts);
  EXPECT_GT(bounded, 100);
  EXPECT_GT(bone_contacts, 100);
}

// Tissue-tissue and bone tip-tissue searches are skipped for points within a proven
// out-of-reach bound (own motion plus the other surface's drift): an upper block coming down
// onto a lower one and leaving again while both carry a wave, over a bone spike the lower block
// sinks onto. At every step the contacts equal a fresh world's, and the skips are really used.
TEST(ContactGeneration, SoftSoftAndBoneTipBoundsNeverChangeContacts) {
  Model model;
  model.soft_bodies.push_back(Block("lower", Vec3(-10, -10, 0), Vec3(10, 10, 4), 5, 5, 2));
  model.soft_bodies.push_back(Block("upper", Vec3(-5, -5, 5.5), Vec3(5, 5, 8), 5, 5, 1));
  const Vec3 tip(2.5, 1.5, -1.2);
  mesh::TriMesh spike;
  spike.nodes.resize(3, 5);
  spike.nodes.col(0) = tip;
  for (int k = 0; k < 4; ++k) {
    spike.nodes.col(k + 1) = tip + Vec3(k == 0 || k == 3 ? -2 : 2, k < 2 ? -2 : 2, -30);
  }
  spike.tris = {{0, 1, 2}, {0, 2, 3}, {0, 3, 4}, {0, 4, 1}, {1, 4, 3}, {1, 3, 2}};
  model.bones.push_back(BoneModel{"spur", "", spike, 1, {}, {}});
  State state = MakeInitialState(model);
  const std::vector<Points> rest = Positions(state);
  CollisionParams params;
  CollisionWorld world;
  CollisionOutput out;
  int bounded = 0, tissue = 0, tips = 0;
  for (int step = 0; step < 60; ++step) {
    const double lower_dz = -0.9 * std::sin(0.07 * step), upper_dz = -1.45 * std::sin(0.09 * step);
    for (std::size_t b = 0; b < rest.size(); ++b) {
      for (Eigen::Index i = 0; i < rest[b].cols(); ++i) {
        state.soft_bodies[b].x(2, i) = rest[b](2, i) + (b == 0 ? lower_dz : upper_dz) +
                                       0.05 * std::sin(0.4 * rest[b](0, i) + 0.3 * step);
        state.soft_bodies[b].x(0, i) = rest[b](0, i) + (b == 1 ? 0.03 * step : 0.0);
      }
    }
    DetectAsAFreshWorldWould(model, state, params, &world, &out);
    for (const auto& e : world.soft) {
      for (const FarBounds& f : e.far_soft) {
        for (double m : f.margin) bounded += m > 0;
      }
    }
    for (std::size_t i = 0; i < out.contacts.size(); ++i) {
      tissue += out.obstacle_kind[i] == ConstraintEnd::Kind::kSoftBody;
      tips += out.obstacle_kind[i] == ConstraintEnd::Kind::kBone && out.contacts[i].nodes[1] >= 0;
    }
  }
  std::printf("bounded vertex-steps %d, tissue-tissue contacts %d, bone tip contacts %d\n", bounded,
              tissue, tips);
  EXPECT_GT(bounded, 1000);
  EXPECT_GT(tissue, 100);
  EXPECT_GT(tips, 5);
}

TEST(ContactGeneration, ToolBoneReactionIsStiffnessTimesDepth) {
  Model model;
  model.bones.push_back(BoxBone(Vec3(-10, -10, -10), Vec3(10, 10, 0)));
  model.instruments.push_back(testing::TipInstrument("burr", InstrumentKind::kBurr, 2.5));
  State state = MakeInitialState(model);
  state.tools[0].instrument = 0;
  state.tools[0].pose.orientation = kDown;
  state.tools[0].pose.position_mm = Vec3(0.7, -1.1, -1.0);  // sphere centre 1.5 above: 1 mm deep
  CollisionParams params;
  CollisionWorld world;
  CollisionOutput out;
  Detect(model, state, state.tools, params, &world, &out);
  EXPECT_TRUE(out.contacts.empty());  // bone is fixed, tool kinematic: no solver term
  const Vec3 expected(0, 0, params.tool_bone_stiffness_n_per_mm * 1.0);  // N
  EXPECT_LT((out.bone_force_n[0] - expected).norm(), 1e-12);
  EXPECT_LT((ToolForces(out)[0] - expected).norm(), 1e-12);
  ASSERT_EQ(out.bone_touches.size(), 1u);
  EXPECT_EQ(out.bone_touches[0].body_kind, ConstraintEnd::Kind::kBone);
}

TEST(ContactGeneration, TissueOnBoneIsPushedOutAlongTheBoneNormal) {
  Model model;
  model.soft_bodies.push_back(Block("cuff", Vec3(-5, -5, -0.5), Vec3(5, 5, 3), 5, 5, 2));
  model.bones.push_back(BoxBone(Vec3(-10, -10, -10), Vec3(10, 10, 0)));
  State state = MakeInitialState(model);
  CollisionWorld world;
  CollisionOutput out;
  Detect(model, state, state.tools, CollisionParams{}, &world, &out);
  ASSERT_EQ(out.contacts.size(), 36u);  // the 6 x 6 bottom nodes, 0.5 mm inside the bone
  for (const PointContact& c : out.contacts) {
    EXPECT_EQ(c.normal, Vec3(0, 0, 1));
    EXPECT_NEAR(c.offset_mm, 0.1, 1e-15);
    EXPECT_EQ(state.soft_bodies[0].x(2, c.nodes[0]), -0.5);
    EXPECT_EQ(c.obstacle_id, 0);
    EXPECT_EQ(c.tool_slot, -1);
  }
}

Model ThreadOnBlock(bool stitched) {
  Model model;
  model.soft_bodies.push_back(Block("tendon", Vec3(-5, -5, 0), Vec3(5, 5, 3), 5, 5, 3));
  ThreadModel t;
  t.name = "suture";
  const int n = stitched ? 14 : 21;
  t.initial.nodes.resize(3, n);
  for (int i = 0; i < n; ++i) {
    t.initial.nodes.col(i) =
        stitched ? Vec3(0.3, 0.3, -5.5 + i) : Vec3(-10.0 + i, 0.3, 3 + 0.5 * t.diameter_mm + 0.05);
    if (i > 0) t.initial.edges.push_back({i - 1, i});
  }
  model.threads.push_back(t);
  return model;
}

TEST(ContactGeneration, ThreadLyingOnTissueGetsContactsOnBothSides) {
  const Model model = ThreadOnBlock(false);
  const State state = MakeInitialState(model);
  CollisionParams params;
  CollisionWorld world;
  CollisionOutput out;
  Detect(model, state, state.tools, params, &world, &out);
  int thread_side = 0, tissue_side = 0;
  const double rt = 0.5 * model.threads[0].diameter_mm;
  for (const PointContact& c : out.contacts) {
    if (c.target == PointContact::Target::kThread) {
      ++thread_side;
      EXPECT_GT(c.normal.z(), 0.0);
      const Vec3 p = state.threads[0].x.col(c.nodes[0]);
      if (std::abs(p.x()) < 4) {  // over the top face: plane 3 + r + skin, already 0.05 violated
        EXPECT_LT((c.normal - Vec3(0, 0, 1)).norm(), 1e-15);
        EXPECT_NEAR(c.offset_mm, 3 + rt + params.contact_distance_mm, 1e-12);
      }
    } else {
      ++tissue_side;
      EXPECT_LT(c.normal.z(), 0.0);
      EXPECT_EQ(c.obstacle_id, 0);
    }
  }
  EXPECT_GE(thread_side, 10);
  EXPECT_EQ(thread_side, tissue_side);
}

TEST(ContactGeneration, StitchedThreadIsNotPushedOutOfTheTissue) {
  const Model model = ThreadOnBlock(true);
  const State state = MakeInitialState(model);
  CollisionWorld world;
  CollisionOutput out;
  Detect(model, state, state.tools, CollisionParams{}, &world, &out);
  EXPECT_TRUE(out.contacts.empty());
}

// A thread run straight down through bone (as the stitched thread above runs through tissue):
// bone is never passed through, so every node the search reaches inside it (down to
// thread_bone_reach_mm below the alarm band) gets a contact pushing it out along the face's
// normal, those beside the crossing too, at the thread-bone stiffness. Before: the crossing
// segment counted as a piercing (its nodes and neighbours blocked) and nodes deeper than
// max_depth_mm (1.5) had no contact, so this got none at all.
TEST(ContactGeneration, AThreadThroughBoneIsPushedOutAtEveryDepthTheSearchReaches) {
  Model model;
  model.bones.push_back(BoxBone(Vec3(-10, -10, -10), Vec3(10, 10, 0)));
  ThreadModel t;
  t.name = "suture";
  t.initial.nodes.resize(3, 14);
  for (int i = 0; i < 14; ++i) {
    t.initial.nodes.col(i) = Vec3(0.3, 0.3, -5.5 + i);  // z = -5.5 ... 7.5
    if (i > 0) t.initial.edges.push_back({i - 1, i});
  }
  model.threads.push_back(t);
  const State state = MakeInitialState(model);
  CollisionParams params;
  CollisionWorld world;
  CollisionOutput out;
  Detect(model, state, state.tools, params, &world, &out);
  const double rt = 0.5 * model.threads[0].diameter_mm;
  std::vector<int> nodes;
  for (const PointContact& c : out.contacts) {
    ASSERT_EQ(c.target, PointContact::Target::kThread);
    EXPECT_LT((c.normal - Vec3(0, 0, 1)).norm(), 1e-12);
    EXPECT_NEAR(c.offset_mm, rt + params.contact_distance_mm, 1e-12);
    EXPECT_EQ(c.stiffness_n_per_mm, params.thread_bone_stiffness_n_per_mm);
    if (c.nodes[1] < 0 || c.weights[1] == 0) nodes.push_back(c.nodes[0]);
  }
  // Nodes at z = -3.5 ... 0.5: inside down to the reach (3 mm below the 1.275 mm band of a
  // 0.55 mm thread: 4.275 mm), and the one 0.5 mm above the face within the alarm band.
  EXPECT_EQ(nodes, (std::vector<int>{2, 3, 4, 5, 6}));
}

TEST(ContactGeneration, EventsStartAndEndWithRegionAndToolForcesSum) {
  Model model;
  model.soft_bodies.push_back(Block("tendon", Vec3(-5, -5, 0), Vec3(5, 5, 3), 5, 5, 3));
  model.regions.push_back(Region{"elsewhere", "tendon", {}, Vec3(4, 4, 0), Vec3(5, 5, 3)});
  model.regions.push_back(Region{"footprint", "tendon", {}, Vec3(-5, -5, 0), Vec3(5, 5, 3.5)});
  model.instruments.push_back(
      testing::TipInstrument("probe", InstrumentKind::kElectrocautery, 1.0));
  State state = MakeInitialState(model);
  state.tools[0].instrument = 0;
  state.tools[0].pose.orientation = kDown;
  state.tools[0].pose.position_mm = Vec3(0.2, 0.1, 2.8);
  CollisionWorld world;
  CollisionOutput out;
  Detect(model, state, state.tools, CollisionParams{}, &world, &out);
  ASSERT_FALSE(out.contacts.empty());
  Vec3 expected = Vec3::Zero();
  for (PointContact& c : out.contacts) {
    c.force_n = 0.25;  // as a solver would fill it
    expected -= 0.25 * c.normal;
  }
  EXPECT_LT((ToolForces(out)[0] - expected).norm(), 1e-12);
  EXPECT_GT(ToolForces(out)[0].z(), 0);  // tissue pushes the tool back up
  std::vector<ToolContact> touching;
  std::vector<Event> events;
  UpdateContactEvents(model, state, out, &touching, &events);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, "contact_start");
  EXPECT_EQ(events[0].tool, "probe");
  EXPECT_EQ(events[0].body, "tendon");
  EXPECT_EQ(events[0].detail, "region=footprint");
  ASSERT_EQ(touching.size(), 1u);
  UpdateContactEvents(model, state, out, &touching, &events);  // still touching: no event
  EXPECT_EQ(events.size(), 1u);
  for (PointContact& c : out.contacts) c.force_n = 0;  // separated
  UpdateContactEvents(model, state, out, &touching, &events);
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[1].kind, "contact_end");
  EXPECT_TRUE(touching.empty());
}

}  // namespace
}  // namespace arthrosim::collision
