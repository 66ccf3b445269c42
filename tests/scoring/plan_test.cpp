// Plans load strictly: the bundled plans against the scene, and each kind of mistake is an
// InputError naming the file, line and field.
#include <gtest/gtest.h>

#include "arthrosim/core/error.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/scoring/plan.h"
#include "synthetic_run.h"

namespace arthrosim::scoring {
namespace {

TEST(Plan, BundledPlansLoadAgainstTheScene) {
  const Model model = io::LoadScenario("scenarios/rotator_cuff_repair.yaml");
  const Plan repair = LoadPlan("scenarios/plans/rotator_cuff_repair.yaml", &model);
  EXPECT_EQ(repair.steps.size(), 12u);
  EXPECT_EQ(repair.steps[5].id, "anchor_hole");
  ASSERT_EQ(repair.steps[5].complete.size(), 1u);
  EXPECT_EQ(repair.steps[5].complete[0].detail.at("angle_deg").min.value(), 35.0);
  EXPECT_TRUE(repair.steps[5].critical);
  EXPECT_EQ(repair.protected_structures.size(), 1u);
  const Plan tour = LoadPlan("scenarios/plans/rotator_cuff_tour.yaml", &model);
  EXPECT_EQ(tour.steps.size(), 5u);
  EXPECT_EQ(tour.weights.repair_quality, 0.0);
}

// Replaces `from` by `to` in the synthetic plan and expects an error naming `field` and `line`.
void ExpectError(const std::string& from, const std::string& to, const std::string& field, int line,
                 const std::string& words) {
  std::string text = testing::SynthPlanText();
  const std::size_t at = text.find(from);
  ASSERT_NE(at, std::string::npos) << from;
  text.replace(at, from.size(), to);
  const Model model = testing::MakeSynthModel();
  try {
    LoadPlanFromText(text, "plan.yaml", &model);
    FAIL() << "accepted: " << to;
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "plan.yaml");
    EXPECT_EQ(e.field(), field) << e.what();
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
  }
}

TEST(Plan, MistakesNameFileLineAndField) {
  const Model model = testing::MakeSynthModel();
  EXPECT_NO_THROW(LoadPlanFromText(testing::SynthPlanText(), "plan.yaml", &model));
  ExpectError("pass_score: 70", "pass_score: 70\nbogus: 1", "bogus", 4, "unknown key");
  ExpectError("time_budget: 1.0", "time_budget: -1", "steps[1].time_budget", 22, "> 0");
  ExpectError("instruments: [burr]", "instruments: [drill]", "steps[1].instruments[0]", 16,
              "unknown instrument 'drill'");
  ExpectError("requires: [burr]", "requires: [reduce]", "steps[2].requires", 28, "earlier step");
  ExpectError("landmark: site, within: 3", "landmark: nowhere, within: 3",
              "steps[2].complete[0].event.landmark", 30, "unknown landmark");
  ExpectError("angle_deg: {min: 35, max: 55}", "angle_deg: {min: 55, max: 35}",
              "steps[2].complete[0].event.detail.angle_deg", 31, "min must be <= max");
  ExpectError("bone_removed: {bone: humerus", "bone_removed: {bone: femur",
              "steps[1].complete[0].bone_removed.bone", 21, "unknown bone");
  ExpectError("max_force: 2.0", "max_force: lots", "protected[0].max_force", 6,
              "expected a number");
  ExpectError("scenario: scoring-synthetic", "scenario: knee", "scenario", 2, "knee");
  ExpectError("- id: reduce", "- id: burr", "steps[3].id", 33, "duplicate step id");
  ExpectError("      - in_view: {landmark: view, min_time: 0.2}",
              "      - {in_view: {landmark: view}, distance: {region: edge}}",
              "steps[0].complete[0]", 12, "exactly one");
}

TEST(Plan, MissingFileAndBadYaml) {
  EXPECT_THROW(LoadPlan("no/such/plan.yaml"), InputError);
  try {
    LoadPlanFromText("name: [unclosed\n", "bad.yaml");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "bad.yaml");
    EXPECT_NE(std::string(e.what()).find("YAML syntax error"), std::string::npos);
  }
}

}  // namespace
}  // namespace arthrosim::scoring
