// The trainee variants of the expert repair, scored against the repair plan from their run files
// alone: each fails the step it should, for the reason it should, where the expert run passes
// that same step (the control). The runs are made once by the fixture tests Run.<name>
// (tests/cli/CMakeLists.txt) into build/test_runs (ARTHROSIM_TEST_RUNS=DIR reads them elsewhere):
//  - novice_order: the pilot hole and the anchor before the footprint is prepared;
//  - novice_damage: the shaver in the protected muscle belly, the burr on the articular surface
//    outside every target, both before the diagnostic look is done;
//  - novice_economy (with its trainee noise): the expert's steps at half speed with tremor,
//    overshoot and hesitation, scored with the expert run as reference;
//  - novice_bite: the second limb passed ~4.5 mm from the torn edge (too close);
//  - novice_knot: the knot thrown but never pushed down onto its target.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include "arthrosim/scoring/plan.h"
#include "arthrosim/scoring/run_data.h"
#include "arthrosim/scoring/score.h"

namespace arthrosim::scoring {
namespace {

const std::string kPlan =
    std::string(ARTHROSIM_SOURCE_DIR) + "/scenarios/plans/rotator_cuff_repair.yaml";

std::string RunPath(const std::string& name) {
  const char* dir = std::getenv("ARTHROSIM_TEST_RUNS");  // else the fixture runs' folder
  const std::string runs = dir != nullptr ? dir : ARTHROSIM_BINARY_DIR "/test_runs";
  return runs + "/rotator_cuff_repair_" + name + ".h5";
}

const RunData& RunOf(const std::string& name) {
  static std::map<std::string, RunData>* runs = new std::map<std::string, RunData>;
  auto it = runs->find(name);
  if (it == runs->end()) {
    const std::string path = RunPath(name);
    it = runs->emplace(name, ReadRunData(path, LoadRunModel(path, ""))).first;
  }
  return it->second;
}

ScoreReport Score(const std::string& name, const std::vector<std::string>& references = {}) {
  const RunData& run = RunOf(name);
  const Plan plan = LoadPlan(kPlan, &run.model);
  std::vector<const RunData*> refs;
  for (const std::string& r : references) refs.push_back(&RunOf(r));
  return Evaluate(plan, run, refs);
}

const StepResult& Step(const ScoreReport& r, const std::string& id) {
  for (const StepResult& s : r.steps)
    if (s.id == id) return s;
  ADD_FAILURE() << "no step " << id;
  static const StepResult none;
  return none;
}

const Metric* FindMetric(const ScoreReport& r, const std::string& id) {
  for (const Metric& m : r.metrics)
    if (m.id == id) return &m;
  return nullptr;
}

int CountViolations(const ScoreReport& r, const std::string& kind, const std::string& step = "") {
  int n = 0;
  for (const Violation& v : r.violations)
    if (v.kind == kind && (step.empty() || v.step == step)) ++n;
  return n;
}

bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// The number after "key=" in an event's detail, or NaN.
double DetailValue(const Event& e, const std::string& key) {
  const std::size_t at = (" " + e.detail).find(" " + key + "=");
  if (at == std::string::npos) return std::nan("");
  return std::atof(e.detail.c_str() + at + key.size() + 1);
}

// The run's events of `kind` (in order).
std::vector<const Event*> EventsOf(const std::string& run, const std::string& kind) {
  std::vector<const Event*> out;
  for (const Event& e : RunOf(run).events)
    if (e.kind == kind) out.push_back(&e);
  return out;
}

TEST(TraineeVariants, OrderPunchesTheHoleBeforeTheFootprintIsPrepared) {
  const ScoreReport expert = Score("expert");
  ASSERT_TRUE(Step(expert, "anchor_hole").passed) << Step(expert, "anchor_hole").reason;
  EXPECT_EQ(CountViolations(expert, "order", "anchor_hole"), 0);

  const ScoreReport order = Score("novice_order");
  const StepResult& hole = Step(order, "anchor_hole");
  EXPECT_TRUE(hole.completed) << "the hole itself is made, only out of order";
  EXPECT_FALSE(hole.passed);
  EXPECT_TRUE(Contains(hole.reason, "out of order")) << hole.reason;
  EXPECT_TRUE(Contains(hole.reason, "footprint")) << hole.reason;
  EXPECT_EQ(CountViolations(order, "order", "anchor_hole"), 1);
  // The anchor hole is a critical step: the run fails whatever its total.
  EXPECT_FALSE(order.passed);
  ASSERT_FALSE(order.critical_errors.empty());
  EXPECT_TRUE(Contains(order.critical_errors.front(), "pilot hole"))
      << order.critical_errors.front();
  // Everything the expert does before the hole is done as well.
  for (const char* id : {"diagnostic", "biceps_tenotomy", "debridement", "acromioplasty"})
    EXPECT_TRUE(Step(order, id).passed) << id << ": " << Step(order, id).reason;
}

TEST(TraineeVariants, DamageIsFlaggedOnTheProtectedMuscleAndOutsideTheTargets) {
  const ScoreReport expert = Score("expert");
  EXPECT_EQ(CountViolations(expert, "damage"), 0);
  const Metric* expert_outside = FindMetric(expert, "safety.volume_outside_target");
  ASSERT_NE(expert_outside, nullptr);
  EXPECT_TRUE(expert_outside->pass) << expert_outside->value;

  const ScoreReport damage = Score("novice_damage");
  EXPECT_GT(CountViolations(damage, "damage"), 0) << "shaving into the muscle belly";
  const Metric* outside = FindMetric(damage, "safety.volume_outside_target");
  ASSERT_NE(outside, nullptr);
  EXPECT_FALSE(outside->pass) << "bone and tissue removed outside every target: " << outside->value
                              << " mm3";
  EXPECT_GT(outside->value, expert_outside->value);
  // The muscle belly is a critical protected structure: any damage fails the run.
  EXPECT_FALSE(damage.passed);
  EXPECT_FALSE(damage.critical_errors.empty());
  EXPECT_LT(damage.domains.at("safety"), expert.domains.at("safety"));
}

TEST(TraineeVariants, EconomyTakesLongerPathsAndTwiceTheTime) {
  const ScoreReport expert = Score("expert", {"expert"});
  const ScoreReport economy = Score("novice_economy", {"expert"});
  // The published expert/novice time ratio is about 2 (the script doubles every duration; the
  // trainee noise adds hesitation on top).
  const double time_ratio = RunOf("novice_economy").time_s.back() / RunOf("expert").time_s.back();
  std::printf("economy vs expert: time %.1f s / %.1f s = %.2f\n",
              RunOf("novice_economy").time_s.back(), RunOf("expert").time_s.back(), time_ratio);
  EXPECT_GE(time_ratio, 1.9);
  EXPECT_LE(time_ratio, 2.6);
  // Economy (path over the expert's): the expert is 1 against itself; the trainee's tremor and
  // overshoot put at least one instrument above the band (<= 2) and none below the expert.
  int over_band = 0, instruments = 0;
  for (const Metric& m : economy.metrics) {
    if (m.id.rfind("motion.", 0) != 0 || !Contains(m.id, ".economy")) continue;
    if (m.id == "motion.camera.economy") continue;  // the scope follows targets, no hand noise
    ++instruments;
    std::printf("  %s = %.2f%s\n", m.id.c_str(), m.value, m.pass ? "" : " (over the band)");
    EXPECT_GT(m.value, 1.0) << m.id;
    if (!m.pass) ++over_band;
    const Metric* same = FindMetric(expert, m.id);
    ASSERT_NE(same, nullptr) << m.id;
    EXPECT_NEAR(same->value, 1.0, 1e-12) << m.id;
  }
  EXPECT_GE(instruments, 7);
  EXPECT_GE(over_band, 1);
  EXPECT_LT(economy.domains.at("efficiency"), expert.domains.at("efficiency"));
  // The same steps are done: an economy trainee is slow, not wrong.
  // (footprint_preparation: the burr jammed in the acromion before the proxy backed out of jams)
  for (const char* id :
       {"biceps_tenotomy", "acromioplasty", "footprint_preparation", "anchor_hole", "anchor"})
    EXPECT_TRUE(Step(economy, id).completed) << id << ": " << Step(economy, id).reason;
}

TEST(TraineeVariants, BiteTooCloseToTheTornEdgeFailsTheSuturePass) {
  const ScoreReport expert = Score("expert");
  ASSERT_TRUE(Step(expert, "suture_passing").passed) << Step(expert, "suture_passing").reason;

  const ScoreReport bite = Score("novice_bite");
  const std::vector<const Event*> passes = EventsOf("novice_bite", "suture_pass");
  ASSERT_EQ(passes.size(), 2u) << "both limbs are passed, one of them too close";
  const double first_mm = DetailValue(*passes[0], "bite_mm");
  const double second_mm = DetailValue(*passes[1], "bite_mm");
  std::printf("novice bite: bites %.2f / %.2f mm from the torn edge\n", first_mm, second_mm);
  EXPECT_GE(first_mm, 10.0) << "the first bite is the expert's";
  EXPECT_LE(first_mm, 15.0);
  EXPECT_LT(second_mm, 6.0) << "the trainee's bite, ~4.5 mm from the edge";
  const StepResult& step = Step(bite, "suture_passing");
  EXPECT_FALSE(step.passed);
  EXPECT_TRUE(Contains(step.reason, "bite_mm")) << step.reason;
  EXPECT_FALSE(bite.passed);
  EXPECT_LT(bite.domains.at("repair_quality"), expert.domains.at("repair_quality"));
  // Before the passes it is the expert's repair.
  for (const char* id : {"debridement", "acromioplasty", "anchor_hole", "anchor"})
    EXPECT_TRUE(Step(bite, id).passed) << id << ": " << Step(bite, id).reason;
}

TEST(TraineeVariants, KnotLeftAboveItsTargetIsNotSeated) {
  const ScoreReport expert = Score("expert");
  ASSERT_TRUE(Step(expert, "knot").passed) << Step(expert, "knot").reason;
  const std::vector<const Event*> seated = EventsOf("expert", "knot_seated");
  ASSERT_EQ(seated.size(), 1u);

  const ScoreReport knot = Score("novice_knot");
  const std::vector<const Event*> thrown = EventsOf("novice_knot", "knot");
  ASSERT_EQ(thrown.size(), 1u) << "the half hitch is thrown as the expert throws it";
  EXPECT_TRUE(EventsOf("novice_knot", "knot_seated").empty());
  // Where the knot stays: the midpoint of its two nodes against the midpoint of the nodes the
  // expert's knot is seated on (its target: the same limbs, passed the same way), in the
  // variant's last frame, and along the limbs: on each limb the knot stays on a node beyond
  // (toward the free end of) the one the expert seats it on. Since the limbs are passed short
  // over the reduced tendon the knot is thrown one node above its target (0.8 mm; 1.5 mm with
  // the limbs standing clear of the head, >= 2 mm before that): the step fails because the
  // knot is never seated, not by the distance, which is inside the plan's 2 mm tolerance.
  const State& last = RunOf("novice_knot").last;
  const auto at = [&](const Event& e) {
    Vec3 sum = Vec3::Zero();
    for (const char* limb : {"a", "b"}) {
      const int t = RunOf("novice_knot").model.FindThread(std::string("suture_") + limb);
      const auto node = static_cast<Eigen::Index>(DetailValue(e, std::string("node_") + limb));
      sum += last.threads[static_cast<std::size_t>(t)].x.col(node);
    }
    return Vec3(0.5 * sum);
  };
  const double off_mm = (at(*thrown[0]) - at(*seated[0])).norm();
  std::printf(
      "novice knot: on nodes %.0f / %.0f, the expert's seated on %.0f / %.0f: %.2f mm from "
      "its target\n",
      DetailValue(*thrown[0], "node_a"), DetailValue(*thrown[0], "node_b"),
      DetailValue(*seated[0], "node_a"), DetailValue(*seated[0], "node_b"), off_mm);
  EXPECT_GT(DetailValue(*thrown[0], "node_a"), DetailValue(*seated[0], "node_a"));
  EXPECT_GT(DetailValue(*thrown[0], "node_b"), DetailValue(*seated[0], "node_b"));
  EXPECT_GT(off_mm, 0.5) << "at least half a segment off";
  const StepResult& step = Step(knot, "knot");
  EXPECT_FALSE(step.passed);
  EXPECT_TRUE(Contains(step.reason, "knot_seated")) << step.reason;
  EXPECT_FALSE(knot.passed);
  EXPECT_TRUE(Step(knot, "suture_passing").passed) << Step(knot, "suture_passing").reason;
}

}  // namespace
}  // namespace arthrosim::scoring
