#pragma once
// Live feedback (docs/metrics.md, "Live feedback"): the plan's checks evaluated while a session
// runs, on the same frames and events offline scoring reads from the run file, with the same
// code (the streaming checks of progress.h). Each step of the session is observed once; what
// deserves the trainee's attention comes back as warnings:
//   contact        an instrument touches a protected structure
//   contact_time   the total contact with a protected structure exceeds its allowance
//   force          the instrument force while touching a protected structure exceeds its limit
//   damage         a damage event (cut, burr, shave, ...) on a protected structure
//   order          an action of a step whose prerequisite steps are not complete
//   outside_target tissue or bone removed outside the planned targets beyond the plan's allowance
// Debounce: a warning (type and subject) is given when its condition is seen and was not seen
// during the preceding `quiet_s` of simulated time; a condition that persists or flickers is
// reported once. Deterministic: a function of the observed states only (no wall clock).
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/scoring/plan.h"

namespace arthrosim::scoring {

/// Event kind of a warning in the run file (`/events`).
inline constexpr const char* kWarningEventKind = "live_warning";

struct LiveWarning {
  std::string type;     ///< contact, contact_time, force, damage, order, outside_target
  std::string subject;  ///< protected structure name, step id (order) or "targets"
  std::string tool;     ///< instrument concerned ("" if none)
  std::string body;     ///< body concerned ("" if none)
  std::int64_t step = 0;
  double time_s = 0;                ///< simulated time the condition was seen, s
  Vec3 position_mm = Vec3::Zero();  ///< where (contact or event position; 0 if none)
  std::string message;              ///< the line sent to the trainee (OpenIGTLink STRING)
  std::string detail;               ///< key=value pairs of the run-file event
  /// The run-file event of this warning (kind kWarningEventKind).
  Event AsEvent() const;
};

struct LiveOptions {
  double quiet_s = 1.0;  ///< a warning repeats only after its condition was absent this long, s
};

class LiveEvaluator {
 public:
  /// Evaluates `plan` (loaded against `model`) on a session of `model`; both are copied.
  LiveEvaluator(const Plan& plan, const Model& model, const LiveOptions& options = {});
  ~LiveEvaluator();
  LiveEvaluator(const LiveEvaluator&) = delete;
  LiveEvaluator& operator=(const LiveEvaluator&) = delete;

  /// Observes the events of `state` (those recorded since the last call; warning events are
  /// ignored) and, when `frame` is true, the frame itself (contacts, forces, camera, bones) as
  /// the run file stores it. Call with the initial state (frame) first, then after every step,
  /// `frame` true exactly for the steps the run file keeps as frames. Returns the warnings due.
  std::vector<LiveWarning> Observe(const State& state, bool frame);

  /// Whether step `i` of the plan is complete as of the last observation.
  bool StepComplete(int i) const;
  /// Warnings given so far, by type.
  const std::map<std::string, int>& given() const;
  /// Conditions seen but not reported because of the debounce, by type.
  const std::map<std::string, int>& suppressed() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The warnings a session recorded in `run_path` would have given, from its frames and events
/// (ignoring the warning events it may hold). `model` must be the run's (LoadRunModel).
/// @throws InputError if the file is not a readable run.
std::vector<LiveWarning> ReplayLive(const Plan& plan, const Model& model,
                                    const std::string& run_path, const LiveOptions& options = {});

}  // namespace arthrosim::scoring
