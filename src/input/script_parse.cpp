// Script YAML -> Timeline: strict validation, name resolution, noise (hesitation, overshoot).
#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <initializer_list>

#include "arthrosim/core/error.h"
#include "arthrosim/core/rng.h"
#include "arthrosim/core/units.h"
#include "script_timeline.h"

namespace arthrosim::input {

/// Tip position of a hand at time t (no tremor); defined in script_source.cpp.
Vec3 HandTipAt(const Timeline& tl, int slot, double t);

double NoiseUniform(std::uint64_t seed, int stream, int index, int purpose) {
  std::uint64_t s = seed;
  s ^= 0x9e3779b97f4a7c15ull * static_cast<std::uint64_t>(stream + 1);
  s ^= 0xbf58476d1ce4e5b9ull * static_cast<std::uint64_t>(index + 1);
  s ^= 0x94d049bb133111ebull * static_cast<std::uint64_t>(purpose + 1);
  NextRandom(&s);  // decorrelate neighbouring keys
  return NextUniform(&s);
}

namespace {

enum Purpose { kHesitate = 0, kHesitateLength = 1, kOvershoot = 2, kTremor = 3 };

class Parser {
 public:
  Parser(const std::string& file, const Model& model) : file_(file), model_(model) {}

  [[noreturn]] void Fail(const YAML::Node& n, const std::string& field,
                         const std::string& msg) const {
    const int line = n.IsDefined() && n.Mark().line >= 0 ? n.Mark().line + 1 : 0;
    throw InputError(file_, line, field, msg);
  }

