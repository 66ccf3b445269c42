#include "arthrosim/io/run_reader.h"

#include <algorithm>
#include <array>
#include <filesystem>
#include <limits>
#include <stdexcept>
#include <type_traits>
#include <vector>

#include "arthrosim/core/error.h"
#include "arthrosim/io/hdf5.h"
#include "arthrosim/io/hdf5_layout.h"
#include "run_open.h"
#include "state_datasets.h"

namespace arthrosim::io {
namespace {

constexpr std::size_t kChunkCache = std::size_t{4} << 20;

/// The datasets of an entity's per-frame fields (FieldStore::kFrame), in table order.
struct FieldsIn {
  std::vector<h5::Dataset> ds;
  std::vector<detail::ValueType> types;
};

template <class S>
void OpenFields(const h5::Group& g, const S& sample, FieldsIn* out) {
  VisitFields(sample, [&](const auto& value, const FieldInfo& info) {
    using T = std::decay_t<decltype(value)>;
    if (info.store != FieldStore::kFrame) return;
    if constexpr (detail::kFrameValue<T>) {
      // Absent in files written before the field existed: read back as its default.
      out->ds.push_back(g.Exists(info.name) ? g.OpenDataset(info.name, kChunkCache)
                                            : h5::Dataset());
      out->types.push_back(detail::TypeOf<T>());
    }
  });
}

/// Reads frame t of one per-frame value (slot k of a per-slot row when slot >= 0); `rows` nodes
/// or elements for per-node values.
template <class T>
void ReadValue(const h5::Dataset& ds, const detail::ValueType& type, hsize_t t, int slot,
               hsize_t rows, T* value) {
  std::vector<hsize_t> start{t}, count{1};
  if (slot >= 0) {
    start.push_back(static_cast<hsize_t>(slot));
    count.push_back(1);
  }
  if (type.per_node) {
    start.push_back(0);
    count.push_back(rows);
  }
  if (type.row_vector) {
    rows = ds.dims()[1];
    start.push_back(0);
    count.push_back(rows);
  }
  if (type.width > 0) {
    start.push_back(0);
    count.push_back(type.width);
  }
  if constexpr (std::is_same_v<T, Pose>) {
    std::array<double, 7> row;
    ds.Read(start, count, type.mem, row.data());
    *value = detail::PoseFromRow(row.data());
  } else if constexpr (std::is_same_v<T, Points>) {
    value->resize(3, static_cast<Eigen::Index>(rows));
    ds.Read(start, count, type.mem, value->data());
  } else if constexpr (std::is_same_v<T, std::vector<std::uint8_t>> ||
                       std::is_same_v<T, std::vector<double>>) {
    value->resize(rows);
    ds.Read(start, count, type.mem, value->data());
  } else if constexpr (std::is_arithmetic_v<T>) {
    ds.Read(start, count, type.mem, value);
  } else {
    ds.Read(start, count, type.mem, value->data());
  }
}

/// Fills the stored fields of `out` from frame t and sets those the file does not keep to their
/// defaults (a default-constructed S's: empty, or e.g. State::factor_switch_step = -1).
template <class S>
void ReadFields(const FieldsIn& in, hsize_t t, int slot, hsize_t nodes, hsize_t elements, S* out) {
  const S fresh{};
  std::array<const void*, kMaxStateFields> defaults{};
  FieldAddresses(&fresh, &defaults);
  std::size_t i = 0;
  std::size_t member = 0;
  VisitFields(*out, [&](auto& value, const FieldInfo& info) {
    using T = std::decay_t<decltype(value)>;
    const auto* fresh_value = static_cast<const T*>(defaults[member++]);
    if (info.store == FieldStore::kNone) {  // only in checkpoints (run_checkpoint.h)
      value = *fresh_value;
      return;
    }
    if (info.store != FieldStore::kFrame) return;
    if constexpr (detail::kFrameValue<T>) {
      const hsize_t rows = info.dim == FieldDim::kElements ? elements : nodes;
      if (!in.ds[i].valid()) {
        if constexpr (std::is_same_v<T, Vec3>) {
          value = Vec3::Zero();  // Vec3{} leaves Eigen's storage uninitialised
        } else {
          value = T{};
        }
      } else {
        ReadValue(in.ds[i], in.types[i], t, slot, rows, &value);
      }
      if constexpr (std::is_same_v<T, std::vector<std::uint8_t>>) {
        if (info.sparse && std::find(value.begin(), value.end(), 1) == value.end()) value.clear();
      }
      ++i;
    }
  });
}

// Offsets/counts of a block series plus its data dataset.
struct Blocks {
  h5::Dataset data;
  h5::Dataset offset_ds, count_ds;
  std::vector<std::int64_t> offset, count;

