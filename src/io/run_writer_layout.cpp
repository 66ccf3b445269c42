#include <cstdint>
#include <ctime>
#include <filesystem>
#include <limits>
#include <string>

#include "arthrosim/io/hdf5.h"
#include "arthrosim/io/hdf5_layout.h"
#include "arthrosim/version.h"
#include "arthrosim_io_build_info.h"
#include "run_writer_impl.h"

// Creating the run file's layout: every group and dataset exists before SWMR writing starts.

namespace arthrosim::io {
namespace {

using detail::BlockSeries;
using detail::FrameSeries;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string UtcNow() {
  // Wall clock: metadata only, never part of the state datasets.
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

/// The scenario's path made absolute (so that a run read from another directory still finds its
/// meshes); the path as given when it cannot be made absolute or is empty (synthetic models).
std::string AbsoluteScenarioPath(const std::string& as_given) {
  if (as_given.empty()) return as_given;
  std::error_code ec;
  const std::filesystem::path abs = std::filesystem::absolute(as_given, ec);
  return ec ? as_given : abs.lexically_normal().string();
}

}  // namespace

using namespace detail;  // NOLINT(google-build-using-namespace): the writer's private parts

void RunWriter::Impl::CreateLayout(const Model& model, const State& initial) {
  CreateRoot(model, initial);
  CreateBodies(model, initial);
  CreateThreads(model, initial);
  CreateBones(model, initial);
  CreateTools(model, initial);
  CreateRecords();
  CreateCheckpoints(model);
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
  meta.SetAttr("scenario_path_absolute", AbsoluteScenarioPath(model.scenario_path));
  meta.SetAttr("compiler", ARTHROSIM_IO_COMPILER);
  meta.SetAttr("cxx_flags", ARTHROSIM_IO_CXX_FLAGS);
  meta.SetAttr("build_type", ARTHROSIM_IO_BUILD_TYPE);
  meta.SetAttr("hdf5_version", h5::LibraryVersion());
  meta.SetAttr("created_utc", UtcNow());

  CreateFields(root, initial, 0, z, options.float_deflate_level, chunk(), &root_fields);
  std::size_t i = 0;
  VisitFields(initial, [&](const auto& value, const FieldInfo& info) {
    if (info.store != FieldStore::kFrame) return;
    if (static_cast<const void*>(&value) == &initial.time_s) time_series = i;
    ++i;
  });

  event_mem = layout::EventType(false);
  event_file = layout::EventType(true);
  // 32 events per chunk: the part-filled chunk is stored again at every flush with new events.
  events.Create(root, layout::kEvents, event_file.get(), event_mem.get(), 0,
                sizeof(layout::EventRecord), z, 32);
  events_end.Create(root, layout::kEventsEnd, H5T_STD_I64LE, H5T_NATIVE_INT64, {}, {}, nullptr, z,
                    chunk());
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
    CreateFields(g, sb, 0, z, zf, chunk(), &b.fields, nullptr, false,
                 static_cast<hsize_t>(sb.x.cols()));
    b.node_count.Create(g, layout::kNodeCount, H5T_STD_I64LE, H5T_NATIVE_INT64, {}, {}, nullptr, z,
                        chunk());
    b.element_count.Create(g, layout::kElementCount, H5T_STD_I64LE, H5T_NATIVE_INT64, {}, {},
                           nullptr, z, chunk());
    VisitFields(sb, [&](const auto& value, const FieldInfo& info) {
      if (static_cast<const void*>(&value) != &sb.tets) return;
      h5::DatasetSpec spec = h5::GrowingSpec({0, 4}, 4);
      spec.deflate = z;
      b.elements = g.CreateDataset(info.name, H5T_STD_I32LE, spec);
    });
    b.alive_elements.Create(g, layout::kAliveElements, H5T_STD_I32LE, H5T_NATIVE_INT32, 4, 16, z,
                            chunk());
    b.positions.Create(g, FieldOf(sb, sb.x).name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 3, 24, zf,
                       chunk());
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
    CreateFields(g, initial.threads[i], 0, z, zf, chunk(), &t.fields, nullptr, false,
                 static_cast<hsize_t>(initial.threads[i].x.cols()));
    t.node_count.Create(g, layout::kNodeCount, H5T_STD_I64LE, H5T_NATIVE_INT64, {}, {}, nullptr, z,
                        chunk());
    t.alive_segments.Create(g, layout::kAliveSegments, H5T_STD_I32LE, H5T_NATIVE_INT32, 2, 8, z,
                            chunk());
    t.positions.Create(g, FieldOf(initial.threads[i], initial.threads[i].x).name, H5T_IEEE_F64LE,
                       H5T_NATIVE_DOUBLE, 3, 24, zf, chunk());
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
        // A carving burr stores the whole surface every frame with a few vertices moved:
        // chunks of several surfaces let shuffle + deflate find the unmoved ones (a 64 KiB
        // chunk holds less than one shoulder-scene surface: ~4x larger on disk).
        bones[i].vertices.Create(g, info.name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 3, 24, zf,
                                 chunk(), 16384);
      } else {
        bones[i].triangles.Create(g, info.name, H5T_STD_I32LE, H5T_NATIVE_INT32, 3, 12, z, chunk());
      }
    });
    CreateFields(g, initial.bones[i], 0, z, zf, chunk(), &bones[i].fields);
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
    CreateFields(g, sample, 0, z, zf, chunk(), &t.fields, &sample.instrument, true);
    t.active.Create(g, layout::kActive, H5T_STD_U8LE, H5T_NATIVE_UINT8, {}, {}, nullptr, z,
                    chunk());
    t.slot.Create(g, layout::kSlot, H5T_STD_I8LE, H5T_NATIVE_INT8, {}, {}, &kNoSlot, z, chunk());
  }
  h5::Group gs = file.root().CreateGroup(layout::kToolSlots);
  CreateFields(gs, sample, kToolSlots, z, zf, chunk(), &slots);
  h5::Group gc = file.root().CreateGroup(layout::kCamera);
  CreateFields(gc, initial.camera, 0, z, zf, chunk(), &camera);
}

void RunWriter::Impl::CreateRecords() {
  const int z = options.deflate_level;
  h5::Group gk = file.root().CreateGroup(layout::kConstraints);
  constraint_mem = layout::ConstraintType(false);
  constraint_file = layout::ConstraintType(true);
  constraints.Create(gk, layout::kRows, constraint_file.get(), constraint_mem.get(), 0,
                     sizeof(layout::ConstraintRecord), z, chunk());

  h5::Group gtc = file.root().CreateGroup(layout::kToolContacts);
  contact_mem = layout::ToolContactType(false);
  contact_file = layout::ToolContactType(true);
  contacts.Create(gtc, layout::kRows, contact_file.get(), contact_mem.get(), 0,
                  sizeof(layout::ToolContactRecord), z, chunk());

  const State sample;
  h5::Group gho = file.root().CreateGroup(FieldOf(sample, sample.holes).name);
  holes.Create(gho, layout::kRows, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, layout::kHoleColumns,
               sizeof(double) * layout::kHoleColumns, z, chunk());
  h5::Group gan = file.root().CreateGroup(FieldOf(sample, sample.anchors).name);
  anchors.Create(gan, layout::kRows, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, layout::kAnchorColumns,
                 sizeof(double) * layout::kAnchorColumns, z, chunk());
}
}  // namespace arthrosim::io