  void CheckKeys(const YAML::Node& map, const std::string& field,
                 std::initializer_list<const char*> allowed) const {
    if (!map.IsMap()) Fail(map, field, "expected a map");
    for (const auto& kv : map) {
      const std::string key = kv.first.as<std::string>();
      if (std::find_if(allowed.begin(), allowed.end(), [&](const char* a) { return key == a; }) ==
          allowed.end()) {
        std::string list;
        for (const char* a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
        Fail(kv.first, field + "." + key, fmt::format("unknown key '{}'; allowed: {}", key, list));
      }
    }
  }

  double Num(const YAML::Node& n, const std::string& field) const {
    if (!n.IsScalar()) Fail(n, field, "expected a number");
    double v = 0;
    try {
      v = n.as<double>();
    } catch (const YAML::Exception&) {
      Fail(n, field, fmt::format("expected a number, found '{}'", n.Scalar()));
    }
    if (!std::isfinite(v)) Fail(n, field, "expected a finite number");
    return v;
  }
  double Num(const YAML::Node& map, const char* key, const std::string& field, double def) const {
    const YAML::Node n = map[key];
    return n ? Num(n, field + "." + key) : def;
  }
  double Positive(const YAML::Node& map, const char* key, const std::string& field, double def,
                  bool allow_zero) const {
    const double v = Num(map, key, field, def);
    if (v < 0 || (!allow_zero && v == 0)) {
      Fail(map[key], field + "." + key, allow_zero ? "must be >= 0" : "must be > 0");
    }
    return v;
  }
  std::string Str(const YAML::Node& n, const std::string& field) const {
    if (!n.IsScalar()) Fail(n, field, "expected a string");
    return n.Scalar();
  }
  Vec3 Vec(const YAML::Node& n, const std::string& field) const {
    if (!n.IsSequence() || n.size() != 3) Fail(n, field, "expected [x, y, z]");
    return Vec3(Num(n[0], field), Num(n[1], field), Num(n[2], field));
  }
  Easing Ease(const YAML::Node& map, const std::string& field, Easing def) const {
    const YAML::Node n = map["easing"];
    if (!n) return def;
    const std::optional<Easing> e = ParseEasing(Str(n, field + ".easing"));
    if (!e)
      Fail(n, field + ".easing",
           fmt::format("unknown easing '{}'; expected linear, smoothstep or minimum_jerk",
                       n.Scalar()));
    return *e;
  }

  /// A landmark name or [x, y, z]; portals too if allow_portal.
  Vec3 Location(const YAML::Node& n, const std::string& field, bool allow_portal) const {
    if (n.IsSequence()) return Vec(n, field);
    const std::string name = Str(n, field);
    const int l = model_.FindLandmark(name);
    if (l >= 0) return model_.landmarks[l].position_mm;
    if (allow_portal) {
      const int p = model_.FindPortal(name);
      if (p >= 0) return model_.portals[p].position_mm;
    }
    std::string names;
    for (const Landmark& lm : model_.landmarks) names += (names.empty() ? "" : ", ") + lm.name;
    Fail(n, field,
         fmt::format("unknown landmark '{}'{}; the scenario has: {}", name,
                     allow_portal ? " (or portal)" : "", names.empty() ? "(none)" : names));
  }

  Vec3 Portal(const YAML::Node& n, const std::string& field) const {
    const std::string name = Str(n, field);
    const int p = model_.FindPortal(name);
    if (p < 0) {
      std::string names;
      for (const struct Portal& po : model_.portals) names += (names.empty() ? "" : ", ") + po.name;
      Fail(n, field,
           fmt::format("unknown portal '{}'; the scenario has: {}", name,
                       names.empty() ? "(none)" : names));
    }
    return model_.portals[p].position_mm;
  }

  const std::string& file_;
  const Model& model_;
};

int LineOf(const YAML::Node& n) { return n.Mark().line >= 0 ? n.Mark().line + 1 : 0; }

struct NoiseCtx {
  NoiseParams p;
  double scale = 0;
  std::uint64_t seed = 1;
};

NoiseParams ParseNoise(const Parser& ps, const YAML::Node& n) {
  ps.CheckKeys(n, "noise",
               {"tremor_amplitude", "tremor_frequency", "overshoot", "hesitation_probability",
                "hesitation_min", "hesitation_max"});
  NoiseParams p;
  p.tremor_amplitude_mm = ps.Positive(n, "tremor_amplitude", "noise", 0, true);
  p.tremor_frequency_hz = ps.Positive(n, "tremor_frequency", "noise", 8, false);
  p.overshoot = ps.Positive(n, "overshoot", "noise", 0, true);
  p.hesitation_probability = ps.Positive(n, "hesitation_probability", "noise", 0, true);
  if (p.hesitation_probability > 1)
    ps.Fail(n["hesitation_probability"], "noise.hesitation_probability", "must be in [0, 1]");
  p.hesitation_min_s = ps.Positive(n, "hesitation_min", "noise", 0.2, true);
  p.hesitation_max_s = ps.Positive(n, "hesitation_max", "noise", 0.8, true);
  if (p.hesitation_max_s < p.hesitation_min_s)
    ps.Fail(n["hesitation_max"], "noise.hesitation_max", "must be >= hesitation_min");
  return p;
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

/// Start time of an action: the cursor, or `at` if given (must not be earlier).
double StartTime(const Parser& ps, const YAML::Node& body, const std::string& field, double cursor,
                 bool noisy) {
  if (!body.IsMap() || !body["at"]) return cursor;
  const double at = ps.Num(body["at"], field + ".at");
  if (at + 1e-12 < cursor) {
    // Hesitations may push a hand past a written start time: then it just starts late.
    if (noisy) return cursor;
    ps.Fail(body["at"], field + ".at",
            fmt::format("starts at {} s, before the previous action ends at {} s", at, cursor));
  }
  return std::max(at, cursor);
}

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
    const std::string op = item.begin()->first.as<std::string>();
    const YAML::Node body = item.begin()->second;
    const std::string field = where + "." + op;
    const int line = LineOf(item);

    // Hesitation: a seeded pause before the action.
    if (noisy && op != "wait" &&
        NoiseUniform(noise.seed, slot, static_cast<int>(i), kHesitate) <
            noise.p.hesitation_probability * noise.scale) {
      const double u = NoiseUniform(noise.seed, slot, static_cast<int>(i), kHesitateLength);
      const double pause =
          noise.p.hesitation_min_s + u * (noise.p.hesitation_max_s - noise.p.hesitation_min_s);
      HandAction w;
      w.op = HandOp::kWait;
      w.t0 = cursor;
      w.t1 = cursor + pause;
      w.start = w.end = cur;
      w.line = line;
      out.push_back(w);
      cursor = w.t1;
    }

    const double t0 = StartTime(ps, body, field, cursor, noisy);
    if (t0 > cursor) {  // explicit gap before `at`
      HandAction w;
      w.t0 = cursor;
      w.t1 = t0;
      w.start = w.end = cur;
      w.line = line;
      out.push_back(w);
    }
    HandAction a;
    a.t0 = t0;
    a.start = cur;
    a.end = cur;
    a.line = line;
    auto need_instrument = [&]() {
      if (cur.instrument < 0)
        ps.Fail(item, field, fmt::format("no instrument in {}: pick one first", track));
    };
    double duration = 0;
    if (op == "wait") {
      a.op = HandOp::kWait;
      if (body.IsMap()) {
        ps.CheckKeys(body, field, {"duration", "at"});
        duration = ps.Positive(body, "duration", field, 0, true);
      } else {
        duration = ps.Num(body, field);
        if (duration < 0) ps.Fail(body, field, "must be >= 0");
      }
    } else if (op == "pick") {
      ps.CheckKeys(body, field,
                   {"instrument", "portal", "toward", "depth", "duration", "easing", "roll", "at"});
      if (cur.instrument >= 0) {
        ps.Fail(item, field,
                fmt::format("{} already holds '{}': withdraw it first", track,
                            ps.model_.instruments[cur.instrument].name));
      }
      if (!body["instrument"]) ps.Fail(body, field + ".instrument", "required");
      const std::string name = ps.Str(body["instrument"], field + ".instrument");
      const int idx = ps.model_.FindInstrument(name);
      if (idx < 0) {
        std::string names;
        for (const InstrumentModel& im : ps.model_.instruments)
          names += (names.empty() ? "" : ", ") + im.name;
        ps.Fail(body["instrument"], field + ".instrument",
                fmt::format("unknown instrument '{}'; the scenario has: {}", name,
                            names.empty() ? "(none)" : names));
      }
      Vec3 portal;
      if (body["portal"]) {
        portal = ps.Portal(body["portal"], field + ".portal");
      } else {
        const int p = ps.model_.FindPortal(ps.model_.instruments[idx].portal);
        if (p < 0)
          ps.Fail(body["instrument"], field + ".instrument",
                  fmt::format("instrument '{}' names portal '{}', which the scenario lacks", name,
                              ps.model_.instruments[idx].portal));
        portal = ps.model_.portals[p].position_mm;
      }
      Vec3 toward;
      if (body["toward"]) {
        toward = ps.Location(body["toward"], field + ".toward", false);
      } else {  // aim at the target of the next move of this hand
        bool found = false;
        for (std::size_t j = i + 1; j < seq.size() && !found; ++j) {
          const YAML::Node nx = seq[j];
          if (nx.IsMap() && nx.size() == 1 && nx.begin()->first.as<std::string>() == "move") {
            const YAML::Node mb = nx.begin()->second;
            const std::string mf = fmt::format("{}[{}].move", track, j);
            if (mb.IsMap() && mb["to"]) {
              toward = ps.Location(mb["to"], mf + ".to", false);
              if (mb["offset"]) toward += ps.Vec(mb["offset"], mf + ".offset");
              found = true;
            }
          }
        }
        if (!found) ps.Fail(body, field + ".toward", "required when no move follows the pick");
      }
      if ((toward - portal).norm() < 1e-9)
        ps.Fail(body, field + ".toward", "coincides with the portal");
      a.op = HandOp::kPick;
      a.easing = ps.Ease(body, field, Easing::kMinimumJerk);
      const double depth = ps.Positive(body, "depth", field, 10.0, true);
      duration = ps.Positive(body, "duration", field, 1.0, true);
      const Vec3 dir = (toward - portal).normalized();
      a.start.instrument = idx;
      a.start.portal_mm = portal;
      a.start.position_mm = portal;
      a.start.orientation = AimAlong(dir, ps.Num(body, "roll", field, 0) * units::kDegToRad);
      a.start.jaw = 0;
      a.end = a.start;
      a.end.position_mm = portal + depth * dir;
    } else if (op == "move") {
      ps.CheckKeys(body, field,
                   {"to", "offset", "standoff", "aim", "roll", "duration", "easing", "at"});
      need_instrument();
      if (!body["to"]) ps.Fail(body, field + ".to", "required");
      Vec3 target = ps.Location(body["to"], field + ".to", false);
      if (body["offset"]) target += ps.Vec(body["offset"], field + ".offset");
      const double standoff = ps.Positive(body, "standoff", field, 0, true);
      if (standoff > 0) target -= standoff * (target - cur.portal_mm).normalized();
      a.op = HandOp::kMove;
      a.easing = ps.Ease(body, field, Easing::kMinimumJerk);
      duration = ps.Positive(body, "duration", field, 1.0, true);
      a.roll_rad = ps.Num(body, "roll", field, 0) * units::kDegToRad;
      a.end = cur;
      a.end.position_mm = target;
      const YAML::Node aim = body["aim"];
      if (!aim || (aim.IsScalar() && aim.Scalar() == "portal")) {
        a.aim_portal = true;
        if ((target - cur.portal_mm).norm() < 1e-9)
          ps.Fail(body["to"], field + ".to", "target coincides with the portal");
        a.end.orientation = AimAlong(target - cur.portal_mm, a.roll_rad);
      } else {
        const Vec3 d = ps.Vec(aim, field + ".aim");
        if (d.norm() < 1e-12) ps.Fail(aim, field + ".aim", "direction must be non-zero");
        a.end.orientation = AimAlong(d, a.roll_rad);
      }
      if (noise.scale > 0 && noise.p.overshoot > 0) {
        const double u = NoiseUniform(noise.seed, slot, static_cast<int>(i), kOvershoot);
        a.overshoot_mm = noise.p.overshoot * noise.scale * (0.5 + u) * (target - cur.position_mm);
      }
    } else if (op == "push" && body.IsMap() && body["force"]) {
      if (body["depth"]) ps.Fail(body["depth"], field + ".depth", "give either depth or force");
      ps.CheckKeys(body, field,
                   {"force", "ramp", "gain", "max_speed", "max_depth", "duration", "at"});
      need_instrument();
      a.op = HandOp::kPush;
      duration = ParseForceProfile(ps, body, field, &a.force);
    } else if (op == "push") {
      ps.CheckKeys(body, field, {"depth", "force", "duration", "easing", "at"});
      need_instrument();
      if (!body["depth"]) ps.Fail(body, field + ".depth", "required (or force)");
      a.op = HandOp::kPush;
      a.easing = ps.Ease(body, field, Easing::kMinimumJerk);
      duration = ps.Positive(body, "duration", field, 0.5, true);
      a.end = cur;
      a.end.position_mm = cur.position_mm + ps.Num(body["depth"], field + ".depth") *
                                                (cur.orientation * Vec3::UnitZ());
    } else if (op == "close" || op == "open") {
      ps.CheckKeys(body, field, {"to", "duration", "easing", "at"});
      need_instrument();
      a.op = HandOp::kJaw;
      a.easing = ps.Ease(body, field, Easing::kSmoothstep);
      duration = ps.Positive(body, "duration", field, 0.3, true);
      a.end = cur;
      a.end.jaw = ps.Num(body, "to", field, op == "close" ? 1.0 : 0.0);
      if (a.end.jaw < 0 || a.end.jaw > 1)
        ps.Fail(body["to"], field + ".to", "jaw must be in [0, 1]");
    } else if (op == "press" || op == "hold" || op == "release") {
      if (op == "press") {
        ps.CheckKeys(body, field, {"button", "duration", "at"});
      } else {
        ps.CheckKeys(body, field, {"button", "at"});
      }
      need_instrument();
      if (!body["button"]) ps.Fail(body, field + ".button", "required (1 or 2)");
      const double b = ps.Num(body["button"], field + ".button");
      if (b != 1 && b != 2) ps.Fail(body["button"], field + ".button", "expected 1 or 2");
      const std::uint8_t bit = static_cast<std::uint8_t>(b == 1 ? 1 : 2);
      a.end = cur;
      if (op == "press") {
        a.op = HandOp::kPress;
        a.press_bits = bit;
        duration = ps.Positive(body, "duration", field, 0.1, false);
      } else if (op == "hold") {
        a.op = HandOp::kHold;
        a.end.held = static_cast<std::uint8_t>(cur.held | bit);
      } else {
        a.op = HandOp::kRelease;
        a.end.held = static_cast<std::uint8_t>(cur.held & ~bit);
      }
    } else if (op == "withdraw") {
      ps.CheckKeys(body, field, {"duration", "easing", "at"});
      need_instrument();
      a.op = HandOp::kWithdraw;
      a.easing = ps.Ease(body, field, Easing::kMinimumJerk);
      duration = ps.Positive(body, "duration", field, 1.0, true);
      a.end = cur;
      a.end.position_mm = cur.portal_mm;
      a.end.instrument = -1;
      a.end.jaw = 0;
      a.end.held = 0;
    } else {
      ps.Fail(item, where,
              fmt::format("unknown action '{}'; expected pick, move, push, close, open, press, "
                          "hold, release, wait or withdraw",
                          op));
    }
    a.t1 = t0 + duration;
    // hold/release are instants; store them as zero-length actions.
    out.push_back(a);
    cur = a.end;
    cursor = a.t1;
  }
}

LookTarget ParseLook(const Parser& ps, const YAML::Node& n, const std::string& field) {
  LookTarget lt;
  if (n.IsScalar() && (n.Scalar() == "slot0" || n.Scalar() == "slot1")) {
    lt.slot = n.Scalar() == "slot0" ? 0 : 1;
    return lt;
  }
  lt.point_mm = ps.Location(n, field, false);
  return lt;
}

Vec3 LookPoint(const Timeline& tl, const LookTarget& lt, double t) {
  return lt.slot < 0 ? lt.point_mm : HandTipAt(tl, lt.slot, t);
}

void BuildCamera(const Parser& ps, const YAML::Node& seq, Timeline* tl) {
  if (!seq.IsSequence()) ps.Fail(seq, "camera", "expected a list of actions");
  CameraKey cur = tl->camera_initial;
  double cursor = 0;
  const int cam_portal = ps.model_.FindPortal(ps.model_.camera.portal);
  for (std::size_t i = 0; i < seq.size(); ++i) {
    const YAML::Node item = seq[i];
    const std::string where = fmt::format("camera[{}]", i);
    if (!item.IsMap() || item.size() != 1) ps.Fail(item, where, "expected one action: {op: {...}}");
    const std::string op = item.begin()->first.as<std::string>();
    const YAML::Node body = item.begin()->second;
    const std::string field = where + "." + op;
    const double t0 = StartTime(ps, body, field, cursor, false);
    if (t0 > cursor) {
      CameraAction w;
      w.t0 = cursor;
      w.t1 = t0;
      w.start = w.end = cur;
      tl->camera.push_back(w);
    }
    CameraAction a;
    a.t0 = t0;
    a.start = cur;
    a.end = cur;
    double duration = 0;
    if (op == "wait") {
      if (body.IsMap()) {
        ps.CheckKeys(body, field, {"duration", "at"});
        duration = ps.Positive(body, "duration", field, 0, true);
      } else {
        duration = ps.Num(body, field);
        if (duration < 0) ps.Fail(body, field, "must be >= 0");
      }
      a.blend_s = duration;
    } else if (op == "move" || op == "follow") {
      const bool follow = op == "follow";
      if (follow) {
        ps.CheckKeys(body, field,
                     {"target", "distance", "lens_roll", "head_roll", "duration", "transition",
                      "easing", "at"});
        if (!body["target"]) ps.Fail(body, field + ".target", "required");
        a.end.look = ParseLook(ps, body["target"], field + ".target");
        duration = ps.Positive(body, "duration", field, 1.0, true);
        a.blend_s = std::min(duration, ps.Positive(body, "transition", field, 0.5, true));
        if (body["distance"]) {
          const double dist = ps.Positive(body, "distance", field, 0, false);
          const Vec3 target = LookPoint(*tl, a.end.look, t0 + a.blend_s);
          const Vec3 d = target - cur.position_mm;
          if (d.norm() < 1e-9)
            ps.Fail(body["distance"], field + ".distance", "camera is at the target");
          a.end.position_mm = target - dist * d.normalized();
        }
      } else {
        ps.CheckKeys(body, field,
                     {"position", "offset", "standoff", "look_at", "lens_roll", "head_roll",
                      "duration", "easing", "at"});
        if (body["position"]) {
          Vec3 p = ps.Location(body["position"], field + ".position", true);
          if (body["offset"]) p += ps.Vec(body["offset"], field + ".offset");
          const double standoff = ps.Positive(body, "standoff", field, 0, true);
          if (standoff > 0) {
            if (cam_portal < 0)
              ps.Fail(body["standoff"], field + ".standoff",
                      fmt::format("needs the camera portal '{}', which the scenario lacks",
                                  ps.model_.camera.portal));
            const Vec3 d = p - ps.model_.portals[cam_portal].position_mm;
            if (d.norm() > 1e-9) p -= standoff * d.normalized();
          }
          a.end.position_mm = p;
        } else if (body["offset"] || body["standoff"]) {
          ps.Fail(body, field + ".position", "offset/standoff need a position");
        }
        if (body["look_at"]) a.end.look = ParseLook(ps, body["look_at"], field + ".look_at");
        duration = ps.Positive(body, "duration", field, 1.0, true);
        a.blend_s = duration;
      }
      a.easing = ps.Ease(body, field, Easing::kMinimumJerk);
      if (body["lens_roll"])
        a.end.lens_roll_rad = ps.Num(body["lens_roll"], field + ".lens_roll") * units::kDegToRad;
      if (body["head_roll"])
        a.end.head_roll_rad = ps.Num(body["head_roll"], field + ".head_roll") * units::kDegToRad;
    } else {
      ps.Fail(item, where,
              fmt::format("unknown camera action '{}'; expected move, follow or wait", op));
    }
    a.t1 = t0 + duration;
    tl->camera.push_back(a);
    cur = a.end;
    cursor = a.t1;
  }
}

/// One instrument cannot be in both hands at once.
void CheckInstrumentOverlap(const Parser& ps, const Timeline& tl) {
  struct Use {
    int instrument;
    double t0, t1;
    int line;
  };
  std::array<std::vector<Use>, kToolSlots> uses;
  for (int s = 0; s < kToolSlots; ++s) {
    for (const HandAction& a : tl.hands[s]) {
      if (a.op == HandOp::kPick) uses[s].push_back({a.start.instrument, a.t0, 1e300, a.line});
      if (a.op == HandOp::kWithdraw && !uses[s].empty()) uses[s].back().t1 = a.t1;
    }
  }
  for (const Use& u : uses[1]) {
    for (const Use& v : uses[0]) {
      if (u.instrument == v.instrument && u.t0 < v.t1 && v.t0 < u.t1) {
        throw InputError(
            ps.file_, std::max(u.line, v.line), "instrument",
            fmt::format("'{}' is in slot0 and slot1 at the same time ({} s)",
                        ps.model_.instruments[u.instrument].name, std::max(u.t0, v.t0)));
      }
    }
  }
}

}  // namespace

Timeline BuildTimeline(const std::string& yaml_text, const std::string& file, const Model& model,
                       const ScriptOptions& options) {
  if (!(options.dt_s > 0)) throw InputError(file, 0, "dt", "simulation step must be > 0");
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw InputError(file, e.mark.line >= 0 ? e.mark.line + 1 : 0, "", "YAML syntax: " + e.msg);
  }
  const Parser ps(file, model);
  if (!root.IsMap()) ps.Fail(root, "", "expected a map at the top level");
  ps.CheckKeys(root, "", {"name", "description", "seed", "noise", "slot0", "slot1", "camera"});
  Timeline tl;
  tl.file = file;
  tl.dt_s = options.dt_s;
  if (!root["name"]) ps.Fail(root, "name", "required");
  tl.name = ps.Str(root["name"], "name");
  if (root["description"]) ps.Str(root["description"], "description");

