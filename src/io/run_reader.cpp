#include "arthrosim/io/run_reader.h"

#include <algorithm>
#include <limits>
#include <stdexcept>

#include "arthrosim/core/error.h"
#include "arthrosim/io/hdf5.h"
#include "arthrosim/io/hdf5_layout.h"

namespace arthrosim::io {
namespace {

constexpr std::size_t kChunkCache = std::size_t{4} << 20;

Pose PoseFromRow(const double* r) {
  Pose p;
  p.position_mm = Vec3(r[0], r[1], r[2]);
  p.orientation = Quat(r[3], r[4], r[5], r[6]);  // Eigen's constructor order: w x y z
  return p;
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
  h5::Dataset positions, node_count_ds, element_count_ds, element_alive, elements;
  h5::Dataset removed_ds, cauterized_ds;  // absent in files written before the operations
  std::vector<std::int64_t> node_count, element_count;
  std::vector<double> removed;
  std::vector<mesh::Tet> tets;  // all rows of /elements
  Blocks alive_elements;
};

struct ThreadIn {
  h5::Dataset positions, node_count_ds, node_alive;
  std::vector<std::int64_t> node_count;
};

struct BoneIn {
  Blocks vertices, triangles;
  h5::Dataset removed_ds, by_region_ds;
  std::vector<double> removed, by_region;  ///< by_region: frames x columns, row-major
  std::size_t by_region_columns = 0;
};

}  // namespace

struct RunReader::Impl {
  std::string path;
  h5::File file;
  RunInfo info;
  std::int64_t frames = 0;

  h5::Dataset time_ds, step_ds, rng_ds, next_id_ds, events, events_end_ds;
  h5::Dataset slot_instrument_ds, slot_pose_ds, slot_jaw_ds, slot_buttons_ds, slot_force_ds;
  h5::Dataset cam_pose_ds, cam_lens_ds, cam_head_ds;
  std::vector<double> time;
  std::vector<std::int64_t> step, next_id, events_end;
  std::vector<std::uint64_t> rng;
  std::vector<std::int32_t> slot_instrument;
  std::vector<double> slot_pose, slot_jaw, slot_force;
  std::vector<std::uint8_t> slot_buttons;
  std::vector<double> cam_pose, cam_lens, cam_head;
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
  info.scenario_name = root.AttrString("scenario_name");
  info.scenario_sha256 = root.AttrString("scenario_sha256");
  info.arthrosim_version = root.AttrString("arthrosim_version");
  info.dt_s = root.AttrDouble("dt");
  const h5::Group meta = root.OpenGroup(layout::kMeta);
  info.scenario_path = meta.AttrString("scenario_path");
  info.scenario_yaml = meta.OpenDataset("scenario_yaml").ReadString();

  auto frame = [&](h5::Dataset& d) { per_frame.push_back(&d); };
  time_ds = root.OpenDataset("time");
  step_ds = root.OpenDataset("step");
  rng_ds = root.OpenDataset("rng_state");
  next_id_ds = root.OpenDataset("next_constraint_id");
  events = root.OpenDataset("events", kChunkCache);
  events_end_ds = root.OpenDataset("events_end");
  for (h5::Dataset* d : {&time_ds, &step_ds, &rng_ds, &next_id_ds, &events_end_ds}) frame(*d);

