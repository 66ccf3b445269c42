#include "arthrosim/io/run_writer.h"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <exception>
#include <filesystem>
#include <limits>
#include <stdexcept>

#include "arthrosim/core/error.h"
#include "arthrosim/io/hdf5.h"
#include "arthrosim/io/hdf5_layout.h"
#include "arthrosim/io/xdmf.h"
#include "arthrosim/version.h"
#include "arthrosim_io_build_info.h"
#include "run_series.h"

namespace arthrosim::io {
namespace {

using detail::BlockSeries;
using detail::FrameSeries;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kZero = 0.0;
constexpr std::uint8_t kZeroU8 = 0;
constexpr std::int32_t kNoInstrument = -1;
constexpr std::int8_t kNoSlot = -1;

/// x y z qw qx qy qz (Eigen stores x y z w).
std::array<double, 7> PoseRow(const Pose& p) {
  return {p.position_mm.x(), p.position_mm.y(), p.position_mm.z(), p.orientation.w(),
          p.orientation.x(), p.orientation.y(), p.orientation.z()};
}

std::string UtcNow() {
  // Wall clock: metadata only, never part of the state datasets.
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

void CheckName(const Model& model, const std::string& field, const std::string& name) {
  if (name.empty() || name == "." || name == ".." || name.find('/') != std::string::npos) {
    throw InputError(model.scenario_path, 0, field,
                     "name '" + name + "' cannot name an HDF5 group (non-empty, no '/')");
  }
}

template <class Items>
void CheckNames(const Model& model, const std::string& field, const Items& items) {
  std::vector<std::string> seen;
  for (const auto& it : items) {
    CheckName(model, field, it.name);
    if (std::find(seen.begin(), seen.end(), it.name) != seen.end()) {
      throw InputError(model.scenario_path, 0, field, "duplicate name '" + it.name + "'");
    }
    seen.push_back(it.name);
  }
}

struct BodyOut {
  FrameSeries positions, node_count, element_count, element_alive;
  FrameSeries removed_volume, cauterized;  // operations: cut/shaved volume, cautery marks
  h5::Dataset elements;
  std::vector<mesh::Tet> written;  // rows of /elements so far (append-only check)
  BlockSeries alive_elements, xdmf_points;
};

struct ThreadOut {
  FrameSeries positions, node_count, node_alive;
  BlockSeries alive_segments, xdmf_points;
};

struct BoneOut {
  BlockSeries vertices, triangles;
  FrameSeries removed_volume, removed_by_region;
};

struct ToolOut {
  FrameSeries pose, jaw, buttons, force, active, slot;
};

}  // namespace

struct RunWriter::Impl {
  std::string path, xmf_path;
  RunWriterOptions options;
  // Copied from the Model (the writer does not keep a reference to it).
  std::vector<std::string> body_names, thread_names, bone_names;
  std::size_t instrument_count = 0;
  double flush_interval_s = 1.0;
  h5::File file;
  bool closed = false;

  FrameSeries time, step, rng_state, next_constraint_id, events_end;
  h5::Dataset events;
  h5::Handle event_mem, event_file, constraint_mem, constraint_file, contact_mem, contact_file;
  std::vector<BodyOut> bodies;
  std::vector<ThreadOut> threads;
  std::vector<BoneOut> bones;
  std::vector<ToolOut> tools;
  FrameSeries slot_instrument, slot_pose, slot_jaw, slot_buttons, slot_force;
  FrameSeries camera_pose, camera_lens_roll, camera_head_roll;
  BlockSeries constraints, contacts;
  BlockSeries holes, anchors;  // float64 rows: HoleRow / AnchorRow of hdf5_layout.h

  std::int64_t frames = 0, flushed = 0;
  std::int64_t xdmf_frames = 0;     // frames in the sidecar as last written
  std::int64_t written_frames = 0;  // frames whose every dataset is in the file (/time last)
  std::int64_t last_step = std::numeric_limits<std::int64_t>::min();
  std::int64_t last_events_step = std::numeric_limits<std::int64_t>::min();
  std::int64_t events_total = 0, events_written = 0;
  double last_flush_time = 0;
  std::vector<layout::EventRecord> pending_events;  // recorded since the last frame
  std::vector<layout::EventRecord> frame_events;    // of buffered frames, not yet in the file
  std::vector<double> times;                        // mirror of /time for the .xmf

