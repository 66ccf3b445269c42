#pragma once
// Internal pieces of Evaluate, one file per group of metrics.
#include <string>
#include <vector>

#include "arthrosim/scoring/score.h"

namespace arthrosim::scoring::detail {

/// The numeric value of `key` in a `key=value key=value` detail string; false if absent or not
/// a number.
bool DetailValue(const std::string& detail, const std::string& key, double* value);
/// The string value of `key` ("" if absent).
std::string DetailText(const std::string& detail, const std::string& key);

/// Whether `p` lies inside the box of region `name` (false if there is no such region).
bool InRegionBox(const Model& model, const std::string& name, const Vec3& p);

/// Index of the frame at or after time t (last frame if none).
std::int64_t FrameAtOrAfter(const RunData& run, double t_s);

/// Per-step verdicts, order violations and repair-quality metrics (steps.cpp).
void EvaluateSteps(const Plan& plan, const RunData& run, ScoreReport* report);
/// Wrong-instrument actions (steps.cpp).
void EvaluateInstrumentUse(const Plan& plan, const RunData& run, ScoreReport* report);
/// Protected structures, damage and volume outside targets (safety.cpp).
void EvaluateSafety(const Plan& plan, const RunData& run, ScoreReport* report);
/// Motion per instrument and camera, camera view metrics (motion_metrics.cpp).
void EvaluateMotion(const Plan& plan, const RunData& run,
                    const std::vector<const RunData*>& references, ScoreReport* report);

/// Event kinds that act on tissue or bone (damage when on a protected structure).
bool IsDamageEvent(const std::string& kind);
/// Action kinds the plan attributes to steps (the plan's list or the default one).
std::vector<std::string> ActionEvents(const Plan& plan);

/// Adds a metric; pass is computed from min/max (NaN never passes a band).
Metric& AddMetric(ScoreReport* report, std::string id, std::string domain, std::string label,
                  std::string unit, double value, std::optional<double> min,
                  std::optional<double> max, bool critical = false);

}  // namespace arthrosim::scoring::detail
