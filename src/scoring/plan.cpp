#include "arthrosim/scoring/plan.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include "arthrosim/core/error.h"

namespace arthrosim::scoring {
namespace {

int LineOf(const YAML::Node& n) { return n.Mark().is_null() ? 0 : n.Mark().line + 1; }

// A mapping whose keys must come from an allowed list; accessors fail with file:line:field.
class Map {
 public:
  Map(const std::string& file, const YAML::Node& node, std::string field,
      std::initializer_list<const char*> allowed)
      : file_(file), node_(node), field_(std::move(field)) {
    if (!node.IsMap()) Fail(node, field_, "expected a mapping");
    for (auto it = node.begin(); it != node.end(); ++it) {
      const std::string key = it->first.as<std::string>();
      if (std::none_of(allowed.begin(), allowed.end(), [&](const char* a) { return key == a; })) {
        std::string list;
        for (const char* a : allowed) list += std::string(list.empty() ? "" : ", ") + a;
        Fail(it->first, Field(key), "unknown key (expected one of: " + list + ")");
      }
    }
  }

  [[noreturn]] void Fail(const YAML::Node& n, const std::string& field,
                         const std::string& msg) const {
    throw InputError(file_, LineOf(n), field, msg);
  }
  std::string Field(const std::string& key) const {
    return field_.empty() ? key : field_ + "." + key;
  }
  bool Has(const char* key) const { return static_cast<bool>(node_[key]); }
  YAML::Node Get(const char* key) const { return node_[key]; }
  int line() const { return LineOf(node_); }
  const std::string& file() const { return file_; }

  YAML::Node Required(const char* key) const {
    if (!Has(key)) Fail(node_, Field(key), "required field is missing");
    return node_[key];
  }
  double Number(const char* key, std::optional<double> fallback = std::nullopt) const {
    if (!Has(key)) {
      if (fallback) return *fallback;
      Required(key);
    }
    return ToNumber(Get(key), Field(key));
  }
  double ToNumber(const YAML::Node& n, const std::string& field) const {
    double v = 0;
    try {
      if (!n.IsScalar()) throw YAML::Exception(n.Mark(), "");
      v = n.as<double>();
    } catch (const YAML::Exception&) {
      Fail(n, field, "expected a number");
    }
    if (!std::isfinite(v)) Fail(n, field, "expected a finite number");
    return v;
  }
  double NonNegative(const char* key, double fallback) const {
    const double v = Number(key, fallback);
    if (v < 0) Fail(Get(key), Field(key), "must be >= 0");
    return v;
  }
  std::string String(const char* key, std::optional<std::string> fallback = std::nullopt) const {
    if (!Has(key)) {
      if (fallback) return *fallback;
      Required(key);
    }
    const YAML::Node n = Get(key);
    if (!n.IsScalar() || n.Scalar().empty()) Fail(n, Field(key), "expected a non-empty string");
    return n.Scalar();
  }
  bool Bool(const char* key, bool fallback) const {
    if (!Has(key)) return fallback;
    try {
      return Get(key).as<bool>();
    } catch (const YAML::Exception&) {
      Fail(Get(key), Field(key), "expected true or false");
    }
  }
  std::vector<std::string> Strings(const char* key) const {
    std::vector<std::string> out;
    if (!Has(key)) return out;
    const YAML::Node n = Get(key);
    if (!n.IsSequence()) Fail(n, Field(key), "expected a list of names");
    for (std::size_t i = 0; i < n.size(); ++i) {
      if (!n[i].IsScalar() || n[i].Scalar().empty())
        Fail(n[i], Field(key) + "[" + std::to_string(i) + "]", "expected a non-empty string");
      out.push_back(n[i].Scalar());
    }
    return out;
  }

