#pragma once
// A procedure plan (docs/plan-format.md): ordered steps with allowed instruments, a target, a
// completion criterion in measurable terms, prerequisites and a time budget; protected
// structures with force limits and zero-damage rules; motion thresholds; domain weights.
// Loaded strictly: every problem is an InputError naming file, line and field.
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "arthrosim/core/model.h"

namespace arthrosim::scoring {

/// A closed interval on a number; either end may be absent.
struct Range {
  std::optional<double> min;
  std::optional<double> max;
  bool Contains(double v) const { return (!min || v >= *min) && (!max || v <= *max); }
};

/// One completion criterion of a step. Kinds:
/// - kEvent: at least `count` events of kind `event` by an allowed instrument (on `body` if set,
///   within `within_mm` of `landmark` / inside `region`'s box if set) whose detail values lie in
///   their ranges (`detail`: key -> range, keys from the event's `key=value` detail).
/// - kBoneRemoved: the bone's removed volume (`/bones/<bone>/removed_volume`) has grown by at
///   least `min_volume_mm3` since the step started.
/// - kDistance: at the end of the run the centroid of `region`'s nodes lies within `max_mm` of
///   `landmark`, or of the box of region `to_region` (0 inside it): the tendon edge onto the
///   footprint, measured as the edge's distance to the footprint's bone bed.
/// - kInView: the camera saw `landmark` (inside the scope's field of view) for `min_time_s`.
struct Criterion {
  enum class Kind : std::uint8_t { kEvent, kBoneRemoved, kDistance, kInView };
  Kind kind = Kind::kEvent;
  std::string event;                    ///< kEvent: event kind
  std::string body;                     ///< kEvent: body/bone/thread name ("" = any)
  std::string landmark;                 ///< kEvent, kDistance, kInView
  std::string region;                   ///< kEvent (position inside its box), kDistance (its nodes)
  double within_mm = 0;                 ///< kEvent: 0 = no distance condition
  int count = 1;                        ///< kEvent
  std::map<std::string, Range> detail;  ///< kEvent: detail key -> allowed range
  std::string bone;                     ///< kBoneRemoved
  double min_volume_mm3 = 0;            ///< kBoneRemoved
  std::string to_region;  ///< kDistance: measured to this region's box instead of `landmark`
  double max_mm = 0;      ///< kDistance
  double min_time_s = 0;  ///< kInView
  int line = 0;           ///< line in the plan file (for messages)
};

/// Instrument name of the arthroscope in a step's instrument list (camera-only steps).
inline constexpr const char* kCameraName = "camera";

struct PlanStep {
  std::string id;
  std::string title;
  std::vector<std::string> instruments;  ///< instrument names allowed for this step
  std::string operation;                 ///< the event kind of the step's action ("" = none)
  /// Other event kinds this step's instruments make as part of its operation (the scorpion
  /// needle's tissue hold, `grasp`, while it passes a suture): the step's actions, not actions
  /// with a wrong instrument.
  std::vector<std::string> also_events;
  std::string target_landmark;              ///< "" if none
  std::string target_region;                ///< "" if none
  std::vector<Criterion> complete;          ///< all must hold
  std::vector<std::string> requires_steps;  ///< ids of steps that must be complete first
  double time_budget_s = 0;                 ///< max duration from first action to completion
  bool critical = false;                    ///< failing this step fails the session
};

/// A structure that must not be hurt.
struct ProtectedStructure {
  std::string name;
  std::string body;    ///< soft body / bone / thread name of the scenario
  std::string region;  ///< optional: only this region's box of the body counts
  /// optional: only this tissue of the bone counts (BoneModel::tissues, e.g. "cartilage"):
  /// damage events whose detail names it (`tissue=`), contacts nearest to its triangles
  std::string tissue;
  double max_force_n = 0;         ///< tool force limit while in contact, N
  double max_contact_time_s = 0;  ///< allowed total contact time, s (0 = none allowed)
  bool zero_damage = true;        ///< any damage event on it is a critical error
  bool critical = false;          ///< exceeding the force limit is a critical error
};

/// Thresholds of the motion metrics (docs/metrics.md).
struct MotionThresholds {
  double movement_speed_mm_s = 7.5;     ///< a movement starts when speed rises above this
  double idle_speed_mm_s = 5.0;         ///< inserted and slower than this = idle
  double max_horizon_deg = 15.0;        ///< camera horizon deviation counted above this
  double min_tip_in_view = 0.8;         ///< required share of working time with the tip in view
  double max_outside_volume_mm3 = 0.5;  ///< tissue+bone removed outside every step's target
  double max_idle_share = 0.5;          ///< idle time / inserted time above this fails
};

struct DomainWeights {
  double plan_adherence = 0.3;
  double efficiency = 0.2;
  double safety = 0.3;
  double repair_quality = 0.2;
};

struct Plan {
  std::string name;
  std::string path;
  std::string scenario;  ///< scenario name it is written for ("" = any)
  std::vector<PlanStep> steps;
  std::vector<ProtectedStructure> protected_structures;
  MotionThresholds motion;
  DomainWeights weights;
  double pass_score = 70;  ///< total below this fails
  /// Damage event kinds (cut, burr, ...) for zero-damage rules and wrong-instrument actions.
  std::vector<std::string> action_events;

  /// Index of the step with this id, or -1.
  int FindStep(const std::string& id) const;
};

/// Loads and validates a plan. If `model` is given, every instrument, body, landmark and region
/// name must exist in it. @throws InputError (file, line, field, what was expected).
Plan LoadPlan(const std::string& path, const Model* model = nullptr);
/// Same from text; `path` is used in messages.
Plan LoadPlanFromText(const std::string& text, const std::string& path,
                      const Model* model = nullptr);

}  // namespace arthrosim::scoring