  void Open(const h5::Group& g, const std::string& name) {
    data = g.OpenDataset(name, kChunkCache);
    offset_ds = g.OpenDataset(layout::OffsetName(name));
    count_ds = g.OpenDataset(layout::CountName(name));
  }
  void Load() {
    offset = offset_ds.ReadAll<std::int64_t>();
    count = count_ds.ReadAll<std::int64_t>();
  }
  void Refresh() {
    data.Refresh();
    offset_ds.Refresh();
    count_ds.Refresh();
  }
  hsize_t frames() const { return std::min(offset_ds.dims()[0], count_ds.dims()[0]); }
};

// Frame t's rows of a float64 block series with `columns` columns (none if it is absent).
std::vector<std::vector<double>> ReadRows(const Blocks& b, std::size_t t, int columns) {
  std::vector<std::vector<double>> out;
  if (!b.data.valid() || t >= b.count.size()) return out;
  const auto off = static_cast<hsize_t>(b.offset[t]);
  const auto n = static_cast<hsize_t>(b.count[t]);
  std::vector<double> flat(n * static_cast<hsize_t>(columns));
  if (n > 0) {
    b.data.Read({off, 0}, {n, static_cast<hsize_t>(columns)}, H5T_NATIVE_DOUBLE, flat.data());
  }
  for (hsize_t r = 0; r < n; ++r) {
    const auto first =
        flat.begin() + static_cast<std::ptrdiff_t>(r * static_cast<hsize_t>(columns));
    out.emplace_back(first, first + columns);
  }
  return out;
}

struct BodyIn {
  FieldsIn fields;
  h5::Dataset node_count_ds, element_count_ds, elements;
  std::vector<std::int64_t> node_count, element_count;
  std::vector<mesh::Tet> tets;  // all rows of /elements
  Blocks alive_elements, positions;
};

struct ThreadIn {
  FieldsIn fields;
  h5::Dataset node_count_ds;
  std::vector<std::int64_t> node_count;
  Blocks positions;
};

// Frame t's block of a positions series as 3 x n points.
void ReadPoints(const Blocks& b, std::size_t t, Points* x) {
  const auto off = static_cast<hsize_t>(b.offset[t]);
  const auto n = static_cast<hsize_t>(b.count[t]);
  x->resize(3, static_cast<Eigen::Index>(n));
  if (n > 0) b.data.Read({off, 0}, {n, 3}, H5T_NATIVE_DOUBLE, x->data());
}

struct BoneIn {
  FieldsIn fields;
  Blocks vertices, triangles;
};

}  // namespace

std::string LocateRunScenario(const std::string& run_path, const std::string& as_given,
                              const std::string& absolute) {
  std::error_code ec;
  if (!as_given.empty() && std::filesystem::exists(as_given, ec)) return as_given;
  if (!absolute.empty() && std::filesystem::exists(absolute, ec)) return absolute;
  const std::string where = absolute.empty() || absolute == as_given
                                ? "the run's scenario '" + as_given + "' is not here"
                                : "neither the run's scenario as given, '" + as_given +
                                      "', nor its recorded absolute path '" + absolute +
                                      "' exists here";
  throw InputError(run_path, 0, "/meta scenario_path",
                   where + " (its meshes are needed); pass --scenario FILE");
}

struct RunReader::Impl {
  std::string path;
  h5::File file;
  RunInfo info;
  std::int64_t frames = 0;

  FieldsIn root_fields, slots, camera;
  h5::Dataset time_ds, step_ds, events, events_end_ds;
  std::vector<double> time;
  std::vector<std::int64_t> step, events_end;
  std::vector<BodyIn> bodies;
  std::vector<ThreadIn> threads;
  std::vector<BoneIn> bones;
  Blocks constraints, contacts;
  Blocks holes, anchors;  // absent in files written before they existed
  h5::Handle event_mem, constraint_mem, contact_mem;

  // Every dataset with one row per frame: the complete frame count is their smallest extent
  // (a live writer may have extended some and not yet others).
  std::vector<h5::Dataset*> per_frame;

