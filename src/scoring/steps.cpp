// Plan adherence: when each step's criteria are met, its duration against the budget, actions
// before prerequisites, actions with an instrument the plan does not allow.
#include <fmt/core.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "arthrosim/core/soft_nodes.h"
#include "progress.h"
#include "score_internal.h"

namespace arthrosim::scoring::detail {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Outcome of one criterion: when it was met (NaN if never) and, if not, why.
struct CriterionOutcome {
  double time_s = kNaN;
  std::string why;
};

CriterionOutcome EventCriterion(const PlanStep& step, const Criterion& c, const RunData& run,
                                const Event** used) {
  CriterionProgress progress(step, c);
  for (std::size_t i = 0; i < run.events.size() && !progress.met(); ++i)
    progress.OnEvent(run.model, run.events[i], static_cast<std::int64_t>(i));
  CriterionOutcome out;
  if (progress.used_event() >= 0) *used = &run.events[progress.used_event()];
  if (progress.met()) {
    out.time_s = progress.met_s();
  } else if (!progress.any_candidate()) {
    out.why = fmt::format("no '{}' by {}", c.event, fmt::join(step.instruments, " or "));
  } else if (progress.matched() > 0) {
    out.why = fmt::format("{} of {} '{}' done", progress.matched(), c.count, c.event);
    // An instructor wants to know why the others did not count (a bite too close to the edge).
    if (!progress.last_rejection().empty())
      out.why += fmt::format("; another not counted: {}", progress.last_rejection());
  } else {
    out.why = fmt::format("'{}' {}", c.event, progress.last_mismatch());
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

CriterionOutcome BoneCriterion(const PlanStep& step, const Criterion& c, const RunData& run) {
  const int b = run.model.FindBone(c.bone);
  CriterionProgress progress(step, c);
  for (std::int64_t k = 0; k < run.frames() && !progress.met(); ++k)
    progress.OnFrame(run.time_s[k], false, run.bone_removed_mm3[b][k]);
  CriterionOutcome out;
  if (progress.met()) {
    out.time_s = progress.met_s();
    return out;
  }
  out.why = fmt::format("{:.2f} mm3 of {} removed, needed {:g}", progress.removed_mm3(), c.bone,
                        c.min_volume_mm3);
  return out;
}

// Centroid (mm) of a region's nodes in the last frame that still belong to the tissue (nodes
// cutting or shaving left without elements stay where they were cut: NodesInAliveTets); NaN if
// the region has none.
Vec3 RegionCentroid(const RunData& run, const Region& region) {
  const int b = run.model.FindSoftBody(region.body);
  Vec3 sum = Vec3::Zero();
  int n = 0;
  if (b >= 0 && b < static_cast<int>(run.last.soft_bodies.size())) {
    const SoftBodyState& body = run.last.soft_bodies[static_cast<std::size_t>(b)];
    const Points& x = body.x;
    const std::vector<std::uint8_t> in_tissue = NodesInAliveTets(body);
    for (std::int32_t i : region.nodes) {
      if (i < x.cols() && in_tissue[static_cast<std::size_t>(i)]) {
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
  const Vec3 centroid = RegionCentroid(run, region);
  std::string to = c.landmark;
  double d = 0;
  if (c.to_region.empty()) {
    d = (centroid - run.model.landmarks[run.model.FindLandmark(c.landmark)].position_mm).norm();
  } else {
    // The nearest point of the box (the centroid itself when inside): 0 on the region.
    const Region& box = run.model.regions[run.model.FindRegion(c.to_region)];
    d = (centroid - centroid.cwiseMax(box.box_min_mm).cwiseMin(box.box_max_mm)).norm();
    to = "region " + c.to_region;
  }
  AddMetric(report, "quality." + step.id + ".gap", "repair_quality",
            fmt::format("{}: {} to {} at the end", step.title, c.region, to), "mm", d, std::nullopt,
            c.max_mm);
  if (d <= c.max_mm) {
    out.time_s = run.time_s.back();
  } else {
    out.why = fmt::format("{} ends {:.1f} mm from {} (allowed {:g} mm)", c.region, d, to, c.max_mm);
  }
  return out;
}

CriterionOutcome InViewCriterion(const PlanStep& step, const Criterion& c, const RunData& run,
                                 double* first_seen) {
  CriterionProgress progress(step, c);
  const int l = run.model.FindLandmark(c.landmark);
  for (std::int64_t k = 0; k < run.frames() && !progress.met(); ++k) {
    const bool seen =
        l >= 0 &&
        run.landmark_visible[static_cast<std::size_t>(l)][static_cast<std::size_t>(k)] != 0;
    progress.OnFrame(run.time_s[k], seen, 0.0);
  }
  if (std::isnan(*first_seen)) *first_seen = progress.first_seen_s();
  CriterionOutcome out;
  if (progress.met()) {
    out.time_s = progress.met_s();
    return out;
  }
  out.why = fmt::format("{} in view for {:.1f} s, needed {:g} s", c.landmark, progress.seen_s(),
                        c.min_time_s);
  return out;
}

// Whether event e (an action of the step) meets one of the step's event criteria but for their
// count: the right kind, body, place and details.
bool CountsTowardStep(const PlanStep& step, const Model& model, const Event& e) {
  return std::any_of(step.complete.begin(), step.complete.end(), [&](const Criterion& c) {
    return c.kind == Criterion::Kind::kEvent && c.event == e.kind &&
           EventMismatch(model, c, e).empty();
  });
}

// First action of a step: its operation or a criterion's event by an allowed instrument; of
// those, the first that counts toward one of its event criteria if any does (the footprint's
// first burr event, not the acromioplasty's before it), else the first.
double FirstAction(const PlanStep& step, const RunData& run) {
  double first = kNaN;
  for (const Event& e : run.events) {
    if (!IsStepAction(step, e)) continue;
    if (CountsTowardStep(step, run.model, e)) return e.time_s;
    if (std::isnan(first)) first = e.time_s;
  }
  return first;
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

// When the step's hand became free for it: the last action of its instruments before
// `first_action_s` that does not count toward the step (the spur burred before the same burr
// goes to the footprint), or NaN if there is none.
double PreviousTaskEnd(const PlanStep& step, const RunData& run, double first_action_s) {
  double last = kNaN;
  for (const Event& e : run.events) {
    if (!(e.time_s < first_action_s)) break;
    if (IsStepAction(step, e) && !CountsTowardStep(step, run.model, e)) last = e.time_s;
  }
  return last;
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
      o = BoneCriterion(step, c, run);
    } else if (c.kind == Criterion::Kind::kDistance) {
      o = DistanceCriterion(step, c, run, report);
    } else {
      o = InViewCriterion(step, c, run, &first_seen);
    }
    if (std::isnan(o.time_s)) missing.push_back(o.why);
    end = std::max(end, o.time_s);
  }
  *first_action = FirstAction(step, run);
  const double reference = std::isnan(*first_action) ? end : *first_action;
  r.start_s = Insertion(step, run, std::isfinite(reference) ? reference : run.time_s.back());
  // One insertion for two steps (the burr from the spur to the footprint): this step starts when
  // the instrument's previous task ended.
  const double previous_end = PreviousTaskEnd(step, run, *first_action);
  if (previous_end > r.start_s) r.start_s = previous_end;
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
      if (!StepActsBy(step, e.kind)) continue;
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
