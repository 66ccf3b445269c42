#include "arthrosim/io/xdmf.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "arthrosim/core/enum_names.h"
#include "arthrosim/core/state_fields.h"
#include "arthrosim/io/hdf5.h"
#include "arthrosim/io/hdf5_layout.h"

namespace arthrosim::io {
namespace {

std::string Escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

// Rows [offset, offset+count) of a [total_rows, columns] dataset as a data item.
//
// kXdmf3: a plain HDF item whose content carries the selection ("file:/path|start:stride:count:
// dataspace"); ParaView's Xdmf3 readers turn it into an HDF5 hyperslab read. Their Geometry
// ignores HyperSlab items (it copies its first child's heavy-data controllers, and a HyperSlab
// item has none: "Skipping unrecognized array type [None]", 0 points).
// kXdmf2: a HyperSlab item (start/stride/count rows); the legacy XDMFReader reads it but not the
// Xdmf3 content form.
void AppendRows(std::string& x, XdmfDialect dialect, const std::string& h5, const XdmfSeries& s,
                std::int64_t offset, std::int64_t count) {
  const char* type = s.is_float ? "Float" : "Int";
  if (dialect == XdmfDialect::kXdmf3) {
    fmt::format_to(std::back_inserter(x),
                   "<DataItem Dimensions=\"{0} {1}\" NumberType=\"{4}\" Precision=\"{5}\" "
                   "Format=\"HDF\">{6}:{7}|{2} 0:1 1:{0} {1}:{3} {1}</DataItem>\n",
                   count, s.columns, offset, s.total_rows, type, s.precision, Escape(h5),
                   Escape(s.dataset));
    return;
  }
  fmt::format_to(std::back_inserter(x),
                 "<DataItem ItemType=\"HyperSlab\" Dimensions=\"{0} {1}\" Type=\"HyperSlab\">\n"
                 "<DataItem Dimensions=\"3 2\" Format=\"XML\">{2} 0 1 1 {0} {1}</DataItem>\n"
                 "<DataItem Dimensions=\"{3} {1}\" NumberType=\"{4}\" Precision=\"{5}\" "
                 "Format=\"HDF\">{6}:{7}</DataItem>\n</DataItem>\n",
                 count, s.columns, offset, s.total_rows, type, s.precision, Escape(h5),
                 Escape(s.dataset));
}

const char* TopologyType(XdmfCell c) {
  static constexpr EnumName<XdmfCell> kNames[] = {{XdmfCell::kTetrahedron, "Tetrahedron"},
                                                  {XdmfCell::kTriangle, "Triangle"},
                                                  {XdmfCell::kPolyline, "Polyline"}};
  return NameIn(kNames, c, "Tetrahedron");
}

// Emits the XML of `run` piecewise: emit(text) receives the header, then each listed frame, then
// the footer.
template <class Emit>
void EmitXdmf(const XdmfRun& run, XdmfDialect dialect, Emit&& emit) {
  std::string x =
      "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n  <Domain>\n"
      "    <Grid Name=\"arthrosim\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  emit(x);
  std::size_t frames = run.times.size();
  for (const XdmfMesh& m : run.meshes) {
    frames = std::min({frames, m.cells.offset.size(), m.cells.count.size(), m.points.offset.size(),
                       m.points.count.size()});
  }
  double listed_s = 0;
  for (std::size_t t = 0; t < frames; ++t) {
    const bool listed =
        t == 0 || t + 1 == frames || run.times[t] - listed_s >= run.interval_s * (1 - 1e-9);
    if (!listed) continue;
    listed_s = run.times[t];
    x.clear();
    fmt::format_to(std::back_inserter(x),
                   "<Grid Name=\"frame{}\" GridType=\"Collection\" CollectionType=\"Spatial\">\n"
                   "<Time Value=\"{}\"/>\n",
                   t < run.frame_index.size() ? run.frame_index[t] : static_cast<std::int64_t>(t),
                   run.times[t]);
    for (const XdmfMesh& m : run.meshes) {
      const std::int64_t nc = m.cells.count[t];
      const std::int64_t np = m.points.count[t];
      if (nc <= 0 || np <= 0) continue;
      fmt::format_to(std::back_inserter(x),
                     "<Grid Name=\"{}\" GridType=\"Uniform\">\n"
                     "<Topology TopologyType=\"{}\" NumberOfElements=\"{}\"{}>\n",
                     Escape(m.name), TopologyType(m.cell), nc,
                     m.cell == XdmfCell::kPolyline ? " NodesPerElement=\"2\"" : "");
      AppendRows(x, dialect, run.h5_name, m.cells, m.cells.offset[t], nc);
      x += "</Topology>\n<Geometry GeometryType=\"XYZ\">\n";
      AppendRows(x, dialect, run.h5_name, m.points, m.points.offset[t], np);
      x += "</Geometry>\n</Grid>\n";
    }
    x += "</Grid>\n";
    emit(x);
  }
  emit(std::string("    </Grid>\n  </Domain>\n</Xdmf>\n"));
}

}  // namespace

std::string XdmfText(const XdmfRun& run, XdmfDialect dialect) {
  std::string text;
  EmitXdmf(run, dialect, [&text](const std::string& part) { text += part; });
  return text;
}

namespace {

// Writes `path` through `path.tmp` and a rename, so a reader never sees a partial file; `write`
// fills the stream. The temporary is removed on failure.
template <class Write>
void WriteThroughTemporary(const std::string& path, const Write& write) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    write(out);
    out.close();
    if (!out) {
      std::remove(tmp.c_str());
      throw std::runtime_error("cannot write '" + tmp + "'");
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::remove(tmp.c_str());
    throw std::runtime_error("cannot rename '" + tmp + "' to '" + path + "': " + ec.message());
  }
}

}  // namespace