  // Scratch buffers reused every frame.
  std::vector<std::int32_t> ints;
  std::vector<std::uint8_t> marks;
  std::vector<float> floats;
  std::vector<layout::ConstraintRecord> records;
  std::vector<layout::ToolContactRecord> contact_records;
  mutable std::vector<int> seen;  // Validate: slots holding each instrument

  void CreateLayout(const Model& model, const State& initial);
  void Validate(const State& s) const;
  /// Buffers `s` as the next frame; writes the buffered block when it is full.
  void WriteFrame(const State& s);
  /// Writes every buffered frame to the file: all datasets, then /time (a frame counts once
  /// /time has it, so a reader never sees part of a frame).
  void WriteBlock();
  /// Calls f on every per-frame and block series except /time, in write order.
  template <class F>
  void ForEachSeries(F f);
  std::size_t BufferedBytes();
  void WriteXdmf();
};

void RunWriter::Impl::CreateLayout(const Model& model_ref, const State& initial) {
  const Model* model = &model_ref;
  const int z = options.deflate_level;
  const int zf = options.float_deflate_level;
  h5::Group& root = file.root();
  root.SetAttr("format", layout::kFormatName);
  root.SetAttr("format_version", layout::kFormatVersion);
  root.SetAttr("arthrosim_version", kVersion);
  root.SetAttr("scenario_name", model->name);
  root.SetAttr("scenario_sha256", model->scenario_sha256);
  root.SetAttr("dt", model->options.dt_s);
  root.SetAttr("output_every_steps", std::int64_t{model->options.output_every_steps});
  root.SetAttr("flush_interval", model->options.flush_interval_s);
  root.SetAttr("seed", static_cast<std::int64_t>(model->options.seed));

  h5::Group meta = root.CreateGroup(layout::kMeta);
  meta.CreateStringDataset("scenario_yaml", model->scenario_text);
  meta.SetAttr("scenario_path", model->scenario_path);
  meta.SetAttr("compiler", ARTHROSIM_IO_COMPILER);
  meta.SetAttr("cxx_flags", ARTHROSIM_IO_CXX_FLAGS);
  meta.SetAttr("build_type", ARTHROSIM_IO_BUILD_TYPE);
  meta.SetAttr("hdf5_version", h5::LibraryVersion());
  meta.SetAttr("created_utc", UtcNow());

  time.Create(root, "time", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {}, {}, nullptr, z);
  step.Create(root, "step", H5T_STD_I64LE, H5T_NATIVE_INT64, {}, {}, nullptr, z);
  rng_state.Create(root, "rng_state", H5T_STD_U64LE, H5T_NATIVE_UINT64, {}, {}, nullptr, z);
  next_constraint_id.Create(root, "next_constraint_id", H5T_STD_I64LE, H5T_NATIVE_INT64, {}, {},
                            nullptr, z);

  event_mem = layout::EventType(false);
  event_file = layout::EventType(true);
  {
    h5::DatasetSpec spec = h5::GrowingSpec({0}, sizeof(layout::EventRecord));
    spec.deflate = z;
    events = root.CreateDataset("events", event_file.get(), spec);
  }
  events_end.Create(root, "events_end", H5T_STD_I64LE, H5T_NATIVE_INT64, {}, {}, nullptr, z);

  h5::Group gb = root.CreateGroup(layout::kBodies);
  bodies.resize(model->soft_bodies.size());
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    const hsize_t n = static_cast<hsize_t>(initial.soft_bodies[i].x.cols());
    const hsize_t e = initial.soft_bodies[i].tets.size();
    h5::Group g = gb.CreateGroup(model->soft_bodies[i].name);
    g.SetAttr("index", static_cast<std::int64_t>(i));
    g.SetAttr("initial_nodes", static_cast<std::int64_t>(n));
    g.SetAttr("initial_elements", static_cast<std::int64_t>(e));
    BodyOut& b = bodies[i];
    b.positions.Create(g, "positions", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {n, 3}, {1}, &kNaN, zf);
    b.node_count.Create(g, "node_count", H5T_STD_I64LE, H5T_NATIVE_INT64, {}, {}, nullptr, z);
    b.element_count.Create(g, "element_count", H5T_STD_I64LE, H5T_NATIVE_INT64, {}, {}, nullptr, z);
    b.element_alive.Create(g, "element_alive", H5T_STD_U8LE, H5T_NATIVE_UINT8, {e}, {1}, &kZeroU8,
                           z);
    h5::DatasetSpec spec = h5::GrowingSpec({0, 4}, 4);
    spec.deflate = z;
    b.elements = g.CreateDataset("elements", H5T_STD_I32LE, spec);
    b.alive_elements.Create(g, "alive_elements", H5T_STD_I32LE, H5T_NATIVE_INT32, 4, 16, z);
    b.removed_volume.Create(g, "removed_volume", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {}, {}, nullptr,
                            z);
    b.cauterized.Create(g, "cauterized", H5T_STD_U8LE, H5T_NATIVE_UINT8, {n}, {1}, &kZeroU8, z);
    b.xdmf_points.Create(g, "xdmf_points", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, 3, 12, zf);
  }

