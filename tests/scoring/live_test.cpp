// Live feedback on the synthetic runs: the clean run gives no warning; each injected error gives
// its warning at the time offline scoring flags it (the same checks, streamed); the debounce
// reports a persisting or flickering condition once and repeats it after the quiet time.
#include <gtest/gtest.h>

#include <cmath>

#include "arthrosim/scoring/live.h"
#include "arthrosim/scoring/score.h"
#include "synthetic_run.h"

namespace arthrosim::scoring {
namespace {

using testing::SynthSpec;

struct Both {
  ScoreReport report;
  std::vector<LiveWarning> warnings;
};

Both LiveSynth(const std::string& name, const SynthSpec& spec) {
  const std::string path = testing::TestDir("live_" + name) + "/run.h5";
  testing::WriteSynthRun(path, spec);
  const Model model = testing::MakeSynthModel();
  const Plan plan = LoadPlanFromText(testing::SynthPlanText(), "synth.yaml", &model);
  return {Evaluate(plan, ReadRunData(path, model)), ReplayLive(plan, model, path)};
}

std::vector<const LiveWarning*> OfType(const std::vector<LiveWarning>& all,
                                       const std::string& type) {
  std::vector<const LiveWarning*> out;
  for (const LiveWarning& w : all)
    if (w.type == type) out.push_back(&w);
  return out;
}

// Every offline violation of `kind` has a warning of the same type and subject at its time.
void ExpectWarnedWhereFlagged(const Both& b, const std::string& kind) {
  int flagged = 0;
  for (const Violation& v : b.report.violations) {
    if (v.kind != kind) continue;
    ++flagged;
    bool warned = false;
    for (const LiveWarning* w : OfType(b.warnings, kind))
      warned = warned ||
               (std::abs(w->time_s - v.time_s) < 1e-9 && (v.step.empty() || w->subject == v.step));
    EXPECT_TRUE(warned) << kind << " flagged offline at " << v.time_s << " s: " << v.text;
  }
  EXPECT_GT(flagged, 0) << "offline scoring flags no " << kind;
}

TEST(Live, CleanRunGivesNoWarning) {
  const Both b = LiveSynth("clean", {});
  EXPECT_TRUE(b.report.violations.empty());
  for (const LiveWarning& w : b.warnings) ADD_FAILURE() << w.message;
}

TEST(Live, ForceOnAProtectedStructureWarnsWhenScoringFlagsIt) {
  SynthSpec spec;
  spec.muscle_touch_force_n = 5;  // grasper on the muscle, frames 85..95
  const Both b = LiveSynth("force", spec);
  ExpectWarnedWhereFlagged(b, "force");
  // contact at the first touching frame, once (the touch lasts 0.2 s < the quiet time)
  const auto contact = OfType(b.warnings, "contact");
  ASSERT_EQ(contact.size(), 1u);
  EXPECT_NEAR(contact[0]->time_s, 1.7, 1e-9);
  EXPECT_EQ(contact[0]->subject, "belly");
  EXPECT_EQ(contact[0]->tool, "grasper");
  EXPECT_EQ(OfType(b.warnings, "force").size(), 1u);
  EXPECT_NE(OfType(b.warnings, "force")[0]->message.find("5.0 N on the belly with the grasper"),
            std::string::npos)
      << OfType(b.warnings, "force")[0]->message;
  // max_contact_time 0: the first touching frame (its 0.02 s interval) exceeds the allowance
  const auto too_long = OfType(b.warnings, "contact_time");
  ASSERT_EQ(too_long.size(), 1u);
  EXPECT_NEAR(too_long[0]->time_s, 1.7, 1e-9);
}

TEST(Live, DamageOnAProtectedStructureWarnsWhenScoringFlagsIt) {
  SynthSpec spec;
  spec.burr_on_muscle = true;
  const Both b = LiveSynth("damage", spec);
  ExpectWarnedWhereFlagged(b, "damage");
  const Event e = OfType(b.warnings, "damage").at(0)->AsEvent();
  EXPECT_EQ(e.kind, kWarningEventKind);
  EXPECT_EQ(e.body, "muscle");
  EXPECT_EQ(e.detail, "type=damage subject=belly event=burr");
}

TEST(Live, ActionBeforeItsPrerequisiteWarnsWhenScoringFlagsIt) {
  SynthSpec spec;
  spec.burr_frame = -1;  // the burr never removes: the hole comes before the burr step is done
  const Both never = LiveSynth("order", spec);
  ExpectWarnedWhereFlagged(never, "order");
  SynthSpec late;
  late.burr_late = true;  // the burr step completes at 1.8 s, after the hole at 1.4 s
  const Both b = LiveSynth("order_late", late);
  ExpectWarnedWhereFlagged(b, "order");
  ASSERT_EQ(OfType(b.warnings, "order").size(), 1u);
  EXPECT_EQ(OfType(b.warnings, "order")[0]->detail,
            "type=order subject=hole event=hole missing=burr");
}

TEST(Live, RemovalOutsideTheTargetWarnsOnceOverTheAllowance) {
  SynthSpec spec;
  spec.burr_outside_target = true;  // 1 mm^3 outside, 0.5 allowed, at frame 30
  const Both b = LiveSynth("outside", spec);
  const auto w = OfType(b.warnings, "outside_target");
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NEAR(w[0]->time_s, 0.6, 1e-9);
  EXPECT_EQ(w[0]->detail,
            "type=outside_target subject=targets event=burr outside_mm3=1 limit_mm3=0.5");
}

// A protected structure touched in bursts: a burst and the ones that follow within the quiet
// time give one warning; a touch after a quiet second gives the next.
TEST(Live, DebounceReportsAConditionOnceUntilItWasAbsentForTheQuietTime) {
  const Model model = testing::MakeSynthModel();
  const Plan plan = LoadPlanFromText(testing::SynthPlanText(), "synth.yaml", &model);
  LiveEvaluator live(plan, model);
  State s = MakeInitialState(model);
  std::vector<double> contact_times;
  for (int k = 0; k <= 200; ++k) {
    s.step = k;
    s.time_s = 0.02 * k;
    s.tool_contacts.clear();
    const bool touching = (k >= 10 && k < 20) || (k >= 40 && k < 45) || k >= 120;
    s.tools[1].instrument = touching ? 2 : -1;
    if (touching) s.tool_contacts.push_back({1, ConstraintEnd::Kind::kSoftBody, 1, Vec3(1, 41, 6)});
    for (const LiveWarning& w : live.Observe(s, true))
      if (w.type == "contact") contact_times.push_back(w.time_s);
  }
  // bursts at 0.2-0.38 s and 0.8-0.88 s (0.42 s apart): one warning; 2.4 s after 1.52 s quiet
  ASSERT_EQ(contact_times.size(), 2u);
  EXPECT_NEAR(contact_times[0], 0.2, 1e-12);
  EXPECT_NEAR(contact_times[1], 2.4, 1e-12);
  EXPECT_EQ(live.given().at("contact"), 2);
  EXPECT_EQ(live.suppressed().at("contact"), 10 + 5 + 81 - 2);
}

}  // namespace
}  // namespace arthrosim::scoring
