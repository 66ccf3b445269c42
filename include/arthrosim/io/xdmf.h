#pragma once
// XDMF sidecar (run.xmf) for ParaView: a Temporal collection with one Spatial collection per
// frame, one grid per soft body (alive tets), bone (triangles) and thread (segments as 2-node
// Polylines). Under SWMR no per-frame datasets exist, so every topology and geometry item is a
// 2-D HyperSlab of a concatenated block series (rows offset[t] .. offset[t]+count[t]); 2-D
// because the Xdmf3 readers of ParaView 5.11 return no points for 3-D geometry hyperslabs.
#include <cstdint>
#include <string>
#include <vector>

namespace arthrosim::io {

/// A concatenated block series of the run file referenced per frame.
struct XdmfSeries {
  std::string dataset;          ///< absolute HDF5 path, e.g. /bodies/cuff/alive_elements
  std::int64_t total_rows = 0;  ///< current row count of the dataset
  int columns = 3;
  bool is_float = false;             ///< Float vs Int
  int precision = 4;                 ///< bytes per number
  std::vector<std::int64_t> offset;  ///< per frame: first row
  std::vector<std::int64_t> count;   ///< per frame: number of rows
};

enum class XdmfCell { kTetrahedron, kTriangle, kPolyline };

/// One mesh over time.
struct XdmfMesh {
  std::string name;  ///< block name in ParaView, e.g. "body:supraspinatus"
  XdmfCell cell = XdmfCell::kTetrahedron;
  XdmfSeries cells;   ///< connectivity rows (0-based indices into this frame's points block)
  XdmfSeries points;  ///< xyz rows, mm
};

struct XdmfRun {
  std::string h5_name;        ///< HDF5 file name relative to the .xmf (same directory)
  std::vector<double> times;  ///< per frame, s
  std::vector<XdmfMesh> meshes;
};

/// The XML text. Frames beyond any series' per-frame arrays are left out; a mesh with no cells
/// or no points in a frame is left out of that frame.
std::string XdmfText(const XdmfRun& run);

/// Writes `text` to `path` atomically (temporary file in the same directory, then rename).
/// @throws std::runtime_error naming the path if it cannot be written.
void WriteFileAtomically(const std::string& path, const std::string& text);

/// "dir/run.h5" -> "dir/run.xmf" (extension replaced; appended if there is none).
std::string XdmfPathFor(const std::string& h5_path);

/// Rebuilds the XdmfRun of a run file from its offset/count arrays (e.g. after a crash:
/// `arthrosim` can regenerate the sidecar of a killed run). Opens the file SWMR-read.
XdmfRun XdmfRunFromFile(const std::string& h5_path);

}  // namespace arthrosim::io
