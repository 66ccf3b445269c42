// Summarize(): the text of `arthrosim info RUN.h5`.
#include <fmt/format.h>

#include <map>

#include "arthrosim/io/run_checkpoint.h"
#include "arthrosim/io/run_reader.h"

namespace arthrosim::io {
namespace {

std::string Bounds(const Points& x, const std::vector<std::uint8_t>* alive) {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 hi = -lo;
  bool any = false;
  for (Eigen::Index i = 0; i < x.cols(); ++i) {
    if (alive != nullptr && (*alive)[static_cast<std::size_t>(i)] == 0) continue;
    lo = lo.cwiseMin(x.col(i));
    hi = hi.cwiseMax(x.col(i));
    any = true;
  }
  if (!any) return "no nodes";
  return fmt::format("bounds [{:.3f}, {:.3f}, {:.3f}] .. [{:.3f}, {:.3f}, {:.3f}] mm", lo.x(),
                     lo.y(), lo.z(), hi.x(), hi.y(), hi.z());
}

}  // namespace

std::string Summarize(const std::string& path) {
  const RunReader r(path);
  const RunInfo& info = r.info();
  std::string s;
  auto out = std::back_inserter(s);
  fmt::format_to(out, "{}: arthrosim {} run of scenario '{}' (sha256 {})\n", path,
                 info.arthrosim_version, info.scenario_name, info.scenario_sha256);
  const std::int64_t n = r.frame_count();
  if (n == 0) {
    fmt::format_to(out, "frames: 0\n");
    return s;
  }
  fmt::format_to(out, "frames: {} (steps {} .. {}), time {:.6g} .. {:.6g} s ({:.6g} s), dt {} s\n",
                 n, r.step(0), r.step(n - 1), r.time(0), r.time(n - 1), r.time(n - 1) - r.time(0),
                 info.dt_s);
  const State last = r.Frame(n - 1);
  fmt::format_to(out, "at the last frame:\n");
  for (std::size_t i = 0; i < info.soft_bodies.size(); ++i) {
    const SoftBodyState& b = last.soft_bodies[i];
    std::size_t alive = 0;
    for (std::uint8_t a : b.tet_alive) alive += a != 0 ? 1 : 0;
    fmt::format_to(out, "  body '{}': {} nodes, {} elements ({} alive), {}\n", info.soft_bodies[i],
                   b.x.cols(), b.tets.size(), alive, Bounds(b.x, nullptr));
  }
  for (std::size_t i = 0; i < info.bones.size(); ++i) {
    const BoneState& b = last.bones[i];
    fmt::format_to(out, "  bone '{}': {} vertices, {} triangles, removed {:.6g} mm^3, {}\n",
                   info.bones[i], b.surface.nodes.cols(), b.surface.tris.size(),
                   b.removed_volume_mm3, Bounds(b.surface.nodes, nullptr));
  }
  for (std::size_t i = 0; i < info.threads.size(); ++i) {
    const ThreadState& t = last.threads[i];
    std::size_t alive = 0;
    for (std::uint8_t a : t.node_alive) alive += a != 0 ? 1 : 0;
    fmt::format_to(out, "  thread '{}': {} nodes ({} alive), {}\n", info.threads[i], t.x.cols(),
                   alive, Bounds(t.x, &t.node_alive));
  }
  for (std::size_t k = 0; k < last.tools.size(); ++k) {
    const int inst = last.tools[k].instrument;
    fmt::format_to(out, "  tool slot {}: {}\n", k,
                   inst >= 0 && inst < static_cast<int>(info.instruments.size())
                       ? info.instruments[static_cast<std::size_t>(inst)]
                       : std::string("empty"));
  }
  fmt::format_to(out, "  constraints: {}\n", last.constraints.size());
  const std::vector<Event> events = r.EventsUpTo(n - 1);
  std::map<std::string, int> kinds;  // ordered: stable output
  for (const Event& e : events) ++kinds[e.kind];
  fmt::format_to(out, "events: {}", events.size());
  const char* sep = " (";
  for (const auto& [kind, count] : kinds) {
    fmt::format_to(out, "{}{} {}", sep, kind, count);
    sep = ", ";
  }
  fmt::format_to(out, "{}\n", events.empty() ? "" : ")");
  const RunCheckpoints cp(path);
  if (!cp.origin().parent.empty()) {
    fmt::format_to(out, "continues: {} from step {} ({:.6g} s)\n", cp.origin().parent,
                   cp.origin().parent_step, cp.origin().parent_time_s);
  }
  if (cp.entries().empty()) {
    fmt::format_to(out, "checkpoints: none\n");
  } else {
    std::int64_t bytes = 0;
    for (const CheckpointEntry& e : cp.entries()) bytes += e.bytes;
    fmt::format_to(out, "checkpoints: {} (last at step {}, {:.6g} s; {} kB encoded)\n",
                   cp.entries().size(), cp.entries().back().step, cp.entries().back().time_s,
                   bytes / 1024);
  }
  return s;
}

}  // namespace arthrosim::io