  h5::Group gt = root.CreateGroup(layout::kThreads);
  threads.resize(model->threads.size());
  for (std::size_t i = 0; i < threads.size(); ++i) {
    const hsize_t n = static_cast<hsize_t>(initial.threads[i].x.cols());
    h5::Group g = gt.CreateGroup(model->threads[i].name);
    g.SetAttr("index", static_cast<std::int64_t>(i));
    g.SetAttr("diameter_mm", model->threads[i].diameter_mm);
    ThreadOut& t = threads[i];
    t.positions.Create(g, "positions", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {n, 3}, {1}, &kNaN, zf);
    t.node_count.Create(g, "node_count", H5T_STD_I64LE, H5T_NATIVE_INT64, {}, {}, nullptr, z);
    t.node_alive.Create(g, "node_alive", H5T_STD_U8LE, H5T_NATIVE_UINT8, {n}, {1}, &kZeroU8, z);
    t.alive_segments.Create(g, "alive_segments", H5T_STD_I32LE, H5T_NATIVE_INT32, 2, 8, z);
    t.xdmf_points.Create(g, "xdmf_points", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, 3, 12, zf);
  }

  h5::Group gbo = root.CreateGroup(layout::kBones);
  bones.resize(model->bones.size());
  for (std::size_t i = 0; i < bones.size(); ++i) {
    h5::Group g = gbo.CreateGroup(model->bones[i].name);
    g.SetAttr("index", static_cast<std::int64_t>(i));
    g.SetAttr("hardness", model->bones[i].hardness);
    bones[i].vertices.Create(g, "vertices", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 3, 24, zf);
    bones[i].triangles.Create(g, "triangles", H5T_STD_I32LE, H5T_NATIVE_INT32, 3, 12, z);
    bones[i].removed_volume.Create(g, "removed_volume", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {}, {},
                                   nullptr, z);
    // One column per Model region (in scenario order) plus "elsewhere".
    std::string columns;
    for (const Region& r : model->regions) columns += r.name + ",";
    g.SetAttr("removed_by_region_columns", columns + "elsewhere");
    bones[i].removed_by_region.Create(g, "removed_volume_by_region", H5T_IEEE_F64LE,
                                      H5T_NATIVE_DOUBLE, {model->regions.size() + 1}, {}, nullptr,
                                      z);
  }

  h5::Group gto = root.CreateGroup(layout::kTools);
  tools.resize(model->instruments.size());
  for (std::size_t i = 0; i < tools.size(); ++i) {
    const InstrumentModel& im = model->instruments[i];
    h5::Group g = gto.CreateGroup(im.name);
    g.SetAttr("index", static_cast<std::int64_t>(i));
    g.SetAttr("kind", InstrumentKindName(im.kind));
    g.SetAttr("portal", im.portal);
    ToolOut& t = tools[i];
    t.pose.Create(g, "pose", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {7}, {}, &kNaN, z);
    t.jaw.Create(g, "jaw", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {}, {}, nullptr, z);
    t.buttons.Create(g, "buttons", H5T_STD_U8LE, H5T_NATIVE_UINT8, {}, {}, nullptr, z);
    t.force.Create(g, "force", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {3}, {}, nullptr, z);
    t.active.Create(g, "active", H5T_STD_U8LE, H5T_NATIVE_UINT8, {}, {}, nullptr, z);
    t.slot.Create(g, "slot", H5T_STD_I8LE, H5T_NATIVE_INT8, {}, {}, &kNoSlot, z);
  }

