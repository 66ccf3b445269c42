#pragma once
// Scoring a run against a plan (docs/metrics.md, docs/score-format.md): per-step verdicts,
// violations, motion/safety/camera/repair metrics, domain scores and the total.
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "arthrosim/scoring/plan.h"
#include "arthrosim/scoring/run_data.h"

namespace arthrosim::scoring {

inline constexpr int kScoreSchemaVersion = 1;

/// One measured quantity. `value` is NaN when the run holds no data for it.
struct Metric {
  std::string id;      ///< e.g. "motion.burr.path_length"
  std::string domain;  ///< plan_adherence, efficiency, safety, repair_quality, info
  std::string label;   ///< words for the report
  std::string unit;
  double value = 0;
  std::optional<double> min, max;  ///< pass band; neither = informational (always passes)
  bool pass = true;
  bool critical = false;    ///< a failure here fails the session regardless of the total
  std::optional<double> z;  ///< against the reference runs
  std::optional<double> reference_mean;
};

struct StepResult {
  std::string id, title;
  bool completed = false;
  bool passed = false;
  double start_s = 0, end_s = 0, duration_s = 0;  ///< NaN when unknown
  std::int64_t completion_frame = -1;
  std::string reason;  ///< why it failed (empty when passed)
};

struct Violation {
  std::string kind;  ///< order, wrong_instrument, damage, force
  double time_s = 0;
  std::string step;  ///< step id concerned ("" if none)
  std::string text;
};

struct ScoreReport {
  std::string run_file, plan_name, scenario;
  double duration_s = 0;
  int references = 0;
  std::vector<StepResult> steps;
  std::vector<Violation> violations;
  std::vector<Metric> metrics;
  std::map<std::string, double> domains;  ///< domain -> 0..100 (absent = no metric)
  double total = 0;
  bool passed = false;
  std::vector<std::string> critical_errors;
};

/// Scores `run` against `plan`; `references` (expert runs of the same scenario) give z-scores
/// and the economy ratios. Deterministic: same inputs give the same report.
ScoreReport Evaluate(const Plan& plan, const RunData& run,
                     const std::vector<const RunData*>& references = {});

/// The report as JSON (docs/score-format.md), keys in a fixed order; byte-identical for the
/// same report.
std::string ToJson(const ScoreReport& report);
/// An xAPI statement of the result (scaled score in [-1, 1], ISO 8601 duration).
std::string ToXapi(const ScoreReport& report);
/// A few lines for the console: verdict, total, domains, failed steps and critical errors.
std::string ConsoleSummary(const ScoreReport& report);
/// Seconds as an ISO 8601 duration ("PT1M5.25S").
std::string IsoDuration(double seconds);

}  // namespace arthrosim::scoring
