// The scenario's `operations:` section: one small reader per operation, called in the order of
// the section's allowed keys.
#include "scenario_operations.h"

#include <string>

namespace arthrosim::io {
namespace {

// A number in [lo, hi] (inclusive ends as stated in the message).
double InRange(const YamlSection& s, const char* key, double fallback, double lo, double hi,
               const char* expected) {
  const double v = s.Number(key, fallback);
  if (v < lo || v > hi)
    s.reader().Fail(s.Get(key), s.Field(key), std::string("must be ") + expected);
  return v;
}

void ReadScissors(const YamlSection& ops, ScissorsOptions* o) {
  if (!ops.Has("scissors")) return;
  const YamlSection s(ops.reader(), ops.Get("scissors"), ops.Field("scissors"),
                      {"mode", "snap_fraction", "min_jaw_step"});
  const std::string mode = s.String("mode", "remove");
  if (mode == "remove") {
    o->mode = CutMode::kRemove;
  } else if (mode == "split") {
    o->mode = CutMode::kSplit;
  } else {
    s.reader().Fail(s.Get("mode"), s.Field("mode"), "expected remove or split, got '" + mode + "'");
  }
  o->snap_fraction = InRange(s, "snap_fraction", o->snap_fraction, 0, 0.49, "in [0, 0.49]");
  o->min_jaw_step = InRange(s, "min_jaw_step", o->min_jaw_step, 0, 1, "in [0, 1]");
}

void ReadCutter(const YamlSection& ops, CutterOptions* o) {
  if (!ops.Has("cutter")) return;
  const YamlSection s(ops.reader(), ops.Get("cutter"), ops.Field("cutter"),
                      {"reach", "cut_at_jaw"});
  o->reach_mm = s.Positive("reach", o->reach_mm);
  o->cut_at_jaw = InRange(s, "cut_at_jaw", o->cut_at_jaw, 0.01, 1, "in [0.01, 1]");
}

void ReadSoftShaving(const YamlSection& ops, const char* name, SoftShavingOptions* o) {
  if (!ops.Has(name)) return;
  const YamlSection s(ops.reader(), ops.Get(name), ops.Field(name),
                      {"rate", "reach", "smoothing", "min_volume_fraction"});
  o->rate_mm_s = s.Positive("rate", o->rate_mm_s);
  o->reach_mm = s.NonNegative("reach", o->reach_mm);
  o->smoothing = InRange(s, "smoothing", o->smoothing, 0, 1, "in [0, 1]");
  o->min_volume_fraction =
      InRange(s, "min_volume_fraction", o->min_volume_fraction, 0, 0.99, "in [0, 0.99]");
}

void ReadBurr(const YamlSection& ops, BurrOptions* o) {
  if (!ops.Has("burr")) return;
  const YamlSection b(ops.reader(), ops.Get("burr"), ops.Field("burr"),
                      {"depth_rate", "speed", "max_edge", "smoothing_ring"});
  o->depth_rate_mm_s = b.Positive("depth_rate", o->depth_rate_mm_s);
  o->speed = b.Positive("speed", o->speed);
  if (o->speed > 1) b.reader().Fail(b.Get("speed"), b.Field("speed"), "must be in (0, 1]");
  o->max_edge_mm = b.Positive("max_edge", o->max_edge_mm);
  o->smoothing_ring_mm = b.NonNegative("smoothing_ring", o->smoothing_ring_mm);
}

void ReadAwl(const YamlSection& ops, AwlOptions* o) {
  if (!ops.Has("awl")) return;
  const YamlSection a(ops.reader(), ops.Get("awl"), ops.Field("awl"),
                      {"method", "max_angle", "max_edge", "min_depth"});
  o->method = static_cast<int>(a.Integer("method", o->method, 1));
  if (o->method > 2) a.reader().Fail(a.Get("method"), a.Field("method"), "expected 1 or 2");
  o->max_angle_deg = a.Positive("max_angle", o->max_angle_deg);
  if (o->max_angle_deg >= 90) {
    a.reader().Fail(a.Get("max_angle"), a.Field("max_angle"), "must be < 90 (degrees)");
  }
  o->max_edge_mm = a.Positive("max_edge", o->max_edge_mm);
  o->min_depth_mm = a.Positive("min_depth", o->min_depth_mm);
}

// The anchor's sutures must be threads of the scenario that nothing else holds in place.
void ReadAnchor(const YamlSection& ops, const Model& m, AnchorOptions* o) {
  if (!ops.Has("anchor")) return;
  const YamlSection a(ops.reader(), ops.Get("anchor"), ops.Field("anchor"),
                      {"min_hole_depth", "capture_radius", "stiffness", "sutures"});
  o->min_hole_depth_mm = a.Positive("min_hole_depth", o->min_hole_depth_mm);
  o->capture_radius_mm = a.Positive("capture_radius", o->capture_radius_mm);
  o->stiffness_n_per_mm = a.Positive("stiffness", o->stiffness_n_per_mm);
  const YAML::Node list = a.Sequence("sutures", false);
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string field = IndexedField(a.Field("sutures"), i);
    if (!list[i].IsScalar() || list[i].Scalar().empty()) {
      a.reader().Fail(list[i], field, "expected a thread name");
    }
    const std::string name = list[i].Scalar();
    const int t = m.FindThread(name);
    if (t < 0) a.reader().Fail(list[i], field, "no thread named '" + name + "' in bodies");
    if (!m.threads[static_cast<std::size_t>(t)].fixed_nodes.empty()) {
      a.reader().Fail(list[i], field,
                      "thread '" + name +
                          "' has fixed_nodes; a suture the anchor carries is held by the "
                          "anchor, not fixed (remove its fixed_nodes)");
    }
    o->sutures.push_back(name);
  }
}

// Grasper and retriever (docs/operations.md "Grasping").
void ReadGrasp(const YamlSection& ops, const char* name, GraspOptions* o) {
  if (!ops.Has(name)) return;
  const YamlSection s(ops.reader(), ops.Get(name), ops.Field(name),
                      {"dist_limit", "jaw_closed", "stiffness"});
  o->dist_limit_mm = s.Positive("dist_limit", o->dist_limit_mm);
  o->jaw_closed = InRange(s, "jaw_closed", o->jaw_closed, 0.01, 1, "in [0.01, 1]");
  o->stiffness_n_per_mm = s.Positive("stiffness", o->stiffness_n_per_mm);
}

// Scorpion needle (docs/operations.md "Suturing").
void ReadScorpionNeedle(const YamlSection& ops, ScorpionNeedleOptions* o) {
  if (!ops.Has("scorpion_needle")) return;
  const YamlSection s(
      ops.reader(), ops.Get("scorpion_needle"), ops.Field("scorpion_needle"),
      {"dist_limit_1", "dist_limit_2", "grasp_jaw", "node_spacing", "nodes_through",
       "tissue_stiffness", "thread_stiffness", "stitch_stiffness", "stitch_friction"});
  o->dist_limit_1_mm = s.Positive("dist_limit_1", o->dist_limit_1_mm);
  o->dist_limit_2_mm = s.Positive("dist_limit_2", o->dist_limit_2_mm);
  o->grasp_jaw = InRange(s, "grasp_jaw", o->grasp_jaw, 0, 1, "in [0, 1]");
  o->node_spacing_mm = s.Positive("node_spacing", o->node_spacing_mm);
  o->nodes_through = static_cast<int>(s.Integer("nodes_through", o->nodes_through, 1));
  o->tissue_stiffness_n_per_mm = s.Positive("tissue_stiffness", o->tissue_stiffness_n_per_mm);
  o->thread_stiffness_n_per_mm = s.Positive("thread_stiffness", o->thread_stiffness_n_per_mm);
  o->stitch_stiffness_n_per_mm = s.Positive("stitch_stiffness", o->stitch_stiffness_n_per_mm);
  o->stitch_friction_n = s.Number("stitch_friction", o->stitch_friction_n);
}

void ReadHook(const YamlSection& ops, HookOptions* o) {
  if (!ops.Has("hook")) return;
  const YamlSection s(ops.reader(), ops.Get("hook"), ops.Field("hook"),
                      {"catch_reach", "dist_limit", "release_angle", "stiffness", "friction"});
  o->catch_reach_mm = s.Positive("catch_reach", o->catch_reach_mm);
  o->dist_limit_mm = s.Positive("dist_limit", o->dist_limit_mm);
  o->release_angle_deg = s.Positive("release_angle", o->release_angle_deg);
  o->stiffness_n_per_mm = s.Positive("stiffness", o->stiffness_n_per_mm);
  o->friction_n = s.NonNegative("friction", o->friction_n);
}

// Knot pusher (docs/operations.md "Knot tying").
void ReadKnotPusher(const YamlSection& ops, KnotPusherOptions* o) {
  if (!ops.Has("knot_pusher")) return;
  const YamlSection s(ops.reader(), ops.Get("knot_pusher"), ops.Field("knot_pusher"),
                      {"dist_limit", "thread_stiffness", "knot_stiffness", "knot_size",
                       "target_node", "pull_force", "pull_time", "slip_limit"});
  o->dist_limit_mm = s.Positive("dist_limit", o->dist_limit_mm);
  o->thread_stiffness_n_per_mm = s.Positive("thread_stiffness", o->thread_stiffness_n_per_mm);
  o->knot_stiffness_n_per_mm = s.Positive("knot_stiffness", o->knot_stiffness_n_per_mm);
  o->knot_size_mm = s.Positive("knot_size", o->knot_size_mm);
  o->target_node = static_cast<int>(s.Integer("target_node", o->target_node, 1));
  o->pull_force_n = s.Positive("pull_force", o->pull_force_n);
  o->pull_time_s = s.Positive("pull_time", o->pull_time_s);
  o->slip_limit_mm = s.Positive("slip_limit", o->slip_limit_mm);
}

}  // namespace

void ReadOperations(const YamlSection& root, Model* m) {
  if (!root.Has("operations")) return;
  OperationOptions& o = m->operations;
  const YamlSection ops(root.reader(), root.Get("operations"), "operations",
                        {"scissors", "cutter", "shaver", "electrocautery", "burr", "awl", "anchor",
                         "grasper", "retriever", "scorpion_needle", "knot_pusher", "hook"});
  ReadScissors(ops, &o.scissors);
  ReadCutter(ops, &o.cutter);
  ReadSoftShaving(ops, "shaver", &o.shaver);
  ReadSoftShaving(ops, "electrocautery", &o.electrocautery);
  ReadBurr(ops, &o.burr);
  ReadAwl(ops, &o.awl);
  ReadAnchor(ops, *m, &o.anchor);
  ReadGrasp(ops, "grasper", &o.grasper);
  ReadGrasp(ops, "retriever", &o.retriever);
  ReadScorpionNeedle(ops, &o.scorpion_needle);
  ReadKnotPusher(ops, &o.knot_pusher);
  ReadHook(ops, &o.hook);
}

}  // namespace arthrosim::io