  h5::Group gs = root.CreateGroup(layout::kToolSlots);
  constexpr hsize_t kS = kToolSlots;
  slot_instrument.Create(gs, "instrument", H5T_STD_I32LE, H5T_NATIVE_INT32, {kS}, {},
                         &kNoInstrument, z);
  slot_pose.Create(gs, "pose", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {kS, 7}, {}, nullptr, z);
  slot_jaw.Create(gs, "jaw", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {kS}, {}, nullptr, z);
  slot_buttons.Create(gs, "buttons", H5T_STD_U8LE, H5T_NATIVE_UINT8, {kS}, {}, nullptr, z);
  slot_force.Create(gs, "force", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {kS, 3}, {}, nullptr, z);

  h5::Group gc = root.CreateGroup(layout::kCamera);
  camera_pose.Create(gc, "pose", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {7}, {}, nullptr, z);
  camera_lens_roll.Create(gc, "lens_roll", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {}, {}, nullptr, z);
  camera_head_roll.Create(gc, "head_roll", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {}, {}, nullptr, z);

  h5::Group gk = root.CreateGroup(layout::kConstraints);
  constraint_mem = layout::ConstraintType(false);
  constraint_file = layout::ConstraintType(true);
  constraints.Create(gk, "rows", constraint_file.get(), constraint_mem.get(), 0,
                     sizeof(layout::ConstraintRecord), z);

  h5::Group gtc = root.CreateGroup(layout::kToolContacts);
  contact_mem = layout::ToolContactType(false);
  contact_file = layout::ToolContactType(true);
  contacts.Create(gtc, "rows", contact_file.get(), contact_mem.get(), 0,
                  sizeof(layout::ToolContactRecord), z);

