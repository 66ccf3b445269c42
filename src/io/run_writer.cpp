#include "arthrosim/io/run_writer.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <filesystem>
#include <limits>
#include <stdexcept>

#include "arthrosim/core/error.h"
#include "arthrosim/io/hdf5.h"
#include "arthrosim/io/hdf5_layout.h"
#include "arthrosim/io/xdmf.h"
#include "run_writer_impl.h"

namespace arthrosim::io {
namespace {

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
}  // namespace

using namespace detail;  // NOLINT(google-build-using-namespace): the writer's private parts

template <class F>
void RunWriter::Impl::ForEachSeries(F f) {
  for (BodyOut& b : bodies) {
    ForEach(b.fields, f);
    f(b.node_count), f(b.element_count), f(b.alive_elements), f(b.positions);
  }
  for (ThreadOut& t : threads) {
    ForEach(t.fields, f);
    f(t.node_count), f(t.alive_segments), f(t.positions);
  }
  for (BoneOut& b : bones) f(b.vertices), f(b.triangles), ForEach(b.fields, f);
  for (ToolOut& o : tools) ForEach(o.fields, f), f(o.active), f(o.slot);
  ForEach(slots, f);
  ForEach(camera, f);
  f(constraints), f(contacts), f(holes), f(anchors);
  for (std::size_t i = 0; i < root_fields.series.size(); ++i) {
    if (i != time_series) f(root_fields.series[i]);
  }
}

std::size_t RunWriter::Impl::BufferedBytes() {
  std::size_t bytes = root_fields.series[time_series].buffered_bytes() +
                      events_end.buffered_bytes() + events.buffered_bytes();
  ForEachSeries([&](const auto& series) { bytes += series.buffered_bytes(); });
  return bytes;
}

void RunWriter::Impl::WriteBlock(bool seal) {
  if (!frame_events.empty()) {
    events.Append(frame_events.data(), static_cast<std::int64_t>(frame_events.size()));
    frame_events.clear();
  }
  // Per-frame series store their full chunks; block series and events store their rows, then
  // the offsets, counts and events_end that refer to them, only when sealing (a reader counts
  // the frames that every per-frame dataset has, so a reference never comes before its rows).
  ForEachSeries([seal](auto& series) { series.WriteOut(seal); });
  if (seal) {
    events.WriteOut(RowSeries::Tail::kPartial);
    events_end.WriteOut(true);
  }
  root_fields.series[time_series].WriteOut(seal);  // last: a frame counts once /time has it
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
  ListFrame(s.time_s);
  last_time_s = s.time_s;
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
      queue->Drain();  // a direct HDF5 call: after the queued ones, as without the writer thread
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
    layout::HoldPositions(sb.x, options.position_quantum_mm, options.position_tolerance_mm,
                          &b.held);
    b.positions.Write(b.held.data(), static_cast<std::int64_t>(n));
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
    layout::HoldPositions(st.x, options.position_quantum_mm, options.position_tolerance_mm,
                          &th.held);
    th.positions.Write(th.held.data(), static_cast<std::int64_t>(n));
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

void RunWriter::Impl::CreateXdmf() {
  listed = XdmfRun{};
  listed.h5_name = std::filesystem::path(path).filename().string();
  listed.interval_s = 0;  // frames are listed as they are written (ListFrame)
  auto series = [](const BlockSeries& b, int columns, bool is_float, int precision) {
    XdmfSeries s;
    s.dataset = b.path();
    s.columns = columns;
    s.is_float = is_float;
    s.precision = precision;
    return s;
  };
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    listed.meshes.push_back({"body:" + body_names[i], XdmfCell::kTetrahedron,
                             series(bodies[i].alive_elements, 4, false, 4),
                             series(bodies[i].positions, 3, true, 8)});
  }
  for (std::size_t i = 0; i < bones.size(); ++i) {
    listed.meshes.push_back({"bone:" + bone_names[i], XdmfCell::kTriangle,
                             series(bones[i].triangles, 3, false, 4),
                             series(bones[i].vertices, 3, true, 8)});
  }
  for (std::size_t i = 0; i < threads.size(); ++i) {
    listed.meshes.push_back({"thread:" + thread_names[i], XdmfCell::kPolyline,
                             series(threads[i].alive_segments, 2, false, 4),
                             series(threads[i].positions, 3, true, 8)});
  }
}

// Calls f(mesh series, block series) for the cells and points of every sidecar mesh.
template <class F>
void RunWriter::Impl::ForEachXdmfSeries(F f) {
  std::size_t k = 0;
  for (BodyOut& b : bodies) {
    f(listed.meshes[k].cells, b.alive_elements), f(listed.meshes[k].points, b.positions);
    ++k;
  }
  for (BoneOut& b : bones) {
    f(listed.meshes[k].cells, b.triangles), f(listed.meshes[k].points, b.vertices);
    ++k;
  }
  for (ThreadOut& t : threads) {
    f(listed.meshes[k].cells, t.alive_segments), f(listed.meshes[k].points, t.positions);
    ++k;
  }
}

void RunWriter::Impl::ListFrame(double time_s) {
  if (!options.write_xdmf) return;
  const bool due =
      listed.times.empty() || time_s - last_listed_s >= options.xdmf_interval_s * (1 - 1e-9);
  if (!due) return;
  last_listed_s = time_s;
  listed.times.push_back(time_s);
  listed.frame_index.push_back(frames);
  ForEachXdmfSeries([](XdmfSeries& x, const BlockSeries& b) {
    x.offset.push_back(b.last_offset());
    x.count.push_back(b.last_count());
  });
}

void RunWriter::Impl::WriteSidecar(void* impl) {
  auto& m = *static_cast<RunWriter::Impl*>(impl);
  WriteXdmfFile(m.xmf_path, m.sidecar);
  m.sidecar_done.fetch_add(1, std::memory_order_release);
}

void RunWriter::Impl::WriteXdmf() {
  if (!options.write_xdmf) return;
  xdmf_frames = frames;
  // The writer thread may still be writing the previous sidecar (rare: a sidecar is due at most
  // once per flush): wait for it before refilling the copy.
  if (sidecar_done.load(std::memory_order_acquire) != sidecar_queued) queue->Drain();
  ForEachXdmfSeries([](XdmfSeries& x, const BlockSeries& b) { x.total_rows = b.total_rows(); });
  sidecar = listed;  // copy-assignment: reuses the copy's capacity
  // The last frame is always listed: added to the copy when it was not due.
  if (sidecar.frame_index.back() != frames - 1) {
    sidecar.times.push_back(last_time_s);
    sidecar.frame_index.push_back(frames - 1);
    std::size_t k = 0;
    ForEachXdmfSeries([&](XdmfSeries&, const BlockSeries& b) {
      XdmfSeries& x = k % 2 == 0 ? sidecar.meshes[k / 2].cells : sidecar.meshes[k / 2].points;
      x.offset.push_back(b.last_offset());
      x.count.push_back(b.last_count());
      ++k;
    });
  }
  ++sidecar_queued;
  queue->Call(&WriteSidecar, this);
}

void RunWriter::Impl::UseQueue() {
  queue = std::make_unique<WriteQueue>(options.background_writer, options.max_flushes_behind);
  WriteQueue* q = queue.get();
  ForEachSeries([q](auto& series) { series.set_queue(q); });
  root_fields.series[time_series].set_queue(q);
  events_end.set_queue(q);
  events.set_queue(q);
  // The checkpoint series are written by a job of the queue itself (StoreCheckpoint): directly.
}

void RunWriter::Impl::QueueFlush() {
  WriteBlock(true);
  queue->FlushFile(&file, frames);
  flushed = frames;
  // The sidecar is rewritten whole (every frame's entry names the datasets' current sizes), so
  // rewriting it at every flush would cost O(frames^2) over a long session: beyond
  // `xdmf_every_flush_frames` frames it is rewritten once it lags by the growth fraction, and
  // always at Close (`arthrosim info RUN.h5 --write-xdmf` rebuilds it from a killed run).
  const auto lagging = static_cast<double>(frames - xdmf_frames);
  if (frames <= options.xdmf_every_flush_frames ||
      lagging >= options.xdmf_growth * static_cast<double>(xdmf_frames)) {
    WriteXdmf();
  }
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
  const double frame_s = model.options.dt_s * model.options.output_every_steps;
  m.flush_frames = std::max<std::int64_t>(
      1, std::llround(std::min(model.options.flush_interval_s / frame_s, 1e6)));
  m.xmf_path = options.write_xdmf ? XdmfPathFor(path) : "";
  if (options.deflate_level < 0 || options.deflate_level > 9 || options.float_deflate_level < 0 ||
      options.float_deflate_level > 9) {
    throw std::invalid_argument("RunWriter: deflate levels must be in 0..9");
  }
  if (options.block_frames < 1) throw std::invalid_argument("RunWriter: block_frames must be >= 1");
  int exponent = 0;
  const double mantissa = std::frexp(options.position_quantum_mm, &exponent);
  if (options.position_quantum_mm < 0 || (options.position_quantum_mm > 0 && mantissa != 0.5)) {
    throw std::invalid_argument("RunWriter: position_quantum_mm must be 0 or a power of two");
  }
  if (!(options.position_tolerance_mm >= 0)) {
    throw std::invalid_argument("RunWriter: position_tolerance_mm must be >= 0");
  }
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
    m.CreateXdmf();
    m.UseQueue();
    m.file.StartSwmrWrite();  // from here on no object may be created
    m.WriteFrame(initial);
    m.WriteBlock(true);
    if (m.checkpoint.every_steps > 0) m.AppendCheckpoint(initial, 0);
    m.queue->FlushFile(&m.file, m.frames);
    m.flushed = m.frames;
    m.WriteXdmf();
    m.queue->Drain();  // frame 0 and the first checkpoint are durable when the writer exists
  } catch (...) {
    // Do not leave a half-made file behind.
    try {
      if (m.queue) m.queue->Drain();
    } catch (...) {
    }
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
  // Flushes fall on chunk boundaries of the per-frame datasets (flush_frames frames per chunk):
  // every flush writes whole chunks, which are never rewritten.
  if (m.frames % m.flush_frames == 0) m.QueueFlush();
  if (m.CheckpointDue(s)) {
    // The checkpoint alone is made durable: flushing the frames here, between two chunk
    // boundaries, would write part-filled chunks. Its frame follows with the next flush.
    m.AppendCheckpoint(s, m.frames - 1);
    m.queue->FlushFile(&m.file, -1);
  }
}

void RunWriter::WriteCheckpoint(const State& s) {
  Impl& m = *impl_;
  if (m.closed) throw std::logic_error("RunWriter: WriteCheckpoint after Close");
  if (m.checkpoint.every_steps == 0 || s.step == m.checkpoint.last_step) return;
  m.AppendCheckpoint(s, s.step == m.last_step ? m.frames - 1 : -1);
  Flush();
}

void RunWriter::Flush() {
  Impl& m = *impl_;
  if (m.closed) throw std::logic_error("RunWriter: Flush after Close");
  m.QueueFlush();
  m.queue->Drain();
}

void RunWriter::Close() {
  Impl& m = *impl_;
  if (m.closed) return;
  m.closed = true;  // even if what follows throws: never write to a half-closed file
  std::exception_ptr error;
  try {
    m.WriteBlock(true);
    m.queue->FlushFile(&m.file, m.frames);
    m.flushed = m.frames;
  } catch (...) {
    error = std::current_exception();
  }
  try {
    m.queue->Drain();  // every queued job has run (or the first error is known)
  } catch (...) {
    if (!error) error = std::current_exception();
  }
  try {
    m.file.Close();  // always, so that the file is left consistent
  } catch (...) {
    if (!error) error = std::current_exception();
  }
  if (error) std::rethrow_exception(error);
  m.WriteXdmf();
  m.queue->Drain();
}

std::int64_t RunWriter::frames() const { return impl_->frames; }
std::int64_t RunWriter::checkpoints() const { return impl_->checkpoint.count; }
std::int64_t RunWriter::flushed_frames() const { return impl_->queue->durable_frames(); }
const std::string& RunWriter::path() const { return impl_->path; }
const std::string& RunWriter::xdmf_path() const { return impl_->xmf_path; }

}  // namespace arthrosim::io
