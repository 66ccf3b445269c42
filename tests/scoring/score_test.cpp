// Scoring on synthetic runs: the clean run passes every step and scores >= 90; each injected
// error is flagged by its metric or step, for the reason it should.
#include <gtest/gtest.h>

#include <fmt/core.h>

#include <cmath>
#include <numbers>

#include "arthrosim/scoring/report_html.h"
#include "arthrosim/scoring/score.h"
#include "synthetic_run.h"

namespace arthrosim::scoring {
namespace {

using testing::SynthSpec;

struct Scored {
  RunData run;
  ScoreReport report;
};

Scored ScoreSynth(const std::string& name, const SynthSpec& spec,
                  const std::vector<const RunData*>& refs = {}) {
  const std::string path = testing::TestDir(name) + "/run.h5";
  testing::WriteSynthRun(path, spec);
  const Model model = testing::MakeSynthModel();
  const Plan plan = LoadPlanFromText(testing::SynthPlanText(), "synth.yaml", &model);
  Scored s{ReadRunData(path, model), {}};
  s.report = Evaluate(plan, s.run, refs);
  return s;
}

const Metric& Find(const ScoreReport& r, const std::string& id) {
  for (const Metric& m : r.metrics)
    if (m.id == id) return m;
  throw std::runtime_error("no metric " + id);
}

// The metric `id` of `r` has `value` and fails its check.
void ExpectFailingMetric(const ScoreReport& r, const std::string& id, double value) {
  EXPECT_EQ(Find(r, id).value, value) << id;
  EXPECT_FALSE(Find(r, id).pass) << id;
}

const StepResult& Step(const ScoreReport& r, const std::string& id) {
  for (const StepResult& s : r.steps)
    if (s.id == id) return s;
  throw std::runtime_error("no step " + id);
}

bool HasViolation(const ScoreReport& r, const std::string& kind) {
  for (const Violation& v : r.violations)
    if (v.kind == kind) return true;
  return false;
}

TEST(Score, CleanRunPassesEveryStep) {
  const Scored s = ScoreSynth("clean", {});
  const ScoreReport& r = s.report;
  for (const StepResult& step : r.steps) EXPECT_TRUE(step.passed) << step.id << ": " << step.reason;
  for (const Metric& m : r.metrics) EXPECT_TRUE(m.pass) << m.id << " = " << m.value;
  EXPECT_TRUE(r.violations.empty());
  EXPECT_TRUE(r.critical_errors.empty());
  EXPECT_GE(r.total, 90.0);
  EXPECT_TRUE(r.passed);
  // Times from the formulas: burr inserted at frame 10, 1 mm^3 removed at frame 30.
  EXPECT_NEAR(Step(r, "burr").start_s, 0.2, 1e-12);
  EXPECT_NEAR(Step(r, "burr").end_s, 0.6, 1e-12);
  EXPECT_NEAR(Step(r, "hole").duration_s, 0.4, 1e-12);
  EXPECT_NEAR(Find(r, "quality.hole.hole.angle_deg").value, 45.0, 1e-9);
  EXPECT_NEAR(Find(r, "quality.hole.hole.position_error").value, 0.0, 1e-12);
  EXPECT_NEAR(Find(r, "quality.reduce.gap").value, std::sqrt(3.0), 1e-12);
  // Awl: 10 mm at 50 mm/s then held: path 10 mm, one movement, idle 20 of 30 intervals.
  EXPECT_NEAR(Find(r, "motion.awl.path_length").value, 10.0, 1e-12);
  EXPECT_EQ(Find(r, "motion.awl.movements").value, 1.0);
  EXPECT_NEAR(Find(r, "motion.awl.idle_time").value, 0.4, 1e-12);
  EXPECT_NEAR(Find(r, "motion.burr.path_length").value, 20.0, 1e-9);
  EXPECT_NEAR(Find(r, "camera.tip_in_view").value, 1.0, 1e-12);
  EXPECT_LT(Find(r, "camera.horizon_deviation").value, 1e-6);
}

// One insertion of the awl for a stray hole 10 mm off the site (frame 55) and then the hole
// (frame 70): the step starts when the stray action ended, not at the insertion (frame 50).
TEST(Score, AStepStartsWhenItsInstrumentsPreviousTaskEnds) {
  SynthSpec spec;
  spec.stray_hole_frame = 55;
  const ScoreReport r = ScoreSynth("stray_hole", spec).report;
  EXPECT_TRUE(Step(r, "hole").passed) << Step(r, "hole").reason;
  EXPECT_NEAR(Step(r, "hole").start_s, 1.1, 1e-12);
  EXPECT_NEAR(Step(r, "hole").duration_s, 0.3, 1e-12);
}

TEST(Score, AnchorAngleOutsideBandFailsTheStep) {
  SynthSpec spec;
  spec.hole_angle_deg = 70;
  const ScoreReport r = ScoreSynth("angle", spec).report;
  EXPECT_FALSE(Step(r, "hole").passed);
  EXPECT_NE(Step(r, "hole").reason.find("angle_deg = 70, expected 35 to 55"), std::string::npos)
      << Step(r, "hole").reason;
  EXPECT_FALSE(Find(r, "quality.hole.hole.angle_deg").pass);
  EXPECT_TRUE(Find(r, "quality.hole.hole.depth_mm").pass);
  EXPECT_FALSE(r.passed);
}

// A step that needs two events, with one on target and one 10 mm off: the reason says why the
// other did not count (an instructor sees "the second bite was too close", not only "1 of 2").
TEST(Score, AnUncountedEventIsNamedInTheReason) {
  SynthSpec spec;
  spec.stray_hole_frame = 55;
  const std::string path = testing::TestDir("two_holes") + "/run.h5";
  testing::WriteSynthRun(path, spec);
  const Model model = testing::MakeSynthModel();
  std::string text = testing::SynthPlanText();
  const std::string one = "landmark: site, within: 3,";
  ASSERT_NE(text.find(one), std::string::npos);
  text.replace(text.find(one), one.size(), "landmark: site, within: 3, count: 2,");
  const Plan plan = LoadPlanFromText(text, "synth.yaml", &model);
  const ScoreReport r = Evaluate(plan, ReadRunData(path, model), {});
  EXPECT_FALSE(Step(r, "hole").completed);
  EXPECT_EQ(Step(r, "hole").reason,
            "not done: 1 of 2 'hole' done; another not counted: 10.0 mm from site (allowed 3 mm)");
}

TEST(Score, HoleAwayFromTheSiteFailsPositionError) {
  SynthSpec spec;
  spec.hole_offset_mm = 5;
  const ScoreReport r = ScoreSynth("offset", spec).report;
  EXPECT_FALSE(Step(r, "hole").completed);
  EXPECT_NEAR(Find(r, "quality.hole.hole.position_error").value, 5.0, 1e-12);
  EXPECT_FALSE(Find(r, "quality.hole.hole.position_error").pass);
  EXPECT_NE(Step(r, "hole").reason.find("5.0 mm from site"), std::string::npos);
}

TEST(Score, ActionBeforeItsPrerequisiteIsAnOrderViolation) {
  SynthSpec spec;
  spec.burr_frame = -1;  // the burr never removes: the hole comes before the burr step is done
  const ScoreReport r = ScoreSynth("order", spec).report;
  EXPECT_TRUE(HasViolation(r, "order"));
  EXPECT_FALSE(Step(r, "burr").completed);
  EXPECT_FALSE(Step(r, "hole").passed);
  EXPECT_NE(Step(r, "hole").reason.find("before 'Burr the target' was done"), std::string::npos)
      << Step(r, "hole").reason;
}

TEST(Score, ActionBeforeALaterCompletedPrerequisiteIsAnOrderViolation) {
  SynthSpec spec;
  spec.burr_late = true;  // the burr step completes at 1.8 s, the hole is punched at 1.4 s
  const ScoreReport r = ScoreSynth("order_late", spec).report;
  EXPECT_TRUE(Step(r, "burr").completed);
  EXPECT_TRUE(HasViolation(r, "order"));
  EXPECT_FALSE(Step(r, "hole").passed);
  EXPECT_NE(Step(r, "hole").reason.find("acted at 1.40 s"), std::string::npos)
      << Step(r, "hole").reason;
}

TEST(Score, WrongInstrumentIsFlagged) {
  SynthSpec spec;
  spec.hole_by_grasper = true;
  const ScoreReport r = ScoreSynth("wrong", spec).report;
  EXPECT_TRUE(HasViolation(r, "wrong_instrument"));
  ExpectFailingMetric(r, "plan.wrong_instrument_actions", 1.0);
  EXPECT_FALSE(Step(r, "hole").completed);
}

// An event kind a step lists under `also` is that step's, by its instruments: the same hole by
// the grasper is not a wrong-instrument action once the grasper's step says it makes holes.
TEST(Score, EventsAStepListsUnderAlsoAreItsOwn) {
  SynthSpec spec;
  spec.hole_by_grasper = true;
  const std::string path = testing::TestDir("also") + "/run.h5";
  testing::WriteSynthRun(path, spec);
  const Model model = testing::MakeSynthModel();
  std::string text = testing::SynthPlanText();
  const std::string reduce = "    instruments: [grasper]\n";
  ASSERT_NE(text.find(reduce), std::string::npos);
  text.replace(text.find(reduce), reduce.size(), reduce + "    also: [hole]\n");
  const Plan plan = LoadPlanFromText(text, "synth.yaml", &model);
  const ScoreReport r = Evaluate(plan, ReadRunData(path, model), {});
  EXPECT_FALSE(HasViolation(r, "wrong_instrument"));
  EXPECT_EQ(Find(r, "plan.wrong_instrument_actions").value, 0.0);
}

// The reduction measured to the footprint's bone bed (distance: {to_region}): the centroid of
// the edge to the nearest point of the bed's box. The clean tendon lies 1 mm medial of the bed
// and passes; moved 10 mm medially (unreduced) it fails with the gap in the reason; lying on
// the bed but 3.3 mm up (the edge's mid-thickness above the bone) it still passes, where the
// landmark form, the same edge to a point on the bone, fails.
ScoreReport ScoreReduction(const std::string& name, const SynthSpec& spec, bool to_bed) {
  const std::string path = testing::TestDir(name) + "/run.h5";
  testing::WriteSynthRun(path, spec);
  const Model model = testing::MakeSynthModel();
  std::string text = testing::SynthPlanText();
  const std::string old_criterion = "{region: edge, landmark: footprint, max: 2}";
  EXPECT_NE(text.find(old_criterion), std::string::npos);
  if (to_bed)
    text.replace(text.find(old_criterion), old_criterion.size(),
                 "{region: edge, to_region: bed, max: 2}");
  const Plan plan = LoadPlanFromText(text, "synth.yaml", &model);
  return Evaluate(plan, ReadRunData(path, model), {});
}

ScoreReport ScoreReduction(const std::string& name, const Vec3& shift_mm, bool to_bed) {
  SynthSpec spec;
  spec.tendon_shift_mm = shift_mm;
  return ScoreReduction(name, spec, to_bed);
}

TEST(Score, TendonEdgeMeasuredToTheFootprintBed) {
  const ScoreReport clean = ScoreReduction("bed_clean", Vec3::Zero(), true);
  EXPECT_TRUE(Step(clean, "reduce").passed) << Step(clean, "reduce").reason;
  EXPECT_NEAR(Find(clean, "quality.reduce.gap").value, 1.0, 1e-12);

  const ScoreReport medial = ScoreReduction("bed_medial", Vec3(-10, 0, 0), true);
  EXPECT_FALSE(Step(medial, "reduce").passed);
  ExpectFailingMetric(medial, "quality.reduce.gap", 11.0);
  EXPECT_NE(Step(medial, "reduce").reason.find("edge ends 11.0 mm from region bed"),
            std::string::npos)
      << Step(medial, "reduce").reason;

  const ScoreReport up = ScoreReduction("bed_up", Vec3(0, 0, 3.3), true);
  EXPECT_TRUE(Step(up, "reduce").passed) << Step(up, "reduce").reason;
  EXPECT_NEAR(Find(up, "quality.reduce.gap").value, 1.0, 1e-12);
  const ScoreReport up_landmark = ScoreReduction("bed_up_landmark", Vec3(0, 0, 3.3), false);
  EXPECT_FALSE(Step(up_landmark, "reduce").passed);
}

// A node that cutting or shaving left without elements stays where it was cut: it is not where
// the edge is, and the centroid skips it (the edge's other three nodes, 0.33 mm nearer the bed
// than the four together).
TEST(Score, TendonEdgeCentroidSkipsDebrisNodes) {
  SynthSpec spec;
  spec.tendon_debris_shift_mm = Vec3(-40, 0, 0);  // node 0 left 40 mm medial
  const ScoreReport r = ScoreReduction("debris", spec, true);
  // nodes 1, 2, 3 of the tet at (-20, 0, 2): centroid x = -20 + 4/3, 1 - 4/3 mm medial of the bed
  EXPECT_NEAR(Find(r, "quality.reduce.gap").value, 2.0 / 3.0, 1e-12);
  EXPECT_TRUE(Step(r, "reduce").passed) << Step(r, "reduce").reason;
}

TEST(Score, DistanceCriterionNeedsOneTarget) {
  const Model model = testing::MakeSynthModel();
  std::string text = testing::SynthPlanText();
  const std::string old_criterion = "{region: edge, landmark: footprint, max: 2}";
  ASSERT_NE(text.find(old_criterion), std::string::npos);
  std::string both = text;
  both.replace(both.find(old_criterion), old_criterion.size(),
               "{region: edge, landmark: footprint, to_region: bed, max: 2}");
  EXPECT_THROW(LoadPlanFromText(both, "synth.yaml", &model), std::exception);
  std::string unknown = text;
  unknown.replace(unknown.find(old_criterion), old_criterion.size(),
                  "{region: edge, to_region: nowhere, max: 2}");
  EXPECT_THROW(LoadPlanFromText(unknown, "synth.yaml", &model), std::exception);
}

TEST(Score, ForceOnAProtectedStructureIsCritical) {
  SynthSpec spec;
  spec.muscle_touch_force_n = 5;
  const ScoreReport r = ScoreSynth("protected", spec).report;
  EXPECT_NEAR(Find(r, "safety.belly.contact_time").value, 0.22, 1e-9);  // frames 85..95
  ExpectFailingMetric(r, "safety.belly.peak_force", 5.0);
  EXPECT_FALSE(Find(r, "safety.belly.time_over_force").pass);
  ASSERT_FALSE(r.critical_errors.empty());
  EXPECT_NE(r.critical_errors[0].find("force above 2 N on belly"), std::string::npos);
  EXPECT_FALSE(r.passed);  // regardless of the total
  for (const StepResult& step : r.steps) EXPECT_TRUE(step.passed) << step.id;
}

TEST(Score, DamageOnAProtectedStructureIsCritical) {
  SynthSpec spec;
  spec.burr_on_muscle = true;
  const ScoreReport r = ScoreSynth("damage", spec).report;
  EXPECT_EQ(Find(r, "safety.belly.damage_events").value, 1.0);
  EXPECT_TRUE(HasViolation(r, "damage"));
  EXPECT_FALSE(r.passed);
}

// A removal where a completion criterion expects its kind of event (the hole step: within 3 mm of
// the site, on the humerus) is on target, whatever its detail values; the same removal 4 mm from
// the site is outside every target. The hole step has a landmark target, no target region.
TEST(Score, RemovalWhereACriterionPlacesItIsOnTarget) {
  SynthSpec spec;
  spec.hole_volume_mm3 = 2;
  spec.hole_angle_deg = 80;  // out of the criterion's range: still where it was planned
  const ScoreReport on = ScoreSynth("criterion_on", spec).report;
  EXPECT_EQ(Find(on, "safety.volume_outside_target").value, 0.0);
  EXPECT_TRUE(Find(on, "safety.volume_outside_target").pass);
  spec.hole_offset_mm = 4;
  const ScoreReport off = ScoreSynth("criterion_off", spec).report;
  EXPECT_EQ(Find(off, "safety.volume_outside_target").value, 2.0);
  EXPECT_FALSE(Find(off, "safety.volume_outside_target").pass);
}

// Damage events less than 1 s apart are one episode: one violation and one critical error, the
// count of events in the metric. Frames 30-32 (0.60-0.64 s) are one episode, frame 90 (1.8 s)
// another.
TEST(Score, DamageEventsCloseInTimeAreOneEpisode) {
  SynthSpec spec;
  spec.muscle_burr_frames = {30, 31, 32, 90};
  const ScoreReport r = ScoreSynth("episodes", spec).report;
  EXPECT_EQ(Find(r, "safety.belly.damage_events").value, 4.0);
  std::vector<Violation> damage;
  for (const Violation& v : r.violations)
    if (v.kind == "damage") damage.push_back(v);
  ASSERT_EQ(damage.size(), 2u);
  EXPECT_NEAR(damage[0].time_s, 0.60, 1e-9);
  EXPECT_NE(damage[0].text.find("(3 events until 0.64 s)"), std::string::npos) << damage[0].text;
  EXPECT_NEAR(damage[1].time_s, 1.80, 1e-9);
  EXPECT_EQ(damage[1].text.find("events until"), std::string::npos) << damage[1].text;
  EXPECT_EQ(r.critical_errors.size(), 2u);
}

TEST(Score, RemovalOutsideTheTargetIsCounted) {
  SynthSpec spec;
  spec.burr_outside_target = true;
  ExpectFailingMetric(ScoreSynth("outside", spec).report, "safety.volume_outside_target", 1.0);
}

TEST(Score, OverTheTimeBudgetFailsTheStep) {
  SynthSpec spec;
  spec.hole_frame = 79;  // 0.58 s after the awl went in at frame 50
  const ScoreReport r = ScoreSynth("slow", spec).report;
  EXPECT_TRUE(Step(r, "hole").completed);
  EXPECT_FALSE(Step(r, "hole").passed);
  EXPECT_NE(Step(r, "hole").reason.find("took 0.6 s, the budget is 0.5 s"), std::string::npos)
      << Step(r, "hole").reason;
  EXPECT_FALSE(Find(r, "step.hole.duration").pass);
  EXPECT_FALSE(r.passed);
}

TEST(Score, CameraLookingAwayLosesTheView) {
  SynthSpec spec;
  spec.camera_away = true;
  const ScoreReport r = ScoreSynth("away", spec).report;
  EXPECT_FALSE(Step(r, "look").completed);
  ExpectFailingMetric(r, "camera.tip_in_view", 0.0);
}

// The awl's tip is in the view cone from below the humerus but behind the bone: its 31 frames
// are not seen, so at most the burr's half of the working time counts (1.0 with the occlusion
// check removed: every tip is in the cone).
TEST(Score, ATipBehindBoneIsNotInView) {
  SynthSpec spec;
  spec.camera_below_bone = true;
  const Scored s = ScoreSynth("below_bone", spec);
  const InstrumentSeries& awl = s.run.instruments[1];
  ASSERT_EQ(awl.name, "awl");
  int awl_frames = 0;
  for (std::int64_t k = 0; k < s.run.frames(); ++k) {
    if (!awl.active[k]) continue;
    ++awl_frames;
    EXPECT_TRUE(PointInView(s.run.model, s.run.camera[k], awl.pose[k].position_mm)) << k;
    EXPECT_EQ(awl.tip_visible[k], 0) << k;
  }
  EXPECT_EQ(awl_frames, 31);
  EXPECT_LE(Find(s.report, "camera.tip_in_view").value, 0.5 + 1e-12);
}

// The `look` step's in_view criterion counts only frames in which the scope sees its landmark:
// from below the bone the landmark (5 mm above the bone's top face) is in the view cone in every
// frame but hidden, so the step is never done (with the cone alone it was done at 0.2 s).
TEST(Score, ALandmarkBehindBoneIsNotInView) {
  SynthSpec spec;
  spec.camera_below_bone = true;
  const Scored s = ScoreSynth("landmark_below_bone", spec);
  const int view = s.run.model.FindLandmark("view");
  ASSERT_GE(view, 0);
  for (std::int64_t k = 0; k < s.run.frames(); ++k) {
    EXPECT_TRUE(PointInView(s.run.model, s.run.camera[k],
                            s.run.model.landmarks[static_cast<std::size_t>(view)].position_mm));
    EXPECT_EQ(s.run.landmark_visible[static_cast<std::size_t>(view)][k], 0) << k;
  }
  EXPECT_FALSE(Step(s.report, "look").completed);
  EXPECT_NE(Step(s.report, "look").reason.find("view in view for 0.0 s"), std::string::npos)
      << Step(s.report, "look").reason;
  // Seen from above, the same landmark is seen in every frame and the step is done.
  const Scored above = ScoreSynth("landmark_above_bone", {});
  EXPECT_TRUE(Step(above.report, "look").passed) << Step(above.report, "look").reason;
}

TEST(Score, RolledCameraHeadDeviatesFromTheHorizon) {
  SynthSpec spec;
  spec.head_roll_rad = std::numbers::pi / 2;
  const ScoreReport r = ScoreSynth("horizon", spec).report;
  EXPECT_NEAR(Find(r, "camera.horizon_deviation").value, 90.0, 1e-6);
  EXPECT_FALSE(Find(r, "camera.horizon_deviation").pass);
}

TEST(Score, IdleInstrumentIsFlagged) {
  SynthSpec spec;
  spec.awl_idle = true;
  ExpectFailingMetric(ScoreSynth("idle", spec).report, "motion.awl.idle_share", 1.0);
}

TEST(Score, EconomyAndZScoresAgainstAReference) {
  const Scored expert = ScoreSynth("expert", {});
  SynthSpec spec;
  spec.burr_zigzag = true;
  const ScoreReport r = ScoreSynth("zigzag", spec, {&expert.run}).report;
  const Metric& economy = Find(r, "motion.burr.economy");
  EXPECT_GT(economy.value, 2.0);
  EXPECT_FALSE(economy.pass);
  EXPECT_NEAR(Find(r, "motion.awl.economy").value, 1.0, 1e-12);
  EXPECT_TRUE(Find(r, "motion.awl.economy").pass);
  const Metric& path = Find(r, "motion.burr.path_length");
  ASSERT_TRUE(path.z.has_value());
  EXPECT_NEAR(*path.reference_mean, 20.0, 1e-9);
  EXPECT_NEAR(*path.z, (path.value - 20.0) / 2.0, 1e-9);  // sd floored at 10 % of the mean
  EXPECT_EQ(r.references, 1);
}

TEST(Score, JsonIsByteIdenticalAndXapiScaled) {
  const Scored a = ScoreSynth("json_a", {});
  const Scored b = ScoreSynth("json_b", {});
  const std::string ja = ToJson(a.report), jb = ToJson(b.report);
  EXPECT_EQ(ja, jb);
  EXPECT_NE(ja.find("\"schema_version\": 1"), std::string::npos);
  EXPECT_NE(ja.find("\"id\": \"quality.hole.hole.angle_deg\""), std::string::npos);
  const std::string x = ToXapi(a.report);
  EXPECT_NE(x.find("\"scaled\": " + fmt::format("{}", a.report.total / 100)), std::string::npos);
  EXPECT_NE(x.find("\"duration\": \"PT1.98S\""), std::string::npos) << x;
  EXPECT_EQ(IsoDuration(3725.5), "PT1H2M5.50S");
}

TEST(Score, HtmlReportHasEveryPart) {
  const Scored s = ScoreSynth("html", {});
  const Model model = testing::MakeSynthModel();
  const Plan plan = LoadPlanFromText(testing::SynthPlanText(), "synth.yaml", &model);
  HtmlOptions o;
  o.thumbnails = false;
  const std::string html = ReportHtml(plan, s.run, s.report, o);
  for (const char* part :
       {"class='timeline'", "class='force'", "top view", "side view", "Punch the hole", "PASS"})
    EXPECT_NE(html.find(part), std::string::npos) << part;
  // No network resource: the only URLs are the SVG namespace.
  auto count = [&](const std::string& what) {
    std::size_t n = 0;
    for (std::size_t at = html.find(what); at != std::string::npos; at = html.find(what, at + 1))
      ++n;
    return n;
  };
  EXPECT_EQ(count("http"), count("http://www.w3.org/2000/svg"));
  EXPECT_GT(count("<svg"), 3u);
  EXPECT_EQ(Base64("hello"), "aGVsbG8=");
  EXPECT_EQ(Base64("hi!"), "aGkh");
}

}  // namespace
}  // namespace arthrosim::scoring