  h5::Group gho = root.CreateGroup(layout::kHoles);
  holes.Create(gho, "rows", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, layout::kHoleColumns,
               sizeof(double) * layout::kHoleColumns, z);
  h5::Group gan = root.CreateGroup(layout::kAnchors);
  anchors.Create(gan, "rows", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, layout::kAnchorColumns,
                 sizeof(double) * layout::kAnchorColumns, z);
}

template <class F>
void RunWriter::Impl::ForEachSeries(F f) {
  for (BodyOut& b : bodies) {
    f(b.positions), f(b.node_count), f(b.element_count), f(b.element_alive);
    f(b.removed_volume), f(b.cauterized);
    f(b.alive_elements), f(b.xdmf_points);
  }
  for (ThreadOut& t : threads) {
    f(t.positions), f(t.node_count), f(t.node_alive), f(t.alive_segments), f(t.xdmf_points);
  }
  for (BoneOut& b : bones)
    f(b.vertices), f(b.triangles), f(b.removed_volume), f(b.removed_by_region);
  for (ToolOut& o : tools) f(o.pose), f(o.jaw), f(o.buttons), f(o.force), f(o.active), f(o.slot);
  f(slot_instrument), f(slot_pose), f(slot_jaw), f(slot_buttons), f(slot_force);
  f(camera_pose), f(camera_lens_roll), f(camera_head_roll);
  f(constraints), f(contacts), f(holes), f(anchors);
  f(events_end), f(rng_state), f(next_constraint_id), f(step);
}

std::size_t RunWriter::Impl::BufferedBytes() {
  std::size_t bytes = time.buffered_bytes() + frame_events.size() * sizeof(layout::EventRecord);
  ForEachSeries([&](const auto& series) { bytes += series.buffered_bytes(); });
  return bytes;
}

void RunWriter::Impl::WriteBlock() {
  if (!frame_events.empty()) {  // the rows before /events_end refers to them
    const hsize_t n = frame_events.size();
    const hsize_t extent = static_cast<hsize_t>(events_written) + n;
    const hsize_t start = static_cast<hsize_t>(events_written);
    events.SetExtent(1, &extent);
    events.Write(1, &start, &n, event_mem.get(), frame_events.data());
    events_written += static_cast<std::int64_t>(n);
    frame_events.clear();
  }
  ForEachSeries([](auto& series) { series.WriteOut(); });
  time.WriteOut();
  written_frames = frames;
}

void RunWriter::Impl::Validate(const State& s) const {
  auto fail = [&](const std::string& what) {
    throw std::invalid_argument("RunWriter('" + path + "'): step " + std::to_string(s.step) + ": " +
                                what);
  };
  if (frames > 0 && s.step <= last_step) {
    fail("step must increase (last frame was step " + std::to_string(last_step) + ")");
  }
  if (s.soft_bodies.size() != body_names.size() || s.threads.size() != thread_names.size() ||
      s.bones.size() != bone_names.size()) {
    fail("State has other body/thread/bone counts than the Model");
  }
  for (std::size_t i = 0; i < body_names.size(); ++i) {
    const SoftBodyState& b = s.soft_bodies[i];
    const std::string& name = body_names[i];
    if (b.tets.size() != b.tet_alive.size()) fail("body '" + name + "': tet_alive size");
    if (i < bodies.size()) {  // not yet created while the initial state is checked
      const std::vector<mesh::Tet>& w = bodies[i].written;
      if (b.tets.size() < w.size() || !std::equal(w.begin(), w.end(), b.tets.begin())) {
        fail("body '" + name + "': tets changed in place (only appending is supported)");
      }
    }
    const auto n = static_cast<std::int32_t>(b.x.cols());
    for (const mesh::Tet& t : b.tets) {
      for (std::int32_t v : t) {
        if (v < 0 || v >= n) fail("body '" + name + "': tet node index out of range");
      }
    }
  }
  for (std::size_t i = 0; i < thread_names.size(); ++i) {
    if (s.threads[i].node_alive.size() != static_cast<std::size_t>(s.threads[i].x.cols())) {
      fail("thread '" + thread_names[i] + "': node_alive size");
    }
  }
  for (std::size_t i = 0; i < bone_names.size(); ++i) {
    const auto n = static_cast<std::int32_t>(s.bones[i].surface.nodes.cols());
    for (const mesh::Tri& t : s.bones[i].surface.tris) {
      for (std::int32_t v : t) {
        if (v < 0 || v >= n) fail("bone '" + bone_names[i] + "': index out of range");
      }
    }
  }
  seen.assign(instrument_count, 0);
  for (const ToolState& t : s.tools) {
    if (t.instrument < -1 || t.instrument >= static_cast<int>(instrument_count)) {
      fail("tool slot holds unknown instrument " + std::to_string(t.instrument));
    }
    if (t.instrument >= 0 && seen[static_cast<std::size_t>(t.instrument)]++ > 0) {
      fail("an instrument is in two slots");
    }
  }
}

void RunWriter::Impl::WriteFrame(const State& s) {
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    const SoftBodyState& sb = s.soft_bodies[i];
    BodyOut& b = bodies[i];
    const auto n = static_cast<hsize_t>(sb.x.cols());
    const hsize_t e = sb.tets.size();
    b.positions.Write({n, 3}, sb.x.data());
    b.node_count.Push(static_cast<std::int64_t>(n));
    if (e > b.written.size()) {  // tets appended by splitting
      const std::size_t first = b.written.size();
      b.elements.AppendRows(H5T_NATIVE_INT32, sb.tets[first].data(), e - first);
      b.written.insert(b.written.end(), sb.tets.begin() + static_cast<std::ptrdiff_t>(first),
                       sb.tets.end());
    }
    b.element_count.Push(static_cast<std::int64_t>(e));
    b.element_alive.Write({e}, sb.tet_alive.data());
    b.removed_volume.Push(sb.removed_volume_mm3);
    marks.assign(n, 0);  // per node; nodes past the State's vector are unmarked
    std::copy_n(sb.cauterized.begin(), std::min<std::size_t>(sb.cauterized.size(), n),
                marks.begin());
    b.cauterized.Write({n}, marks.data());
    ints.clear();
    for (std::size_t k = 0; k < e; ++k) {
      if (sb.tet_alive[k] != 0) ints.insert(ints.end(), sb.tets[k].begin(), sb.tets[k].end());
    }
    b.alive_elements.Write(ints.data(), static_cast<std::int64_t>(ints.size() / 4));
    floats.assign(sb.x.data(), sb.x.data() + sb.x.size());
    b.xdmf_points.Write(floats.data(), static_cast<std::int64_t>(n));
  }

