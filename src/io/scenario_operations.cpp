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

}  // namespace

void ReadOperations(const YamlSection& root, Model* m) {
  if (!root.Has("operations")) return;
  OperationOptions& o = m->operations;
  const YamlSection ops(root.reader(), root.Get("operations"), "operations",
                        {"scissors", "cutter", "shaver", "electrocautery"});
  ReadScissors(ops, &o.scissors);
  ReadCutter(ops, &o.cutter);
  ReadSoftShaving(ops, "shaver", &o.shaver);
  ReadSoftShaving(ops, "electrocautery", &o.electrocautery);
}

}  // namespace arthrosim::io
