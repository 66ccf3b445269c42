// Plan adherence: when each step's criteria are met, its duration against the budget, actions
// before prerequisites, actions with an instrument the plan does not allow.
#include <fmt/core.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "score_internal.h"

namespace arthrosim::scoring::detail {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

bool Allowed(const PlanStep& step, const std::string& tool) {
  return std::find(step.instruments.begin(), step.instruments.end(), tool) !=
         step.instruments.end();
}

// Outcome of one criterion: when it was met (NaN if never) and, if not, why.
struct CriterionOutcome {
  double time_s = kNaN;
  std::string why;
};

std::string RangeText(const Range& r) {
  if (r.min && r.max) return fmt::format("{:g} to {:g}", *r.min, *r.max);
  if (r.min) return fmt::format("at least {:g}", *r.min);
  return fmt::format("at most {:g}", *r.max);
}

// Why an event of the right kind and instrument does not satisfy the criterion ("" if it does).
std::string EventMismatch(const Model& model, const Criterion& c, const Event& e) {
  if (!c.body.empty() && e.body != c.body)
    return fmt::format("on '{}' instead of '{}'", e.body, c.body);
  if (!c.landmark.empty() && c.within_mm > 0) {
    const int l = model.FindLandmark(c.landmark);
    const double d = l < 0 ? kNaN : (e.position_mm - model.landmarks[l].position_mm).norm();
    if (!(d <= c.within_mm))
      return fmt::format("{:.1f} mm from {} (allowed {:g} mm)", d, c.landmark, c.within_mm);
  }
  if (!c.region.empty() && !InRegionBox(model, c.region, e.position_mm))
    return fmt::format("outside region {}", c.region);
  for (const auto& [key, range] : c.detail) {
    double v = 0;
    if (!DetailValue(e.detail, key, &v)) return fmt::format("no {} in the event", key);
    if (!range.Contains(v)) return fmt::format("{} = {:g}, expected {}", key, v, RangeText(range));
  }
  return "";
}

CriterionOutcome EventCriterion(const PlanStep& step, const Criterion& c, const RunData& run,
                                const Event** used) {
  CriterionOutcome out;
  int matched = 0;
  const Event* last_candidate = nullptr;
  std::string last_why;
  for (const Event& e : run.events) {
    if (e.kind != c.event || !Allowed(step, e.tool)) continue;
    last_candidate = &e;
    last_why = EventMismatch(run.model, c, e);
    if (!last_why.empty()) continue;
    *used = &e;
    if (++matched == c.count) {
      out.time_s = e.time_s;
      return out;
    }
  }
  if (!*used) *used = last_candidate;
  if (!last_candidate) {
    out.why = fmt::format("no '{}' by {}", c.event, fmt::join(step.instruments, " or "));
  } else if (matched > 0) {
    out.why = fmt::format("{} of {} '{}' done", matched, c.count, c.event);
  } else {
    out.why = fmt::format("'{}' {}", c.event, last_why);
  }
  return out;
}

// Repair-quality metrics from the event a criterion used (the completing one, else the last
// attempt): its distance to the landmark and every detail value with its range.
void EventQualityMetrics(const PlanStep& step, const Criterion& c, const RunData& run,
                         const Event* e, ScoreReport* report) {
  const std::string base = "quality." + step.id + "." + c.event;
  if (!c.landmark.empty() && c.within_mm > 0) {
    const int l = run.model.FindLandmark(c.landmark);
    const double d = e ? (e->position_mm - run.model.landmarks[l].position_mm).norm() : kNaN;
    AddMetric(report, base + ".position_error", "repair_quality",
              fmt::format("{}: {} distance to {}", step.title, c.event, c.landmark), "mm", d,
              std::nullopt, c.within_mm);
  }
  for (const auto& [key, range] : c.detail) {
    double v = kNaN;
    if (e && !DetailValue(e->detail, key, &v)) v = kNaN;
    AddMetric(report, base + "." + key, "repair_quality",
              fmt::format("{}: {} {}", step.title, c.event, key), "", v, range.min, range.max);
  }
}

CriterionOutcome BoneCriterion(const Criterion& c, const RunData& run) {
  CriterionOutcome out;
  const int b = run.model.FindBone(c.bone);
  const std::vector<double>& v = run.bone_removed_mm3[b];
  for (std::size_t k = 0; k < v.size(); ++k) {
    if (v[k] - v[0] >= c.min_volume_mm3) {
      out.time_s = run.time_s[k];
      return out;
    }
  }
  out.why = fmt::format("{:.2f} mm3 of {} removed, needed {:g}", v.back() - v.front(), c.bone,
                        c.min_volume_mm3);
  return out;
}

// Centroid (mm) of a region's nodes in the last frame; NaN if the region has none.
Vec3 RegionCentroid(const RunData& run, const Region& region) {
  const int b = run.model.FindSoftBody(region.body);
  Vec3 sum = Vec3::Zero();
  int n = 0;
  if (b >= 0 && b < static_cast<int>(run.last.soft_bodies.size())) {
    const Points& x = run.last.soft_bodies[b].x;
    for (std::int32_t i : region.nodes) {
      if (i < x.cols()) {
        sum += x.col(i);
        ++n;
      }
    }
  }
  return n > 0 ? Vec3(sum / n) : Vec3::Constant(kNaN);
}

CriterionOutcome DistanceCriterion(const PlanStep& step, const Criterion& c, const RunData& run,
                                   ScoreReport* report) {
  CriterionOutcome out;
  const Region& region = run.model.regions[run.model.FindRegion(c.region)];
  const Vec3 target = run.model.landmarks[run.model.FindLandmark(c.landmark)].position_mm;
  const double d = (RegionCentroid(run, region) - target).norm();
  AddMetric(report, "quality." + step.id + ".gap", "repair_quality",
            fmt::format("{}: {} to {} at the end", step.title, c.region, c.landmark), "mm", d,
            std::nullopt, c.max_mm);
  if (d <= c.max_mm) {
    out.time_s = run.time_s.back();
  } else {
    out.why = fmt::format("{} ends {:.1f} mm from {} (allowed {:g} mm)", c.region, d, c.landmark,
                          c.max_mm);
  }
  return out;
}

CriterionOutcome InViewCriterion(const Criterion& c, const RunData& run, double* first_seen) {
  CriterionOutcome out;
  const Vec3 p = run.model.landmarks[run.model.FindLandmark(c.landmark)].position_mm;
  double seen = 0;
  for (std::int64_t k = 0; k < run.frames(); ++k) {
    if (!PointInView(run.model, run.camera[k], p)) continue;
    if (std::isnan(*first_seen)) *first_seen = run.time_s[k];
    if (k > 0) seen += run.time_s[k] - run.time_s[k - 1];
    if (seen >= c.min_time_s) {
      out.time_s = run.time_s[k];
      return out;
    }
  }
  out.why = fmt::format("{} in view for {:.1f} s, needed {:g} s", c.landmark, seen, c.min_time_s);
  return out;
}

// First action of a step: its operation or a criterion's event by an allowed instrument.
double FirstAction(const PlanStep& step, const RunData& run) {
  for (const Event& e : run.events) {
    if (!Allowed(step, e.tool)) continue;
    bool related = !step.operation.empty() && e.kind == step.operation;
    for (const Criterion& c : step.complete)
      related = related || (c.kind == Criterion::Kind::kEvent && e.kind == c.event);
    if (related) return e.time_s;
  }
  return kNaN;
}

// Latest insertion of an allowed instrument at or before `t_s` (the first insertion if none
// precedes it, NaN if never inserted): when the trainee picked up the step's tool.
double Insertion(const PlanStep& step, const RunData& run, double t_s) {
  double latest = kNaN, first = kNaN;
  for (const InstrumentSeries& s : run.instruments) {
    if (!Allowed(step, s.name)) continue;
    for (std::int64_t k = 0; k < run.frames(); ++k) {
      if (!s.active[k] || (k > 0 && s.active[k - 1])) continue;
      const double t = run.time_s[k];
      if (!(t >= first)) first = t;
      if (t <= t_s + 1e-9 && !(t <= latest)) latest = t;
    }
  }
  return std::isnan(latest) ? first : latest;
}

StepResult EvaluateStep(const PlanStep& step, const RunData& run, double* first_action,
                        ScoreReport* report) {
  StepResult r;
  r.id = step.id;
  r.title = step.title;
  double end = -std::numeric_limits<double>::infinity();
  double first_seen = kNaN;
  std::vector<std::string> missing;
  for (const Criterion& c : step.complete) {
    CriterionOutcome o;
    if (c.kind == Criterion::Kind::kEvent) {
      const Event* used = nullptr;
      o = EventCriterion(step, c, run, &used);
      EventQualityMetrics(step, c, run, used, report);
    } else if (c.kind == Criterion::Kind::kBoneRemoved) {
      o = BoneCriterion(c, run);
    } else if (c.kind == Criterion::Kind::kDistance) {
      o = DistanceCriterion(step, c, run, report);
    } else {
      o = InViewCriterion(c, run, &first_seen);
    }
    if (std::isnan(o.time_s)) missing.push_back(o.why);
    end = std::max(end, o.time_s);
  }
  *first_action = FirstAction(step, run);
  const double reference = std::isnan(*first_action) ? end : *first_action;
  r.start_s = Insertion(step, run, std::isfinite(reference) ? reference : run.time_s.back());
  if (std::isnan(r.start_s)) r.start_s = first_seen;
  if (std::isnan(*first_action)) *first_action = r.start_s;
  r.completed = missing.empty();
  r.end_s = r.completed ? end : kNaN;
  if (r.completed && std::isnan(r.start_s)) r.start_s = r.end_s;
  r.duration_s = r.end_s - r.start_s;
  if (r.completed) r.completion_frame = FrameAtOrAfter(run, r.end_s);
  if (!r.completed) {
    r.reason = "not done: " + fmt::format("{}", fmt::join(missing, "; "));
  } else if (r.duration_s > step.time_budget_s) {
    r.reason = fmt::format("took {:.1f} s, the budget is {:g} s", r.duration_s, step.time_budget_s);
  }
  r.passed = r.completed && r.reason.empty();
  return r;
}

}  // namespace

