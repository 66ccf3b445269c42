// The streaming checks shared by offline scoring and live feedback (progress.h).
#include "progress.h"

#include <fmt/core.h>

#include <algorithm>

#include "arthrosim/mesh/surface_tissue.h"
#include "arthrosim/scoring/run_data.h"
#include "score_internal.h"

namespace arthrosim::scoring::detail {
namespace {

std::string RangeText(const Range& r) {
  if (r.min && r.max) return fmt::format("{:g} to {:g}", *r.min, *r.max);
  if (r.min) return fmt::format("at least {:g}", *r.min);
  return fmt::format("at most {:g}", *r.max);
}

struct BodyRef {
  ConstraintEnd::Kind kind = ConstraintEnd::Kind::kSoftBody;
  int index = -1;
};

// Whether `p` (a contact on bone `bone`) lies nearest to a triangle of its tissue `tissue`.
bool OnTissue(const Model& model, int bone, const std::string& tissue, const Vec3& p) {
  if (bone < 0) return false;
  const BoneModel& b = model.bones[static_cast<std::size_t>(bone)];
  const std::int8_t label = mesh::TissueNear(b.surface, b.tri_tissue, p);
  return label != mesh::kBoneTissue && b.tissues[static_cast<std::size_t>(label)] == tissue;
}

BodyRef FindBody(const Model& model, const std::string& name) {
  if (int i = model.FindSoftBody(name); i >= 0) return {ConstraintEnd::Kind::kSoftBody, i};
  if (int i = model.FindBone(name); i >= 0) return {ConstraintEnd::Kind::kBone, i};
  return {ConstraintEnd::Kind::kThread, model.FindThread(name)};
}

}  // namespace

bool Allowed(const PlanStep& step, const std::string& tool) {
  return std::find(step.instruments.begin(), step.instruments.end(), tool) !=
         step.instruments.end();
}

bool StepActsBy(const PlanStep& step, const std::string& kind) {
  if (kind.empty()) return false;
  if (kind == step.operation) return true;
  const auto& also = step.also_events;
  if (std::find(also.begin(), also.end(), kind) != also.end()) return true;
  return std::any_of(step.complete.begin(), step.complete.end(), [&](const Criterion& c) {
    return c.kind == Criterion::Kind::kEvent && c.event == kind;
  });
}

bool IsStepAction(const PlanStep& step, const Event& e) {
  return Allowed(step, e.tool) && StepActsBy(step, e.kind);
}

std::string EventMismatch(const Model& model, const Criterion& c, const Event& e) {
  if (!c.body.empty() && e.body != c.body)
    return fmt::format("on '{}' instead of '{}'", e.body, c.body);
  if (!c.landmark.empty() && c.within_mm > 0) {
    const int l = model.FindLandmark(c.landmark);
    const double d = l < 0 ? kNoTime : (e.position_mm - model.landmarks[l].position_mm).norm();
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

void CriterionProgress::OnEvent(const Model& model, const Event& e, std::int64_t index) {
  if (c_->kind != Criterion::Kind::kEvent || met()) return;
  if (e.kind != c_->event || !Allowed(*step_, e.tool)) return;
  last_candidate_ = index;
  last_why_ = EventMismatch(model, *c_, e);
  if (!last_why_.empty()) {
    last_rejection_ = last_why_;
    return;
  }
  used_ = index;
  if (++matched_ == c_->count) met_s_ = e.time_s;
}

void CriterionProgress::OnFrame(double t_s, bool landmark_seen, double bone_removed_mm3) {
  const bool first = !have_frame_;
  const double dt_s = first ? 0.0 : t_s - prev_t_s_;
  have_frame_ = true;
  prev_t_s_ = t_s;
  if (c_->kind == Criterion::Kind::kBoneRemoved) {
    if (first) first_removed_ = bone_removed_mm3;
    last_removed_ = bone_removed_mm3;
    if (!met() && bone_removed_mm3 - first_removed_ >= c_->min_volume_mm3) met_s_ = t_s;
    return;
  }
  if (c_->kind != Criterion::Kind::kInView || met()) return;
  if (!landmark_seen) return;
  if (std::isnan(first_seen_s_)) first_seen_s_ = t_s;
  if (!first) seen_s_ += dt_s;
  if (seen_s_ >= c_->min_time_s) met_s_ = t_s;
}

ProtectedTouch TouchOf(const Model& model, const ProtectedStructure& p,
                       const std::vector<ToolContact>& contacts, const SlotForces& force_n) {
  const BodyRef body = FindBody(model, p.body);
  ProtectedTouch touch;
  for (const ToolContact& c : contacts) {
    if (c.body_kind != body.kind || c.body != body.index) continue;
    if (!p.region.empty() && !InRegionBox(model, p.region, c.position_mm)) continue;
    if (!p.tissue.empty() && !OnTissue(model, body.index, p.tissue, c.position_mm)) continue;
    const double f = c.tool_slot >= 0 && c.tool_slot < kToolSlots
                         ? force_n[static_cast<std::size_t>(c.tool_slot)]
                         : 0.0;
    const double before_n = touch.force_n;
    touch.force_n = std::max(touch.force_n, f);  // the largest force of a touching slot
    if (!touch.touching || touch.force_n > before_n) {
      touch.slot = c.tool_slot;
      touch.position_mm = c.position_mm;
    }
    touch.touching = true;
  }
  return touch;
}

void ProtectedProgress::OnFrame(double t_s, const ProtectedTouch& touch) {
  const double dt_s = have_frame_ ? t_s - prev_t_s_ : 0.0;
  have_frame_ = true;
  prev_t_s_ = t_s;
  if (!touch.touching) return;
  contact_s_ += dt_s;
  peak_n_ = std::max(peak_n_, touch.force_n);
  if (touch.force_n > p_->max_force_n) {
    over_s_ += dt_s;
    if (std::isnan(first_over_s_)) first_over_s_ = t_s;
  }
}

bool DamagesProtected(const Model& model, const ProtectedStructure& p, const Event& e) {
  if (!IsDamageEvent(e.kind) || e.body != p.body) return false;
  if (!p.tissue.empty() && DetailText(e.detail, "tissue") != p.tissue) return false;
  return p.region.empty() || InRegionBox(model, p.region, e.position_mm);
}

namespace {

// Whether a criterion expects an event of `e`'s kind where `e` happened: its body (if it names
// one) and its place (within its landmark radius, inside its region box). Detail values (depth,
// angle) do not count: a hole at the wrong angle is still made where it was planned.
bool CriterionTargets(const Model& model, const Criterion& c, const Event& e) {
  if (c.kind != Criterion::Kind::kEvent || c.event != e.kind) return false;
  if (!c.body.empty() && e.body != c.body) return false;
  const bool placed = (!c.landmark.empty() && c.within_mm > 0) || !c.region.empty();
  if (!placed) return false;
  if (!c.landmark.empty() && c.within_mm > 0) {
    const int l = model.FindLandmark(c.landmark);
    if (l < 0 || !((e.position_mm - model.landmarks[l].position_mm).norm() <= c.within_mm))
      return false;
  }
  return c.region.empty() || InRegionBox(model, c.region, e.position_mm);
}

}  // namespace

bool RemovedOutsideTarget(const Plan& plan, const Model& model, const Event& e,
                          double* volume_mm3) {
  double volume = 0;
  if (!DetailValue(e.detail, "volume_mm3", &volume)) return false;
  for (const PlanStep& step : plan.steps) {
    if (step.operation == e.kind && !step.target_region.empty() &&
        InRegionBox(model, step.target_region, e.position_mm))
      return false;
    for (const Criterion& c : step.complete)
      if (CriterionTargets(model, c, e)) return false;
  }
  *volume_mm3 = volume;
  return true;
}

}  // namespace arthrosim::scoring::detail
