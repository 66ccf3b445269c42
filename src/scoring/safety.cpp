// Safety: contacts with protected structures (time, peak force, time above the force limit),
// damage events on them, tissue and bone removed outside every step's target.
#include <fmt/core.h>

#include <algorithm>
#include <cmath>

#include "progress.h"
#include "score_internal.h"

namespace arthrosim::scoring::detail {
namespace {

// |force| on the instrument of each slot at frame k (0 for an empty slot).
SlotForces FrameSlotForces(const RunData& run, std::int64_t k) {
  SlotForces f{};
  for (int slot = 0; slot < kToolSlots; ++slot) {
    for (const InstrumentSeries& s : run.instruments) {
      if (s.slot[k] != slot) continue;
      f[static_cast<std::size_t>(slot)] = s.force_n[k];
      break;
    }
  }
  return f;
}

void ProtectedContacts(const ProtectedStructure& p, const RunData& run, ScoreReport* report) {
  ProtectedProgress progress(p);
  for (std::int64_t k = 0; k < run.frames(); ++k)
    progress.OnFrame(run.time_s[k],
                     TouchOf(run.model, p, run.contacts[k], FrameSlotForces(run, k)));
  const double contact_s = progress.contact_s(), over_s = progress.over_force_s();
  const double peak_n = progress.peak_n(), first_over = progress.first_over_s();
  const std::string base = "safety." + p.name;
  AddMetric(report, base + ".contact_time", "safety", fmt::format("time touching {}", p.name), "s",
            contact_s, std::nullopt, p.max_contact_time_s);
  AddMetric(report, base + ".peak_force", "safety",
            fmt::format("peak instrument force while touching {}", p.name), "N", peak_n,
            std::nullopt, p.max_force_n);
  AddMetric(report, base + ".time_over_force", "safety",
            fmt::format("time above {:g} N on {}", p.max_force_n, p.name), "s", over_s,
            std::nullopt, 0.0, p.critical);
  if (!std::isnan(first_over)) {
    const std::string text =
        fmt::format("force above {:g} N on {} at {:.2f} s", p.max_force_n, p.name, first_over);
    report->violations.push_back({"force", first_over, "", text});
    if (p.critical) report->critical_errors.push_back(text);
  }
}

// Damage events on a protected structure less than this apart are one episode: one violation
// (and one critical error) an instructor reads, not one per step of a shaver pass. Live feedback
// warns once per episode too (LiveOptions::quiet_s has the same value).
constexpr double kDamageEpisodeGapS = 1.0;

struct DamageEpisode {
  const Event* first = nullptr;
  double last_s = 0;
  int events = 0;
};

void ReportDamageEpisode(const ProtectedStructure& p, const DamageEpisode& ep,
                         ScoreReport* report) {
  const Event& e = *ep.first;
  std::string text =
      fmt::format("'{}' by {} on protected {} at {:.2f} s", e.kind, e.tool, p.name, e.time_s);
  if (ep.events > 1) text += fmt::format(" ({} events until {:.2f} s)", ep.events, ep.last_s);
  report->violations.push_back({"damage", e.time_s, "", text});
  if (p.zero_damage) report->critical_errors.push_back(text);
}

void ProtectedDamage(const ProtectedStructure& p, const RunData& run, ScoreReport* report) {
  int damage = 0;
  DamageEpisode episode;
  for (const Event& e : run.events) {
    if (!DamagesProtected(run.model, p, e)) continue;
    ++damage;
    if (episode.first != nullptr && e.time_s - episode.last_s < kDamageEpisodeGapS) {
      episode.last_s = e.time_s;
      ++episode.events;
      continue;
    }
    if (episode.first != nullptr) ReportDamageEpisode(p, episode, report);
    episode = {&e, e.time_s, 1};
  }
  if (episode.first != nullptr) ReportDamageEpisode(p, episode, report);
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
    if (RemovedOutsideTarget(plan, run.model, e, &volume)) outside += volume;
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