 private:
  const std::string& file_;
  YAML::Node node_;
  std::string field_;
};

// Names the plan may refer to; checked only when a Model is given.
void CheckName(const Map& m, const char* key, const std::string& name, bool known,
               const char* what) {
  if (!known) m.Fail(m.Get(key), m.Field(key), "unknown " + std::string(what) + " '" + name + "'");
}

bool BodyExists(const Model& model, const std::string& name) {
  return model.FindSoftBody(name) >= 0 || model.FindBone(name) >= 0 || model.FindThread(name) >= 0;
}

Range ReadRange(const Map& parent, const YAML::Node& n, const std::string& field) {
  const Map m(parent.file(), n, field, {"min", "max"});
  Range r;
  if (m.Has("min")) r.min = m.Number("min");
  if (m.Has("max")) r.max = m.Number("max");
  if (!r.min && !r.max) m.Fail(n, field, "give min, max or both");
  if (r.min && r.max && *r.min > *r.max) m.Fail(n, field, "min must be <= max");
  return r;
}

Criterion ReadEventCriterion(const Map& m, const Model* model) {
  Criterion c;
  c.kind = Criterion::Kind::kEvent;
  c.event = m.String("kind");
  c.body = m.String("body", "");
  c.landmark = m.String("landmark", "");
  c.region = m.String("region", "");
  c.within_mm = m.NonNegative("within", 0);
  const double count = m.Number("count", 1);
  if (count < 1 || count != std::floor(count) || count > 1e6)
    m.Fail(m.Get("count"), m.Field("count"), "expected an integer >= 1");
  c.count = static_cast<int>(count);
  if (c.within_mm > 0 && c.landmark.empty())
    m.Fail(m.Get("within"), m.Field("within"), "needs a landmark");
  if (m.Has("detail")) {
    const YAML::Node d = m.Get("detail");
    if (!d.IsMap()) m.Fail(d, m.Field("detail"), "expected a mapping key: {min, max}");
    for (auto it = d.begin(); it != d.end(); ++it) {
      const std::string key = it->first.as<std::string>();
      c.detail[key] = ReadRange(m, it->second, m.Field("detail." + key));
    }
  }
  if (model) {
    if (!c.body.empty()) CheckName(m, "body", c.body, BodyExists(*model, c.body), "body");
    if (!c.landmark.empty())
      CheckName(m, "landmark", c.landmark, model->FindLandmark(c.landmark) >= 0, "landmark");
    if (!c.region.empty())
      CheckName(m, "region", c.region, model->FindRegion(c.region) >= 0, "region");
  }
  return c;
}

Criterion ReadCriterion(const Map& parent, const YAML::Node& n, const std::string& field,
                        const Model* model) {
  const Map outer(parent.file(), n, field, {"event", "bone_removed", "distance", "in_view"});
  if (n.size() != 1)
    outer.Fail(n, field, "expected exactly one of event, bone_removed, distance, in_view");
  Criterion c;
  if (outer.Has("event")) {
    c = ReadEventCriterion(Map(parent.file(), outer.Get("event"), outer.Field("event"),
                               {"kind", "body", "landmark", "region", "within", "count", "detail"}),
                           model);
  } else if (outer.Has("bone_removed")) {
    const Map m(parent.file(), outer.Get("bone_removed"), outer.Field("bone_removed"),
                {"bone", "min_volume"});
    c.kind = Criterion::Kind::kBoneRemoved;
    c.bone = m.String("bone");
    c.min_volume_mm3 = m.NonNegative("min_volume", 0);
    if (model) CheckName(m, "bone", c.bone, model->FindBone(c.bone) >= 0, "bone");
  } else if (outer.Has("distance")) {
    const Map m(parent.file(), outer.Get("distance"), outer.Field("distance"),
                {"region", "landmark", "max"});
    c.kind = Criterion::Kind::kDistance;
    c.region = m.String("region");
    c.landmark = m.String("landmark");
    c.max_mm = m.NonNegative("max", 0);
    if (model) {
      CheckName(m, "region", c.region, model->FindRegion(c.region) >= 0, "region");
      CheckName(m, "landmark", c.landmark, model->FindLandmark(c.landmark) >= 0, "landmark");
    }
  } else {
    const Map m(parent.file(), outer.Get("in_view"), outer.Field("in_view"),
                {"landmark", "min_time"});
    c.kind = Criterion::Kind::kInView;
    c.landmark = m.String("landmark");
    c.min_time_s = m.NonNegative("min_time", 0);
    if (model)
      CheckName(m, "landmark", c.landmark, model->FindLandmark(c.landmark) >= 0, "landmark");
  }
  c.line = LineOf(n);
  return c;
}

PlanStep ReadStep(const Map& root, const YAML::Node& n, const std::string& field,
                  const Model* model) {
  const Map m(root.file(), n, field,
              {"id", "title", "instruments", "operation", "target", "complete", "requires",
               "time_budget", "critical"});
  PlanStep s;
  s.id = m.String("id");
  s.title = m.String("title");
  s.instruments = m.Strings("instruments");
  if (s.instruments.empty()) m.Fail(n, m.Field("instruments"), "list at least one instrument");
  s.operation = m.String("operation", "");
  if (m.Has("target")) {
    const Map t(root.file(), m.Get("target"), m.Field("target"), {"landmark", "region"});
    s.target_landmark = t.String("landmark", "");
    s.target_region = t.String("region", "");
    if (model) {
      if (!s.target_landmark.empty())
        CheckName(t, "landmark", s.target_landmark, model->FindLandmark(s.target_landmark) >= 0,
                  "landmark");
      if (!s.target_region.empty())
        CheckName(t, "region", s.target_region, model->FindRegion(s.target_region) >= 0, "region");
    }
  }
  const YAML::Node complete = m.Required("complete");
  if (!complete.IsSequence() || complete.size() == 0)
    m.Fail(complete, m.Field("complete"), "expected a non-empty list of criteria");
  for (std::size_t i = 0; i < complete.size(); ++i)
    s.complete.push_back(
        ReadCriterion(m, complete[i], m.Field("complete[" + std::to_string(i) + "]"), model));
  s.requires_steps = m.Strings("requires");
  s.time_budget_s = m.Number("time_budget");
  if (!(s.time_budget_s > 0)) m.Fail(m.Get("time_budget"), m.Field("time_budget"), "must be > 0");
  s.critical = m.Bool("critical", false);
  if (model) {
    for (std::size_t i = 0; i < s.instruments.size(); ++i)
      if (s.instruments[i] != kCameraName && model->FindInstrument(s.instruments[i]) < 0)
        m.Fail(m.Get("instruments")[i], m.Field("instruments[" + std::to_string(i) + "]"),
               "unknown instrument '" + s.instruments[i] + "'");
  }
  return s;
}

ProtectedStructure ReadProtected(const Map& root, const YAML::Node& n, const std::string& field,
                                 const Model* model) {
  const Map m(
      root.file(), n, field,
      {"name", "body", "region", "max_force", "max_contact_time", "zero_damage", "critical"});
  ProtectedStructure p;
  p.name = m.String("name");
  p.body = m.String("body");
  p.region = m.String("region", "");
  p.max_force_n = m.Number("max_force");
  if (!(p.max_force_n > 0)) m.Fail(m.Get("max_force"), m.Field("max_force"), "must be > 0");
  p.max_contact_time_s = m.NonNegative("max_contact_time", 0);
  p.zero_damage = m.Bool("zero_damage", true);
  p.critical = m.Bool("critical", false);
  if (model) {
    CheckName(m, "body", p.body, BodyExists(*model, p.body), "body");
    if (!p.region.empty())
      CheckName(m, "region", p.region, model->FindRegion(p.region) >= 0, "region");
  }
  return p;
}

void ReadWeightsAndMotion(const Map& root, Plan* plan) {
  if (root.Has("weights")) {
    const Map w(root.file(), root.Get("weights"), "weights",
                {"plan_adherence", "efficiency", "safety", "repair_quality"});
    plan->weights.plan_adherence = w.NonNegative("plan_adherence", plan->weights.plan_adherence);
    plan->weights.efficiency = w.NonNegative("efficiency", plan->weights.efficiency);
    plan->weights.safety = w.NonNegative("safety", plan->weights.safety);
    plan->weights.repair_quality = w.NonNegative("repair_quality", plan->weights.repair_quality);
    const DomainWeights& d = plan->weights;
    if (!(d.plan_adherence + d.efficiency + d.safety + d.repair_quality > 0))
      w.Fail(root.Get("weights"), "weights", "at least one weight must be > 0");
  }
  if (root.Has("motion")) {
    const Map m(root.file(), root.Get("motion"), "motion",
                {"movement_speed", "idle_speed", "max_horizon", "min_tip_in_view",
                 "max_outside_volume", "max_idle_share"});
    MotionThresholds& t = plan->motion;
    t.movement_speed_mm_s = m.NonNegative("movement_speed", t.movement_speed_mm_s);
    t.idle_speed_mm_s = m.NonNegative("idle_speed", t.idle_speed_mm_s);
    t.max_horizon_deg = m.NonNegative("max_horizon", t.max_horizon_deg);
    t.min_tip_in_view = m.NonNegative("min_tip_in_view", t.min_tip_in_view);
    t.max_outside_volume_mm3 = m.NonNegative("max_outside_volume", t.max_outside_volume_mm3);
    t.max_idle_share = m.NonNegative("max_idle_share", t.max_idle_share);
    if (t.min_tip_in_view > 1)
      m.Fail(m.Get("min_tip_in_view"), m.Field("min_tip_in_view"), "must be in [0, 1]");
  }
}

// Prerequisites name earlier steps only (so the order is a plan, not a cycle); ids are unique.
void CheckSteps(const Map& root, const Plan& plan) {
  const YAML::Node steps = root.Get("steps");
  std::set<std::string> seen;
  for (std::size_t i = 0; i < plan.steps.size(); ++i) {
    const std::string field = "steps[" + std::to_string(i) + "]";
    if (!seen.insert(plan.steps[i].id).second)
      root.Fail(steps[i]["id"], field + ".id", "duplicate step id '" + plan.steps[i].id + "'");
    for (const std::string& r : plan.steps[i].requires_steps) {
      const int k = plan.FindStep(r);
      if (k < 0 || k >= static_cast<int>(i))
        root.Fail(steps[i]["requires"], field + ".requires",
                  "'" + r + "' is not the id of an earlier step");
    }
  }
}

}  // namespace

int Plan::FindStep(const std::string& id) const {
  for (std::size_t i = 0; i < steps.size(); ++i)
    if (steps[i].id == id) return static_cast<int>(i);
  return -1;
}

Plan LoadPlanFromText(const std::string& text, const std::string& path, const Model* model) {
  YAML::Node doc;
  try {
    doc = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw InputError(path, e.mark.is_null() ? 0 : e.mark.line + 1, "", "invalid YAML: " + e.msg);
  }
  const Map root(path, doc, "",
                 {"name", "scenario", "pass_score", "weights", "motion", "action_events",
                  "protected", "steps"});
  Plan plan;
  plan.path = path;
  plan.name = root.String("name");
  plan.scenario = root.String("scenario", "");
  plan.pass_score = root.NonNegative("pass_score", plan.pass_score);
  if (plan.pass_score > 100) root.Fail(root.Get("pass_score"), "pass_score", "must be <= 100");
  ReadWeightsAndMotion(root, &plan);
  plan.action_events = root.Strings("action_events");
  if (root.Has("protected")) {
    const YAML::Node p = root.Get("protected");
    if (!p.IsSequence()) root.Fail(p, "protected", "expected a list");
    for (std::size_t i = 0; i < p.size(); ++i)
      plan.protected_structures.push_back(
          ReadProtected(root, p[i], "protected[" + std::to_string(i) + "]", model));
  }
  const YAML::Node steps = root.Required("steps");
  if (!steps.IsSequence() || steps.size() == 0)
    root.Fail(steps, "steps", "expected a non-empty list of steps");
  for (std::size_t i = 0; i < steps.size(); ++i)
    plan.steps.push_back(ReadStep(root, steps[i], "steps[" + std::to_string(i) + "]", model));
  CheckSteps(root, plan);
  if (model && !plan.scenario.empty() && plan.scenario != model->name)
    root.Fail(root.Get("scenario"), "scenario",
              "plan is for scenario '" + plan.scenario + "', the run is of '" + model->name + "'");
  return plan;
}

Plan LoadPlan(const std::string& path, const Model* model) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "", "cannot open the plan file");
  std::ostringstream text;
  text << in.rdbuf();
  return LoadPlanFromText(text.str(), path, model);
}

}  // namespace arthrosim::scoring
