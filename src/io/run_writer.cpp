#include "arthrosim/io/run_writer.h"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <exception>
#include <filesystem>
#include <limits>
#include <stdexcept>
#include <type_traits>

#include "arthrosim/core/error.h"
#include "arthrosim/io/hdf5.h"
#include "arthrosim/io/hdf5_layout.h"
#include "arthrosim/io/xdmf.h"
#include "arthrosim/version.h"
#include "arthrosim_io_build_info.h"
#include "run_series.h"
#include "state_datasets.h"

namespace arthrosim::io {
namespace {

using detail::BlockSeries;
using detail::FrameSeries;

using detail::PoseRow;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr std::int8_t kNoSlot = -1;

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

/// The per-frame datasets of an entity's fields stored per frame (FieldStore::kFrame), in the
/// order the State field table visits them.
struct FieldSet {
  std::vector<FrameSeries> series;
  std::vector<detail::ValueType> types;
  std::vector<std::vector<unsigned char>> rows;  // per-slot values gathered for one frame
  std::vector<std::size_t> row_bytes;            // bytes of one slot's value
  std::vector<std::uint8_t> pad;                 // per-node marks padded to the node count
};

/// Creates a dataset in g for every per-frame field of `sample` (rows of `slots` values when
/// slots > 0). `skip` (a member of sample, or nullptr) gets none.
template <class S>
void CreateFields(h5::Group& g, const S& sample, hsize_t slots, int z, int zf, FieldSet* out,
                  const void* skip = nullptr, bool nan_poses = false, hsize_t nodes = 0) {
  VisitFields(sample, [&](const auto& value, const FieldInfo& info) {
    using T = std::decay_t<decltype(value)>;
    if (info.store != FieldStore::kFrame || static_cast<const void*>(&value) == skip) return;
    if constexpr (detail::kFrameValue<T>) {
      const detail::ValueType t = detail::TypeOf<T>();
      std::vector<hsize_t> row;
      std::vector<int> grow;
      if (slots > 0) row.push_back(slots);
      if (t.per_node) {
        row.push_back(info.dim == FieldDim::kNodes && nodes > 0 ? nodes : detail::RowsOf(value));
        grow.push_back(static_cast<int>(row.size()));
      }
      if (t.row_vector) row.push_back(detail::RowsOf(value));
      if (t.width > 0) row.push_back(t.width);
      const FieldFill fill = nan_poses && std::is_same_v<T, Pose> ? FieldFill::kNaN : info.fill;
      out->series.emplace_back().Create(g, info.name, t.file, t.mem, row, grow,
                                        detail::FillOf<T>(fill), info.bulk_float ? zf : z);
      out->types.push_back(t);
      const std::size_t bytes = detail::BytesOf(value);
      out->row_bytes.push_back(bytes);
      out->rows.emplace_back(bytes * (slots > 0 ? slots : 1));
    } else {
      throw std::logic_error(std::string("RunWriter: field '") + info.name +
                             "' has a type that cannot be stored per frame");
    }
  });
}

/// Buffers one frame of a dataset: `rows` rows (nodes, elements; 1 for fixed shapes).
void WriteRow(FrameSeries& series, const detail::ValueType& t, hsize_t slots, hsize_t rows,
              const void* data) {
  const hsize_t w = t.width;
  if (slots > 0) {
    if (w > 0) return series.Write({slots, w}, data);
    return series.Write({slots}, data);
  }
  if (t.per_node || t.row_vector) {
    if (w > 0) return series.Write({rows, w}, data);
    return series.Write({rows}, data);
  }
  if (w > 0) return series.Write({w}, data);
  series.Write({}, data);
}

/// Buffers the per-frame fields of s (one entity with `nodes` nodes) as the next frame. Per-node
/// marks shorter than the node count are padded with zeros. No heap allocation in steady state.
template <class S>
void WriteFields(const S& s, FieldSet* f, const void* skip = nullptr, hsize_t nodes = 0) {
  std::size_t i = 0;
  std::array<double, 7> pose;
  VisitFields(s, [&](const auto& value, const FieldInfo& info) {
    using T = std::decay_t<decltype(value)>;
    if (info.store != FieldStore::kFrame || static_cast<const void*>(&value) == skip) return;
    if constexpr (std::is_same_v<T, std::vector<std::uint8_t>>) {
      if (info.dim == FieldDim::kNodes && value.size() != nodes) {
        f->pad.assign(nodes, 0);
        std::copy_n(value.begin(), std::min<std::size_t>(value.size(), nodes), f->pad.begin());
        WriteRow(f->series[i], f->types[i], 0, nodes, f->pad.data());
        ++i;
        return;
      }
    }
    if constexpr (detail::kFrameValue<T>) {
      WriteRow(f->series[i], f->types[i], 0, detail::RowsOf(value), detail::DataOf(value, &pose));
      ++i;
    }
  });
}

/// Buffers one frame of per-slot fields: field j of every slot as one [slots, ...] row.
template <class S, std::size_t N>
void WriteSlotFields(const std::array<S, N>& slots, FieldSet* f) {
  std::array<double, 7> pose;
  for (std::size_t k = 0; k < N; ++k) {
    std::size_t j = 0;
    VisitFields(slots[k], [&](const auto& value, const FieldInfo& info) {
      using T = std::decay_t<decltype(value)>;
      if (info.store != FieldStore::kFrame) return;
      if constexpr (detail::kFrameValue<T>) {
        const auto* p = static_cast<const unsigned char*>(detail::DataOf(value, &pose));
        std::copy(p, p + f->row_bytes[j], f->rows[j].data() + k * f->row_bytes[j]);
        ++j;
      }
    });
  }
  for (std::size_t j = 0; j < f->series.size(); ++j) {
    WriteRow(f->series[j], f->types[j], N, 1, f->rows[j].data());
  }
}

/// Calls f on every series of a field set.
template <class F>
void ForEach(FieldSet& set, F& f) {
  for (FrameSeries& s : set.series) f(s);
}

struct BodyOut {
  FieldSet fields;
  FrameSeries node_count, element_count;
  h5::Dataset elements;
  std::vector<mesh::Tet> written;  // rows of /elements so far (append-only check)
  BlockSeries alive_elements, xdmf_points;
};

struct ThreadOut {
  FieldSet fields;
  FrameSeries node_count;
  BlockSeries alive_segments, xdmf_points;
};

struct BoneOut {
  FieldSet fields;
  BlockSeries vertices, triangles;
};

/// The per-instrument view of the tool slots (/tools/<instrument>).
struct ToolOut {
  FieldSet fields;  // the slot's fields but `instrument`; NaN pose while not inserted
  FrameSeries active, slot;
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

