// Hook: a contact-only instrument (the paper leaves it to the basic collision response). A thread
// in the bend of the barb is snagged by a sliding spring at the bend (tag "hook"): the hook pulls
// the thread along while the thread runs through the bend (friction operations.hook.friction,
// 0 by default), so drawing the hook back pulls a loop of the limb out. The thread slips out
// through the mouth when the hook is turned so that the limbs' pull points out of the bend, or
// when it is torn farther than dist_limit from the bend. Events `hook_catch` and `hook_release`.
#include <cmath>
#include <cstdio>

#include "arthrosim/core/instrument_geometry.h"
#include "arthrosim/core/units.h"
#include "arthrosim/physics/constraints.h"
#include "suture_ops.h"

namespace arthrosim::instruments {
namespace {

constexpr const char* kHookTag = "hook";
/// The limbs' directions are taken to the thread points this many nodes along each way.
constexpr double kLimbNodes = 3.0;
/// Below this length of the sum of the two limb directions (a bend opened wider than about
/// 150 deg: the thread nearly straight across the seat) the pull has no direction to judge.
constexpr double kMinPull = 0.5;
/// The seat must move at least this far toward the mouth in a step (mm) to snag a thread.
constexpr double kMinDrawMm = 1e-3;

// The seat of the bend in the tool frame (where a thread touching both the shaft and the barb
// lies: on the bisector, as far from both as their radius plus the thread's) and the unit
// direction out of the bend's mouth.
struct Bend {
  Vec3 seat = Vec3::Zero();
  Vec3 mouth = Vec3::UnitZ();
};

Bend HookBend(const InstrumentModel& instrument, double thread_radius_mm) {
  const InstrumentParts parts = InstrumentPartsLocal(instrument, 0.0);
  Vec3 shaft_back = Vec3::Zero(), corner = Vec3::Zero(), barb_end = Vec3::Zero();
  double radius_mm = 0;
  for (int i = 0; i < parts.count; ++i) {
    const InstrumentPart& p = parts.parts[static_cast<std::size_t>(i)];
    if (p.part != ToolPart::kHook) continue;
    radius_mm = p.radius_mm;
    if (p.side == 1) {
      shaft_back = p.v[0];
      corner = p.v[1];
    } else {
      barb_end = p.v[1];
    }
  }
  const Vec3 along_shaft = (shaft_back - corner).normalized();
  const Vec3 along_barb = (barb_end - corner).normalized();
  Bend bend;
  bend.mouth = (along_shaft + along_barb).normalized();
  const double half_angle = 0.5 * std::acos(std::clamp(along_shaft.dot(along_barb), -1.0, 1.0));
  const double depth_mm = std::min((radius_mm + thread_radius_mm) / std::sin(half_angle),
                                   0.9 * (barb_end - corner).norm());
  bend.seat = corner + depth_mm * bend.mouth;
  return bend;
}

double ThreadRadiusMm(const Model& model) {
  double r = 0;
  for (const ThreadModel& t : model.threads) r = std::max(r, 0.5 * t.diameter_mm);
  return r;
}

// The point at arc parameter s of a thread (clamped to the chain).
Vec3 ThreadPointAt(const ThreadState& t, double s) {
  const int last = static_cast<int>(t.x.cols()) - 1;
  s = std::clamp(s, 0.0, static_cast<double>(last));
  const int i = std::min(static_cast<int>(std::floor(s)), last - 1);
  const double f = s - i;
  return (1 - f) * t.x.col(i) + f * t.x.col(i + 1);
}

// Angle (deg) between the direction in which the thread's two limbs pull on the point at arc
// parameter s (the sum of the unit vectors along each limb, equal tension on both sides of a
// frictionless bend) and the direction into the bend; 0 while the thread runs nearly straight
// across the seat (no pull to judge).
double PullAngleDeg(const ThreadState& t, double s, const Vec3& mouth) {
  const Vec3 p = ThreadPointAt(t, s);
  Vec3 pull = Vec3::Zero();
  for (const double q : {s - kLimbNodes, s + kLimbNodes}) {
    const Vec3 d = ThreadPointAt(t, q) - p;
    if (d.norm() > 1e-9) pull += d.normalized();
  }
  if (pull.norm() < kMinPull) return 0;
  return std::acos(std::clamp(pull.normalized().dot(-mouth), -1.0, 1.0)) * 180.0 / units::kPi;
}

// Releases the slot's hold if the hook was turned away or the thread slipped beyond the limit;
// true if the thread is (still) held afterwards.
bool KeepOrRelease(const Model& model, int slot, const Bend& bend, State* state) {
  const HookOptions& opt = model.operations.hook;
  const std::int64_t id = ToolConstraint(*state, slot, kHookTag);
  if (id < 0) return false;
  const SpringConstraint* c = physics::FindConstraint(*state, id);
  const Pose& pose = state->tools[static_cast<std::size_t>(slot)].pose;
  const Vec3 seat = pose.Apply(bend.seat), mouth = pose.orientation * bend.mouth;
  const Vec3 at = physics::EndPosition(*state, c->b);
  const double stretch_mm = (at - seat).norm();
  const double angle_deg = PullAngleDeg(state->threads[static_cast<std::size_t>(c->b.index)],
                                        physics::ThreadEndParameter(c->b), mouth);
  const char* reason = stretch_mm > opt.dist_limit_mm      ? "distance"
                       : angle_deg > opt.release_angle_deg ? "turned"
                                                           : nullptr;
  if (reason == nullptr) return true;
  const std::string thread = model.threads[static_cast<std::size_t>(c->b.index)].name;
  physics::RemoveConstraint(state, id);
  char detail[160];
  std::snprintf(detail, sizeof detail, "constraint=%lld reason=%s stretch_mm=%.3f angle_deg=%.1f",
                static_cast<long long>(id), reason, stretch_mm, angle_deg);
  RecordEvent(model, slot, "hook_release", thread, detail, at, state);
  return false;
}

// Nearest point of a live thread segment to p within reach: thread, arc parameter, distance.
struct ThreadPoint {
  int thread = -1;
  double s = 0;
  double distance_mm = 0;
  Vec3 point_mm = Vec3::Zero();
};

ThreadPoint NearestThreadPoint(const State& state, const Vec3& p, double reach_mm) {
  ThreadPoint best;
  best.distance_mm = reach_mm;
  for (std::size_t t = 0; t < state.threads.size(); ++t) {
    const ThreadState& th = state.threads[t];
    const auto alive = [&](int n) {
      return th.node_alive.empty() || th.node_alive[static_cast<std::size_t>(n)] != 0;
    };
    for (int n = 0; n + 1 < th.x.cols(); ++n) {
      if (!alive(n) || !alive(n + 1)) continue;
      const Vec3 a = th.x.col(n), ab = th.x.col(n + 1) - a;
      const double len2 = ab.squaredNorm();
      const double f = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
      const Vec3 q = a + f * ab;
      const double d = (q - p).norm();
      if (d < best.distance_mm) {  // strict: ties keep the lower thread and segment
        best = ThreadPoint{static_cast<int>(t), n + f, d, q};
      }
    }
  }
  return best;
}

// Snags the thread nearest the seat while the hook is drawn toward its mouth (the thread goes
// into the bend; a hook standing still or pushed forward never snags, so a thread that just
// slipped out through the mouth is not caught again).
void Catch(const Model& model, int slot, const StepContext& context, const Bend& bend,
           State* state) {
  const HookOptions& opt = model.operations.hook;
  const ToolState& tool = state->tools[static_cast<std::size_t>(slot)];
  const Vec3 seat = tool.pose.Apply(bend.seat), mouth = tool.pose.orientation * bend.mouth;
  if (context.prev_tools == nullptr) return;
  const ToolState& prev = (*context.prev_tools)[static_cast<std::size_t>(slot)];
  if (prev.instrument != tool.instrument) return;
  if (!((seat - prev.pose.Apply(bend.seat)).dot(mouth) > kMinDrawMm)) return;
  const ThreadPoint hit = NearestThreadPoint(*state, seat, opt.catch_reach_mm);
  if (hit.thread < 0) return;
  SpringConstraint c;
  c.tag = kHookTag;
  c.a.kind = ConstraintEnd::Kind::kTool;
  c.a.index = slot;
  c.a.offset_mm = bend.seat;
  c.b = physics::ThreadPointEnd(hit.thread, hit.s);
  c.stiffness_n_per_mm = opt.stiffness_n_per_mm;
  c.slide_friction_n = opt.friction_n;
  const std::int64_t id = physics::AddConstraint(state, std::move(c));
  char detail[128];
  std::snprintf(detail, sizeof detail, "constraint=%lld s=%.3f distance_mm=%.3f",
                static_cast<long long>(id), hit.s, hit.distance_mm);
  RecordEvent(model, slot, "hook_catch", model.threads[static_cast<std::size_t>(hit.thread)].name,
              detail, hit.point_mm, state);
}

}  // namespace

void HookOperation(const Model& model, int slot, const StepContext& context, State* state,
                   InstrumentScratch* /*scratch*/) {
  const ToolState& tool = state->tools[static_cast<std::size_t>(slot)];
  const Bend bend =
      HookBend(model.instruments[static_cast<std::size_t>(tool.instrument)], ThreadRadiusMm(model));
  if (KeepOrRelease(model, slot, bend, state)) return;
  if (ToolConstraint(*state, slot, kHookTag) < 0) Catch(model, slot, context, bend, state);
}

}  // namespace arthrosim::instruments