  void Open();
  void Load();
};

void RunReader::Impl::Open() {
  const h5::Group& root = file.root();
  if (!root.HasAttr("format") || root.AttrString("format") != layout::kFormatName) {
    throw InputError(path, 0, "", "not an arthrosim run file (root attribute 'format')");
  }
  if (!root.HasAttr("format_version") || root.AttrInt("format_version") != layout::kFormatVersion) {
    throw InputError(
        path, 0, "format_version",
        "run file format version " +
            (root.HasAttr("format_version") ? std::to_string(root.AttrInt("format_version"))
                                            : std::string("(none)")) +
            ", this build reads version " + std::to_string(layout::kFormatVersion) +
            " (docs/hdf5-layout.md); rewrite it by running its scenario again");
  }
  info.scenario_name = root.AttrString("scenario_name");
  info.scenario_sha256 = root.AttrString("scenario_sha256");
  info.arthrosim_version = root.AttrString("arthrosim_version");
  info.dt_s = root.AttrDouble("dt");
  const h5::Group meta = root.OpenGroup(layout::kMeta);
  info.scenario_path = meta.AttrString("scenario_path");
  if (meta.HasAttr("scenario_path_absolute"))
    info.scenario_path_absolute = meta.AttrString("scenario_path_absolute");
  info.scenario_yaml = meta.OpenDataset("scenario_yaml").ReadString();

  auto frame = [&](h5::Dataset& d) { per_frame.push_back(&d); };
  auto frames_of = [&](FieldsIn& f) {
    for (h5::Dataset& d : f.ds) {
      if (d.valid()) frame(d);
    }
  };
  const State sample;
  const SoftBodyState body;
  const ThreadState thread;
  const mesh::TriMesh surface;
  OpenFields(root, sample, &root_fields);
  frames_of(root_fields);
  time_ds = root.OpenDataset(FieldOf(sample, sample.time_s).name);
  step_ds = root.OpenDataset(FieldOf(sample, sample.step).name);
  events = root.OpenDataset(layout::kEvents, kChunkCache);
  events_end_ds = root.OpenDataset(layout::kEventsEnd);
  frame(events_end_ds);

  for (const h5::Group& g : layout::OrderedGroups(root, layout::kBodies)) {
    info.soft_bodies.push_back(layout::LeafName(g.path()));
    BodyIn& b = bodies.emplace_back();
    OpenFields(g, body, &b.fields);
    b.node_count_ds = g.OpenDataset(layout::kNodeCount);
    b.element_count_ds = g.OpenDataset(layout::kElementCount);
    b.elements = g.OpenDataset(FieldOf(body, body.tets).name, kChunkCache);
    b.alive_elements.Open(g, layout::kAliveElements);
    b.positions.Open(g, FieldOf(body, body.x).name);
  }
  for (const h5::Group& g : layout::OrderedGroups(root, layout::kThreads)) {
    info.threads.push_back(layout::LeafName(g.path()));
    ThreadIn& t = threads.emplace_back();
    OpenFields(g, thread, &t.fields);
    t.node_count_ds = g.OpenDataset(layout::kNodeCount);
    t.positions.Open(g, FieldOf(thread, thread.x).name);
  }
  for (const h5::Group& g : layout::OrderedGroups(root, layout::kBones)) {
    info.bones.push_back(layout::LeafName(g.path()));
    BoneIn& b = bones.emplace_back();
    b.vertices.Open(g, FieldOf(surface, surface.nodes).name);
    b.triangles.Open(g, FieldOf(surface, surface.tris).name);
    OpenFields(g, BoneState{}, &b.fields);
  }
  for (const h5::Group& g : layout::OrderedGroups(root, layout::kTools)) {
    info.instruments.push_back(layout::LeafName(g.path()));
  }
  OpenFields(root.OpenGroup(layout::kToolSlots), ToolState{}, &slots);
  OpenFields(root.OpenGroup(layout::kCamera), CameraState{}, &camera);
  frames_of(slots);
  frames_of(camera);
  constraints.Open(root.OpenGroup(layout::kConstraints), layout::kRows);
  for (BodyIn& b : bodies) {
    frames_of(b.fields);
    for (h5::Dataset* d :
         {&b.node_count_ds, &b.element_count_ds, &b.alive_elements.offset_ds,
          &b.alive_elements.count_ds, &b.positions.offset_ds, &b.positions.count_ds}) {
      frame(*d);
    }
  }
  for (ThreadIn& t : threads) {
    frames_of(t.fields);
    for (h5::Dataset* d : {&t.node_count_ds, &t.positions.offset_ds, &t.positions.count_ds}) {
      frame(*d);
    }
  }
  for (BoneIn& b : bones) {
    frames_of(b.fields);
    for (h5::Dataset* d : {&b.vertices.offset_ds, &b.vertices.count_ds, &b.triangles.offset_ds,
                           &b.triangles.count_ds}) {
      frame(*d);
    }
  }
  contacts.Open(root.OpenGroup(layout::kToolContacts), layout::kRows);
  for (auto [list, blocks] : {std::pair{FieldOf(sample, sample.holes).name, &holes},
                              std::pair{FieldOf(sample, sample.anchors).name, &anchors}}) {
    if (root.Exists(list)) blocks->Open(root.OpenGroup(list), layout::kRows);
  }
  for (Blocks* b : {&constraints, &contacts}) {
    frame(b->offset_ds);
    frame(b->count_ds);
  }
  event_mem = layout::EventType(false);
  constraint_mem = layout::ConstraintType(false);
  contact_mem = layout::ToolContactType(false);
}

void RunReader::Impl::Load() {
  hsize_t n = std::numeric_limits<hsize_t>::max();
  for (const h5::Dataset* d : per_frame) n = std::min(n, d->dims()[0]);
  frames = static_cast<std::int64_t>(n);
  time = time_ds.ReadAll<double>();
  step = step_ds.ReadAll<std::int64_t>();
  events_end = events_end_ds.ReadAll<std::int64_t>();
  for (BodyIn& b : bodies) {
    b.node_count = b.node_count_ds.ReadAll<std::int64_t>();
    b.element_count = b.element_count_ds.ReadAll<std::int64_t>();
    const std::vector<std::int32_t> e = b.elements.ReadAll<std::int32_t>();
    b.tets.resize(e.size() / 4);
    std::copy(e.begin(), e.begin() + static_cast<std::ptrdiff_t>(4 * b.tets.size()),
              b.tets.empty() ? nullptr : b.tets[0].data());
    b.alive_elements.Load();
    b.positions.Load();
  }
  for (ThreadIn& t : threads) {
    t.node_count = t.node_count_ds.ReadAll<std::int64_t>();
    t.positions.Load();
  }
  for (BoneIn& b : bones) {
    b.vertices.Load();
    b.triangles.Load();
  }
  constraints.Load();
  contacts.Load();
  for (Blocks* b : {&holes, &anchors}) {
    if (b->data.valid()) b->Load();
  }
}

RunReader::RunReader(const std::string& path) : impl_(std::make_unique<Impl>()) {
  impl_->path = path;
  detail::ReadRunFile(path, &impl_->file, [&] {
    impl_->Open();
    impl_->Load();
  });
}

RunReader::~RunReader() = default;
RunReader::RunReader(RunReader&&) noexcept = default;
RunReader& RunReader::operator=(RunReader&&) noexcept = default;

const RunInfo& RunReader::info() const { return impl_->info; }
std::int64_t RunReader::frame_count() const { return impl_->frames; }

std::int64_t RunReader::Refresh() {
  // Reopens the file: after H5Drefresh, HDF5 1.10.8 read a dataset's second chunk as its first
  // (a chunk lookup kept across the refresh, shared by every handle of the dataset in this
  // process), so every handle is closed first. If reopening fails the reader is unusable.
  const std::string path = impl_->path;
  impl_.reset();
  RunReader fresh(path);
  impl_ = std::move(fresh.impl_);
  return impl_->frames;
}

double RunReader::time(std::int64_t k) const {
  if (k < 0 || k >= impl_->frames) throw std::out_of_range("RunReader::time: bad frame");
  return impl_->time[static_cast<std::size_t>(k)];
}

std::int64_t RunReader::step(std::int64_t k) const {
  if (k < 0 || k >= impl_->frames) throw std::out_of_range("RunReader::step: bad frame");
  return impl_->step[static_cast<std::size_t>(k)];
}

void RunReader::ReadFrame(std::int64_t k, State& out) const {
  const Impl& m = *impl_;
  if (k < 0 || k >= m.frames) {
    throw std::out_of_range("RunReader::ReadFrame: frame " + std::to_string(k) + " not in [0, " +
                            std::to_string(m.frames) + ")");
  }
  const auto t = static_cast<std::size_t>(k);
  const auto th = static_cast<hsize_t>(k);
  ReadFields(m.root_fields, th, -1, 0, 0, &out);

  out.soft_bodies.resize(m.bodies.size());
  for (std::size_t i = 0; i < m.bodies.size(); ++i) {
    const BodyIn& b = m.bodies[i];
    SoftBodyState& s = out.soft_bodies[i];
    const auto n = static_cast<hsize_t>(b.node_count[t]);
    const auto e = static_cast<std::size_t>(b.element_count[t]);
    ReadFields(b.fields, th, -1, n, e, &s);
    ReadPoints(b.positions, t, &s.x);
    s.tets.assign(b.tets.begin(), b.tets.begin() + static_cast<std::ptrdiff_t>(e));
  }

  out.threads.resize(m.threads.size());
  for (std::size_t i = 0; i < m.threads.size(); ++i) {
    const ThreadIn& d = m.threads[i];
    const auto n = static_cast<hsize_t>(d.node_count[t]);
    ReadFields(d.fields, th, -1, n, 0, &out.threads[i]);
    ReadPoints(d.positions, t, &out.threads[i].x);
  }

  out.bones.resize(m.bones.size());
  for (std::size_t i = 0; i < m.bones.size(); ++i) {
    const BoneIn& d = m.bones[i];
    BoneState& s = out.bones[i];
    const auto voff = static_cast<hsize_t>(d.vertices.offset[t]);
    const auto vn = static_cast<hsize_t>(d.vertices.count[t]);
    s.surface.nodes.resize(3, static_cast<Eigen::Index>(vn));
    d.vertices.data.Read({voff, 0}, {vn, 3}, H5T_NATIVE_DOUBLE, s.surface.nodes.data());
    const auto toff = static_cast<hsize_t>(d.triangles.offset[t]);
    const auto tn = static_cast<hsize_t>(d.triangles.count[t]);
    s.surface.tris.resize(tn);
    d.triangles.data.Read({toff, 0}, {tn, 3}, H5T_NATIVE_INT32,
                          s.surface.tris.empty() ? nullptr : s.surface.tris[0].data());
    ReadFields(d.fields, th, -1, 0, 0, &s);
    // Derived (FieldStore::kDerived): surfaces are stored once per change, so the block offsets
    // identify this frame's surface.
    s.revision = (static_cast<std::uint64_t>(voff) << 32) ^ static_cast<std::uint64_t>(toff);
  }

  for (std::size_t slot = 0; slot < kToolSlots; ++slot) {
    ReadFields(m.slots, th, static_cast<int>(slot), 0, 0, &out.tools[slot]);
  }
  ReadFields(m.camera, th, -1, 0, 0, &out.camera);

  {
    const auto off = static_cast<hsize_t>(m.constraints.offset[t]);
    const auto n = static_cast<hsize_t>(m.constraints.count[t]);
    std::vector<layout::ConstraintRecord> rows(n);
    m.constraints.data.Read({off}, {n}, m.constraint_mem.get(), rows.data());
    out.constraints.clear();
    for (const layout::ConstraintRecord& r : rows) out.constraints.push_back(layout::FromRecord(r));
  }
  {
    const auto off = static_cast<hsize_t>(m.contacts.offset[t]);
    const auto n = static_cast<hsize_t>(m.contacts.count[t]);
    std::vector<layout::ToolContactRecord> rows(n);
    m.contacts.data.Read({off}, {n}, m.contact_mem.get(), rows.data());
    out.tool_contacts.clear();
    for (const layout::ToolContactRecord& r : rows)
      out.tool_contacts.push_back(layout::FromRecord(r));
  }
  out.holes.clear();
  for (const std::vector<double>& row : ReadRows(m.holes, t, layout::kHoleColumns)) {
    out.holes.push_back(layout::HoleFromRow(row.data()));
  }
  out.anchors.clear();
  for (const std::vector<double>& row : ReadRows(m.anchors, t, layout::kAnchorColumns)) {
    out.anchors.push_back(layout::AnchorFromRow(row.data()));
  }
  {
    const auto first = static_cast<hsize_t>(t == 0 ? 0 : m.events_end[t - 1]);
    const auto n = static_cast<hsize_t>(m.events_end[t]) - first;
    std::vector<layout::EventRecord> rows(n);
    m.events.Read({first}, {n}, m.event_mem.get(), rows.data());
    out.events.clear();
    for (const layout::EventRecord& r : rows) out.events.push_back(layout::FromRecord(r));
  }
}

State RunReader::Frame(std::int64_t k) const {
  State s;
  ReadFrame(k, s);
  return s;
}

std::vector<Event> RunReader::EventsUpTo(std::int64_t k) const {
  const Impl& m = *impl_;
  if (k < 0 || k >= m.frames) throw std::out_of_range("RunReader::EventsUpTo: bad frame");
  const auto n = static_cast<hsize_t>(m.events_end[static_cast<std::size_t>(k)]);
  std::vector<layout::EventRecord> rows(n);
  m.events.Read({0}, {n}, m.event_mem.get(), rows.data());
  std::vector<Event> out;
  out.reserve(rows.size());
  for (const layout::EventRecord& r : rows) out.push_back(layout::FromRecord(r));
  return out;
}

}  // namespace arthrosim::io