void WriteXdmfFile(const std::string& path, const XdmfRun& run, XdmfDialect dialect) {
  WriteThroughTemporary(path, [&](std::ofstream& out) {
    EmitXdmf(run, dialect, [&out](const std::string& part) {
      out.write(part.data(), static_cast<std::streamsize>(part.size()));
    });
  });
}

void WriteFileAtomically(const std::string& path, const std::string& text) {
  WriteThroughTemporary(path, [&](std::ofstream& out) {
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
  });
}

std::string XdmfPathFor(const std::string& h5_path, XdmfDialect dialect) {
  std::filesystem::path p(h5_path);
  p.replace_extension(dialect == XdmfDialect::kXdmf3 ? ".xmf" : ".xdmf2.xmf");
  return p.string();
}

namespace {

// Reads the per-frame index arrays of block series `name` in group `g`.
XdmfSeries ReadSeries(const h5::Group& g, const std::string& name, int columns, bool is_float,
                      int precision) {
  XdmfSeries s;
  s.dataset = g.path() + "/" + name;
  s.columns = columns;
  s.is_float = is_float;
  s.precision = precision;
  s.total_rows = static_cast<std::int64_t>(g.OpenDataset(name).dims()[0]);
  s.offset = g.OpenDataset(layout::OffsetName(name)).ReadAll<std::int64_t>();
  s.count = g.OpenDataset(layout::CountName(name)).ReadAll<std::int64_t>();
  return s;
}

std::string BaseName(const std::string& path) {
  return std::filesystem::path(path).filename().string();
}

}  // namespace

XdmfRun XdmfRunFromFile(const std::string& h5_path, double interval_s) {
  h5::File f = h5::File::OpenReadOnly(h5_path, true);
  XdmfRun run;
  run.interval_s = interval_s;
  run.h5_name = BaseName(h5_path);
  const State state;
  const SoftBodyState body;
  const ThreadState thread;
  const mesh::TriMesh surface;
  run.times = f.root().OpenDataset(FieldOf(state, state.time_s).name).ReadAll<double>();
  for (const h5::Group& g : layout::OrderedGroups(f.root(), layout::kBodies)) {
    XdmfMesh m;
    m.name = "body:" + layout::LeafName(g.path());
    m.cell = XdmfCell::kTetrahedron;
    m.cells = ReadSeries(g, layout::kAliveElements, 4, false, 4);
    m.points = ReadSeries(g, FieldOf(body, body.x).name, 3, true, 8);
    run.meshes.push_back(std::move(m));
  }
  for (const h5::Group& g : layout::OrderedGroups(f.root(), layout::kBones)) {
    XdmfMesh m;
    m.name = "bone:" + layout::LeafName(g.path());
    m.cell = XdmfCell::kTriangle;
    m.cells = ReadSeries(g, FieldOf(surface, surface.tris).name, 3, false, 4);
    m.points = ReadSeries(g, FieldOf(surface, surface.nodes).name, 3, true, 8);
    run.meshes.push_back(std::move(m));
  }
  for (const h5::Group& g : layout::OrderedGroups(f.root(), layout::kThreads)) {
    XdmfMesh m;
    m.name = "thread:" + layout::LeafName(g.path());
    m.cell = XdmfCell::kPolyline;
    m.cells = ReadSeries(g, layout::kAliveSegments, 2, false, 4);
    m.points = ReadSeries(g, FieldOf(thread, thread.x).name, 3, true, 8);
    run.meshes.push_back(std::move(m));
  }
  return run;
}

}  // namespace arthrosim::io
