// Digest of a run file and its golden-file form (HDF5, format `arthrosim-golden` version 1).
#include <fmt/core.h>

#include <algorithm>
#include <limits>

#include "arthrosim/core/error.h"
#include "arthrosim/core/hash.h"
#include "arthrosim/core/state.h"
#include "arthrosim/io/hdf5.h"
#include "arthrosim/io/run_reader.h"
#include "arthrosim/scoring/compare.h"

namespace arthrosim::scoring {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr const char* kGoldenFormat = "arthrosim-golden";

class Builder {
 public:
  DigestSeries& Get(const std::string& name, SeriesClass cls, int width) {
    const auto it = index_.find(name);
    if (it != index_.end()) return d_.series[it->second];
    index_[name] = d_.series.size();
    DigestSeries s;
    s.name = name;
    s.cls = cls;
    s.width = width;
    d_.series.push_back(std::move(s));
    return d_.series.back();
  }
  void Row(const std::string& name, SeriesClass cls, std::int64_t step,
           std::initializer_list<double> v) {
    DigestSeries& s = Get(name, cls, static_cast<int>(v.size()));
    s.steps.push_back(step);
    s.values.insert(s.values.end(), v.begin(), v.end());
  }
  void Hash(const std::string& name, std::int64_t step, std::uint64_t h) {
    DigestSeries& s = Get(name, SeriesClass::kHash, 1);
    s.steps.push_back(step);
    s.hashes.push_back(h);
  }
  Digest& digest() { return d_; }

