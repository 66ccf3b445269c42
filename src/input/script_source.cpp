// Evaluates a script Timeline at a step time: pure function of (timeline, t).
#include "arthrosim/input/script_source.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "arthrosim/core/error.h"
#include "arthrosim/core/input_file.h"
#include "arthrosim/core/scope_aim.h"
#include "arthrosim/core/units.h"
#include "script_timeline.h"

namespace arthrosim::input {
namespace {

/// Index of the last action with t0 <= t, or -1.
template <class A>
int ActionAt(const std::vector<A>& v, double t) {
  auto it = std::upper_bound(v.begin(), v.end(), t, [](double x, const A& a) { return x < a.t0; });
  return static_cast<int>(it - v.begin()) - 1;
}

struct HandSample {
  HandState state;
  std::uint8_t press = 0;
};

HandSample EvaluateHand(const Timeline& tl, int slot, double t) {
  const std::vector<HandAction>& v = tl.hands[slot];
  HandSample out;
  const int i = ActionAt(v, t);
  if (i < 0) return out;
  const HandAction& a = v[i];
  if (t >= a.t1) {
    out.state = a.end;
    return out;
  }
  const double s = (t - a.t0) / (a.t1 - a.t0);
  out.state = a.start;
  switch (a.op) {
    case HandOp::kPick:
    case HandOp::kMove:
    case HandOp::kPush:
    case HandOp::kWithdraw: {
      const Vec3& p0 = a.start.position_mm;
      const Vec3& p1 = a.end.position_mm;
      Vec3 p;
      if (a.overshoot_mm.squaredNorm() > 0) {
        // Overshoot: reach past the target in the first 3/4, come back in the last 1/4.
        const Vec3 far = p1 + a.overshoot_mm;
        p = s < 0.75 ? Lerp(p0, far, Ease(a.easing, s / 0.75))
                     : Lerp(far, p1, Ease(a.easing, (s - 0.75) / 0.25));
      } else {
        p = Lerp(p0, p1, Ease(a.easing, s));
      }
      out.state.position_mm = p;
      if (a.op == HandOp::kMove) {
        const Vec3 axis = p - a.start.portal_mm;
        if (a.aim_portal) {
          out.state.orientation =
              axis.norm() > 1e-6 ? AimAlong(axis, a.roll_rad) : a.start.orientation;
        } else {
          out.state.orientation = Slerp(a.start.orientation, a.end.orientation, Ease(a.easing, s));
        }
      }
      break;
    }
    case HandOp::kJaw:
      out.state.jaw = Lerp(a.start.jaw, a.end.jaw, Ease(a.easing, s));
      break;
    case HandOp::kPress:
      out.press = a.press_bits;
      break;
    default:
      break;
  }
  return out;
}

/// Buttons down at any time in (t - dt, t].
std::uint8_t LatchedButtons(const Timeline& tl, int slot, double t) {
  const std::vector<HandAction>& v = tl.hands[slot];
  const double lo = t - tl.dt_s;
  std::uint8_t bits = 0;
  const HandSample now = EvaluateHand(tl, slot, t);
  bits |= now.state.held | now.press;
  const int k = ActionAt(v, lo);
  if (k >= 0) bits |= lo < v[k].t1 ? v[k].start.held : v[k].end.held;
  for (const HandAction& a : v) {
    if (a.t0 > t) break;
    if (a.t0 > lo) bits |= a.start.held | a.end.held;
    if (a.op == HandOp::kPress && a.t1 > lo) bits |= a.press_bits;
  }
  return bits;
}

Vec3 TremorAt(const Tremor& tr, double t) {
  if (tr.amplitude_mm == 0) return Vec3::Zero();
  static constexpr double kWeight[3] = {0.5, 0.3, 0.2};
  Vec3 d;
  for (int ax = 0; ax < 3; ++ax) {
    double sum = 0;
    for (int c = 0; c < 3; ++c) {
      sum += kWeight[c] * std::sin(2 * units::kPi * tr.freq_hz[ax][c] * t + tr.phase[ax][c]);
    }
    d[ax] = tr.amplitude_mm * sum;
  }
  return d;
}

/// The look point; a followed hand's tip includes its force-push excursion (not its tremor).
Vec3 LookPointAt(const Timeline& tl, const LookTarget& lt, double t,
                 const std::array<Vec3, kToolSlots>& push_offset) {
  return lt.slot < 0 ? lt.point_mm
                     : Vec3(EvaluateHand(tl, lt.slot, t).state.position_mm + push_offset[lt.slot]);
}

/// Moves that absorb a force push's excursion (blend it out over their duration).
bool AbsorbsPush(const HandAction& a) {
  return a.op == HandOp::kPick || a.op == HandOp::kMove || a.op == HandOp::kWithdraw ||
         (a.op == HandOp::kPush && !a.force.enabled);
}

}  // namespace

double ProfileForceAt(const ForceProfile& p, double u) {
  if (p.t_s.empty()) return 0;
  if (u <= p.t_s.front()) return p.force_n.front();
  if (u >= p.t_s.back()) return p.force_n.back();
  const auto it = std::upper_bound(p.t_s.begin(), p.t_s.end(), u);
  const std::size_t k = static_cast<std::size_t>(it - p.t_s.begin());
  const double w = (u - p.t_s[k - 1]) / (p.t_s[k] - p.t_s[k - 1]);
  return Lerp(p.force_n[k - 1], p.force_n[k], w);
}

Vec3 HandTipAt(const Timeline& tl, int slot, double t) {
  return EvaluateHand(tl, slot, t).state.position_mm;
}

ScriptSource::ScriptSource(const std::string& yaml_text, const std::string& file,
                           const Model& model, const ScriptOptions& options)
    : timeline_(std::make_unique<Timeline>(BuildTimeline(yaml_text, file, model, options))) {}

ScriptSource::~ScriptSource() = default;

std::unique_ptr<ScriptSource> ScriptSource::Open(const std::string& path, const Model& model,
                                                 const ScriptOptions& options) {
  return std::make_unique<ScriptSource>(ReadInputFile(path, "", "cannot open script file"), path,
                                        model, options);
}

bool ScriptSource::Finished(double t_s) const { return t_s > timeline_->end_time_s; }
double ScriptSource::end_time_s() const { return timeline_->end_time_s; }
const std::string& ScriptSource::name() const { return timeline_->name; }

void ScriptSource::Feedback(const FeedbackFrame& feedback) { feedback_ = feedback; }

void ScriptSource::SaveControllers(State* state) const { state->script_push = push_; }

void ScriptSource::RestoreControllers(const State& state) {
  push_ = state.script_push;
  for (int s = 0; s < kToolSlots; ++s) feedback_.force_n[s] = state.tools[s].force_n;
}

// The excursion of a force push along the tool axis: integrated while the push runs, then held
// through non-moving actions and blended out (by its easing) over the next move, depth push or
// withdraw, so the script's written positions hold again afterwards.
Vec3 ScriptSource::PushOffset(int slot, double t) {
  const std::vector<HandAction>& v = timeline_->hands[slot];
  ScriptPushState& ps = push_[slot];
  const int i = ActionAt(v, t);
  // Carry of the previous force push at time t (zero once a later move has absorbed it).
  Vec3 carry = Vec3::Zero();
  if (ps.action >= 0 && i >= ps.action) {
    const HandAction& p = v[ps.action];
    carry = ps.depth_mm * (p.start.orientation * Vec3::UnitZ());
    int j = ps.action + 1;
    while (j < static_cast<int>(v.size()) && !AbsorbsPush(v[j])) ++j;
    if (i > j) {
      carry = Vec3::Zero();
    } else if (i == j) {
      const HandAction& m = v[j];
      const double u = m.t1 > m.t0 ? std::clamp((t - m.t0) / (m.t1 - m.t0), 0.0, 1.0) : 1.0;
      carry *= 1.0 - Ease(m.easing, u);
    }
  }
  if (i < 0 || !v[i].force.enabled || t >= v[i].t1) return carry;

  const HandAction& a = v[i];
  const Vec3 axis = a.start.orientation * Vec3::UnitZ();
  if (ps.action != i) {  // a new push starts where the previous excursion left the tool
    ps.depth_mm = std::clamp(carry.dot(axis), 0.0, a.force.max_depth_mm);
    ps.t_prev_s = a.t0;
    ps.action = i;
  }
  if (t > ps.t_prev_s) {
    // Admittance: depth rate = gain * (target - pressing force). The tool feels the tissue's
    // reaction, so the force it presses with is -F . axis.
    const double pressing = -feedback_.force_n[slot].dot(axis);
    const double error = ProfileForceAt(a.force, t - a.t0) - pressing;
    const double rate = std::clamp(a.force.gain_mm_per_s_n * error, -a.force.max_speed_mm_s,
                                   a.force.max_speed_mm_s);
    ps.depth_mm = std::clamp(ps.depth_mm + rate * (t - ps.t_prev_s), 0.0, a.force.max_depth_mm);
    ps.t_prev_s = t;
  }
  return ps.depth_mm * axis;
}

void ScriptSource::Frame(std::int64_t /*step*/, double t, InputFrame* out) {
  const Timeline& tl = *timeline_;
  std::array<Vec3, kToolSlots> offset;
  for (int s = 0; s < kToolSlots; ++s) {
    const HandSample h = EvaluateHand(tl, s, t);
    ToolCommand& tc = out->tools[s];
    tc.instrument = h.state.instrument;
    offset[s] = PushOffset(s, t);
    tc.pose.position_mm = h.state.position_mm + offset[s];
    if (h.state.instrument >= 0) tc.pose.position_mm += TremorAt(tl.tremor[s], t);
    tc.pose.orientation = h.state.orientation;
    tc.jaw = h.state.jaw;
    tc.buttons = LatchedButtons(tl, s, t);
  }
  CameraCommand& cam = out->camera;
  const int i = ActionAt(tl.camera, t);
  if (i < 0) {
    cam = CameraCommand{};
    cam.pose.position_mm = tl.camera_initial.position_mm;
    cam.pose.orientation = tl.camera_initial_orientation;
    return;
  }
  const CameraAction& a = tl.camera[i];
  const double u = a.blend_s > 0 ? std::min(1.0, (t - a.t0) / a.blend_s) : 1.0;
  const double e = Ease(a.easing, u);
  const Vec3 eye = Lerp(a.start.position_mm, a.end.position_mm, e);
  const Vec3 look =
      Lerp(LookPointAt(tl, a.start.look, t, offset), LookPointAt(tl, a.end.look, t, offset), e);
  cam.pose.position_mm = eye;
  // the oblique view (at zero lens roll) looks at the target; lens_roll then sweeps it about
  // the shaft as turning the light post does
  cam.pose.orientation = AimScopeView(eye, look, tl.camera_lens_angle_rad);
  cam.lens_roll_rad = Lerp(a.start.lens_roll_rad, a.end.lens_roll_rad, e);
  cam.head_roll_rad = Lerp(a.start.head_roll_rad, a.end.head_roll_rad, e);
}

}  // namespace arthrosim::input
