// Live feedback: the streaming checks of progress.h (the ones offline scoring runs over a whole
// run file) fed one step at a time, conditions turned into debounced warnings.
#include "arthrosim/scoring/live.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "arthrosim/io/run_reader.h"
#include "arthrosim/scoring/sight.h"
#include "progress.h"

namespace arthrosim::scoring {

using detail::CriterionProgress;
using detail::ProtectedProgress;
using detail::ProtectedTouch;

Event LiveWarning::AsEvent() const {
  return Event{step, time_s, kWarningEventKind, tool, body, detail, position_mm};
}

struct LiveEvaluator::Impl {
  Plan plan;
  Model model;
  LiveOptions options;
  std::vector<std::vector<CriterionProgress>> criteria;  // [step][criterion]
  std::vector<ProtectedProgress> structures;             // plan.protected_structures order
  SightBlockers blockers;  // the frame's surfaces for in_view criteria (taken when needed)
  std::vector<std::uint8_t> contact_time_warned;
  double outside_mm3 = 0;
  std::int64_t events_seen = 0;
  std::map<std::string, double> last_seen_s;  // type/subject -> last time the condition was seen
  std::map<std::string, int> given, suppressed;
  std::vector<LiveWarning> due;  // of the current observation

  Impl(const Plan& p, const Model& m, const LiveOptions& o) : plan(p), model(m), options(o) {
    for (const PlanStep& step : plan.steps) {
      criteria.emplace_back();
      for (const Criterion& c : step.complete) criteria.back().emplace_back(step, c);
    }
    for (const ProtectedStructure& s : plan.protected_structures) structures.emplace_back(s);
    contact_time_warned.assign(structures.size(), 0);
  }

  // When step i completed (NaN while a criterion is unmet; distance criteria never are here).
  double DoneAt(int i) const {
    double end = -std::numeric_limits<double>::infinity();
    for (const CriterionProgress& c : criteria[static_cast<std::size_t>(i)]) {
      if (!c.met()) return detail::kNoTime;
      end = std::max(end, c.met_s());
    }
    return end;
  }

  std::string ToolIn(const State& s, int slot) const {
    if (slot < 0 || slot >= kToolSlots) return "";
    const int i = s.tools[static_cast<std::size_t>(slot)].instrument;
    return i >= 0 && i < static_cast<int>(model.instruments.size())
               ? model.instruments[static_cast<std::size_t>(i)].name
               : "";
  }

  // The debounce: due when the same type/subject was not seen in the last quiet_s.
  void Raise(LiveWarning w) {
    const std::string key = w.type + "/" + w.subject;
    const auto it = last_seen_s.find(key);
    const bool is_due = it == last_seen_s.end() || w.time_s - it->second >= options.quiet_s;
    last_seen_s[key] = w.time_s;
    if (!is_due) {
      ++suppressed[w.type];
      return;
    }
    ++given[w.type];
    w.message = fmt::format("WARNING {} {} t={:.2f}s: {}", w.type, w.subject, w.time_s, w.message);
    due.push_back(std::move(w));
  }

  LiveWarning Base(const char* type, std::string subject, const Event& e) const {
    LiveWarning w;
    w.type = type;
    w.subject = std::move(subject);
    w.tool = e.tool;
    w.body = e.body;
    w.step = e.step;
    w.time_s = e.time_s;
    w.position_mm = e.position_mm;
    return w;
  }

  void CheckDamage(const Event& e) {
    for (const ProtectedStructure& p : plan.protected_structures) {
      if (!detail::DamagesProtected(model, p, e)) continue;
      LiveWarning w = Base("damage", p.name, e);
      w.message = fmt::format("{} by the {} on the protected {}", e.kind, e.tool, p.name);
      w.detail = fmt::format("type=damage subject={} event={}", p.name, e.kind);
      Raise(std::move(w));
    }
  }

  void CheckOutside(const Event& e) {
    double volume = 0;
    if (!detail::RemovedOutsideTarget(plan, model, e, &volume)) return;
    outside_mm3 += volume;
    const double limit = plan.motion.max_outside_volume_mm3;
    if (!(outside_mm3 > limit)) return;
    LiveWarning w = Base("outside_target", "targets", e);
    w.message = fmt::format(
        "{} by the {} outside the planned targets: {:.2f} mm3 in total, {:g} "
        "allowed",
        e.kind, e.tool, outside_mm3, limit);
    w.detail = fmt::format(
        "type=outside_target subject=targets event={} outside_mm3={:.6g} "
        "limit_mm3={:g}",
        e.kind, outside_mm3, limit);
    Raise(std::move(w));
  }

  void CheckOrder(const Event& e) {
    for (std::size_t i = 0; i < plan.steps.size(); ++i) {
      const PlanStep& step = plan.steps[i];
      if (!detail::IsStepAction(step, e)) continue;
      std::vector<std::string> missing_ids, missing_titles;
      for (const std::string& req : step.requires_steps) {
        const int j = plan.FindStep(req);
        if (DoneAt(j) <= e.time_s) continue;
        missing_ids.push_back(req);
        missing_titles.push_back("'" + plan.steps[static_cast<std::size_t>(j)].title + "'");
      }
      if (missing_ids.empty()) continue;
      LiveWarning w = Base("order", step.id, e);
      std::string titles, ids;
      for (std::size_t k = 0; k < missing_ids.size(); ++k) {
        titles += (k ? " and " : "") + missing_titles[k];
        ids += (k ? "," : "") + missing_ids[k];
      }
      w.message = fmt::format("{} by the {} belongs to '{}', but {} {} not complete", e.kind,
                              e.tool, step.title, titles, missing_ids.size() > 1 ? "are" : "is");
      w.detail = fmt::format("type=order subject={} event={} missing={}", step.id, e.kind, ids);
      Raise(std::move(w));
    }
  }

