#include "arthrosim/scoring/plan.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include "arthrosim/core/error.h"
#include "arthrosim/core/input_file.h"
#include "arthrosim/core/yaml_fields.h"

namespace arthrosim::scoring {
namespace {

// A plan mapping: the shared strict reader (core/yaml_fields.h) with the few extras plans use.
class Map : public YamlSection {
 public:
  Map(const YamlReader& reader, const YAML::Node& node, std::string field,
      std::initializer_list<const char*> allowed)
      : YamlSection(reader, node, std::move(field), allowed) {}

  using YamlSection::Fail;
  using YamlSection::Field;
  /// The field path of a composed key ("complete[2]").
  std::string Field(const std::string& key) const { return FieldPath(field(), key); }
  /// Throws InputError(file, line of n, field, message).
  [[noreturn]] void Fail(const YAML::Node& n, const std::string& field,
                         const std::string& message) const {
    reader().Fail(n, field, message);
  }
  double ToNumber(const YAML::Node& n, const std::string& field) const {
    return reader().Number(n, field);
  }
  /// A list of non-empty names (empty when absent).
  std::vector<std::string> Strings(const char* key) const {
    std::vector<std::string> out;
    const YAML::Node n = Sequence(key, false);
    for (std::size_t i = 0; i < n.size(); ++i) {
      const std::string item = IndexedField(Field(key), i);
      if (!n[i].IsScalar() || n[i].Scalar().empty())
        Fail(n[i], item, "expected a non-empty string");
      out.push_back(n[i].Scalar());
    }
    return out;
  }
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
  const Map m(parent.reader(), n, field, {"min", "max"});
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
      const std::string key = m.reader().Scalar(it->first, m.Field("detail"));
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
  const Map outer(parent.reader(), n, field, {"event", "bone_removed", "distance", "in_view"});
  if (n.size() != 1)
    outer.Fail(n, field, "expected exactly one of event, bone_removed, distance, in_view");
  Criterion c;
  if (outer.Has("event")) {
    c = ReadEventCriterion(Map(parent.reader(), outer.Get("event"), outer.Field("event"),
                               {"kind", "body", "landmark", "region", "within", "count", "detail"}),
                           model);
  } else if (outer.Has("bone_removed")) {
    const Map m(parent.reader(), outer.Get("bone_removed"), outer.Field("bone_removed"),
                {"bone", "min_volume"});
    c.kind = Criterion::Kind::kBoneRemoved;
    c.bone = m.String("bone");
    c.min_volume_mm3 = m.NonNegative("min_volume", 0);
    if (model) CheckName(m, "bone", c.bone, model->FindBone(c.bone) >= 0, "bone");
  } else if (outer.Has("distance")) {
    const Map m(parent.reader(), outer.Get("distance"), outer.Field("distance"),
                {"region", "landmark", "to_region", "max"});
    c.kind = Criterion::Kind::kDistance;
    c.region = m.String("region");
    c.landmark = m.String("landmark", "");
    c.to_region = m.String("to_region", "");
    if (c.landmark.empty() == c.to_region.empty())
      m.Fail(outer.Get("distance"), outer.Field("distance"),
             "give exactly one of landmark, to_region");
    c.max_mm = m.NonNegative("max", 0);
    if (model) {
      CheckName(m, "region", c.region, model->FindRegion(c.region) >= 0, "region");
      if (!c.landmark.empty())
        CheckName(m, "landmark", c.landmark, model->FindLandmark(c.landmark) >= 0, "landmark");
      else
        CheckName(m, "to_region", c.to_region, model->FindRegion(c.to_region) >= 0, "region");
    }
  } else {
    const Map m(parent.reader(), outer.Get("in_view"), outer.Field("in_view"),
                {"landmark", "min_time"});
    c.kind = Criterion::Kind::kInView;
    c.landmark = m.String("landmark");
    c.min_time_s = m.NonNegative("min_time", 0);
    if (model)
      CheckName(m, "landmark", c.landmark, model->FindLandmark(c.landmark) >= 0, "landmark");
  }
  c.line = YamlLine(n);
  return c;
}

PlanStep ReadStep(const Map& root, const YAML::Node& n, const std::string& field,
                  const Model* model) {
  const Map m(root.reader(), n, field,
              {"id", "title", "instruments", "operation", "also", "target", "complete", "requires",
               "time_budget", "critical"});
  PlanStep s;
  s.id = m.String("id");
  s.title = m.String("title");
  s.instruments = m.Strings("instruments");
  if (s.instruments.empty()) m.Fail(n, m.Field("instruments"), "list at least one instrument");
  s.operation = m.String("operation", "");
  s.also_events = m.Strings("also");
  if (m.Has("target")) {
    const Map t(root.reader(), m.Get("target"), m.Field("target"), {"landmark", "region"});
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
  const Map m(root.reader(), n, field,
              {"name", "body", "region", "tissue", "max_force", "max_contact_time", "zero_damage",
               "critical"});
  ProtectedStructure p;
  p.name = m.String("name");
  p.body = m.String("body");
  p.region = m.String("region", "");
  p.tissue = m.String("tissue", "");
  p.max_force_n = m.Number("max_force");
  if (!(p.max_force_n > 0)) m.Fail(m.Get("max_force"), m.Field("max_force"), "must be > 0");
  p.max_contact_time_s = m.NonNegative("max_contact_time", 0);
  p.zero_damage = m.Bool("zero_damage", true);
  p.critical = m.Bool("critical", false);
  if (model) {
    CheckName(m, "body", p.body, BodyExists(*model, p.body), "body");
    if (!p.region.empty())
      CheckName(m, "region", p.region, model->FindRegion(p.region) >= 0, "region");
    if (!p.tissue.empty()) {
      const int b = model->FindBone(p.body);
      const bool known =
          b >= 0 && std::find(model->bones[b].tissues.begin(), model->bones[b].tissues.end(),
                              p.tissue) != model->bones[b].tissues.end();
      CheckName(m, "tissue", p.tissue, known, ("tissue of bone '" + p.body + "'").c_str());
    }
  }
  return p;
}

void ReadWeightsAndMotion(const Map& root, Plan* plan) {
  if (root.Has("weights")) {
    const Map w(root.reader(), root.Get("weights"), "weights",
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
    const Map m(root.reader(), root.Get("motion"), "motion",
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
  const YAML::Node doc = ParseYaml(text, path);
  const YamlReader reader(path);
  const Map root(reader, doc, "",
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
  return LoadPlanFromText(ReadInputFile(path, "", "cannot open the plan file"), path, model);
}

}  // namespace arthrosim::scoring
