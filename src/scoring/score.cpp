#include "arthrosim/scoring/score.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <sstream>

#include "score_internal.h"

namespace arthrosim::scoring {
namespace detail {

bool DetailValue(const std::string& detail, const std::string& key, double* value) {
  const std::string text = DetailText(detail, key);
  if (text.empty()) return false;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size() || !std::isfinite(v)) return false;
  *value = v;
  return true;
}

std::string DetailText(const std::string& detail, const std::string& key) {
  std::istringstream in(detail);
  std::string token;
  while (in >> token) {
    const std::size_t eq = token.find('=');
    if (eq != std::string::npos && token.compare(0, eq, key) == 0 && eq == key.size())
      return token.substr(eq + 1);
  }
  return "";
}

bool InRegionBox(const Model& model, const std::string& name, const Vec3& p) {
  const int r = model.FindRegion(name);
  if (r < 0) return false;
  const Region& g = model.regions[r];
  return (p.array() >= g.box_min_mm.array()).all() && (p.array() <= g.box_max_mm.array()).all();
}

std::int64_t FrameAtOrAfter(const RunData& run, double t_s) { return run.FrameAt(t_s); }

bool IsDamageEvent(const std::string& kind) {
  static const char* const kDamage[] = {"cut", "burr", "shave", "cauterize", "hole", "anchor"};
  return std::any_of(std::begin(kDamage), std::end(kDamage),
                     [&](const char* k) { return kind == k; });
}

std::vector<std::string> ActionEvents(const Plan& plan) {
  if (!plan.action_events.empty()) return plan.action_events;
  return {"cut",   "thread_cut",   "burr",        "shave", "cauterize",   "hole",      "anchor",
          "grasp", "thread_catch", "suture_pass", "knot",  "knot_seated", "hook_catch"};
}

Metric& AddMetric(ScoreReport* report, std::string id, std::string domain, std::string label,
                  std::string unit, double value, std::optional<double> min,
                  std::optional<double> max, bool critical) {
  Metric m;
  m.id = std::move(id);
  m.domain = std::move(domain);
  m.label = std::move(label);
  m.unit = std::move(unit);
  m.value = value;
  m.min = min;
  m.max = max;
  m.critical = critical;
  if (min || max) m.pass = !std::isnan(value) && (!min || value >= *min) && (!max || value <= *max);
  report->metrics.push_back(std::move(m));
  return report->metrics.back();
}

}  // namespace detail

namespace {

// 1 for a pass; partial credit by the ratio to the violated bound; 0 when not measured.
double SubScore(const Metric& m) {
  if (m.pass) return 1.0;
  if (std::isnan(m.value)) return 0.0;
  if (m.max && m.value > *m.max) return *m.max > 0 ? std::clamp(*m.max / m.value, 0.0, 1.0) : 0.0;
  if (m.min && m.value < *m.min)
    return *m.min > 0 && m.value > 0 ? std::clamp(m.value / *m.min, 0.0, 1.0) : 0.0;
  return 0.0;
}

void DomainScores(const Plan& plan, ScoreReport* r) {
  double steps = 0;
  for (const StepResult& s : r->steps) steps += s.passed ? 1.0 : (s.completed ? 0.5 : 0.0);
  int violations = 0;
  for (const Violation& v : r->violations)
    if (v.kind == "order" || v.kind == "wrong_instrument") ++violations;
  r->domains["plan_adherence"] =
      std::clamp(100.0 * steps / static_cast<double>(std::max<std::size_t>(1, r->steps.size())) -
                     10.0 * violations,
                 0.0, 100.0);
  std::map<std::string, std::pair<double, int>> sums;
  for (const Metric& m : r->metrics) {
    if (m.domain == "info" || m.domain == "plan_adherence" || (!m.min && !m.max)) continue;
    sums[m.domain].first += SubScore(m);
    sums[m.domain].second += 1;
  }
  for (const auto& [domain, s] : sums) r->domains[domain] = 100.0 * s.first / s.second;
  const std::map<std::string, double> weights = {{"plan_adherence", plan.weights.plan_adherence},
                                                 {"efficiency", plan.weights.efficiency},
                                                 {"safety", plan.weights.safety},
                                                 {"repair_quality", plan.weights.repair_quality}};
  double total = 0, weight = 0;
  for (const auto& [domain, score] : r->domains) {
    const auto it = weights.find(domain);
    if (it == weights.end()) continue;
    total += it->second * score;
    weight += it->second;
  }
  r->total = weight > 0 ? total / weight : 0.0;
}

void ZScores(const Plan& plan, const std::vector<const RunData*>& refs, ScoreReport* r) {
  if (refs.empty()) return;
  std::map<std::string, std::vector<double>> values;
  for (const RunData* ref : refs) {
    for (const Metric& m : Evaluate(plan, *ref).metrics)
      if (std::isfinite(m.value)) values[m.id].push_back(m.value);
  }
  for (Metric& m : r->metrics) {
    const auto it = values.find(m.id);
    if (it == values.end() || !std::isfinite(m.value)) continue;
    const std::vector<double>& v = it->second;
    double mean = 0;
    for (double x : v) mean += x;
    mean /= static_cast<double>(v.size());
    double var = 0;
    for (double x : v) var += (x - mean) * (x - mean);
    double sd = v.size() >= 2 ? std::sqrt(var / static_cast<double>(v.size() - 1)) : 0.0;
    sd = std::max({sd, 0.1 * std::abs(mean), 1e-9});
    m.reference_mean = mean;
    m.z = (m.value - mean) / sd;
  }
}

}  // namespace

ScoreReport Evaluate(const Plan& plan, const RunData& run,
                     const std::vector<const RunData*>& references) {
  ScoreReport r;
  r.run_file = std::filesystem::path(run.path).filename().string();
  r.plan_name = plan.name;
  r.scenario = run.model.name;
  r.duration_s = run.time_s.back();
  r.references = static_cast<int>(references.size());
  detail::EvaluateSteps(plan, run, &r);
  detail::EvaluateInstrumentUse(plan, run, &r);
  detail::EvaluateSafety(plan, run, &r);
  detail::EvaluateMotion(plan, run, references, &r);
  ZScores(plan, references, &r);
  DomainScores(plan, &r);
  std::stable_sort(r.violations.begin(), r.violations.end(),
                   [](const Violation& a, const Violation& b) { return a.time_s < b.time_s; });
  const bool steps_ok =
      std::all_of(r.steps.begin(), r.steps.end(), [](const StepResult& s) { return s.passed; });
  r.passed = steps_ok && r.critical_errors.empty() && r.total >= plan.pass_score;
  return r;
}

}  // namespace arthrosim::scoring