  for (std::size_t i = 0; i < threads.size(); ++i) {
    const ThreadState& st = s.threads[i];
    ThreadOut& th = threads[i];
    const auto n = static_cast<hsize_t>(st.x.cols());
    th.positions.Write({n, 3}, st.x.data());
    th.node_count.Push(static_cast<std::int64_t>(n));
    th.node_alive.Write({n}, st.node_alive.data());
    ints.clear();
    for (hsize_t k = 0; k + 1 < n; ++k) {  // threads are chains 0-1-...-(n-1)
      if (st.node_alive[k] != 0 && st.node_alive[k + 1] != 0) {
        ints.push_back(static_cast<std::int32_t>(k));
        ints.push_back(static_cast<std::int32_t>(k + 1));
      }
    }
    th.alive_segments.Write(ints.data(), static_cast<std::int64_t>(ints.size() / 2));
    floats.assign(st.x.data(), st.x.data() + st.x.size());
    th.xdmf_points.Write(floats.data(), static_cast<std::int64_t>(n));
  }

  for (std::size_t i = 0; i < bones.size(); ++i) {
    const BoneState& sb = s.bones[i];
    bones[i].vertices.Write(sb.surface.nodes.data(),
                            static_cast<std::int64_t>(sb.surface.nodes.cols()));
    bones[i].triangles.Write(sb.surface.tris.empty() ? nullptr : sb.surface.tris[0].data(),
                             static_cast<std::int64_t>(sb.surface.tris.size()));
    bones[i].removed_volume.Push(sb.removed_volume_mm3);
    bones[i].removed_by_region.Write({sb.removed_by_region_mm3.size()},
                                     sb.removed_by_region_mm3.data());
  }

  // Per instrument of the Model: which slot holds it, if any.
  for (std::size_t i = 0; i < tools.size(); ++i) {
    const ToolState* held = nullptr;
    std::int8_t slot = -1;
    for (int k = 0; k < kToolSlots; ++k) {
      if (s.tools[static_cast<std::size_t>(k)].instrument == static_cast<std::int32_t>(i)) {
        held = &s.tools[static_cast<std::size_t>(k)];
        slot = static_cast<std::int8_t>(k);
      }
    }
    ToolOut& o = tools[i];
    std::array<double, 7> pose;
    pose.fill(kNaN);
    std::array<double, 3> force{0, 0, 0};
    double jaw = 0;
    std::uint8_t buttons = 0;
    if (held != nullptr) {
      pose = PoseRow(held->pose);
      force = {held->force_n.x(), held->force_n.y(), held->force_n.z()};
      jaw = held->jaw;
      buttons = held->buttons;
    }
    o.pose.Write({7}, pose.data());
    o.jaw.Push(jaw);
    o.buttons.Push(buttons);
    o.force.Write({3}, force.data());
    o.active.Push(static_cast<std::uint8_t>(held != nullptr ? 1 : 0));
    o.slot.Push(slot);
  }

  {
    std::array<std::int32_t, kToolSlots> inst{};
    std::array<double, kToolSlots * 7> pose{};
    std::array<double, kToolSlots> jaw{};
    std::array<std::uint8_t, kToolSlots> buttons{};
    std::array<double, kToolSlots * 3> force{};
    for (std::size_t k = 0; k < kToolSlots; ++k) {
      const ToolState& ts = s.tools[k];
      inst[k] = ts.instrument;
      const std::array<double, 7> p = PoseRow(ts.pose);
      std::copy(p.begin(), p.end(), pose.begin() + static_cast<std::ptrdiff_t>(7 * k));
      jaw[k] = ts.jaw;
      buttons[k] = ts.buttons;
      for (int c = 0; c < 3; ++c) force[3 * k + static_cast<std::size_t>(c)] = ts.force_n[c];
    }
    constexpr hsize_t kS = kToolSlots;
    slot_instrument.Write({kS}, inst.data());
    slot_pose.Write({kS, 7}, pose.data());
    slot_jaw.Write({kS}, jaw.data());
    slot_buttons.Write({kS}, buttons.data());
    slot_force.Write({kS, 3}, force.data());
  }