 private:
  Digest d_;
  std::map<std::string, std::size_t> index_;
};

void PoseRow(Builder& b, const std::string& name, std::int64_t step, const Pose& p, bool valid) {
  if (!valid) {
    b.Row(name, SeriesClass::kPosition, step, {kNaN, kNaN, kNaN, kNaN, kNaN, kNaN, kNaN});
    return;
  }
  const Quat& q = p.orientation;
  b.Row(name, SeriesClass::kPosition, step,
        {p.position_mm.x(), p.position_mm.y(), p.position_mm.z(), q.w(), q.x(), q.y(), q.z()});
}

std::uint64_t ConstraintTopology(const State& s) {
  Fnv1a h;
  for (const SpringConstraint& c : s.constraints) {
    h.AddValue(c.id);
    h.Add(c.tag.data(), c.tag.size());
    for (const ConstraintEnd* e : {&c.a, &c.b}) {
      h.AddValue(e->kind);
      h.AddValue(e->index);
      h.AddValue(e->nodes);
    }
  }
  return h.digest();
}

std::uint64_t ContactTopology(const State& s) {
  Fnv1a h;
  for (const ToolContact& c : s.tool_contacts) {
    h.AddValue(c.tool_slot);
    h.AddValue(c.body_kind);
    h.AddValue(c.body);
  }
  return h.digest();
}

void PointsRow(Builder& b, const std::string& name, std::int64_t step, const Points& x) {
  DigestSeries& s = b.Get(name, SeriesClass::kPosition, 0);
  s.width = static_cast<int>(3 * x.cols());
  s.steps.push_back(step);
  s.values.assign(x.data(), x.data() + 3 * x.cols());
}

void FrameSeries(Builder& b, const io::RunInfo& info, const State& s, bool with_positions,
                 std::int64_t frame) {
  const std::int64_t st = s.step;
  b.Row("step", SeriesClass::kExact, st, {static_cast<double>(s.step)});
  b.Row("time", SeriesClass::kMetric, st, {s.time_s});
  b.Hash("state_hash", st, HashState(s));
  for (std::size_t i = 0; i < info.instruments.size(); ++i) {
    const ToolState* t = nullptr;
    for (const ToolState& slot : s.tools)
      if (slot.instrument == static_cast<int>(i)) t = &slot;
    const std::string base = "tools/" + info.instruments[i];
    PoseRow(b, base + "/pose", st, t ? t->pose : Pose{}, t != nullptr);
    const Vec3 f = t ? t->force_n : Vec3::Zero();
    b.Row(base + "/force", SeriesClass::kForce, st, {f.x(), f.y(), f.z()});
    b.Row(base + "/jaw", SeriesClass::kPosition, st, {t ? t->jaw : 0.0});
    b.Row(base + "/buttons", SeriesClass::kExact, st, {t ? double(t->buttons) : 0.0});
  }
  PoseRow(b, "camera/pose", st, s.camera.pose, true);
  b.Row("camera/rolls", SeriesClass::kPosition, st,
        {s.camera.lens_roll_rad, s.camera.head_roll_rad});
  for (std::size_t i = 0; i < s.bones.size() && i < info.bones.size(); ++i) {
    const std::string base = "bones/" + info.bones[i];
    b.Row(base + "/removed_volume", SeriesClass::kMetric, st, {s.bones[i].removed_volume_mm3});
    b.Row(base + "/topology", SeriesClass::kExact, st,
          {double(s.bones[i].surface.nodes.cols()), double(s.bones[i].surface.tris.size())});
  }
  for (std::size_t i = 0; i < s.soft_bodies.size() && i < info.soft_bodies.size(); ++i) {
    const SoftBodyState& body = s.soft_bodies[i];
    const std::string base = "bodies/" + info.soft_bodies[i];
    const auto alive = std::count(body.tet_alive.begin(), body.tet_alive.end(), 1);
    b.Row(base + "/topology", SeriesClass::kExact, st,
          {double(body.x.cols()), double(body.tets.size()), double(alive)});
    if (with_positions) PointsRow(b, fmt::format("{}/positions@frame{}", base, frame), st, body.x);
  }
  for (std::size_t i = 0; i < s.threads.size() && i < info.threads.size(); ++i) {
    const ThreadState& t = s.threads[i];
    const std::string base = "threads/" + info.threads[i];
    const auto alive = std::count(t.node_alive.begin(), t.node_alive.end(), 1);
    b.Row(base + "/topology", SeriesClass::kExact, st, {double(t.x.cols()), double(alive)});
    if (with_positions) PointsRow(b, fmt::format("{}/positions@frame{}", base, frame), st, t.x);
  }
  b.Row("constraints/count", SeriesClass::kExact, st, {double(s.constraints.size())});
  b.Hash("constraints/topology", st, ConstraintTopology(s));
  b.Row("tool_contacts/count", SeriesClass::kExact, st, {double(s.tool_contacts.size())});
  b.Hash("tool_contacts/topology", st, ContactTopology(s));
}

void EventSeries(Builder& b, const std::vector<Event>& events) {
  DigestSeries& text = b.Get("events/text", SeriesClass::kText, 1);
  DigestSeries& values = b.Get("events/values", SeriesClass::kPosition, 4);
  for (const Event& e : events) {
    text.steps.push_back(e.step);
    text.text.push_back(
        fmt::format("{} {} tool={} body={} {}", e.step, e.kind, e.tool, e.body, e.detail));
    values.steps.push_back(e.step);
    values.values.insert(values.values.end(),
                         {e.time_s, e.position_mm.x(), e.position_mm.y(), e.position_mm.z()});
  }
}

[[noreturn]] void Fail(const std::string& path, const std::string& field, const std::string& msg) {
  throw InputError(path, 0, field, msg);
}

std::string GroupName(const std::string& series) {
  std::string g = series;
  std::replace(g.begin(), g.end(), '/', '|');
  return g;
}

template <class T>
void WriteArray(io::h5::Group& g, const char* name, const std::vector<T>& v, int width) {
  io::h5::DatasetSpec spec;
  const hsize_t w = static_cast<hsize_t>(std::max(width, 1));
  spec.dims = {static_cast<hsize_t>(v.size()) / w, w};
  if (!v.empty()) {
    spec.chunk = spec.dims;
    spec.deflate = 6;
  } else {
    spec.deflate = 0;
  }
  io::h5::Dataset d = g.CreateDataset<T>(name, spec);
  if (!v.empty()) d.Write({0, 0}, spec.dims, io::h5::NativeType<T>(), v.data());
}

}  // namespace

Digest DigestOfRun(const std::string& run_path, std::int64_t sparse_every) {
  io::RunReader reader(run_path);
  Builder b;
  b.digest().sparse_every = sparse_every;
  b.digest().scenario = reader.info().scenario_name;
  const std::int64_t frames = reader.frame_count();
  State s;
  for (std::int64_t k = 0; k < frames; ++k) {
    reader.ReadFrame(k, s);
    const bool positions = sparse_every <= 0 || k % sparse_every == 0 || k == frames - 1;
    FrameSeries(b, reader.info(), s, positions, k);
  }
  EventSeries(b, frames > 0 ? reader.EventsUpTo(frames - 1) : std::vector<Event>{});
  return std::move(b.digest());
}