  FieldSet root_fields;         // step, time, next_constraint_id, rng_state
  std::size_t time_series = 0;  // index of /time in root_fields: written last
  FrameSeries events_end;
  h5::Dataset events;
  h5::Handle event_mem, event_file, constraint_mem, constraint_file, contact_mem, contact_file;
  std::vector<BodyOut> bodies;
  std::vector<ThreadOut> threads;
  std::vector<BoneOut> bones;
  std::vector<ToolOut> tools;
  ToolState absent;  // what /tools/<instrument> holds while it is not inserted
  FieldSet slots, camera;
  BlockSeries constraints, contacts;
  BlockSeries holes, anchors;  // float64 rows: AppendHoleRow / AppendAnchorRow of hdf5_layout.h

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
  std::vector<float> floats;
  std::vector<layout::ConstraintRecord> records;
  std::vector<layout::ToolContactRecord> contact_records;
  std::vector<double> record_rows;
  mutable std::vector<int> seen;  // Validate: slots holding each instrument

  void CreateLayout(const Model& model, const State& initial);
  void CreateRoot(const Model& model, const State& initial);
  void CreateBodies(const Model& model, const State& initial);
  void CreateThreads(const Model& model, const State& initial);
  void CreateBones(const Model& model, const State& initial);
  void CreateTools(const Model& model, const State& initial);
  void CreateRecords();
  void Validate(const State& s) const;
  /// Buffers `s` as the next frame; writes the buffered block when it is full.
  void WriteFrame(const State& s);
  void WriteBodies(const State& s);
  void WriteThreads(const State& s);
  void WriteBones(const State& s);
  void WriteInstruments(const State& s);
  void WriteRecords(const State& s);
  void WriteEvents(const State& s);
  /// Writes every buffered frame to the file: all datasets, then /time (a frame counts once
  /// /time has it, so a reader never sees part of a frame).
  void WriteBlock();
  /// Calls f on every per-frame and block series except /time, in write order.
  template <class F>
  void ForEachSeries(F f);
  std::size_t BufferedBytes();
  void WriteXdmf();
};

void RunWriter::Impl::CreateLayout(const Model& model, const State& initial) {
  CreateRoot(model, initial);
  CreateBodies(model, initial);
  CreateThreads(model, initial);
  CreateBones(model, initial);
  CreateTools(model, initial);
  CreateRecords();
}

void RunWriter::Impl::CreateRoot(const Model& model, const State& initial) {
  const int z = options.deflate_level;
  h5::Group& root = file.root();
  root.SetAttr("format", layout::kFormatName);
  root.SetAttr("format_version", layout::kFormatVersion);
  root.SetAttr("arthrosim_version", kVersion);
  root.SetAttr("scenario_name", model.name);
  root.SetAttr("scenario_sha256", model.scenario_sha256);
  root.SetAttr("dt", model.options.dt_s);
  root.SetAttr("output_every_steps", std::int64_t{model.options.output_every_steps});
  root.SetAttr("flush_interval", model.options.flush_interval_s);
  root.SetAttr("seed", static_cast<std::int64_t>(model.options.seed));

  h5::Group meta = root.CreateGroup(layout::kMeta);
  meta.CreateStringDataset("scenario_yaml", model.scenario_text);
  meta.SetAttr("scenario_path", model.scenario_path);
  meta.SetAttr("compiler", ARTHROSIM_IO_COMPILER);
  meta.SetAttr("cxx_flags", ARTHROSIM_IO_CXX_FLAGS);
  meta.SetAttr("build_type", ARTHROSIM_IO_BUILD_TYPE);
  meta.SetAttr("hdf5_version", h5::LibraryVersion());
  meta.SetAttr("created_utc", UtcNow());

  CreateFields(root, initial, 0, z, options.float_deflate_level, &root_fields);
  std::size_t i = 0;
  VisitFields(initial, [&](const auto& value, const FieldInfo& info) {
    if (info.store != FieldStore::kFrame) return;
    if (static_cast<const void*>(&value) == &initial.time_s) time_series = i;
    ++i;
  });

  event_mem = layout::EventType(false);
  event_file = layout::EventType(true);
  h5::DatasetSpec spec = h5::GrowingSpec({0}, sizeof(layout::EventRecord));
  spec.deflate = z;
  events = root.CreateDataset(layout::kEvents, event_file.get(), spec);
  events_end.Create(root, layout::kEventsEnd, H5T_STD_I64LE, H5T_NATIVE_INT64, {}, {}, nullptr, z);
}

void RunWriter::Impl::CreateBodies(const Model& model, const State& initial) {
  const int z = options.deflate_level;
  const int zf = options.float_deflate_level;
  h5::Group gb = file.root().CreateGroup(layout::kBodies);
  bodies.resize(model.soft_bodies.size());
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    const SoftBodyState& sb = initial.soft_bodies[i];
    h5::Group g = gb.CreateGroup(model.soft_bodies[i].name);
    g.SetAttr("index", static_cast<std::int64_t>(i));
    g.SetAttr("initial_nodes", static_cast<std::int64_t>(sb.x.cols()));
    g.SetAttr("initial_elements", static_cast<std::int64_t>(sb.tets.size()));
    BodyOut& b = bodies[i];
    CreateFields(g, sb, 0, z, zf, &b.fields, nullptr, false, static_cast<hsize_t>(sb.x.cols()));
    b.node_count.Create(g, layout::kNodeCount, H5T_STD_I64LE, H5T_NATIVE_INT64, {}, {}, nullptr, z);
    b.element_count.Create(g, layout::kElementCount, H5T_STD_I64LE, H5T_NATIVE_INT64, {}, {},
                           nullptr, z);
    VisitFields(sb, [&](const auto& value, const FieldInfo& info) {
      if (static_cast<const void*>(&value) != &sb.tets) return;
      h5::DatasetSpec spec = h5::GrowingSpec({0, 4}, 4);
      spec.deflate = z;
      b.elements = g.CreateDataset(info.name, H5T_STD_I32LE, spec);
    });
    b.alive_elements.Create(g, layout::kAliveElements, H5T_STD_I32LE, H5T_NATIVE_INT32, 4, 16, z);
    b.xdmf_points.Create(g, layout::kXdmfPoints, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, 3, 12, zf);
  }
}

void RunWriter::Impl::CreateThreads(const Model& model, const State& initial) {
  const int z = options.deflate_level;
  const int zf = options.float_deflate_level;
  h5::Group gt = file.root().CreateGroup(layout::kThreads);
  threads.resize(model.threads.size());
  for (std::size_t i = 0; i < threads.size(); ++i) {
    h5::Group g = gt.CreateGroup(model.threads[i].name);
    g.SetAttr("index", static_cast<std::int64_t>(i));
    g.SetAttr("diameter_mm", model.threads[i].diameter_mm);
    ThreadOut& t = threads[i];
    CreateFields(g, initial.threads[i], 0, z, zf, &t.fields, nullptr, false,
                 static_cast<hsize_t>(initial.threads[i].x.cols()));
    t.node_count.Create(g, layout::kNodeCount, H5T_STD_I64LE, H5T_NATIVE_INT64, {}, {}, nullptr, z);
    t.alive_segments.Create(g, layout::kAliveSegments, H5T_STD_I32LE, H5T_NATIVE_INT32, 2, 8, z);
    t.xdmf_points.Create(g, layout::kXdmfPoints, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, 3, 12, zf);
  }
}

void RunWriter::Impl::CreateBones(const Model& model, const State& initial) {
  const int z = options.deflate_level;
  const int zf = options.float_deflate_level;
  h5::Group gbo = file.root().CreateGroup(layout::kBones);
  bones.resize(model.bones.size());
  for (std::size_t i = 0; i < bones.size(); ++i) {
    h5::Group g = gbo.CreateGroup(model.bones[i].name);
    g.SetAttr("index", static_cast<std::int64_t>(i));
    g.SetAttr("hardness", model.bones[i].hardness);
    // Columns of removed_volume_by_region: one per Model region (in scenario order), "elsewhere".
    std::string columns;
    for (const Region& r : model.regions) columns += r.name + ",";
    g.SetAttr("removed_by_region_columns", columns + "elsewhere");
    const mesh::TriMesh& surface = initial.bones[i].surface;
    VisitFields(surface, [&](const auto& value, const FieldInfo& info) {
      if (static_cast<const void*>(&value) == &surface.nodes) {
        bones[i].vertices.Create(g, info.name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 3, 24, zf);
      } else {
        bones[i].triangles.Create(g, info.name, H5T_STD_I32LE, H5T_NATIVE_INT32, 3, 12, z);
      }
    });
    CreateFields(g, initial.bones[i], 0, z, zf, &bones[i].fields);
  }
}

void RunWriter::Impl::CreateTools(const Model& model, const State& initial) {
  const int z = options.deflate_level;
  const int zf = options.float_deflate_level;
  const ToolState& sample = initial.tools[0];
  absent.pose.position_mm.setConstant(kNaN);
  absent.pose.orientation.coeffs().setConstant(kNaN);
  absent.handle_pose = absent.pose;
  h5::Group gto = file.root().CreateGroup(layout::kTools);
  tools.resize(model.instruments.size());
  for (std::size_t i = 0; i < tools.size(); ++i) {
    const InstrumentModel& im = model.instruments[i];
    h5::Group g = gto.CreateGroup(im.name);
    g.SetAttr("index", static_cast<std::int64_t>(i));
    g.SetAttr("kind", InstrumentKindName(im.kind));
    g.SetAttr("portal", im.portal);
    ToolOut& t = tools[i];
    CreateFields(g, sample, 0, z, zf, &t.fields, &sample.instrument, true);
    t.active.Create(g, layout::kActive, H5T_STD_U8LE, H5T_NATIVE_UINT8, {}, {}, nullptr, z);
    t.slot.Create(g, layout::kSlot, H5T_STD_I8LE, H5T_NATIVE_INT8, {}, {}, &kNoSlot, z);
  }
  h5::Group gs = file.root().CreateGroup(layout::kToolSlots);
  CreateFields(gs, sample, kToolSlots, z, zf, &slots);
  h5::Group gc = file.root().CreateGroup(layout::kCamera);
  CreateFields(gc, initial.camera, 0, z, zf, &camera);
}

void RunWriter::Impl::CreateRecords() {
  const int z = options.deflate_level;
  h5::Group gk = file.root().CreateGroup(layout::kConstraints);
  constraint_mem = layout::ConstraintType(false);
  constraint_file = layout::ConstraintType(true);
  constraints.Create(gk, layout::kRows, constraint_file.get(), constraint_mem.get(), 0,
                     sizeof(layout::ConstraintRecord), z);

  h5::Group gtc = file.root().CreateGroup(layout::kToolContacts);
  contact_mem = layout::ToolContactType(false);
  contact_file = layout::ToolContactType(true);
  contacts.Create(gtc, layout::kRows, contact_file.get(), contact_mem.get(), 0,
                  sizeof(layout::ToolContactRecord), z);

  const State sample;
  h5::Group gho = file.root().CreateGroup(FieldOf(sample, sample.holes).name);
  holes.Create(gho, layout::kRows, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, layout::kHoleColumns,
               sizeof(double) * layout::kHoleColumns, z);
  h5::Group gan = file.root().CreateGroup(FieldOf(sample, sample.anchors).name);
  anchors.Create(gan, layout::kRows, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, layout::kAnchorColumns,
                 sizeof(double) * layout::kAnchorColumns, z);
}

template <class F>
void RunWriter::Impl::ForEachSeries(F f) {
  for (BodyOut& b : bodies) {
    ForEach(b.fields, f);
    f(b.node_count), f(b.element_count), f(b.alive_elements), f(b.xdmf_points);
  }
  for (ThreadOut& t : threads) {
    ForEach(t.fields, f);
    f(t.node_count), f(t.alive_segments), f(t.xdmf_points);
  }
  for (BoneOut& b : bones) f(b.vertices), f(b.triangles), ForEach(b.fields, f);
  for (ToolOut& o : tools) ForEach(o.fields, f), f(o.active), f(o.slot);
  ForEach(slots, f);
  ForEach(camera, f);
  f(constraints), f(contacts), f(holes), f(anchors), f(events_end);
  for (std::size_t i = 0; i < root_fields.series.size(); ++i) {
    if (i != time_series) f(root_fields.series[i]);
  }
}

std::size_t RunWriter::Impl::BufferedBytes() {
  std::size_t bytes = root_fields.series[time_series].buffered_bytes() +
                      frame_events.size() * sizeof(layout::EventRecord);
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
  root_fields.series[time_series].WriteOut();  // last: a frame counts once /time has it
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
  WriteBodies(s);
  WriteThreads(s);
  WriteBones(s);
  WriteInstruments(s);
  WriteSlotFields(s.tools, &slots);
  WriteFields(s.camera, &camera);
  WriteRecords(s);
  WriteEvents(s);
  WriteFields(s, &root_fields);  // /time among them: written out last by WriteBlock
  times.push_back(s.time_s);
  last_step = s.step;
  ++frames;
  if (frames - written_frames >= options.block_frames || BufferedBytes() >= options.block_bytes) {
    WriteBlock();
  }
}

void RunWriter::Impl::WriteBodies(const State& s) {
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    const SoftBodyState& sb = s.soft_bodies[i];
    BodyOut& b = bodies[i];
    const auto n = static_cast<hsize_t>(sb.x.cols());
    const hsize_t e = sb.tets.size();
    WriteFields(sb, &b.fields, nullptr, n);
    b.node_count.Push(static_cast<std::int64_t>(n));
    if (e > b.written.size()) {  // tets appended by splitting
      const std::size_t first = b.written.size();
      b.elements.AppendRows(H5T_NATIVE_INT32, sb.tets[first].data(), e - first);
      b.written.insert(b.written.end(), sb.tets.begin() + static_cast<std::ptrdiff_t>(first),
                       sb.tets.end());
    }
    b.element_count.Push(static_cast<std::int64_t>(e));
    ints.clear();
    for (std::size_t k = 0; k < e; ++k) {
      if (sb.tet_alive[k] != 0) ints.insert(ints.end(), sb.tets[k].begin(), sb.tets[k].end());
    }
    b.alive_elements.Write(ints.data(), static_cast<std::int64_t>(ints.size() / 4));
    floats.assign(sb.x.data(), sb.x.data() + sb.x.size());
    b.xdmf_points.Write(floats.data(), static_cast<std::int64_t>(n));
  }
}