  const std::array<double, 7> cam = PoseRow(s.camera.pose);
  camera_pose.Write({7}, cam.data());
  camera_lens_roll.Push(s.camera.lens_roll_rad);
  camera_head_roll.Push(s.camera.head_roll_rad);

  records.clear();
  for (const SpringConstraint& c : s.constraints) records.push_back(layout::ToRecord(c));
  constraints.Write(records.data(), static_cast<std::int64_t>(records.size()));

  contact_records.clear();
  for (const ToolContact& c : s.tool_contacts) contact_records.push_back(layout::ToRecord(c));
  contacts.Write(contact_records.data(), static_cast<std::int64_t>(contact_records.size()));
  std::vector<double> rows;
  for (const BoneHole& h : s.holes) layout::AppendHoleRow(h, &rows);
  holes.Write(rows.data(), static_cast<std::int64_t>(s.holes.size()));
  rows.clear();
  for (const AnchorState& a : s.anchors) layout::AppendAnchorRow(a, &rows);
  anchors.Write(rows.data(), static_cast<std::int64_t>(s.anchors.size()));

  if (last_events_step != s.step) {
    for (const Event& e : s.events) pending_events.push_back(layout::ToRecord(e));
    last_events_step = s.step;
  }
  frame_events.insert(frame_events.end(), pending_events.begin(), pending_events.end());
  events_total += static_cast<std::int64_t>(pending_events.size());
  pending_events.clear();
  events_end.Push(events_total);

  rng_state.Push(s.rng_state);
  next_constraint_id.Push(s.next_constraint_id);
  step.Push(s.step);
  time.Push(s.time_s);  // last: a frame counts once /time has it
  times.push_back(s.time_s);
  last_step = s.step;
  ++frames;
  if (frames - written_frames >= options.block_frames || BufferedBytes() >= options.block_bytes) {
    WriteBlock();
  }
}

void RunWriter::Impl::WriteXdmf() {
  if (!options.write_xdmf) return;
  xdmf_frames = frames;
  XdmfRun run;
  run.h5_name = std::filesystem::path(path).filename().string();
  run.times = times;
  auto series = [](const BlockSeries& b, int columns, bool is_float, int precision) {
    XdmfSeries s;
    s.dataset = b.path();
    s.total_rows = b.total_rows();
    s.columns = columns;
    s.is_float = is_float;
    s.precision = precision;
    s.offset = b.offsets();
    s.count = b.counts();
    return s;
  };
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    run.meshes.push_back({"body:" + body_names[i], XdmfCell::kTetrahedron,
                          series(bodies[i].alive_elements, 4, false, 4),
                          series(bodies[i].xdmf_points, 3, true, 4)});
  }
  for (std::size_t i = 0; i < bones.size(); ++i) {
    run.meshes.push_back({"bone:" + bone_names[i], XdmfCell::kTriangle,
                          series(bones[i].triangles, 3, false, 4),
                          series(bones[i].vertices, 3, true, 8)});
  }
  for (std::size_t i = 0; i < threads.size(); ++i) {
    run.meshes.push_back({"thread:" + thread_names[i], XdmfCell::kPolyline,
                          series(threads[i].alive_segments, 2, false, 4),
                          series(threads[i].xdmf_points, 3, true, 4)});
  }
  WriteFileAtomically(xmf_path, XdmfText(run));
}

// ---- public ---------------------------------------------------------------------------------