void WriteGolden(const std::string& path, const Digest& digest) {
  try {
    io::h5::File f = io::h5::File::Create(path);
    f.root().SetAttr("format", kGoldenFormat);
    f.root().SetAttr("format_version", std::int64_t{1});
    f.root().SetAttr("sparse_every", digest.sparse_every);
    f.root().SetAttr("scenario_name", digest.scenario);
    f.root().SetAttr("series_order", std::int64_t(digest.series.size()));
    for (std::size_t i = 0; i < digest.series.size(); ++i) {
      const DigestSeries& s = digest.series[i];
      io::h5::Group g = f.root().CreateGroup(GroupName(s.name));
      g.SetAttr("name", s.name);
      g.SetAttr("order", std::int64_t(i));
      g.SetAttr("class", SeriesClassName(s.cls));
      g.SetAttr("width", std::int64_t{s.width});
      WriteArray(g, "steps", s.steps, 1);
      if (s.cls == SeriesClass::kHash)
        WriteArray(g, "hashes", s.hashes, 1);
      else if (s.cls == SeriesClass::kText) {
        std::string joined;
        for (const std::string& t : s.text) joined += t + "\n";
        g.CreateStringDataset("text", joined);
      } else {
        WriteArray(g, "values", s.values, s.width);
      }
    }
    f.Close();
  } catch (const io::h5::Error& e) {
    Fail(path, "", std::string("cannot write the golden file: ") + e.what());
  }
}

bool IsGoldenFile(const std::string& path) {
  try {
    io::h5::File f = io::h5::File::OpenReadOnly(path, false);
    return f.root().HasAttr("format") && f.root().AttrString("format") == kGoldenFormat;
  } catch (const io::h5::Error&) {
    return false;
  }
}

Digest ReadGolden(const std::string& path) {
  Digest d;
  try {
    io::h5::File f = io::h5::File::OpenReadOnly(path, false);
    if (!f.root().HasAttr("format") || f.root().AttrString("format") != kGoldenFormat)
      Fail(path, "format", std::string("not an ") + kGoldenFormat + " file");
    if (f.root().AttrInt("format_version") != 1) Fail(path, "format_version", "expected version 1");
    d.sparse_every = f.root().AttrInt("sparse_every");
    d.scenario = f.root().AttrString("scenario_name");
    d.series.resize(static_cast<std::size_t>(f.root().AttrInt("series_order")));
    for (const std::string& child : f.root().Children()) {
      const io::h5::Group g = f.root().OpenGroup(child);
      const std::int64_t order = g.AttrInt("order");
      if (order < 0 || order >= static_cast<std::int64_t>(d.series.size()))
        Fail(path, child, "series order out of range");
      DigestSeries& s = d.series[order];
      s.name = g.AttrString("name");
      const std::string cls = g.AttrString("class");
      if (const std::optional<SeriesClass> c = ParseSeriesClass(cls)) s.cls = *c;
      s.width = static_cast<int>(g.AttrInt("width"));
      s.steps = g.OpenDataset("steps").ReadAll<std::int64_t>();
      if (s.cls == SeriesClass::kHash) {
        s.hashes = g.OpenDataset("hashes").ReadAll<std::uint64_t>();
      } else if (s.cls == SeriesClass::kText) {
        const std::string joined = g.OpenDataset("text").ReadString();
        std::size_t start = 0;
        for (std::size_t i = 0; i < joined.size(); ++i) {
          if (joined[i] != '\n') continue;
          s.text.push_back(joined.substr(start, i - start));
          start = i + 1;
        }
      } else {
        s.values = g.OpenDataset("values").ReadAll<double>();
      }
    }
  } catch (const io::h5::Error& e) {
    Fail(path, "", std::string("cannot read the golden file: ") + e.what());
  }
  return d;
}

Digest LoadDigest(const std::string& path, std::int64_t sparse_every) {
  return IsGoldenFile(path) ? ReadGolden(path) : DigestOfRun(path, sparse_every);
}

}  // namespace arthrosim::scoring
