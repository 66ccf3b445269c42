// Script YAML -> Timeline: strict validation, name resolution, noise (hesitation, overshoot).
#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <optional>
#include <string>
#include <vector>

#include "arthrosim/core/error.h"
#include "arthrosim/core/rng.h"
#include "arthrosim/core/scope_aim.h"
#include "arthrosim/core/units.h"
#include "script_parser.h"

namespace arthrosim::input {

double NoiseUniform(std::uint64_t seed, int stream, int index, int purpose) {
  std::uint64_t s = seed;
  s ^= 0x9e3779b97f4a7c15ull * static_cast<std::uint64_t>(stream + 1);
  s ^= 0xbf58476d1ce4e5b9ull * static_cast<std::uint64_t>(index + 1);
  s ^= 0x94d049bb133111ebull * static_cast<std::uint64_t>(purpose + 1);
  NextRandom(&s);  // decorrelate neighbouring keys
  return NextUniform(&s);
}

void Parser::Fail(const YAML::Node& n, const std::string& field, const std::string& msg) const {
  reader_.Fail(n, field, msg);
}

void Parser::CheckKeys(const YAML::Node& map, const std::string& field,
                       std::initializer_list<const char*> allowed) const {
  reader_.CheckKeys(map, field, std::vector<const char*>(allowed));
}

void Parser::CheckKeys(const YAML::Node& map, const std::string& field,
                       const std::vector<const char*>& allowed) const {
  reader_.CheckKeys(map, field, allowed);
}

double Parser::Num(const YAML::Node& n, const std::string& field) const {
  return reader_.Number(n, field);
}

double Parser::Num(const YAML::Node& map, const char* key, const std::string& field,
                   double def) const {
  const YAML::Node n = map[key];
  return n ? Num(n, field + "." + key) : def;
}

double Parser::Positive(const YAML::Node& map, const char* key, const std::string& field,
                        double def, bool allow_zero) const {
  const double v = Num(map, key, field, def);
  if (v < 0 || (!allow_zero && v == 0)) {
    Fail(map[key], field + "." + key, allow_zero ? "must be >= 0" : "must be > 0");
  }
  return v;
}

std::string Parser::Str(const YAML::Node& n, const std::string& field) const {
  return reader_.Scalar(n, field);
}

Vec3 Parser::Vec(const YAML::Node& n, const std::string& field) const {
  return reader_.Vector(n, field);
}

Easing Parser::Ease(const YAML::Node& map, const std::string& field, Easing def) const {
  const YAML::Node n = map["easing"];
  if (!n) return def;
  const std::optional<Easing> e = ParseEasing(Str(n, field + ".easing"));
  if (!e)
    Fail(n, field + ".easing",
         fmt::format("unknown easing '{}'; expected linear, smoothstep or minimum_jerk",
                     n.Scalar()));
  return *e;
}

Vec3 Parser::Location(const YAML::Node& n, const std::string& field, bool allow_portal) const {
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

Vec3 Parser::Portal(const YAML::Node& n, const std::string& field) const {
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

double StartTime(const Parser& ps, const YAML::Node& body, const std::string& field, double cursor,
                 bool noisy) {
  if (!body.IsMap() || !body["at"]) return cursor;
  const double at = ps.Num(body["at"], field + ".at");
  if (at + 1e-12 < cursor) {
    if (noisy) return cursor;
    ps.Fail(body["at"], field + ".at",
            fmt::format("starts at {} s, before the previous action ends at {} s", at, cursor));
  }
  return std::max(at, cursor);
}

namespace {

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
    const std::string op = ps.Str(item.begin()->first, where);
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
  const YAML::Node root = ParseYaml(yaml_text, file);
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
    // "18.0" or "1e30" are whole numbers but no uint64 literal: refused like "-1".
    if (s < 0 || s != std::floor(s) ||
        !YAML::convert<std::uint64_t>::decode(root["seed"], noise.seed)) {
      ps.Fail(root["seed"], "seed", "expected an integer >= 0");
    }
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
  tl.camera_lens_angle_rad = model.camera.lens_angle_deg * units::kDegToRad;
  // The initial look point: 30 mm ahead along the scope's oblique view (the way AimScopeView
  // points it), so the first camera move turns the view from where it looked (a point behind
  // the scope made every script's first move start by flipping the view round).
  tl.camera_initial.look.point_mm = model.camera.initial_pose.position_mm +
                                    model.camera.initial_pose.orientation *
                                        (30.0 * ScopeViewDirectionLocal(tl.camera_lens_angle_rad));
  tl.camera_initial_orientation = model.camera.initial_pose.orientation;
  if (root["camera"]) BuildCamera(ps, root["camera"], &tl);

  for (const auto& h : tl.hands) {
    if (!h.empty()) tl.end_time_s = std::max(tl.end_time_s, h.back().t1);
  }
  if (!tl.camera.empty()) tl.end_time_s = std::max(tl.end_time_s, tl.camera.back().t1);
  return tl;
}

}  // namespace arthrosim::input