RunWriter::RunWriter(const std::string& path, const Model& model, const State& initial,
                     RunWriterOptions options)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.path = path;
  m.options = options;
  for (const SoftBodyModel& b : model.soft_bodies) m.body_names.push_back(b.name);
  for (const ThreadModel& t : model.threads) m.thread_names.push_back(t.name);
  for (const BoneModel& b : model.bones) m.bone_names.push_back(b.name);
  m.instrument_count = model.instruments.size();
  m.flush_interval_s = model.options.flush_interval_s;
  m.xmf_path = options.write_xdmf ? XdmfPathFor(path) : "";
  if (options.deflate_level < 0 || options.deflate_level > 9 || options.float_deflate_level < 0 ||
      options.float_deflate_level > 9) {
    throw std::invalid_argument("RunWriter: deflate levels must be in 0..9");
  }
  if (options.block_frames < 1) throw std::invalid_argument("RunWriter: block_frames must be >= 1");
  CheckNames(model, "bodies.name", model.soft_bodies);
  CheckNames(model, "bodies.name", model.threads);
  CheckNames(model, "bodies.name", model.bones);
  CheckNames(model, "instruments.name", model.instruments);
  m.Validate(initial);

  namespace fs = std::filesystem;
  const fs::path p(path);
  std::error_code ec;
  if (path.empty()) throw InputError(path, 0, "output_file", "empty output file name");
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  if (!fs::is_directory(dir, ec)) {
    throw InputError(path, 0, "output_file",
                     "cannot create the run file: directory '" + dir.string() + "' does not exist");
  }
  if (fs::is_directory(p, ec)) {
    throw InputError(path, 0, "output_file", "cannot create the run file: it is a directory");
  }
  try {
    m.file = h5::File::Create(path);
  } catch (const h5::Error& e) {
    throw InputError(path, 0, "output_file",
                     std::string("cannot create the run file: ") + e.what());
  }
  try {
    m.CreateLayout(model, initial);
    m.file.StartSwmrWrite();  // from here on no object may be created
    m.WriteFrame(initial);
    m.WriteBlock();
    m.file.Flush();
    m.flushed = m.frames;
    m.last_flush_time = initial.time_s;
    m.WriteXdmf();
  } catch (...) {
    // Do not leave a half-made file behind.
    try {
      m.file.Close();
    } catch (...) {
    }
    fs::remove(p, ec);
    if (!m.xmf_path.empty()) fs::remove(m.xmf_path, ec);
    throw;
  }
}

RunWriter::~RunWriter() {
  try {
    Close();
  } catch (...) {  // NOLINT(bugprone-empty-catch): a destructor must not throw
  }
}

void RunWriter::RecordEvents(const State& s) {
  Impl& m = *impl_;
  if (m.closed) throw std::logic_error("RunWriter: RecordEvents after Close");
  if (s.step == m.last_events_step) return;
  for (const Event& e : s.events) m.pending_events.push_back(layout::ToRecord(e));
  m.last_events_step = s.step;
}

void RunWriter::Append(const State& s) {
  Impl& m = *impl_;
  if (m.closed) throw std::logic_error("RunWriter: Append after Close");
  m.Validate(s);
  m.WriteFrame(s);
  if (s.time_s - m.last_flush_time >= m.flush_interval_s) Flush();
}

void RunWriter::Flush() {
  Impl& m = *impl_;
  if (m.closed) throw std::logic_error("RunWriter: Flush after Close");
  m.WriteBlock();
  m.file.Flush();
  m.flushed = m.frames;
  m.last_flush_time = m.times.empty() ? 0.0 : m.times.back();
  // The sidecar is rewritten whole (every frame's entry names the datasets' current sizes), so
  // rewriting it at every flush would cost O(frames^2) over a long session: beyond
  // `xdmf_every_flush_frames` frames it is rewritten once it lags by the growth fraction, and
  // always at Close (`arthrosim info RUN.h5 --write-xdmf` rebuilds it from a killed run).
  const auto lagging = static_cast<double>(m.frames - m.xdmf_frames);
  if (m.frames <= m.options.xdmf_every_flush_frames ||
      lagging >= m.options.xdmf_growth * static_cast<double>(m.xdmf_frames)) {
    m.WriteXdmf();
  }
}

void RunWriter::Close() {
  Impl& m = *impl_;
  if (m.closed) return;
  m.closed = true;  // even if what follows throws: never write to a half-closed file
  std::exception_ptr error;
  try {
    m.WriteBlock();
    m.file.Flush();
    m.flushed = m.frames;
  } catch (...) {
    error = std::current_exception();
  }
  try {
    m.file.Close();  // always, so that the file is left consistent
  } catch (...) {
    if (!error) error = std::current_exception();
  }
  if (error) std::rethrow_exception(error);
  m.WriteXdmf();
}

std::int64_t RunWriter::frames() const { return impl_->frames; }
std::int64_t RunWriter::flushed_frames() const { return impl_->flushed; }
const std::string& RunWriter::path() const { return impl_->path; }
const std::string& RunWriter::xdmf_path() const { return impl_->xmf_path; }

}  // namespace arthrosim::io