  NoiseCtx noise;
  if (root["seed"]) {
    const double s = ps.Num(root["seed"], "seed");
    if (s < 0 || s != std::floor(s)) ps.Fail(root["seed"], "seed", "expected an integer >= 0");
    noise.seed = root["seed"].as<std::uint64_t>();
  }
  if (options.seed) noise.seed = *options.seed;
  if (root["noise"]) noise.p = ParseNoise(ps, root["noise"]);
  if (options.noise) noise.p = *options.noise;
  noise.scale = std::max(0.0, options.noise_scale);

  for (int s = 0; s < kToolSlots; ++s) {
    const YAML::Node seq = root[fmt::format("slot{}", s)];
    if (seq) BuildHand(ps, seq, s, noise, &tl);
  }
  CheckInstrumentOverlap(ps, tl);

  // Tremor: three sinusoids per axis around the centre frequency, seeded phases.
  for (int s = 0; s < kToolSlots; ++s) {
    Tremor& tr = tl.tremor[s];
    tr.amplitude_mm = noise.p.tremor_amplitude_mm * noise.scale;
    for (int ax = 0; ax < 3; ++ax) {
      for (int c = 0; c < 3; ++c) {
        const int k = 10 * ax + c;
        tr.freq_hz[ax][c] = noise.p.tremor_frequency_hz *
                            (0.8 + 0.4 * NoiseUniform(noise.seed, 100 + s, k, kTremor));
        tr.phase[ax][c] = 2 * units::kPi * NoiseUniform(noise.seed, 200 + s, k, kTremor);
      }
    }
  }

  tl.camera_initial.position_mm = model.camera.initial_pose.position_mm;
  tl.camera_initial.look.point_mm = model.camera.initial_pose.position_mm +
                                    model.camera.initial_pose.orientation * Vec3(0, 0, -30);
  tl.camera_initial_orientation = model.camera.initial_pose.orientation;
  if (root["camera"]) BuildCamera(ps, root["camera"], &tl);

  for (const auto& h : tl.hands) {
    if (!h.empty()) tl.end_time_s = std::max(tl.end_time_s, h.back().t1);
  }
  if (!tl.camera.empty()) tl.end_time_s = std::max(tl.end_time_s, tl.camera.back().t1);
  return tl;
}

}  // namespace arthrosim::input
