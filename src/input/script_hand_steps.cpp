// A hand's steps (pick, move, push, close/open, press/hold/release, wait, withdraw): one parser
// per step kind in a table; BuildHand walks the list, adds noise and dispatches through it.
#include <fmt/format.h>

#include <algorithm>
#include <string>
#include <vector>

#include "arthrosim/core/units.h"
#include "script_parser.h"

namespace arthrosim::input {
namespace {

/// What a step parser reads: the step's YAML and the hand just before the step.
struct StepInput {
  const Parser& ps;
  const YAML::Node& seq;     ///< the hand's whole list (a pick may aim at the next move)
  std::size_t index;         ///< this step's index in seq
  const YAML::Node& item;    ///< {op: body}
  const YAML::Node& body;    ///< the step's settings
  const std::string& field;  ///< e.g. "slot0[3].move": the prefix of every error's field
  const std::string& track;  ///< "slot0" or "slot1"
  const std::string& op;     ///< the step kind as written
  const HandState& cur;      ///< the hand when the step starts
  const NoiseCtx& noise;
  int slot;
};

/// Fills the action (a->op, a->end, easing...; a->start and a->end arrive as the current hand)
/// and returns its duration, s.
using StepParseFn = double (*)(const StepInput& in, HandAction* a);

/// Flags of a step kind.
enum StepFlags : unsigned {
  kNeedsInstrument = 1u << 0,  ///< fails unless the hand holds an instrument
  kScalarBody = 1u << 1,       ///< the body may be a bare number instead of a map
};

/// One step kind. Entries sharing an op are variants: the first whose `applies` accepts the
/// body parses it.
struct HandStepKind {
  const char* op;
  bool (*applies)(const YAML::Node& body);  ///< nullptr: any body
  std::vector<const char*> keys;            ///< allowed keys of a map body
  unsigned flags;
  StepParseFn parse;
  const char* conflict = nullptr;      ///< a key this variant rejects, before the key check...
  const char* conflict_why = nullptr;  ///< ...with this message
};

double ParseWait(const StepInput& in, HandAction* a) {
  a->op = HandOp::kWait;
  if (in.body.IsMap()) return in.ps.Positive(in.body, "duration", in.field, 0, true);
  const double duration = in.ps.Num(in.body, in.field);
  if (duration < 0) in.ps.Fail(in.body, in.field, "must be >= 0");
  return duration;
}

/// The instrument a pick names (must exist in the scenario).
int PickedInstrument(const StepInput& in) {
  const Parser& ps = in.ps;
  if (!in.body["instrument"]) ps.Fail(in.body, in.field + ".instrument", "required");
  const std::string name = ps.Str(in.body["instrument"], in.field + ".instrument");
  const int idx = ps.model_.FindInstrument(name);
  if (idx < 0) {
    std::string names;
    for (const InstrumentModel& im : ps.model_.instruments)
      names += (names.empty() ? "" : ", ") + im.name;
    ps.Fail(in.body["instrument"], in.field + ".instrument",
            fmt::format("unknown instrument '{}'; the scenario has: {}", name,
                        names.empty() ? "(none)" : names));
  }
  return idx;
}

/// The portal a pick enters through: its own `portal`, else the instrument's, mm.
Vec3 PickPortal(const StepInput& in, int instrument) {
  const Parser& ps = in.ps;
  if (in.body["portal"]) return ps.Portal(in.body["portal"], in.field + ".portal");
  const InstrumentModel& im = ps.model_.instruments[instrument];
  const int p = ps.model_.FindPortal(im.portal);
  if (p < 0)
    ps.Fail(in.body["instrument"], in.field + ".instrument",
            fmt::format("instrument '{}' names portal '{}', which the scenario lacks", im.name,
                        im.portal));
  return ps.model_.portals[p].position_mm;
}

/// Where a pick aims: its own `toward`, else the target of the hand's next move, mm.
Vec3 PickToward(const StepInput& in) {
  const Parser& ps = in.ps;
  if (in.body["toward"]) return ps.Location(in.body["toward"], in.field + ".toward", false);
  for (std::size_t j = in.index + 1; j < in.seq.size(); ++j) {
    const YAML::Node nx = in.seq[j];
    if (!nx.IsMap() || nx.size() != 1 || !nx.begin()->first.IsScalar() ||
        nx.begin()->first.Scalar() != "move") {
      continue;
    }
    const YAML::Node mb = nx.begin()->second;
    const std::string mf = fmt::format("{}[{}].move", in.track, j);
    if (!mb.IsMap() || !mb["to"]) continue;
    Vec3 toward = ps.Location(mb["to"], mf + ".to", false);
    if (mb["offset"]) toward += ps.Vec(mb["offset"], mf + ".offset");
    return toward;
  }
  ps.Fail(in.body, in.field + ".toward", "required when no move follows the pick");
}

double ParsePick(const StepInput& in, HandAction* a) {
  const Parser& ps = in.ps;
  if (in.cur.instrument >= 0) {
    ps.Fail(in.item, in.field,
            fmt::format("{} already holds '{}': withdraw it first", in.track,
                        ps.model_.instruments[in.cur.instrument].name));
  }
  const int idx = PickedInstrument(in);
  const Vec3 portal = PickPortal(in, idx);
  const Vec3 toward = PickToward(in);
  if ((toward - portal).norm() < 1e-9)
    ps.Fail(in.body, in.field + ".toward", "coincides with the portal");
  a->op = HandOp::kPick;
  a->easing = ps.Ease(in.body, in.field, Easing::kMinimumJerk);
  const double depth = ps.Positive(in.body, "depth", in.field, 10.0, true);
  const double duration = ps.Positive(in.body, "duration", in.field, 1.0, true);
  const Vec3 dir = (toward - portal).normalized();
  a->start.instrument = idx;
  a->start.portal_mm = portal;
  a->start.position_mm = portal;
  a->start.orientation = AimAlong(dir, ps.Num(in.body, "roll", in.field, 0) * units::kDegToRad);
  a->start.jaw = 0;
  a->end = a->start;
  a->end.position_mm = portal + depth * dir;
  return duration;
}

double ParseMove(const StepInput& in, HandAction* a) {
  const Parser& ps = in.ps;
  const HandState& cur = in.cur;
  if (!in.body["to"]) ps.Fail(in.body, in.field + ".to", "required");
  Vec3 target = ps.Location(in.body["to"], in.field + ".to", false);
  if (in.body["offset"]) target += ps.Vec(in.body["offset"], in.field + ".offset");
  const double standoff = ps.Positive(in.body, "standoff", in.field, 0, true);
  if (standoff > 0) target -= standoff * (target - cur.portal_mm).normalized();
  a->op = HandOp::kMove;
  a->easing = ps.Ease(in.body, in.field, Easing::kMinimumJerk);
  const double duration = ps.Positive(in.body, "duration", in.field, 1.0, true);
  a->roll_rad = ps.Num(in.body, "roll", in.field, 0) * units::kDegToRad;
  a->end.position_mm = target;
  const YAML::Node aim = in.body["aim"];
  if (!aim || (aim.IsScalar() && aim.Scalar() == "portal")) {
    a->aim_portal = true;
    if ((target - cur.portal_mm).norm() < 1e-9)
      ps.Fail(in.body["to"], in.field + ".to", "target coincides with the portal");
    a->end.orientation = AimAlong(target - cur.portal_mm, a->roll_rad);
  } else {
    const Vec3 d = ps.Vec(aim, in.field + ".aim");
    if (d.norm() < 1e-12) ps.Fail(aim, in.field + ".aim", "direction must be non-zero");
    a->end.orientation = AimAlong(d, a->roll_rad);
  }
  const NoiseCtx& noise = in.noise;
  if (noise.scale > 0 && noise.p.overshoot > 0) {
    const double u = NoiseUniform(noise.seed, in.slot, static_cast<int>(in.index), kOvershoot);
    a->overshoot_mm = noise.p.overshoot * noise.scale * (0.5 + u) * (target - cur.position_mm);
  }
  return duration;
}

/// The `force` of a push (a number, with an optional `ramp`, or [[t, N], ...] keyframes) and
/// the admittance parameters; returns the action's duration, s.
double ParseForceProfile(const Parser& ps, const YAML::Node& body, const std::string& field,
                         ForceProfile* out) {
  const YAML::Node f = body["force"];
  const std::string ff = field + ".force";
  out->enabled = true;
  double duration = 0;
  if (f.IsSequence()) {
    if (body["ramp"]) ps.Fail(body["ramp"], field + ".ramp", "ramp needs a constant force");
    if (f.size() == 0) ps.Fail(f, ff, "expected a number or a list of [t, N] keyframes");
    for (std::size_t k = 0; k < f.size(); ++k) {
      const std::string kf = fmt::format("{}[{}]", ff, k);
      if (!f[k].IsSequence() || f[k].size() != 2) ps.Fail(f[k], kf, "expected [t, N]");
      const double t = ps.Num(f[k][0], kf);
      const double n = ps.Num(f[k][1], kf);
      if (t < 0) ps.Fail(f[k][0], kf, "keyframe time must be >= 0 s");
      if (!out->t_s.empty() && !(t > out->t_s.back()))
        ps.Fail(f[k][0], kf,
                fmt::format("keyframe times must increase ({} s after {} s)", t, out->t_s.back()));
      if (n < 0) ps.Fail(f[k][1], kf, fmt::format("force must be >= 0 N, found {}", n));
      out->t_s.push_back(t);
      out->force_n.push_back(n);
    }
    duration = ps.Positive(body, "duration", field, out->t_s.back(), true);
    if (duration < out->t_s.back())
      ps.Fail(body["duration"], field + ".duration",
              fmt::format("shorter than the last keyframe ({} s)", out->t_s.back()));
  } else {
    const double n = ps.Num(f, ff);
    if (n < 0) ps.Fail(f, ff, fmt::format("force must be >= 0 N, found {}", n));
    const double ramp = ps.Positive(body, "ramp", field, 0, true);
    duration = ps.Positive(body, "duration", field, std::max(0.5, ramp), true);
    if (ramp > duration)
      ps.Fail(body["ramp"], field + ".ramp",
              fmt::format("longer than the duration ({} s)", duration));
    if (ramp > 0) {
      out->t_s = {0.0, ramp};
      out->force_n = {0.0, n};
    } else {
      out->t_s = {0.0};
      out->force_n = {n};
    }
  }
  out->gain_mm_per_s_n = ps.Positive(body, "gain", field, out->gain_mm_per_s_n, false);
  out->max_speed_mm_s = ps.Positive(body, "max_speed", field, out->max_speed_mm_s, false);
  out->max_depth_mm = ps.Positive(body, "max_depth", field, out->max_depth_mm, false);
  return duration;
}

bool HasForce(const YAML::Node& body) { return body.IsMap() && body["force"]; }

double ParseForcePush(const StepInput& in, HandAction* a) {
  a->op = HandOp::kPush;
  return ParseForceProfile(in.ps, in.body, in.field, &a->force);
}

double ParseDepthPush(const StepInput& in, HandAction* a) {
  const Parser& ps = in.ps;
  if (!in.body["depth"]) ps.Fail(in.body, in.field + ".depth", "required (or force)");
  a->op = HandOp::kPush;
  a->easing = ps.Ease(in.body, in.field, Easing::kMinimumJerk);
  const double duration = ps.Positive(in.body, "duration", in.field, 0.5, true);
  a->end.position_mm = in.cur.position_mm + ps.Num(in.body["depth"], in.field + ".depth") *
                                                (in.cur.orientation * Vec3::UnitZ());
  return duration;
}

/// close (default to 1) and open (default to 0): the jaw.
double ParseJaw(const StepInput& in, HandAction* a) {
  const Parser& ps = in.ps;
  a->op = HandOp::kJaw;
  a->easing = ps.Ease(in.body, in.field, Easing::kSmoothstep);
  const double duration = ps.Positive(in.body, "duration", in.field, 0.3, true);
  a->end.jaw = ps.Num(in.body, "to", in.field, in.op == "close" ? 1.0 : 0.0);
  if (a->end.jaw < 0 || a->end.jaw > 1)
    ps.Fail(in.body["to"], in.field + ".to", "jaw must be in [0, 1]");
  return duration;
}

/// The `button` of press/hold/release as its bit (1 or 2).
std::uint8_t ButtonBit(const StepInput& in) {
  const Parser& ps = in.ps;
  if (!in.body["button"]) ps.Fail(in.body, in.field + ".button", "required (1 or 2)");
  const double b = ps.Num(in.body["button"], in.field + ".button");
  if (b != 1 && b != 2) ps.Fail(in.body["button"], in.field + ".button", "expected 1 or 2");
  return static_cast<std::uint8_t>(b == 1 ? 1 : 2);
}

double ParsePress(const StepInput& in, HandAction* a) {
  a->op = HandOp::kPress;
  a->press_bits = ButtonBit(in);
  return in.ps.Positive(in.body, "duration", in.field, 0.1, false);
}

/// hold and release are instants (zero-length actions).
double ParseHold(const StepInput& in, HandAction* a) {
  a->op = HandOp::kHold;
  a->end.held = static_cast<std::uint8_t>(in.cur.held | ButtonBit(in));
  return 0;
}

double ParseRelease(const StepInput& in, HandAction* a) {
  a->op = HandOp::kRelease;
  a->end.held = static_cast<std::uint8_t>(in.cur.held & ~ButtonBit(in));
  return 0;
}

double ParseWithdraw(const StepInput& in, HandAction* a) {
  a->op = HandOp::kWithdraw;
  a->easing = in.ps.Ease(in.body, in.field, Easing::kMinimumJerk);
  const double duration = in.ps.Positive(in.body, "duration", in.field, 1.0, true);
  a->end.position_mm = in.cur.portal_mm;
  a->end.instrument = -1;
  a->end.jaw = 0;
  a->end.held = 0;
  return duration;
}

/// Every hand step kind (docs/trajectory-format.md, "Hand actions"). To add one: write its
/// parser above and add its entry here; the unknown-action message lists the ops in this order.
const std::vector<HandStepKind>& HandStepKinds() {
  static const std::vector<HandStepKind> kinds = {
      {"pick",
       nullptr,
       {"instrument", "portal", "toward", "depth", "duration", "easing", "roll", "at"},
       0,
       ParsePick},
      {"move",
       nullptr,
       {"to", "offset", "standoff", "aim", "roll", "duration", "easing", "at"},
       kNeedsInstrument,
       ParseMove},
      {"push",
       HasForce,
       {"force", "ramp", "gain", "max_speed", "max_depth", "duration", "at"},
       kNeedsInstrument,
       ParseForcePush,
       "depth",
       "give either depth or force"},
      {"push",
       nullptr,
       {"depth", "force", "duration", "easing", "at"},
       kNeedsInstrument,
       ParseDepthPush},
      {"close", nullptr, {"to", "duration", "easing", "at"}, kNeedsInstrument, ParseJaw},
      {"open", nullptr, {"to", "duration", "easing", "at"}, kNeedsInstrument, ParseJaw},
      {"press", nullptr, {"button", "duration", "at"}, kNeedsInstrument, ParsePress},
      {"hold", nullptr, {"button", "at"}, kNeedsInstrument, ParseHold},
      {"release", nullptr, {"button", "at"}, kNeedsInstrument, ParseRelease},
      {"wait", nullptr, {"duration", "at"}, kScalarBody, ParseWait},
      {"withdraw", nullptr, {"duration", "easing", "at"}, kNeedsInstrument, ParseWithdraw},
  };
  return kinds;
}

/// The entry for op and this body, or nullptr if op is unknown.
const HandStepKind* FindStepKind(const std::string& op, const YAML::Node& body) {
  for (const HandStepKind& k : HandStepKinds()) {
    if (op == k.op && (k.applies == nullptr || k.applies(body))) return &k;
  }
  return nullptr;
}

/// "unknown action 'x'; expected pick, move, ... or withdraw".
std::string UnknownStepMessage(const std::string& op) {
  std::vector<std::string> ops;
  for (const HandStepKind& k : HandStepKinds()) {
    if (std::find(ops.begin(), ops.end(), k.op) == ops.end()) ops.emplace_back(k.op);
  }
  std::string list;
  for (std::size_t i = 0; i < ops.size(); ++i)
    list += (i == 0 ? "" : i + 1 == ops.size() ? " or " : ", ") + ops[i];
  return fmt::format("unknown action '{}'; expected {}", op, list);
}

/// Checks the body against the kind (conflict, keys, instrument) and parses it into a.
double ParseStep(const HandStepKind& kind, const StepInput& in, HandAction* a) {
  const Parser& ps = in.ps;
  if (kind.conflict != nullptr && in.body[kind.conflict])
    ps.Fail(in.body[kind.conflict], in.field + "." + kind.conflict, kind.conflict_why);
  if (in.body.IsMap() || !(kind.flags & kScalarBody)) ps.CheckKeys(in.body, in.field, kind.keys);
  if ((kind.flags & kNeedsInstrument) && in.cur.instrument < 0)
    ps.Fail(in.item, in.field, fmt::format("no instrument in {}: pick one first", in.track));
  return kind.parse(in, a);
}

/// A seeded pause before step i, if the noise draws one: appends it and advances *cursor.
void MaybeHesitate(const NoiseCtx& noise, int slot, std::size_t i, const HandState& cur, int line,
                   double* cursor, std::vector<HandAction>* out) {
  const int index = static_cast<int>(i);
  if (NoiseUniform(noise.seed, slot, index, kHesitate) >=
      noise.p.hesitation_probability * noise.scale)
    return;
  const double u = NoiseUniform(noise.seed, slot, index, kHesitateLength);
  const double pause =
      noise.p.hesitation_min_s + u * (noise.p.hesitation_max_s - noise.p.hesitation_min_s);
  HandAction w;
  w.op = HandOp::kWait;
  w.t0 = *cursor;
  w.t1 = *cursor + pause;
  w.start = w.end = cur;
  w.line = line;
  out->push_back(w);
  *cursor = w.t1;
}

}  // namespace

void BuildHand(const Parser& ps, const YAML::Node& seq, int slot, const NoiseCtx& noise,
               Timeline* tl) {
  const std::string track = fmt::format("slot{}", slot);
  if (!seq.IsSequence()) ps.Fail(seq, track, "expected a list of actions");
  std::vector<HandAction>& out = tl->hands[slot];
  HandState cur;
  double cursor = 0;
  // Only hesitations shift the timeline; then a written `at` may be passed and is not an error.
  const bool noisy = noise.scale > 0 && noise.p.hesitation_probability > 0;
  for (std::size_t i = 0; i < seq.size(); ++i) {
    const YAML::Node item = seq[i];
    const std::string where = fmt::format("{}[{}]", track, i);
    if (!item.IsMap() || item.size() != 1) ps.Fail(item, where, "expected one action: {op: {...}}");
    const std::string op = ps.Str(item.begin()->first, where);
    const YAML::Node body = item.begin()->second;
    const std::string field = where + "." + op;
    const int line = YamlLine(item);

    if (noisy && op != "wait") MaybeHesitate(noise, slot, i, cur, line, &cursor, &out);
    const double t0 = StartTime(ps, body, field, cursor, noisy);
    if (t0 > cursor) {  // explicit gap before `at`
      HandAction w;
      w.t0 = cursor;
      w.t1 = t0;
      w.start = w.end = cur;
      w.line = line;
      out.push_back(w);
    }
    const HandStepKind* kind = FindStepKind(op, body);
    if (kind == nullptr) ps.Fail(item, where, UnknownStepMessage(op));
    HandAction a;
    a.t0 = t0;
    a.start = cur;
    a.end = cur;
    a.line = line;
    const StepInput in{ps, seq, i, item, body, field, track, op, cur, noise, slot};
    a.t1 = t0 + ParseStep(*kind, in, &a);
    out.push_back(a);
    cur = a.end;
    cursor = a.t1;
  }
}

}  // namespace arthrosim::input