void EvaluateSteps(const Plan& plan, const RunData& run, ScoreReport* report) {
  std::vector<double> first_action(plan.steps.size(), kNaN);
  for (std::size_t i = 0; i < plan.steps.size(); ++i)
    report->steps.push_back(EvaluateStep(plan.steps[i], run, &first_action[i], report));
  for (std::size_t i = 0; i < plan.steps.size(); ++i) {
    StepResult& r = report->steps[i];
    const PlanStep& step = plan.steps[i];
    AddMetric(report, "step." + step.id + ".duration", "efficiency",
              fmt::format("{}: duration", step.title), "s", r.duration_s, std::nullopt,
              step.time_budget_s);
    const double acted = first_action[i];
    if (std::isnan(acted)) continue;
    for (const std::string& req : step.requires_steps) {
      const StepResult& p = report->steps[plan.FindStep(req)];
      if (p.completed && p.end_s <= acted) continue;
      const std::string text =
          fmt::format("'{}' acted at {:.2f} s before '{}' was done", step.title, acted, p.title);
      report->violations.push_back({"order", acted, step.id, text});
      if (r.passed) r.reason = "out of order: " + text;
      r.passed = false;
    }
  }
  for (std::size_t i = 0; i < plan.steps.size(); ++i)
    if (plan.steps[i].critical && !report->steps[i].passed)
      report->critical_errors.push_back(fmt::format("critical step '{}' failed: {}",
                                                    plan.steps[i].title, report->steps[i].reason));
}