  for (const h5::Group& g : layout::OrderedGroups(root, layout::kBodies)) {
    info.soft_bodies.push_back(layout::LeafName(g.path()));
    BodyIn& b = bodies.emplace_back();
    b.positions = g.OpenDataset("positions", kChunkCache);
    b.node_count_ds = g.OpenDataset("node_count");
    b.element_count_ds = g.OpenDataset("element_count");
    b.element_alive = g.OpenDataset("element_alive", kChunkCache);
    b.elements = g.OpenDataset("elements", kChunkCache);
    b.alive_elements.Open(g, "alive_elements");
    if (g.Exists("removed_volume")) b.removed_ds = g.OpenDataset("removed_volume");
    if (g.Exists("cauterized")) b.cauterized_ds = g.OpenDataset("cauterized", kChunkCache);
  }
  for (const h5::Group& g : layout::OrderedGroups(root, layout::kThreads)) {
    info.threads.push_back(layout::LeafName(g.path()));
    ThreadIn& t = threads.emplace_back();
    t.positions = g.OpenDataset("positions", kChunkCache);
    t.node_count_ds = g.OpenDataset("node_count");
    t.node_alive = g.OpenDataset("node_alive", kChunkCache);
  }
  for (const h5::Group& g : layout::OrderedGroups(root, layout::kBones)) {
    info.bones.push_back(layout::LeafName(g.path()));
    BoneIn& b = bones.emplace_back();
    b.vertices.Open(g, "vertices");
    b.triangles.Open(g, "triangles");
    b.removed_ds = g.OpenDataset("removed_volume");
    if (g.Exists("removed_volume_by_region")) {
      b.by_region_ds = g.OpenDataset("removed_volume_by_region");
    }
  }
  for (const h5::Group& g : layout::OrderedGroups(root, layout::kTools)) {
    info.instruments.push_back(layout::LeafName(g.path()));
  }
  const h5::Group slots = root.OpenGroup(layout::kToolSlots);
  slot_instrument_ds = slots.OpenDataset("instrument");
  slot_pose_ds = slots.OpenDataset("pose");
  slot_jaw_ds = slots.OpenDataset("jaw");
  slot_buttons_ds = slots.OpenDataset("buttons");
  slot_force_ds = slots.OpenDataset("force");
  const h5::Group cam = root.OpenGroup(layout::kCamera);
  cam_pose_ds = cam.OpenDataset("pose");
  cam_lens_ds = cam.OpenDataset("lens_roll");
  cam_head_ds = cam.OpenDataset("head_roll");
  for (h5::Dataset* d : {&slot_instrument_ds, &slot_pose_ds, &slot_jaw_ds, &slot_buttons_ds,
                         &slot_force_ds, &cam_pose_ds, &cam_lens_ds, &cam_head_ds}) {
    frame(*d);
  }
  constraints.Open(root.OpenGroup(layout::kConstraints), "rows");
  for (BodyIn& b : bodies) {
    for (h5::Dataset* d : {&b.positions, &b.node_count_ds, &b.element_count_ds, &b.element_alive,
                           &b.alive_elements.offset_ds, &b.alive_elements.count_ds}) {
      frame(*d);
    }
    for (h5::Dataset* d : {&b.removed_ds, &b.cauterized_ds}) {
      if (d->valid()) frame(*d);
    }
  }
  for (ThreadIn& t : threads) {
    for (h5::Dataset* d : {&t.positions, &t.node_count_ds, &t.node_alive}) frame(*d);
  }
  for (BoneIn& b : bones) {
    for (h5::Dataset* d : {&b.vertices.offset_ds, &b.vertices.count_ds, &b.triangles.offset_ds,
                           &b.triangles.count_ds, &b.removed_ds}) {
      frame(*d);
    }
  }
  contacts.Open(root.OpenGroup(layout::kToolContacts), "rows");
  if (root.Exists(layout::kHoles)) holes.Open(root.OpenGroup(layout::kHoles), "rows");
  if (root.Exists(layout::kAnchors)) anchors.Open(root.OpenGroup(layout::kAnchors), "rows");
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
  rng = rng_ds.ReadAll<std::uint64_t>();
  next_id = next_id_ds.ReadAll<std::int64_t>();
  events_end = events_end_ds.ReadAll<std::int64_t>();
  slot_instrument = slot_instrument_ds.ReadAll<std::int32_t>();
  slot_pose = slot_pose_ds.ReadAll<double>();
  slot_jaw = slot_jaw_ds.ReadAll<double>();
  slot_buttons = slot_buttons_ds.ReadAll<std::uint8_t>();
  slot_force = slot_force_ds.ReadAll<double>();
  cam_pose = cam_pose_ds.ReadAll<double>();
  cam_lens = cam_lens_ds.ReadAll<double>();
  cam_head = cam_head_ds.ReadAll<double>();
  for (BodyIn& b : bodies) {
    b.node_count = b.node_count_ds.ReadAll<std::int64_t>();
    b.element_count = b.element_count_ds.ReadAll<std::int64_t>();
    const std::vector<std::int32_t> e = b.elements.ReadAll<std::int32_t>();
    b.tets.resize(e.size() / 4);
    std::copy(e.begin(), e.begin() + static_cast<std::ptrdiff_t>(4 * b.tets.size()),
              b.tets.empty() ? nullptr : b.tets[0].data());
    b.alive_elements.Load();
    if (b.removed_ds.valid()) b.removed = b.removed_ds.ReadAll<double>();
  }
  for (ThreadIn& t : threads) t.node_count = t.node_count_ds.ReadAll<std::int64_t>();
  for (BoneIn& b : bones) {
    b.vertices.Load();
    b.triangles.Load();
    b.removed = b.removed_ds.ReadAll<double>();
    if (b.by_region_ds.valid()) {
      b.by_region = b.by_region_ds.ReadAll<double>();
      const std::vector<hsize_t> d = b.by_region_ds.dims();
      b.by_region_columns = d.size() == 2 ? static_cast<std::size_t>(d[1]) : 0;
    }
  }
  constraints.Load();
  contacts.Load();
  for (Blocks* b : {&holes, &anchors}) {
    if (b->data.valid()) b->Load();
  }
}

RunReader::RunReader(const std::string& path) : impl_(std::make_unique<Impl>()) {
  impl_->path = path;
  try {
    impl_->file = h5::File::OpenReadOnly(path, true);
    impl_->Open();
    impl_->Load();
  } catch (const h5::Error& e) {
    throw InputError(path, 0, "", std::string("cannot read run file: ") + e.what());
  }
}

RunReader::~RunReader() = default;
RunReader::RunReader(RunReader&&) noexcept = default;
RunReader& RunReader::operator=(RunReader&&) noexcept = default;

const RunInfo& RunReader::info() const { return impl_->info; }
std::int64_t RunReader::frame_count() const { return impl_->frames; }

std::int64_t RunReader::Refresh() {
  Impl& m = *impl_;
  for (h5::Dataset* d : m.per_frame) d->Refresh();
  m.events.Refresh();
  for (BodyIn& b : m.bodies) {
    b.elements.Refresh();
    b.alive_elements.data.Refresh();
  }
  for (BoneIn& b : m.bones) {
    b.vertices.data.Refresh();
    b.triangles.data.Refresh();
  }
  m.constraints.data.Refresh();
  m.contacts.data.Refresh();
  for (Blocks* b : {&m.holes, &m.anchors}) {
    if (b->data.valid()) b->Refresh();
  }
  m.Load();
  return m.frames;
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
  out.step = m.step[t];
  out.time_s = m.time[t];
  out.rng_state = m.rng[t];
  out.next_constraint_id = m.next_id[t];

  out.soft_bodies.resize(m.bodies.size());
  for (std::size_t i = 0; i < m.bodies.size(); ++i) {
    const BodyIn& b = m.bodies[i];
    SoftBodyState& s = out.soft_bodies[i];
    const auto n = static_cast<hsize_t>(b.node_count[t]);
    const auto e = static_cast<std::size_t>(b.element_count[t]);
    s.x.resize(3, static_cast<Eigen::Index>(n));
    b.positions.Read({th, 0, 0}, {1, n, 3}, H5T_NATIVE_DOUBLE, s.x.data());
    s.tets.assign(b.tets.begin(), b.tets.begin() + static_cast<std::ptrdiff_t>(e));
    s.tet_alive.resize(e);
    b.element_alive.Read({th, 0}, {1, e}, H5T_NATIVE_UINT8, s.tet_alive.data());
    s.removed_volume_mm3 = b.removed.empty() ? 0.0 : b.removed[t];
    s.cauterized.clear();
    if (b.cauterized_ds.valid()) {
      // Stored per node with zero padding; State keeps it empty while nothing is marked.
      std::vector<std::uint8_t> marks(n);
      b.cauterized_ds.Read({th, 0}, {1, n}, H5T_NATIVE_UINT8, marks.data());
      if (std::find(marks.begin(), marks.end(), 1) != marks.end()) s.cauterized = std::move(marks);
    }
    s.v.resize(3, 0);
    s.x_rest.resize(3, 0);
    s.dv_warm.resize(3, 0);
  }

  out.threads.resize(m.threads.size());
  for (std::size_t i = 0; i < m.threads.size(); ++i) {
    const ThreadIn& d = m.threads[i];
    ThreadState& s = out.threads[i];
    const auto n = static_cast<hsize_t>(d.node_count[t]);
    s.x.resize(3, static_cast<Eigen::Index>(n));
    d.positions.Read({th, 0, 0}, {1, n, 3}, H5T_NATIVE_DOUBLE, s.x.data());
    s.node_alive.resize(n);
    d.node_alive.Read({th, 0}, {1, n}, H5T_NATIVE_UINT8, s.node_alive.data());
    s.v.resize(3, 0);
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
    s.removed_volume_mm3 = d.removed[t];
    const std::size_t w = d.by_region_columns;
    if (w > 0 && (static_cast<std::size_t>(t) + 1) * w <= d.by_region.size()) {
      const auto row =
          d.by_region.begin() + static_cast<std::ptrdiff_t>(static_cast<std::size_t>(t) * w);
      s.removed_by_region_mm3.assign(row, row + static_cast<std::ptrdiff_t>(w));
    }
    // Surfaces are stored once per change: the block offsets identify this frame's surface.
    s.revision = (static_cast<std::uint64_t>(voff) << 32) ^ static_cast<std::uint64_t>(toff);
  }

  for (std::size_t k2 = 0; k2 < kToolSlots; ++k2) {
    ToolState& s = out.tools[k2];
    const std::size_t r = t * kToolSlots + k2;
    s.instrument = m.slot_instrument[r];
    s.pose = PoseFromRow(&m.slot_pose[7 * r]);
    s.jaw = m.slot_jaw[r];
    s.buttons = m.slot_buttons[r];
    s.force_n = Vec3(m.slot_force[3 * r], m.slot_force[3 * r + 1], m.slot_force[3 * r + 2]);
  }
  out.camera.pose = PoseFromRow(&m.cam_pose[7 * t]);
  out.camera.lens_roll_rad = m.cam_lens[t];
  out.camera.head_roll_rad = m.cam_head[t];

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
