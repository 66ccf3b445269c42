// Checkpoints of a run file (/checkpoints, docs/hdf5-layout.md "Checkpoints"): written by
// RunWriter on a schedule of simulated time, read by RunCheckpoints for `run --resume` and
// `run --from RUN --at T`.
#include "arthrosim/io/run_checkpoint.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "arthrosim/core/error.h"
#include "arthrosim/core/state_bytes.h"
#include "arthrosim/io/hdf5.h"
#include "arthrosim/io/hdf5_layout.h"
#include "arthrosim/version.h"
#include "arthrosim_io_build_info.h"
#include "run_open.h"
#include "run_writer_impl.h"

namespace arthrosim::io {
namespace {

constexpr const char* kCheckpoints = "checkpoints";
// Each checkpoint's bytes start at a chunk boundary, so that appending one never rewrites the
// previous one's last (part-filled, compressed) chunk: HDF5 would not reuse the space.
constexpr hsize_t kChunkBytes = hsize_t{1} << 16;

std::string Hex(std::uint64_t v) { return fmt::format("{:016x}", v); }

std::uint64_t ParseHex(const std::string& s) {
  try {
    return s.empty() ? 0 : std::stoull(s, nullptr, 16);
  } catch (const std::exception&) {
    return 0;
  }
}

template <class T>
void AppendOne(detail::RowSeries& d, T value) {
  d.Append(&value, 1);
  d.WriteOut(detail::RowSeries::Tail::kPartial);
}

}  // namespace

std::string StateLayoutHex() { return Hex(StateLayoutSignature()); }

RunBuild CurrentBuild() {
  return RunBuild{kVersion, ARTHROSIM_IO_COMPILER, ARTHROSIM_IO_CXX_FLAGS, ARTHROSIM_IO_BUILD_TYPE,
                  StateLayoutHex()};
}

// ---- writing (RunWriter::Impl) ---------------------------------------------------------------

void RunWriter::Impl::CreateCheckpoints(const Model& model) {
  h5::Group meta = file.root().OpenGroup(layout::kMeta);
  const RunOrigin& o = options.origin;
  meta.SetAttr("trajectory", o.trajectory);
  meta.SetAttr("trajectory_sha256", o.trajectory_sha256);
  meta.SetAttr("noise_seed", o.noise_seed);
  meta.SetAttr("noise_scale", o.noise_scale);
  meta.SetAttr("end_step", o.end_step);
  meta.SetAttr("parent", o.parent);
  meta.SetAttr("parent_step", o.parent_step);
  meta.SetAttr("parent_time", o.parent_time_s);
  meta.SetAttr("parent_state_hash", o.parent.empty() ? std::string() : Hex(o.parent_state_hash));
  meta.SetAttr("state_layout", StateLayoutHex());

  detail::CheckpointOut& c = checkpoint;
  h5::Group g = file.root().CreateGroup(kCheckpoints);
  g.SetAttr("every", model.options.checkpoint_every_s);
  c.bytes.Create(g, "state", H5T_STD_U8LE, H5T_NATIVE_UINT8, 0, 1, options.checkpoint_deflate_level,
                 kChunkBytes);
  const int z = options.deflate_level;
  constexpr hsize_t kIndexChunk = 64;  // a few checkpoints per minute
  c.offset.Create(g, "state_offset", H5T_STD_I64LE, H5T_NATIVE_INT64, 0, 8, z, kIndexChunk);
  c.size.Create(g, "state_size", H5T_STD_I64LE, H5T_NATIVE_INT64, 0, 8, z, kIndexChunk);
  c.step.Create(g, "step", H5T_STD_I64LE, H5T_NATIVE_INT64, 0, 8, z, kIndexChunk);
  c.frame.Create(g, "frame", H5T_STD_I64LE, H5T_NATIVE_INT64, 0, 8, z, kIndexChunk);
  c.hash.Create(g, "state_hash", H5T_STD_U64LE, H5T_NATIVE_UINT64, 0, 8, z, kIndexChunk);
  c.time.Create(g, "time", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 0, 8, z, kIndexChunk);
  c.every_steps = 0;
  if (options.checkpoints) {
    const double every = model.options.checkpoint_every_s / model.options.dt_s;
    c.every_steps = std::max<std::int64_t>(1, std::llround(std::min(every, 1e15)));
    c.reference = MakeInitialState(model);
  }
}

bool RunWriter::Impl::CheckpointDue(const State& s) const {
  const detail::CheckpointOut& c = checkpoint;
  if (c.every_steps == 0 || s.step == c.last_step) return false;
  return c.last_step < 0 || s.step / c.every_steps > c.last_step / c.every_steps;
}

void RunWriter::Impl::AppendCheckpoint(const State& s, std::int64_t frame) {
  detail::CheckpointOut& c = checkpoint;
  // Encoding, hashing and compressing a State take ~10 ms for the shoulder scene: a job for the
  // writer thread, on a copy of s (copy-assigned: its buffers are reused). Its series store
  // their chunks at once (no queue): the job runs in its place in the queue's order.
  if (c.done.load(std::memory_order_acquire) != c.queued) queue->Drain();  // copy still in use
  c.pending = s;
  c.pending_frame = frame;
  ++c.queued;
  queue->Call(&StoreCheckpoint, this);
  ++c.count;
  c.last_step = s.step;
}

void RunWriter::Impl::StoreCheckpoint(void* impl) {
  detail::CheckpointOut& c = static_cast<RunWriter::Impl*>(impl)->checkpoint;
  const State& s = c.pending;
  EncodeState(s, c.reference, &c.buffer);
  // Every checkpoint starts a chunk: sealing fills the last one up, so that appending the next
  // checkpoint never stores a chunk again.
  const std::int64_t start = c.bytes.total_rows();
  c.bytes.Append(c.buffer.data(), static_cast<std::int64_t>(c.buffer.size()));
  c.bytes.WriteOut(detail::RowSeries::Tail::kSeal);
  // The index rows after the bytes they describe, /checkpoints/time last (as /time for frames).
  AppendOne(c.offset, start);
  AppendOne(c.size, static_cast<std::int64_t>(c.buffer.size()));
  AppendOne(c.step, s.step);
  AppendOne(c.frame, c.pending_frame);
  AppendOne(c.hash, HashState(s));
  AppendOne(c.time, s.time_s);
  c.done.fetch_add(1, std::memory_order_release);
}

// ---- reading -----------------------------------------------------------------------------------

struct RunCheckpoints::Impl {
  std::string path;
  h5::File file;
  h5::Dataset bytes;
  std::vector<CheckpointEntry> entries;
  std::vector<std::int64_t> offsets;
  RunOrigin origin;
  RunBuild build;
  std::string scenario_yaml, scenario_path, scenario_path_absolute, scenario_sha256;
  double dt_s = 0;

