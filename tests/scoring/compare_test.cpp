// Golden comparison: equal runs, a run perturbed at step k names step k, tolerances and NaN
// policy, golden files round-trip, --exact catches what tolerances allow.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "arthrosim/core/error.h"
#include "arthrosim/scoring/compare.h"
#include "synthetic_run.h"

namespace arthrosim::scoring {
namespace {

using testing::SynthSpec;

std::string Write(const std::string& dir, const std::string& name, const SynthSpec& spec) {
  const std::string path = dir + "/" + name + ".h5";
  testing::WriteSynthRun(path, spec);
  return path;
}

TEST(Compare, SameRunIsEqual) {
  const std::string dir = testing::TestDir("compare_same");
  const Digest a = DigestOfRun(Write(dir, "a", {}), 0);
  const Digest b = DigestOfRun(Write(dir, "b", {}), 0);
  const CompareResult r = CompareDigests(a, b, CompareOptions::Defaults());
  EXPECT_TRUE(r.equal) << r.Report();
  EXPECT_GT(r.values_compared, 1000);
  CompareOptions exact = CompareOptions::Defaults();
  exact.exact = true;
  EXPECT_TRUE(CompareDigests(a, b, exact).equal);
}

TEST(Compare, PerturbationAtStepKNamesStepK) {
  const std::string dir = testing::TestDir("compare_perturbed");
  const Digest golden = DigestOfRun(Write(dir, "golden", {}), 0);
  for (const int k : {55, 72}) {
    SynthSpec spec;
    spec.noise_frame = k;
    spec.position_noise_mm = 1e-3;
    const Digest run = DigestOfRun(Write(dir, "k" + std::to_string(k), spec), 0);
    const CompareResult r = CompareDigests(run, golden, CompareOptions::Defaults());
    ASSERT_FALSE(r.equal);
    EXPECT_EQ(r.first->step, k);
    EXPECT_EQ(r.first->series, "tools/awl/pose");
    EXPECT_EQ(r.first->column, 0);
    EXPECT_NE(r.Report().find("step " + std::to_string(k) + ": tools/awl/pose"), std::string::npos)
        << r.Report();
  }
}

TEST(Compare, ToleranceAbsorbsTinyDifferencesButExactDoesNot) {
  const std::string dir = testing::TestDir("compare_tolerance");
  const Digest golden = DigestOfRun(Write(dir, "golden", {}), 0);
  SynthSpec spec;
  spec.noise_frame = 60;
  spec.position_noise_mm = 1e-8;  // below atol 1e-6 mm
  const Digest run = DigestOfRun(Write(dir, "tiny", spec), 0);
  EXPECT_TRUE(CompareDigests(run, golden, CompareOptions::Defaults()).equal);
  CompareOptions exact = CompareOptions::Defaults();
  exact.exact = true;
  const CompareResult r = CompareDigests(run, golden, exact);
  ASSERT_FALSE(r.equal);
  EXPECT_EQ(r.first->step, 60);
}

TEST(Compare, EventsAndTopologyCompareExactly) {
  const std::string dir = testing::TestDir("compare_events");
  const Digest golden = DigestOfRun(Write(dir, "golden", {}), 0);
  SynthSpec spec;
  spec.hole_angle_deg = 45.0001;  // only an event's detail differs
  const CompareResult r =
      CompareDigests(DigestOfRun(Write(dir, "angle", spec), 0), golden, CompareOptions::Defaults());
  ASSERT_FALSE(r.equal);
  EXPECT_EQ(r.first->series, "events/text");
  EXPECT_EQ(r.first->step, 70);
}

TEST(Compare, CombinedToleranceAndNanPolicy) {
  DigestSeries g{"x", SeriesClass::kMetric, 1, {0, 1, 2, 3}, {0.0, 100.0, NAN, 1e-12}, {}, {}};
  DigestSeries r = g;
  r.values = {1e-10, 100.00005, NAN, 0.0};
  Digest dg, dr;
  dg.series = {g};
  dr.series = {r};
  CompareOptions o;
  o.by_class[SeriesClass::kMetric] = {1e-9, 1e-6};  // zero reference: atol decides
  EXPECT_TRUE(CompareDigests(dr, dg, o).equal);
  o.nan = NanPolicy::kDiffer;
  const CompareResult nan = CompareDigests(dr, dg, o);
  ASSERT_FALSE(nan.equal);
  EXPECT_EQ(nan.first->row, 2);
  o.nan = NanPolicy::kSamePlace;
  dr.series[0].values[2] = 1.0;  // NaN vs a number always differs
  EXPECT_FALSE(CompareDigests(dr, dg, o).equal);
  dr.series[0].values[2] = NAN;
  o.by_class[SeriesClass::kMetric] = {1e-9, 1e-7};  // 5e-5 off 100 > 1e-9 + 1e-7 * 100
  const CompareResult rel = CompareDigests(dr, dg, o);
  ASSERT_FALSE(rel.equal);
  EXPECT_EQ(rel.first->row, 1);
}

TEST(Compare, GoldenFileRoundTripsAndStaysSparse) {
  const std::string dir = testing::TestDir("compare_golden");
  const std::string run = Write(dir, "run", {});
  const Digest sparse = DigestOfRun(run, 25);
  WriteGolden(dir + "/golden.h5", sparse);
  EXPECT_TRUE(IsGoldenFile(dir + "/golden.h5"));
  EXPECT_FALSE(IsGoldenFile(run));
  const Digest back = ReadGolden(dir + "/golden.h5");
  CompareOptions exact = CompareOptions::Defaults();
  exact.exact = true;
  EXPECT_TRUE(CompareDigests(sparse, back, exact).equal);
  EXPECT_EQ(back.sparse_every, 25);
  int position_frames = 0;
  for (const DigestSeries& s : back.series)
    if (s.name.rfind("bodies/tendon/positions@", 0) == 0) ++position_frames;
  EXPECT_EQ(position_frames, 5);  // frames 0, 25, 50, 75 and the last (99)
  // A run compared with the golden file uses the golden's sparse frames.
  const CompareResult r = CompareDigests(LoadDigest(run, 25), LoadDigest(dir + "/golden.h5", 0),
                                         CompareOptions::Defaults());
  EXPECT_TRUE(r.equal) << r.Report();
  // A shorter run is a regression at the first missing frame.
  SynthSpec shorter;
  shorter.frames = 90;
  const CompareResult s = CompareDigests(DigestOfRun(Write(dir, "short", shorter), 25), back,
                                         CompareOptions::Defaults());
  ASSERT_FALSE(s.equal);
  EXPECT_EQ(s.first->step, 89);  // the short run keeps positions of its last frame, 89
}

TEST(Compare, TolerancesFileIsStrict) {
  const std::string dir = testing::TestDir("compare_tolerances");
  auto write = [&](const std::string& text) {
    std::ofstream(dir + "/t.yaml") << text;
    return dir + "/t.yaml";
  };
  const CompareOptions o =
      LoadTolerances(write("position: {atol: 1.0e-3, rtol: 0}\nnan: differ\n"
                           "series: {tools/awl/pose: {atol: 0.5, rtol: 0.1}}\n"));
  EXPECT_EQ(o.by_class.at(SeriesClass::kPosition).atol, 1e-3);
  EXPECT_EQ(o.by_series.at("tools/awl/pose").rtol, 0.1);
  EXPECT_EQ(o.nan, NanPolicy::kDiffer);
  try {
    LoadTolerances(write("position: {atol: 1}\nforce: {atol: -1}\n"));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 2);
    EXPECT_EQ(e.field(), "force.atol");
  }
  EXPECT_THROW(LoadTolerances(write("exact: {atol: 1}\n")), InputError);
  EXPECT_THROW(LoadTolerances(write("positions: {atol: 1}\n")), InputError);
}

}  // namespace
}  // namespace arthrosim::scoring
