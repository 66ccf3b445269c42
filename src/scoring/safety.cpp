// Safety: contacts with protected structures (time, peak force, time above the force limit),
// damage events on them, tissue and bone removed outside every step's target.
#include <fmt/core.h>

#include <algorithm>
#include <cmath>

#include "score_internal.h"

namespace arthrosim::scoring::detail {
namespace {

struct BodyRef {
  ConstraintEnd::Kind kind = ConstraintEnd::Kind::kSoftBody;
  int index = -1;
};

BodyRef FindBody(const Model& model, const std::string& name) {
  if (int i = model.FindSoftBody(name); i >= 0) return {ConstraintEnd::Kind::kSoftBody, i};
  if (int i = model.FindBone(name); i >= 0) return {ConstraintEnd::Kind::kBone, i};
  return {ConstraintEnd::Kind::kThread, model.FindThread(name)};
}

// Frame interval k-1 -> k counts for frame k (frame 0 has none).
double FrameDt(const RunData& run, std::int64_t k) {
  return k > 0 ? run.time_s[k] - run.time_s[k - 1] : 0.0;
}

// |force| on the instrument in `slot` at frame k (0 if empty).
double SlotForce(const RunData& run, std::int64_t k, int slot) {
  for (const InstrumentSeries& s : run.instruments)
    if (s.slot[k] == slot) return s.force_n[k];
  return 0.0;
}

void ProtectedContacts(const ProtectedStructure& p, const RunData& run, ScoreReport* report) {
  const BodyRef body = FindBody(run.model, p.body);
  double contact_s = 0, over_s = 0, peak_n = 0, first_over = -1;
  for (std::int64_t k = 0; k < run.frames(); ++k) {
    double force = 0;
    bool touching = false;
    for (const ToolContact& c : run.contacts[k]) {
      if (c.body_kind != body.kind || c.body != body.index) continue;
      if (!p.region.empty() && !InRegionBox(run.model, p.region, c.position_mm)) continue;
      touching = true;
      force = std::max(force, SlotForce(run, k, c.tool_slot));
    }
    if (!touching) continue;
    contact_s += FrameDt(run, k);
    peak_n = std::max(peak_n, force);
    if (force > p.max_force_n) {
      over_s += FrameDt(run, k);
      if (first_over < 0) first_over = run.time_s[k];
    }
  }
  const std::string base = "safety." + p.name;
  AddMetric(report, base + ".contact_time", "safety", fmt::format("time touching {}", p.name), "s",
            contact_s, std::nullopt, p.max_contact_time_s);
  AddMetric(report, base + ".peak_force", "safety",
            fmt::format("peak instrument force while touching {}", p.name), "N", peak_n,
            std::nullopt, p.max_force_n);
  AddMetric(report, base + ".time_over_force", "safety",
            fmt::format("time above {:g} N on {}", p.max_force_n, p.name), "s", over_s,
            std::nullopt, 0.0, p.critical);
  if (first_over >= 0) {
    const std::string text =
        fmt::format("force above {:g} N on {} at {:.2f} s", p.max_force_n, p.name, first_over);
    report->violations.push_back({"force", first_over, "", text});
    if (p.critical) report->critical_errors.push_back(text);
  }
}

void ProtectedDamage(const ProtectedStructure& p, const RunData& run, ScoreReport* report) {
  int damage = 0;
  for (const Event& e : run.events) {
    if (!IsDamageEvent(e.kind) || e.body != p.body) continue;
    if (!p.region.empty() && !InRegionBox(run.model, p.region, e.position_mm)) continue;
    ++damage;
    const std::string text =
        fmt::format("'{}' by {} on protected {} at {:.2f} s", e.kind, e.tool, p.name, e.time_s);
    report->violations.push_back({"damage", e.time_s, "", text});
    if (p.zero_damage) report->critical_errors.push_back(text);
  }
  AddMetric(report, "safety." + p.name + ".damage_events", "safety",
            fmt::format("damage events on {}", p.name), "count", damage, std::nullopt,
            p.zero_damage ? std::optional<double>(0.0) : std::nullopt, p.zero_damage);
}

// Removal events (detail volume_mm3=) whose position is inside no target region of a step
// doing that kind of removal.
void OutsideVolume(const Plan& plan, const RunData& run, ScoreReport* report) {
  double outside = 0;
  for (const Event& e : run.events) {
    double volume = 0;
    if (!DetailValue(e.detail, "volume_mm3", &volume)) continue;
    bool on_target = false;
    for (const PlanStep& step : plan.steps) {
      if (step.operation != e.kind || step.target_region.empty()) continue;
      on_target = on_target || InRegionBox(run.model, step.target_region, e.position_mm);
    }
    if (!on_target) outside += volume;
  }
  AddMetric(report, "safety.volume_outside_target", "safety",
            "tissue and bone removed outside the planned targets", "mm3", outside, std::nullopt,
            plan.motion.max_outside_volume_mm3);
}

}  // namespace

void EvaluateSafety(const Plan& plan, const RunData& run, ScoreReport* report) {
  for (const ProtectedStructure& p : plan.protected_structures) {
    ProtectedContacts(p, run, report);
    ProtectedDamage(p, run, report);
  }
  OutsideVolume(plan, run, report);
}

}  // namespace arthrosim::scoring::detail
