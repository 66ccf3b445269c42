// Scorpion needle on the slab scene: load the suture (button 1), take the tissue edge between
// the jaws, pass (button 2); the thread nodes lie where the paper places them, stay attached as
// the tendon moves 5 mm, the bite distance to `tendon_edge` is right, nothing diverges; a tail
// that would run into bone is laid back along the shaft.
#include <unistd.h>

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "arthrosim/core/error.h"
#include "arthrosim/core/parallel.h"
#include "arthrosim/physics/constraints.h"
#include "suture_scene.h"

namespace arthrosim::instruments {
namespace {

using testing::SlotDriver;

// Horizontal, pointing -x (toward the slab from its free edge), upper jaw (side 0) up.
Quat TowardMinusX() { return testing::ToolAxes(Vec3(0, 0, 1), Vec3(0, 1, 0), Vec3(-1, 0, 0)); }

constexpr std::uint8_t kB1 = 1, kB2 = 2;

double Detail(const Event& e, const std::string& key) {
  const std::size_t at = e.detail.find(key + "=");
  EXPECT_NE(at, std::string::npos) << key << " in " << e.detail;
  return at == std::string::npos ? 0 : std::atof(e.detail.c_str() + at + key.size() + 1);
}

Vec3 DetailPoint(const Event& e, const std::string& key) {
  const std::size_t at = e.detail.find(key + "=");
  Vec3 p = Vec3::Zero();
  if (at == std::string::npos) return p;
  std::sscanf(e.detail.c_str() + at + key.size() + 1, "%lf,%lf,%lf", &p.x(), &p.y(), &p.z());
  return p;
}

struct Pass {
  std::vector<Event> events;  // thread_catch, grasp, suture_pass of the run, in order
};

// Loads the suture at thread node 27 (x = 33), carries it to the slab's free edge, closes the
// jaws on the edge and passes. Returns the suture_pass event (kind empty if none).
Event LoadAndPass(SlotDriver* d, Pass* log) {
  d->frame.tools[0].pose.orientation = TowardMinusX();
  const auto keep = [&] {
    for (const Event& e : d->state->events)
      if (e.kind == "thread_catch" || e.kind == "grasp" || e.kind == "suture_pass" ||
          e.kind == "release")
        log->events.push_back(e);
  };
  d->Step(Vec3(33, 10, 8), 0.0);
  d->Step(Vec3(33, 10, 8), 0.0, kB1);  // catch the thread at the tip
  keep();
  for (int k = 1; k <= 12; ++k) d->Step(Vec3(33, 10, 8 - 0.5 * k), 0.0, kB1), keep();  // down
  for (int k = 1; k <= 12; ++k) d->Step(Vec3(33 - 0.5 * k, 10, 2), 0.0, kB1), keep();  // in
  for (int k = 1; k <= 5; ++k) d->Step(Vec3(27, 10, 2), 0.1 * k, kB1), keep();  // close on it
  d->Step(Vec3(27, 10, 2), 0.5, kB1 | kB2);
  keep();
  for (const Event& e : d->state->events)
    if (e.kind == "suture_pass") return e;
  return Event{};
}

TEST(ScorpionNeedle, PassPlacesTheNodesAsThePaperSays) {
  const Model m = testing::SlabModel();
  State s = MakeInitialState(m);
  SlotDriver d(m, &s, "scorpion_needle");
  Pass log;
  const Event pass = LoadAndPass(&d, &log);
  ASSERT_FALSE(log.events.empty());
  EXPECT_EQ(log.events.front().kind, "thread_catch");
  ASSERT_EQ(pass.kind, "suture_pass") << "events: " << log.events.size();
  const int entry = static_cast<int>(Detail(pass, "entry_node"));
  const int exit = static_cast<int>(Detail(pass, "exit_node"));
  EXPECT_EQ(entry, 27);
  ASSERT_GE(exit - entry, 3) << "at least the paper's third node";
  const Vec3 entry_mm = DetailPoint(pass, "entry_mm"), exit_mm = DetailPoint(pass, "exit_mm");
  // Entry on the bottom face, exit on the top face (triangle centres), the path through the slab.
  EXPECT_NEAR(entry_mm.z(), 0.0, 0.5);
  EXPECT_NEAR(exit_mm.z(), 4.0, 0.5);
  const Points& x = s.threads[0].x;
  EXPECT_LT((x.col(entry) - entry_mm).norm(), 1e-3);
  EXPECT_LT((x.col(exit) - exit_mm).norm(), 1e-3);
  // The rest at 1 mm intervals along the entry->exit direction, away from the tissue.
  const Vec3 dir = (x.col(exit) - x.col(entry)).normalized();
  EXPECT_GT(dir.dot((exit_mm - entry_mm).normalized()), 0.999);
  for (int n = exit; n + 1 < x.cols(); ++n) {
    const Vec3 seg = x.col(n + 1) - x.col(n);
    EXPECT_NEAR(seg.norm(), 1.0, 1e-9) << "node " << n;
    EXPECT_GT(seg.normalized().dot(dir), 1 - 1e-9) << "node " << n;
  }
  // The pass stretches no segment of the thread (the limb behind the entry follows it); the
  // first segment, at the fixed end, was drawn taut by the tool carrying the limb before.
  const Points& x0 = m.threads[0].initial.nodes;
  for (int n = 2; n < x.cols(); ++n)
    EXPECT_LE((x.col(n) - x.col(n - 1)).norm(), 1.01 * (x0.col(n) - x0.col(n - 1)).norm())
        << "segment " << n;
  // One stitch spring per node inside the tissue, the tool no longer holds the thread.
  EXPECT_EQ(physics::FindConstraintsByTag(s, "stitch").size(),
            static_cast<std::size_t>(exit - entry + 1));
  EXPECT_TRUE(physics::FindConstraintsByTag(s, "scorpion_thread").empty());
}

// The slab scene with a bone plate (x in [18, 30], y in [0, 20], z in [11, 15] mm) over the
// slab, across the line a passed tail is laid along (straight up from the exit, at x = 27).
// The mesh is written into the folder LoadSlabScenario then writes the scenario into.
Model SlabUnderBonePlateModel() {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("arthrosim_suture_slab_plate_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  {
    std::ofstream obj(dir / "plate.obj");
    const double lo[3] = {18, 0, 11}, hi[3] = {30, 20, 15};
    for (int k = 0; k < 8; ++k)
      obj << "v " << (k & 1 ? hi : lo)[0] << " " << (k & 2 ? hi : lo)[1] << " "
          << (k & 4 ? hi : lo)[2] << "\n";
    // Twelve outward triangles (vertex k: bit 0 x, bit 1 y, bit 2 z; OBJ counts from 1).
    obj << "f 1 3 4\nf 1 4 2\nf 5 6 8\nf 5 8 7\nf 1 2 6\nf 1 6 5\n"
           "f 3 7 8\nf 3 8 4\nf 1 5 7\nf 1 7 3\nf 2 4 8\nf 2 8 6\n";
  }
  return testing::LoadSlabScenario("suture_slab_plate", 5e6,
                                   R"(  - name: suture
    kind: thread
    thread: {start: [6, 10, 8], end: [46, 10, 8], nodes: 41, damping: 5, fixed_nodes: [0]}
  - {name: plate, kind: rigid, mesh: plate.obj}
)",
                                   "[60, 10, 30]", R"(instruments:
  - {name: scorpion_needle, kind: scorpion_needle, portal: lateral, tip_length: 8}
camera: {portal: lateral, position: [50, 10, 20], look_at: [10, 10, 5]}
)");
}

// Where the paper's straight tail would run into bone, the rest of it is laid back along the
// needle's shaft (tool -z, here +x) from the last node clear of the bone. Fails with the paper's
// straight layout: its last two nodes (8 and 9 mm beyond the exit) lie inside the plate.
TEST(ScorpionNeedle, APassedTailThatWouldRunIntoBoneTurnsBackAlongTheShaft) {
  const Model m = SlabUnderBonePlateModel();
  ASSERT_EQ(m.bones.size(), 1u);
  State s = MakeInitialState(m);
  SlotDriver d(m, &s, "scorpion_needle");
  Pass log;
  const Event pass = LoadAndPass(&d, &log);
  ASSERT_EQ(pass.kind, "suture_pass");
  const int exit = static_cast<int>(Detail(pass, "exit_node"));
  const Points& x = s.threads[0].x;
  const double clearance_mm = 0.5 * m.threads[0].diameter_mm + m.contact.contact_distance_mm;
  int turned_at = -1;
  for (int n = exit; n + 1 < x.cols(); ++n) {
    const Vec3 seg = x.col(n + 1) - x.col(n);
    EXPECT_NEAR(seg.norm(), 1.0, 1e-9) << "node " << n;
    if (turned_at < 0 && seg.normalized().dot(Vec3::UnitX()) > 1 - 1e-9) turned_at = n;
    if (turned_at >= 0) {
      EXPECT_GT(seg.normalized().dot(Vec3::UnitX()), 1 - 1e-9) << "node " << n;
    }
    EXPECT_LT(x(2, n + 1), 11.0 - clearance_mm + 1e-9) << "node " << n + 1 << " at the plate";
  }
  ASSERT_GE(turned_at, 0) << "the tail never turned";
  EXPECT_GT(x(2, turned_at), 11.0 - clearance_mm - 1.0) << "turned no earlier than it had to";
  EXPECT_LT(turned_at + 1, x.cols() - 1) << "some of the tail runs back along the shaft";
}

TEST(ScorpionNeedle, BiteDistanceIsTheDistanceToTheTendonEdge) {
  const Model m = testing::SlabModel();  // stiff: the edge stays where it was at rest
  State s = MakeInitialState(m);
  SlotDriver d(m, &s, "scorpion_needle");
  Pass log;
  const Event pass = LoadAndPass(&d, &log);
  ASSERT_EQ(pass.kind, "suture_pass");
  // The torn edge is the face x = 30 at rest; the tissue moved little, so the geometric
  // distance is the entry point's distance to that plane.
  const Vec3 entry_mm = DetailPoint(pass, "entry_mm");
  EXPECT_NEAR(Detail(pass, "bite_to_edge_mm"), 30.0 - entry_mm.x(), 0.5);
  EXPECT_GT(Detail(pass, "bite_to_edge_mm"), 1.0);
}

// Debridement leaves edge nodes without elements where they were cut (debris); once the tendon
// is drawn away from them (a reduction), such a node can lie nearer the bite than the edge the
// tissue has. The bite distance must skip it: here one edge node loses its elements and is put
// 1 mm from where the pass enters; the distance stays the live edge's.
TEST(ScorpionNeedle, BiteDistanceSkipsEdgeNodesLeftWithoutTissue) {
  const Model m = testing::SlabModel();
  Vec3 entry_mm = Vec3::Zero();
  {
    State s = MakeInitialState(m);
    SlotDriver d(m, &s, "scorpion_needle");
    Pass log;
    const Event pass = LoadAndPass(&d, &log);
    ASSERT_EQ(pass.kind, "suture_pass");
    entry_mm = DetailPoint(pass, "entry_mm");
  }
  State s = MakeInitialState(m);
  const Region& edge = m.regions[static_cast<std::size_t>(m.FindRegion("tendon_edge"))];
  ASSERT_FALSE(edge.nodes.empty());
  const std::int32_t debris = edge.nodes.front();
  SoftBodyState& tendon = s.soft_bodies[0];
  int killed = 0;
  for (std::size_t t = 0; t < tendon.tets.size(); ++t)
    for (const std::int32_t node : tendon.tets[t])
      if (node == debris && tendon.tet_alive[t]) {
        tendon.tet_alive[t] = 0;
        ++killed;
      }
  ASSERT_GT(killed, 0);
  tendon.x.col(debris) = entry_mm + Vec3(0, 0, -1);
  tendon.x_rest.col(debris) = tendon.x.col(debris);
  SlotDriver d(m, &s, "scorpion_needle");
  Pass log;
  const Event pass = LoadAndPass(&d, &log);
  ASSERT_EQ(pass.kind, "suture_pass");
  const Vec3 entry = DetailPoint(pass, "entry_mm");
  ASSERT_LT((entry - entry_mm).norm(), 2.0) << "the pass entered elsewhere";
  EXPECT_NEAR(Detail(pass, "bite_to_edge_mm"), 30.0 - entry.x(), 0.5);
}

TEST(ScorpionNeedle, StitchesHoldAsTheTendonMovesAndNothingDiverges) {
  // A firm grasp (50 N/mm, 5 mm reach) so the grasper can lift the stiff slab's end.
  const Model m = testing::SlabModel("operations: {grasper: {stiffness: 50, dist_limit: 5}}\n");
  State s = MakeInitialState(m);
  SlotDriver d(m, &s, "scorpion_needle");
  Pass log;
  ASSERT_EQ(LoadAndPass(&d, &log).kind, "suture_pass");
  const std::vector<std::int64_t> stitches = physics::FindConstraintsByTag(s, "stitch");
  ASSERT_FALSE(stitches.empty());
  const Vec3 bite0 = physics::EndPosition(s, physics::FindConstraint(s, stitches[0])->b);
  // The needle lets go and backs out; a grasper in slot 1 takes the tendon beside the bite
  // and lifts it 5 mm.
  d.Step(Vec3(27, 10, 2), 0.5, 0);
  EXPECT_TRUE(physics::FindConstraintsByTag(s, "scorpion_tissue").empty());
  for (int k = 1; k <= 10; ++k) d.Step(Vec3(27 + 1.5 * k, 10, 2), 0.0, 0);
  ToolCommand& grasper = d.frame.tools[1];
  grasper.instrument = m.FindInstrument("grasper");
  grasper.pose.orientation = testing::Downward();
  const Vec3 start(25, 10, 4.4);
  for (int k = 0; k < 4; ++k) {
    grasper.jaw = k < 3 ? 0.0 : 1.0;
    grasper.pose.position_mm = start;
    d.Step(Vec3(42, 10, 2), 0.0, 0);
  }
  ASSERT_EQ(physics::FindConstraintsByTag(s, "grasp").size(), 1u);
  for (int k = 1; k <= 50; ++k) {
    grasper.pose.position_mm = start + Vec3(0, 0, 0.2 * std::min(k, 25));
    d.Step(Vec3(42, 10, 2), 0.0, 0);
  }
  ASSERT_EQ(physics::FindConstraintsByTag(s, "grasp").size(), 1u) << "still held";
  const Vec3 bite1 = physics::EndPosition(s, physics::FindConstraint(s, stitches[0])->b);
  EXPECT_GT(bite1.z() - bite0.z(), 4.0) << "the tendon at the bite moved with the grasper";
  double worst_mm = 0;
  for (const std::int64_t id : stitches) {
    const SpringConstraint* c = physics::FindConstraint(s, id);
    ASSERT_NE(c, nullptr);
    worst_mm =
        std::max(worst_mm, (physics::EndPosition(s, c->a) - physics::EndPosition(s, c->b)).norm());
  }
  EXPECT_LT(worst_mm, 1.0) << "thread nodes stay at their tissue points";
  ASSERT_TRUE(s.threads[0].x.allFinite());
  ASSERT_TRUE(s.soft_bodies[0].x.allFinite());
  // Thread strain: no segment longer than 1 % over its rest length (1 mm).
  const Points& x = s.threads[0].x;
  double worst_strain = 0;
  for (int n = 0; n + 1 < x.cols(); ++n)
    worst_strain = std::max(worst_strain, (x.col(n + 1) - x.col(n)).norm() - 1.0);
  EXPECT_LE(worst_strain, 0.01);
}

// Jaws slid a third open round the slab's free edge with button 1 held (loading the thread):
// they touch it on the way in. Returns the grasps made on the way in; `closed_grasps` those made
// once the jaws close to 0.5 there.
int GraspsDuringApproach(const Model& m, int* closed_grasps) {
  State s = MakeInitialState(m);
  SlotDriver d(m, &s, "scorpion_needle");
  d.frame.tools[0].pose.orientation = TowardMinusX();
  int open = 0;
  *closed_grasps = 0;
  const auto count = [&](int* into) {
    for (const Event& e : s.events) *into += e.kind == "grasp" ? 1 : 0;
  };
  d.Step(Vec3(33, 10, 8), 0.3, kB1);  // the thread at the tip is caught
  for (int k = 1; k <= 12; ++k) d.Step(Vec3(33, 10, 8 - 0.5 * k), 0.3, kB1), count(&open);
  bool touched = false;
  for (int k = 1; k <= 12; ++k) {
    d.Step(Vec3(33 - 0.5 * k, 10, 2), 0.3, kB1), count(&open);
    for (const physics::PointContact& c : d.ws.contacts.contacts)
      touched = touched || (c.tool_slot == 0 && c.force_n > 0);
  }
  EXPECT_TRUE(touched) << "the open jaws touch the slab on the way in";
  for (int k = 1; k <= 5; ++k) d.Step(Vec3(27, 10, 2), 0.3 + 0.04 * k, kB1), count(closed_grasps);
  return open;
}

TEST(ScorpionNeedle, OpenJawsSlidRoundTheTissueDoNotGraspIt) {
  int closed = 0;
  EXPECT_EQ(GraspsDuringApproach(testing::SlabModel(), &closed), 0);
  EXPECT_EQ(closed, 1);
  // With grasp_jaw 0 (any jaw) the tissue is taken on the way in, before the jaws close.
  EXPECT_EQ(GraspsDuringApproach(
                testing::SlabModel("operations: {scorpion_needle: {grasp_jaw: 0}}\n"), &closed),
            1);
  EXPECT_EQ(closed, 0);
}

TEST(ScorpionNeedle, ReadsGraspJaw) {
  EXPECT_DOUBLE_EQ(testing::SlabModel().operations.scorpion_needle.grasp_jaw, 0.35);
  EXPECT_DOUBLE_EQ(testing::SlabModel("operations: {scorpion_needle: {grasp_jaw: 0.6}}\n")
                       .operations.scorpion_needle.grasp_jaw,
                   0.6);
  EXPECT_THROW(testing::SlabModel("operations: {scorpion_needle: {grasp_jaw: 1.5}}\n"), InputError);
}

State SutureRun(const Model& m) {
  State s = MakeInitialState(m);
  SlotDriver d(m, &s, "scorpion_needle");
  Pass log;
  LoadAndPass(&d, &log);
  for (int k = 1; k <= 10; ++k) d.Step(Vec3(27, 10, 2 + 0.2 * k), 0.5, kB1);
  return s;
}

TEST(ScorpionNeedle, BitIdenticalForOneAndTwoThreads) {
  const auto [a, b] = testing::RunWithOneAndTwoThreads(testing::SlabModel(), SutureRun);
  EXPECT_TRUE(BitwiseEqual(a, b));
  EXPECT_FALSE(physics::FindConstraintsByTag(a, "stitch").empty());
}

}  // namespace
}  // namespace arthrosim::instruments
