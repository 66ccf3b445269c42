// Knot pusher on a slab scene: two suture limbs (A stitched to the slab's torn edge, B fixed at
// an "anchor" 10.2 mm beyond it) converge where the tool takes them; button 1 takes both (never a
// third thread nearby) and throws a half hitch; button 2 slides the knot to the target node and
// lets go; the knot then holds the loop (pulling the edge toward the anchor when the loop is
// short); the pull test tells a good knot from one whose knot springs are too soft.
#include <unistd.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>

#include "arthrosim/core/error.h"
#include "arthrosim/core/parallel.h"
#include "arthrosim/instruments/knot_identify.h"
#include "arthrosim/instruments/knot_pusher.h"
#include "arthrosim/physics/constraints.h"
#include "suture_scene.h"

namespace arthrosim::instruments {
namespace {

using testing::SlotDriver;

constexpr std::uint8_t kB1 = 1, kB2 = 2;
constexpr int kEdgeNode = 447;   // slab node (30, 10, 4): top of the torn edge
const Vec3 kTakeAt(35, 10, 29);  // where the two limbs pass 1 mm either side of the tool

Model KnotModel(const std::string& knot_options = "") {
  return testing::LoadSlabScenario("knot_slab", 2.0e5, R"(  - name: suture_a
    kind: thread
    thread: {start: [30, 9, 4], end: [42, 9, 64], nodes: 61, damping: 5}
  - name: suture_b
    kind: thread
    thread: {start: [40, 11, 4], end: [28, 11, 64], nodes: 61, damping: 5, fixed_nodes: [0]}
  - name: suture_c
    kind: thread
    thread: {start: [38.6, 10, 4], end: [38.6, 10, 64], nodes: 61, damping: 5, fixed_nodes: [0]}
)",
                                   "[60, 10, 60]", R"(instruments:
  - {name: knot_pusher, kind: knot_pusher, portal: lateral, tip_length: 4, tip_radius: 1}
camera: {portal: lateral, position: [50, 10, 40], look_at: [30, 10, 5]}
operations:
  knot_pusher: {)" + knot_options + "}\n");
}

// Suture A's first node is stitched to the slab edge (as a scorpion-needle pass leaves it).
State KnotState(const Model& model) {
  State s = MakeInitialState(model);
  SpringConstraint c;
  c.tag = "stitch";
  c.a.kind = ConstraintEnd::Kind::kThread;
  c.a.index = model.FindThread("suture_a");
  c.a.nodes = {0, -1, -1, -1};
  c.a.weights = {1, 0, 0, 0};
  c.b.kind = ConstraintEnd::Kind::kSoftBody;
  c.b.index = 0;
  c.b.nodes = {kEdgeNode, -1, -1, -1};
  c.b.weights = {1, 0, 0, 0};
  c.stiffness_n_per_mm = 50;
  physics::AddConstraint(&s, c);
  return s;
}

int CountTag(const State& s, const char* tag) {
  int n = 0;
  for (const SpringConstraint& c : s.constraints) n += c.tag == tag ? 1 : 0;
  return n;
}

double Detail(const Event& e, const std::string& key) {
  const std::size_t at = e.detail.find(key + "=");
  EXPECT_NE(at, std::string::npos) << key << " in " << e.detail;
  return at == std::string::npos ? NAN : std::atof(e.detail.c_str() + at + key.size() + 1);
}

std::string DetailText(const Event& e, const std::string& key) {
  const std::size_t at = e.detail.find(key + "=");
  if (at == std::string::npos) return "";
  const std::size_t from = at + key.size() + 1;
  return e.detail.substr(from, e.detail.find(' ', from) - from);
}

// Largest segment strain over the threads (length / rest spacing - 1) and whether every
// coordinate is finite.
double WorstStrain(const Model& model, const State& s, bool* finite) {
  double worst = 0;
  for (std::size_t t = 0; t < s.threads.size(); ++t) {
    const Points& x = s.threads[t].x;
    const Points& x0 = model.threads[t].initial.nodes;
    for (int k = 0; k < x.cols(); ++k) *finite = *finite && x.col(k).allFinite();
    for (int k = 1; k < x.cols(); ++k) {
      const double rest = (x0.col(k) - x0.col(k - 1)).norm();
      worst = std::max(worst, (x.col(k) - x.col(k - 1)).norm() / rest - 1);
    }
  }
  return worst;
}

// The procedure: take both limbs (button 1), then hold button 1 by the third thread, then push
// (button 2) down toward the slab edge until the knot is seated, then 25 steps hands off.
struct TieRun {
  std::vector<Event> knot, seated, catches;
  int held_after_take = 0, held_by_third = 0, knots_after_take = 0;
  double worst_strain = 0;
  bool finite = true;
  Vec3 edge_start = Vec3::Zero(), edge_end = Vec3::Zero();
  std::int64_t seated_step = -1;
  State final;
};

TieRun Tie(const Model& model) {
  TieRun r;
  State s = KnotState(model);
  SlotDriver d(model, &s, "knot_pusher");
  r.edge_start = s.soft_bodies[0].x.col(kEdgeNode);
  const auto step = [&](const Vec3& tip, std::uint8_t buttons) {
    d.Step(tip, 0, buttons);
    for (const Event& e : s.events) {
      if (e.kind == "knot") r.knot.push_back(e);
      if (e.kind == "knot_seated") {
        r.seated.push_back(e);
        r.seated_step = s.step;
      }
      if (e.kind == "thread_catch") r.catches.push_back(e);
    }
    r.worst_strain = std::max(r.worst_strain, WorstStrain(model, s, &r.finite));
  };
  for (int k = 0; k < 3; ++k) step(kTakeAt, kB1);
  r.held_after_take = CountTag(s, kKnotPusherTag);
  r.knots_after_take = static_cast<int>(FindKnots(s).size());
  // Toward suture C (1.6 mm from the tool there) with button 1 still down: not taken.
  for (int k = 1; k <= 5; ++k) step(kTakeAt + Vec3(0.36 * k, 0, 0), kB1);
  r.held_by_third = CountTag(s, kKnotPusherTag);
  for (int k = 4; k >= 0; --k) step(kTakeAt + Vec3(0.36 * k, 0, 0), 0);
  // Push: down toward the edge and the anchor, 0.25 mm a step, button 2.
  Vec3 tip = kTakeAt;
  for (int k = 0; k < 250 && r.seated.empty(); ++k) {
    tip.z() = std::max(12.0, tip.z() - 0.25);
    step(tip, kB2);
  }
  for (int k = 0; k < 25; ++k) step(tip, 0);  // hands off
  r.edge_end = s.soft_bodies[0].x.col(kEdgeNode);
  r.final = s;
  return r;
}

TEST(KnotPusher, TakesTwoLimbsNotAThirdAndTiesAHalfHitch) {
  const Model model = KnotModel();
  const TieRun r = Tie(model);
  EXPECT_EQ(r.held_after_take, 2);
  EXPECT_EQ(r.held_by_third, 2) << "button 1 near a third thread with two held";
  ASSERT_EQ(r.catches.size(), 2u);
  EXPECT_NE(r.catches[0].body, r.catches[1].body);
  for (const Event& e : r.catches) EXPECT_NE(e.body, "suture_c");
  ASSERT_EQ(r.knot.size(), 1u);
  EXPECT_EQ(DetailText(r.knot[0], "type"), "half_hitch");
  EXPECT_EQ(Detail(r.knot[0], "crossings"), 3);
  EXPECT_GT(Detail(r.knot[0], "springs"), 5);
  EXPECT_EQ(r.knots_after_take, 1);
  EXPECT_TRUE(r.finite);
  EXPECT_LE(r.worst_strain, 0.01 + 1e-9);
}

TEST(KnotPusher, SeatsOnTheNinthNodeReleasesTheToolAndHolds) {
  const Model model = KnotModel();
  const TieRun r = Tie(model);
  ASSERT_EQ(r.seated.size(), 1u);
  const State& s = r.final;
  EXPECT_EQ(CountTag(s, kKnotPusherTag), 0) << "tool springs released once seated";
  const std::vector<KnotRef> knots = FindKnots(s);
  ASSERT_EQ(knots.size(), 1u);
  const KnotRef& k = knots[0];
  // The knot nodes are the ninth from the tissue side: A's stitched node 0, B's anchored node 0.
  EXPECT_EQ(TissueSideNode(s, k.thread_a), 0);
  EXPECT_EQ(k.node_a, 9);
  EXPECT_EQ(k.node_b, 9);
  // Where the knot is versus where the ninth nodes are (both measured in the final state).
  const Vec3 knot_at =
      0.5 * (s.threads[k.thread_a].x.col(k.node_a) + s.threads[k.thread_b].x.col(k.node_b));
  EXPECT_LE((knot_at - r.seated[0].position_mm).norm(), 1.0);
  EXPECT_LE(Detail(r.seated[0], "target_error_mm"), 1.0);
  EXPECT_EQ(DetailText(r.seated[0], "type"), "half_hitch") << r.seated[0].detail;
  // The limbs still hold a half hitch 25 steps after the tool let go.
  std::vector<Vec3> a, b;
  for (int n = 0; n < s.threads[k.thread_a].x.cols(); ++n)
    a.push_back(s.threads[k.thread_a].x.col(n));
  for (int n = 0; n < s.threads[k.thread_b].x.cols(); ++n)
    b.push_back(s.threads[k.thread_b].x.col(n));
  EXPECT_EQ(IdentifyKnot(a, b).type, KnotType::kHalfHitch);
  EXPECT_TRUE(r.finite);
  EXPECT_LE(r.worst_strain, 0.01 + 1e-9);
}

// Open: the knot's thread solve stops at the iteration cap in every step of this run (82
// unconverged solves in 81 steps; 88 in 88 with one line-search factor for all threads). Since
// each independent thread group has its own line search (suture C no longer holds back the
// knot's step), the loop ends 9.192 mm long, its segments stretched up to 0.69 % (1.0268 mm);
// with one factor for all threads it was 8.895 mm. Enable when the knot's solve converges
// (docs/operations.md, "Where the retriever's pull goes").
TEST(KnotPusher, DISABLED_TheLoopBelowTheSeatedKnotIsNineRestSegments) {
  const Model model = KnotModel();
  const TieRun r = Tie(model);
  ASSERT_EQ(r.seated.size(), 1u);
  const std::vector<KnotRef> knots = FindKnots(r.final);
  ASSERT_EQ(knots.size(), 1u);
  const KnotRef& k = knots[0];
  const Points& a = r.final.threads[k.thread_a].x;
  // The loop below the knot is 9 rest segments per limb: the knot sits within 9 mm of the edge.
  EXPECT_LE((a.col(k.node_a) - a.col(0)).norm(), 9 * 1.0198 + 1e-6);
}

TEST(KnotPusher, ShortLoopPullsTheEdgeTowardTheAnchor) {
  // Target node 4: a loop of 2 x 4 segments (8.2 mm) between the edge and the anchor 10.2 mm
  // apart, so the seated knot must hold the edge at least 2 mm closer to the anchor.
  const Model model = KnotModel("target_node: 4");
  const TieRun r = Tie(model);
  const Vec3 anchor = model.threads[1].initial.nodes.col(0);
  const double before = (r.edge_start - anchor).norm(), after = (r.edge_end - anchor).norm();
  std::printf("edge to anchor: %.3f mm before, %.3f mm after (moved %.3f mm)\n", before, after,
              before - after);
  EXPECT_EQ(r.seated.size(), 1u);
  EXPECT_GE(before - after, 2.0);
  EXPECT_TRUE(r.finite);
  EXPECT_LE(r.worst_strain, 0.01 + 1e-9);
}

TEST(KnotPusher, SecurityPullTellsAGoodKnotFromAWeakOne) {
  const TieRun good = Tie(KnotModel());
  ASSERT_EQ(good.seated.size(), 1u);
  const double good_slip = Detail(good.seated[0], "slip_mm");
  EXPECT_LT(good_slip, 1.0);
  EXPECT_EQ(Detail(good.seated[0], "secure"), 1);
  EXPECT_EQ(Detail(good.seated[0], "pull_force_n"), 5);
  // Knot springs 400 x softer: the same pull opens the knot beyond 3 mm.
  const TieRun weak = Tie(KnotModel("knot_stiffness: 0.05"));
  ASSERT_EQ(weak.seated.size(), 1u);
  const double weak_slip = Detail(weak.seated[0], "slip_mm");
  std::printf("slip under 5 N: good knot %.4f mm, weak knot %.3f mm\n", good_slip, weak_slip);
  EXPECT_GT(weak_slip, 3.0);
  EXPECT_EQ(Detail(weak.seated[0], "secure"), 0);
}

TEST(KnotPusher, PullTestLeavesTheStateUnchanged) {
  const TieRun r = Tie(KnotModel());
  const std::vector<KnotRef> knots = FindKnots(r.final);
  ASSERT_EQ(knots.size(), 1u);
  const State before = r.final;
  const double slip = KnotSlipMm(KnotModel(), r.final, knots[0]);
  EXPECT_TRUE(std::isfinite(slip));
  EXPECT_TRUE(BitwiseEqual(before, r.final));
}

// The pull test's cost (issue #12: 1.95G instructions, the expert run's worst step, when it
// stepped every node of every thread): it steps only the knot's two threads, each cut to the
// nodes its knot springs, knot nodes and pulled nodes touch plus kKnotPullWindowMm of rest arc
// on each side. Counted, not timed: the nodes handed to StepThreads and the steps.
TEST(KnotPusher, PullTestStepsOnlyTheKnotsNeighbourhood) {
  const Model model = KnotModel();
  const TieRun r = Tie(model);
  const std::vector<KnotRef> knots = FindKnots(r.final);
  ASSERT_EQ(knots.size(), 1u);
  const KnotRef& k = knots[0];
  // The span each knot thread should get, worked out here from the knot's springs and the rest
  // spacing (1.0198 mm: 5 mm reaches 4 segments beyond the touched nodes).
  const auto expected_nodes = [&](int thread) {
    int lo = 1 << 30, hi = -1;
    const auto touch = [&](int n) { lo = std::min(lo, n), hi = std::max(hi, n); };
    if (thread == k.thread_a) touch(k.node_a), touch(k.node_a - 1);
    if (thread == k.thread_b) touch(k.node_b), touch(k.node_b - 1);
    for (const SpringConstraint& c : r.final.constraints)
      if (c.tag == kKnotTag)
        for (const ConstraintEnd* e : {&c.a, &c.b})
          if (e->index == thread)
            for (int n : e->nodes)
              if (n >= 0) touch(n);
    const Points& x0 = model.threads[thread].initial.nodes;
    const int reach = static_cast<int>(kKnotPullWindowMm / (x0.col(1) - x0.col(0)).norm());
    return std::min<int>(hi + reach, x0.cols() - 1) - std::max(lo - reach, 0) + 1;
  };
  const int expected = expected_nodes(k.thread_a) + expected_nodes(k.thread_b);
  int all_nodes = 0;
  for (const ThreadState& t : r.final.threads) all_nodes += static_cast<int>(t.x.cols());
  KnotPullWork work;
  KnotSlipMm(model, r.final, k, &work);
  std::printf("pull test: %d threads, %d nodes (of %d), %d steps, %d Newton iterations\n",
              work.threads, work.nodes, all_nodes, work.steps, work.newton_iterations);
  EXPECT_EQ(work.threads, 2) << "suture C is not part of the knot";
  EXPECT_EQ(work.nodes, expected);
  EXPECT_LE(work.nodes, all_nodes * 3 / 10);  // 51 of 183 nodes
  EXPECT_EQ(work.steps, 25);                  // pull_time 0.5 s / dt 0.02 s
  EXPECT_GE(work.newton_iterations, work.steps);
  EXPECT_LE(work.newton_iterations, work.steps * (model.thread_solver.max_ccd_rounds + 1) *
                                        model.thread_solver.max_newton_iterations);
  EXPECT_THROW(KnotSlipMm(model, r.final, k, nullptr, -1.0), std::invalid_argument);
}

// Cutting the threads to the knot's neighbourhood does not change the verdict: the slip matches
// the pull test on the knot's whole threads within 0.05 mm (1.7 % of the 3 mm slip limit) for a
// good and a weak knot. Measured on the final state: good 0.3410 vs 0.3502 mm, weak 11.5820 vs
// 11.5611 mm (at seating, the knot_seated values: good -0.5956 vs -0.5650, weak 8.5658 vs
// 8.5438; there the whole-thread values equal the earlier copy of every thread, suture C
// included, to 1e-6 mm). Fixing the cut ends in place instead fails this (weak 2.76 mm).
TEST(KnotPusher, PullTestOnTheNeighbourhoodMatchesTheWholeThreads) {
  for (const char* options : {"", "knot_stiffness: 0.05"}) {
    const Model model = KnotModel(options);
    const TieRun r = Tie(model);
    const std::vector<KnotRef> knots = FindKnots(r.final);
    ASSERT_EQ(knots.size(), 1u);
    KnotPullWork cut, whole;
    const double slip_cut = KnotSlipMm(model, r.final, knots[0], &cut);
    const double slip_whole = KnotSlipMm(model, r.final, knots[0], &whole, 1e9);
    std::printf("knot '%s': slip %.4f mm on %d nodes, %.4f mm on the whole threads (%d nodes)\n",
                options, slip_cut, cut.nodes, slip_whole, whole.nodes);
    EXPECT_EQ(whole.nodes, 122);
    EXPECT_LT(cut.nodes, whole.nodes / 2);
    EXPECT_NEAR(slip_cut, slip_whole, 0.05) << options;
  }
}

TEST(KnotPusher, LimbsTooShortToThrowGiveNoKnot) {
  // A half hitch 4 x the default size needs more thread than the limbs have beyond the loop: it
  // is not thrown, the limbs stay unknotted, so no `knot` event and no knot springs.
  const Model model = KnotModel("knot_size: 4.8");
  State s = KnotState(model);
  SlotDriver d(model, &s, "knot_pusher");
  int knots = 0, catches = 0;
  for (int k = 0; k < 3; ++k) {
    d.Step(kTakeAt, 0, kB1);
    knots += static_cast<int>(d.Events("knot").size());
    catches += static_cast<int>(d.Events("thread_catch").size());
  }
  EXPECT_EQ(catches, 2);
  EXPECT_EQ(knots, 0);
  EXPECT_EQ(CountTag(s, kKnotTag), 0);
}

TEST(KnotPusher, BitIdenticalWithOneAndTwoThreads) {
  const Model model = KnotModel();
  SetThreadCount(1);
  const TieRun one = Tie(model);
  const TieRun again = Tie(model);
  SetThreadCount(2);
  const TieRun two = Tie(model);
  SetThreadCount(1);
  ASSERT_EQ(one.seated.size(), 1u);
  EXPECT_TRUE(BitwiseEqual(one.final, again.final));
  EXPECT_TRUE(BitwiseEqual(one.final, two.final));
}

TEST(KnotPusher, ReadsItsScenarioKeys) {
  const Model model = KnotModel(
      "dist_limit: 3, thread_stiffness: 6, knot_stiffness: 7, knot_size: 1.5, target_node: 4, "
      "pull_force: 4, pull_time: 0.3, slip_limit: 2");
  const KnotPusherOptions& o = model.operations.knot_pusher;
  EXPECT_EQ(o.dist_limit_mm, 3);
  EXPECT_EQ(o.thread_stiffness_n_per_mm, 6);
  EXPECT_EQ(o.knot_stiffness_n_per_mm, 7);
  EXPECT_EQ(o.knot_size_mm, 1.5);
  EXPECT_EQ(o.target_node, 4);
  EXPECT_EQ(o.pull_force_n, 4);
  EXPECT_EQ(o.pull_time_s, 0.3);
  EXPECT_EQ(o.slip_limit_mm, 2);
  EXPECT_THROW(KnotModel("target_node: 0"), arthrosim::InputError);
  EXPECT_THROW(KnotModel("knot_size: -1"), arthrosim::InputError);
}

}  // namespace
}  // namespace arthrosim::instruments