void EvaluateInstrumentUse(const Plan& plan, const RunData& run, ScoreReport* report) {
  const std::vector<std::string> actions = ActionEvents(plan);
  int wrong = 0;
  for (const Event& e : run.events) {
    if (e.tool.empty() || std::find(actions.begin(), actions.end(), e.kind) == actions.end())
      continue;
    bool planned = false, allowed = false;
    std::string step_id;
    for (const PlanStep& step : plan.steps) {
      bool uses = step.operation == e.kind;
      for (const Criterion& c : step.complete)
        uses = uses || (c.kind == Criterion::Kind::kEvent && c.event == e.kind);
      if (!uses) continue;
      if (!planned) step_id = step.id;
      planned = true;
      allowed = allowed || Allowed(step, e.tool);
    }
    if (!planned || allowed) continue;
    ++wrong;
    report->violations.push_back(
        {"wrong_instrument", e.time_s, step_id,
         fmt::format("'{}' done with {} at {:.2f} s, which the plan does not allow", e.kind, e.tool,
                     e.time_s)});
  }
  AddMetric(report, "plan.wrong_instrument_actions", "plan_adherence",
            "actions with an instrument the plan does not allow", "count", wrong, std::nullopt,
            0.0);
}

}  // namespace arthrosim::scoring::detail