  void ObserveFrame(const State& s) {
    FrameSight sight(model, s, &blockers);
    for (std::size_t i = 0; i < plan.steps.size(); ++i) {
      for (std::size_t j = 0; j < plan.steps[i].complete.size(); ++j) {
        const Criterion& c = plan.steps[i].complete[j];
        const int b = c.kind == Criterion::Kind::kBoneRemoved ? model.FindBone(c.bone) : -1;
        const double removed = b >= 0 && b < static_cast<int>(s.bones.size())
                                   ? s.bones[static_cast<std::size_t>(b)].removed_volume_mm3
                                   : 0.0;
        const bool seen = c.kind == Criterion::Kind::kInView && !criteria[i][j].met() &&
                          sight.SeesLandmark(model.FindLandmark(c.landmark));
        criteria[i][j].OnFrame(s.time_s, seen, removed);
      }
    }
  }

  void CheckStructures(const State& s) {
    detail::SlotForces force{};
    for (int k = 0; k < kToolSlots; ++k)
      if (!ToolIn(s, k).empty())
        force[static_cast<std::size_t>(k)] = s.tools[static_cast<std::size_t>(k)].force_n.norm();
    for (std::size_t i = 0; i < structures.size(); ++i) {
      const ProtectedStructure& p = plan.protected_structures[i];
      const ProtectedTouch touch = detail::TouchOf(model, p, s.tool_contacts, force);
      structures[i].OnFrame(s.time_s, touch);
      if (!touch.touching) continue;
      LiveWarning w;
      w.subject = p.name;
      w.tool = ToolIn(s, touch.slot);
      w.body = p.body;
      w.step = s.step;
      w.time_s = s.time_s;
      w.position_mm = touch.position_mm;
      LiveWarning contact = w;
      contact.type = "contact";
      contact.message = fmt::format("the {} touches the protected {}", w.tool, p.name);
      contact.detail = fmt::format("type=contact subject={} force_n={:.3f}", p.name, touch.force_n);
      Raise(std::move(contact));
      if (touch.force_n > p.max_force_n) {
        LiveWarning over = w;
        over.type = "force";
        over.message = fmt::format("{:.1f} N on the {} with the {}, above the {:g} N limit",
                                   touch.force_n, p.name, w.tool, p.max_force_n);
        over.detail = fmt::format("type=force subject={} force_n={:.3f} limit_n={:g}", p.name,
                                  touch.force_n, p.max_force_n);
        Raise(std::move(over));
      }
      if (!contact_time_warned[i] && structures[i].contact_s() > p.max_contact_time_s) {
        contact_time_warned[i] = 1;
        LiveWarning long_contact = w;
        long_contact.type = "contact_time";
        long_contact.message =
            fmt::format("{:.1f} s in contact with the {} in total, more than the {:g} s allowed",
                        structures[i].contact_s(), p.name, p.max_contact_time_s);
        long_contact.detail =
            fmt::format("type=contact_time subject={} contact_s={:.3f} limit_s={:g}", p.name,
                        structures[i].contact_s(), p.max_contact_time_s);
        Raise(std::move(long_contact));
      }
    }
  }
};

LiveEvaluator::LiveEvaluator(const Plan& plan, const Model& model, const LiveOptions& options)
    : impl_(std::make_unique<Impl>(plan, model, options)) {}

LiveEvaluator::~LiveEvaluator() = default;

std::vector<LiveWarning> LiveEvaluator::Observe(const State& state, bool frame) {
  Impl& m = *impl_;
  m.due.clear();
  // 1. What the step did to the plan's progress: its events, then the frame.
  std::vector<const Event*> events;
  for (const Event& e : state.events) {
    if (e.kind == kWarningEventKind) continue;
    events.push_back(&e);
    for (auto& step : m.criteria)
      for (CriterionProgress& c : step) c.OnEvent(m.model, e, m.events_seen);
    ++m.events_seen;
  }
  if (frame) m.ObserveFrame(state);
  // 2. What needs the trainee's attention: the events, in order, then the frame's contacts.
  for (const Event* e : events) {
    m.CheckDamage(*e);
    m.CheckOutside(*e);
    m.CheckOrder(*e);
  }
  if (frame) m.CheckStructures(state);
  return m.due;
}

bool LiveEvaluator::StepComplete(int i) const { return !std::isnan(impl_->DoneAt(i)); }

const std::map<std::string, int>& LiveEvaluator::given() const { return impl_->given; }

const std::map<std::string, int>& LiveEvaluator::suppressed() const { return impl_->suppressed; }

std::vector<LiveWarning> ReplayLive(const Plan& plan, const Model& model,
                                    const std::string& run_path, const LiveOptions& options) {
  io::RunReader reader(run_path);
  LiveEvaluator live(plan, model, options);
  std::vector<LiveWarning> all;
  State s;
  for (std::int64_t k = 0; k < reader.frame_count(); ++k) {
    reader.ReadFrame(k, s);
    for (LiveWarning& w : live.Observe(s, true)) all.push_back(std::move(w));
  }
  return all;
}

}  // namespace arthrosim::scoring