void RunWriter::Impl::WriteThreads(const State& s) {
  for (std::size_t i = 0; i < threads.size(); ++i) {
    const ThreadState& st = s.threads[i];
    ThreadOut& th = threads[i];
    const auto n = static_cast<hsize_t>(st.x.cols());
    WriteFields(st, &th.fields, nullptr, n);
    th.node_count.Push(static_cast<std::int64_t>(n));
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
}

void RunWriter::Impl::WriteBones(const State& s) {
  for (std::size_t i = 0; i < bones.size(); ++i) {
    const BoneState& sb = s.bones[i];
    bones[i].vertices.Write(sb.surface.nodes.data(),
                            static_cast<std::int64_t>(sb.surface.nodes.cols()));
    bones[i].triangles.Write(sb.surface.tris.empty() ? nullptr : sb.surface.tris[0].data(),
                             static_cast<std::int64_t>(sb.surface.tris.size()));
    WriteFields(sb, &bones[i].fields);
  }
}

// Per instrument of the Model: which slot holds it, if any, and that slot's values.
void RunWriter::Impl::WriteInstruments(const State& s) {
  for (std::size_t i = 0; i < tools.size(); ++i) {
    const ToolState* held = &absent;
    std::int8_t slot = -1;
    for (int k = 0; k < kToolSlots; ++k) {
      if (s.tools[static_cast<std::size_t>(k)].instrument == static_cast<std::int32_t>(i)) {
        held = &s.tools[static_cast<std::size_t>(k)];
        slot = static_cast<std::int8_t>(k);
      }
    }
    ToolOut& o = tools[i];
    WriteFields(*held, &o.fields, &held->instrument);
    o.active.Push(static_cast<std::uint8_t>(slot >= 0 ? 1 : 0));
    o.slot.Push(slot);
  }
}

void RunWriter::Impl::WriteRecords(const State& s) {
  records.clear();
  for (const SpringConstraint& c : s.constraints) records.push_back(layout::ToRecord(c));
  constraints.Write(records.data(), static_cast<std::int64_t>(records.size()));
  contact_records.clear();
  for (const ToolContact& c : s.tool_contacts) contact_records.push_back(layout::ToRecord(c));
  contacts.Write(contact_records.data(), static_cast<std::int64_t>(contact_records.size()));
  record_rows.clear();
  for (const BoneHole& h : s.holes) layout::AppendHoleRow(h, &record_rows);
  holes.Write(record_rows.data(), static_cast<std::int64_t>(s.holes.size()));
  record_rows.clear();
  for (const AnchorState& a : s.anchors) layout::AppendAnchorRow(a, &record_rows);
  anchors.Write(record_rows.data(), static_cast<std::int64_t>(s.anchors.size()));
}

void RunWriter::Impl::WriteEvents(const State& s) {
  if (last_events_step != s.step) {
    for (const Event& e : s.events) pending_events.push_back(layout::ToRecord(e));
    last_events_step = s.step;
  }
  frame_events.insert(frame_events.end(), pending_events.begin(), pending_events.end());
  events_total += static_cast<std::int64_t>(pending_events.size());
  pending_events.clear();
  events_end.Push(events_total);
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