  void Open();
};

void RunCheckpoints::Impl::Open() {
  const h5::Group& root = file.root();
  if (!root.HasAttr("format") || root.AttrString("format") != layout::kFormatName) {
    throw InputError(path, 0, "", "not an arthrosim run file (root attribute 'format')");
  }
  scenario_sha256 = root.AttrString("scenario_sha256");
  dt_s = root.AttrDouble("dt");
  build.arthrosim_version = root.AttrString("arthrosim_version");
  const h5::Group meta = root.OpenGroup(layout::kMeta);
  scenario_path = meta.AttrString("scenario_path");
  if (meta.HasAttr("scenario_path_absolute"))
    scenario_path_absolute = meta.AttrString("scenario_path_absolute");
  scenario_yaml = meta.OpenDataset("scenario_yaml").ReadString();
  build.compiler = meta.AttrString("compiler");
  build.cxx_flags = meta.AttrString("cxx_flags");
  build.build_type = meta.AttrString("build_type");
  if (!meta.HasAttr("state_layout") || !root.Exists(kCheckpoints)) return;  // no checkpoints
  build.state_layout = meta.AttrString("state_layout");
  origin.trajectory = meta.AttrString("trajectory");
  origin.trajectory_sha256 = meta.AttrString("trajectory_sha256");
  origin.noise_seed = meta.AttrInt("noise_seed");
  origin.noise_scale = meta.AttrDouble("noise_scale");
  origin.end_step = meta.AttrInt("end_step");
  origin.parent = meta.AttrString("parent");
  origin.parent_step = meta.AttrInt("parent_step");
  origin.parent_time_s = meta.AttrDouble("parent_time");
  origin.parent_state_hash = ParseHex(meta.AttrString("parent_state_hash"));

  const h5::Group g = root.OpenGroup(kCheckpoints);
  bytes = g.OpenDataset("state");
  const auto offset = g.OpenDataset("state_offset").ReadAll<std::int64_t>();
  const auto size = g.OpenDataset("state_size").ReadAll<std::int64_t>();
  const auto step = g.OpenDataset("step").ReadAll<std::int64_t>();
  const auto frame = g.OpenDataset("frame").ReadAll<std::int64_t>();
  const auto hash = g.OpenDataset("state_hash").ReadAll<std::uint64_t>();
  const auto time = g.OpenDataset("time").ReadAll<double>();
  // A killed writer may leave index rows of a checkpoint without /time: complete ones only,
  // and only those whose bytes are in the file.
  const std::size_t n =
      std::min({offset.size(), size.size(), step.size(), frame.size(), hash.size(), time.size()});
  const auto total = static_cast<std::int64_t>(bytes.dims()[0]);
  for (std::size_t i = 0; i < n; ++i) {
    if (offset[i] < 0 || size[i] < 0 || offset[i] + size[i] > total) break;
    entries.push_back(CheckpointEntry{step[i], time[i], frame[i], hash[i], size[i]});
    offsets.push_back(offset[i]);
  }
}

RunCheckpoints::RunCheckpoints(const std::string& path) : impl_(std::make_unique<Impl>()) {
  impl_->path = path;
  detail::ReadRunFile(path, &impl_->file, [&] { impl_->Open(); });
}

RunCheckpoints::~RunCheckpoints() = default;
RunCheckpoints::RunCheckpoints(RunCheckpoints&&) noexcept = default;
RunCheckpoints& RunCheckpoints::operator=(RunCheckpoints&&) noexcept = default;

const std::string& RunCheckpoints::path() const { return impl_->path; }
const std::vector<CheckpointEntry>& RunCheckpoints::entries() const { return impl_->entries; }
const RunOrigin& RunCheckpoints::origin() const { return impl_->origin; }
const RunBuild& RunCheckpoints::build() const { return impl_->build; }
const std::string& RunCheckpoints::scenario_yaml() const { return impl_->scenario_yaml; }
const std::string& RunCheckpoints::scenario_path() const { return impl_->scenario_path; }
const std::string& RunCheckpoints::scenario_path_absolute() const {
  return impl_->scenario_path_absolute;
}
const std::string& RunCheckpoints::scenario_sha256() const { return impl_->scenario_sha256; }
double RunCheckpoints::dt_s() const { return impl_->dt_s; }

std::string RunCheckpoints::BuildMismatch() const {
  const RunBuild& f = impl_->build;
  const RunBuild now = CurrentBuild();
  auto differs = [](const char* what, const std::string& file, const std::string& here) {
    return fmt::format("{} '{}' (this build: '{}')", what, file, here);
  };
  if (f.state_layout != now.state_layout)
    return differs("State layout", f.state_layout, now.state_layout);
  if (f.arthrosim_version != now.arthrosim_version)
    return differs("arthrosim version", f.arthrosim_version, now.arthrosim_version);
  if (f.compiler != now.compiler) return differs("compiler", f.compiler, now.compiler);
  if (f.build_type != now.build_type) return differs("build type", f.build_type, now.build_type);
  if (f.cxx_flags != now.cxx_flags) return differs("compiler flags", f.cxx_flags, now.cxx_flags);
  return "";
}

std::int64_t RunCheckpoints::AtOrBefore(double t_s) const {
  const std::vector<CheckpointEntry>& e = impl_->entries;
  // Within a thousandth of a step of t counts as at t (times are step * dt, rounded).
  const double slack = 1e-3 * impl_->dt_s;
  std::int64_t found = -1;
  for (std::size_t i = 0; i < e.size(); ++i) {
    if (e[i].time_s <= t_s + slack) found = static_cast<std::int64_t>(i);
  }
  return found;
}

State RunCheckpoints::Read(std::size_t i, const Model& model) const {
  const Impl& m = *impl_;
  if (i >= m.entries.size()) throw std::out_of_range("RunCheckpoints::Read: bad index");
  const CheckpointEntry& e = m.entries[i];
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(e.bytes));
  State s;
  try {
    if (!bytes.empty()) {
      m.bytes.Read({static_cast<hsize_t>(m.offsets[i])}, {bytes.size()}, H5T_NATIVE_UINT8,
                   bytes.data());
    }
    DecodeState(bytes, MakeInitialState(model), &s);
  } catch (const std::exception& ex) {
    throw InputError(
        m.path, 0, "checkpoints",
        fmt::format("checkpoint {} (step {}) cannot be read: {}", i, e.step, ex.what()));
  }
  if (HashState(s) != e.state_hash || s.step != e.step) {
    throw InputError(m.path, 0, "checkpoints",
                     fmt::format("checkpoint {} (step {}) does not decode to the State it "
                                 "recorded (hash {}): the scenario's meshes changed since the run, "
                                 "or the file is damaged",
                                 i, e.step, Hex(e.state_hash)));
  }
  return s;
}

}  // namespace arthrosim::io
