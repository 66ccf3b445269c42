#pragma once
// The per-frame and per-event checks of a plan, written once as streaming state: offline
// scoring (steps.cpp, safety.cpp) feeds them every frame and event of a run file, the live
// evaluator (live.cpp) feeds them the frames and events of a session as it runs. Whatever either
// concludes about a step, a protected structure or a removal comes from this code.
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/scoring/plan.h"

namespace arthrosim::scoring::detail {

inline constexpr double kNoTime = std::numeric_limits<double>::quiet_NaN();

/// Whether the plan lets `tool` (instrument name, or "camera") act in `step`.
bool Allowed(const PlanStep& step, const std::string& tool);

/// Whether events of `kind` are the actions of `step`: its operation, an event its instruments
/// make as part of it (`also`), or one of its criteria's event kinds.
bool StepActsBy(const PlanStep& step, const std::string& kind);

/// Whether `e` is an action of `step` (StepActsBy) by an instrument the step allows. A step's
/// first such event is its first action.
bool IsStepAction(const PlanStep& step, const Event& e);

/// Why an event of the criterion's kind does not satisfy criterion `c` ("" if it does): wrong
/// body, too far from the landmark, outside the region, a detail value missing or out of range.
std::string EventMismatch(const Model& model, const Criterion& c, const Event& e);

/// Streaming state of one completion criterion of a step. `event`, `bone_removed` and `in_view`
/// criteria are met at the first event or frame that satisfies them; `distance` criteria are
/// judged on the last frame only and are never met here.
class CriterionProgress {
 public:
  CriterionProgress(const PlanStep& step, const Criterion& c) : step_(&step), c_(&c) {}

  /// One event, in run order; `index` is its position in the run's event list.
  void OnEvent(const Model& model, const Event& e, std::int64_t index);
  /// One frame at time t_s (s, increasing): whether the scope sees the criterion's landmark
  /// (FrameSight::SeesLandmark; in_view criteria) and the removed volume (mm3) of the
  /// criterion's bone (bone_removed criteria); each ignored by the other kinds.
  void OnFrame(double t_s, bool landmark_seen, double bone_removed_mm3);

  bool met() const { return !std::isnan(met_s_); }
  /// When the criterion was met, s (NaN if not yet).
  double met_s() const { return met_s_; }
  /// event: matching events counted so far.
  int matched() const { return matched_; }
  /// event: index of the completing event, else of the last match, else of the last event of
  /// the right kind and instrument (-1 if none).
  std::int64_t used_event() const { return used_ >= 0 ? used_ : last_candidate_; }
  /// event: whether any event of the right kind and instrument arrived.
  bool any_candidate() const { return last_candidate_ >= 0; }
  /// event: why the last candidate did not match ("" if it did).
  const std::string& last_mismatch() const { return last_why_; }
  /// event: why the last candidate that did not match failed ("" if every candidate matched).
  const std::string& last_rejection() const { return last_rejection_; }
  /// bone_removed: volume removed since the first frame, mm3, as of the last frame seen.
  double removed_mm3() const { return last_removed_ - first_removed_; }
  /// in_view: seconds the landmark was in view until the criterion was met.
  double seen_s() const { return seen_s_; }
  /// in_view: first frame time the landmark was in view (NaN if never before being met).
  double first_seen_s() const { return first_seen_s_; }

 private:
  const PlanStep* step_;
  const Criterion* c_;
  double met_s_ = kNoTime;
  int matched_ = 0;
  std::int64_t used_ = -1, last_candidate_ = -1;
  std::string last_why_, last_rejection_;
  bool have_frame_ = false;
  double first_removed_ = 0, last_removed_ = 0;
  double prev_t_s_ = 0, seen_s_ = 0, first_seen_s_ = kNoTime;
};

/// Force (N, |contact force| on the instrument) of each tool slot in one frame; 0 when empty.
using SlotForces = std::array<double, kToolSlots>;

/// What one frame's tool contacts say about a protected structure.
struct ProtectedTouch {
  bool touching = false;
  double force_n = 0;  ///< largest force of a slot touching it
  int slot = -1;       ///< the slot of that force (the first touching slot at equal force)
  Vec3 position_mm = Vec3::Zero();  ///< contact point of that slot
};

/// Whether the frame's contacts touch `p` (its body, inside its region box if it has one).
ProtectedTouch TouchOf(const Model& model, const ProtectedStructure& p,
                       const std::vector<ToolContact>& contacts, const SlotForces& force_n);

/// Streaming contact totals of one protected structure, frame by frame. The interval from the
/// previous frame counts for a touching frame (the first frame has none).
class ProtectedProgress {
 public:
  explicit ProtectedProgress(const ProtectedStructure& p) : p_(&p) {}
  /// One frame at time t_s (s, increasing).
  void OnFrame(double t_s, const ProtectedTouch& touch);

  double contact_s() const { return contact_s_; }
  double over_force_s() const { return over_s_; }
  double peak_n() const { return peak_n_; }
  /// Time of the first touching frame above the force limit (NaN if none).
  double first_over_s() const { return first_over_s_; }

 private:
  const ProtectedStructure* p_;
  bool have_frame_ = false;
  double prev_t_s_ = 0;
  double contact_s_ = 0, over_s_ = 0, peak_n_ = 0, first_over_s_ = kNoTime;
};

/// Whether `e` damages `p`: a damage event kind on its body (inside its region box if any).
bool DamagesProtected(const Model& model, const ProtectedStructure& p, const Event& e);

/// Whether `e` removed tissue or bone (a `volume_mm3` detail) outside every target of its kind of
/// removal: the target region of each step whose operation it is, and the place each completion
/// criterion expecting its kind names (body, landmark radius `within`, region box). If so
/// *volume_mm3 is that volume.
bool RemovedOutsideTarget(const Plan& plan, const Model& model, const Event& e, double* volume_mm3);

}  // namespace arthrosim::scoring::detail
