#pragma once
// XDMF sidecar (run.xmf) for ParaView: a Temporal collection with one Spatial collection per
// listed frame, one grid per soft body (alive tets), bone (triangles) and thread (segments as
// 2-node Polylines). Under SWMR no per-frame datasets exist, so every topology and geometry item
// selects a frame's rows of a concatenated block series (rows offset[t] .. offset[t]+count[t]):
// in the form the Xdmf3 readers read (run.xmf), or as HyperSlab items for the legacy XDMFReader
// (run.xdmf2.xmf, written on request).
#include <cstdint>
#include <string>
#include <vector>

namespace arthrosim::io {

/// Default XdmfRun::interval_s: 5 listed frames per simulated second.
inline constexpr double kXdmfIntervalS = 0.2;

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
  /// Frame numbers of the entries (the grids' names "frame<n>"); empty = 0, 1, 2...
  std::vector<std::int64_t> frame_index;
  std::vector<XdmfMesh> meshes;
  /// Frames listed are at least this much simulated time apart (s; the first and the last frame
  /// are always listed, 0 lists every frame): ParaView does not need 50 frames per second, and
  /// the sidecar's size is per listed frame (~3 kB for the shoulder scene's seven meshes).
  double interval_s = kXdmfIntervalS;
};

/// How a frame's rows of a block series are referenced (ParaView 5.11 has no form that both
/// reader families read: docs/hdf5-layout.md, XDMF sidecar).
enum class XdmfDialect {
  kXdmf3,  ///< HDF items with an inline selection: Xdmf3ReaderS / Xdmf3ReaderT (ParaView's default)
  kXdmf2,  ///< HyperSlab items: the legacy XDMFReader
};

/// The XML text. Frames beyond any series' per-frame arrays are left out, and frames closer than
/// run.interval_s to the previous listed one; a mesh with no cells or no points in a frame is
/// left out of that frame.
std::string XdmfText(const XdmfRun& run, XdmfDialect dialect = XdmfDialect::kXdmf3);

/// Writes XdmfText(run, dialect) to `path` atomically (as WriteFileAtomically), one frame at a
/// time: memory does not grow with the number of frames.
/// @throws std::runtime_error naming the path if it cannot be written.
void WriteXdmfFile(const std::string& path, const XdmfRun& run,
                   XdmfDialect dialect = XdmfDialect::kXdmf3);

/// Writes `text` to `path` atomically (temporary file in the same directory, then rename).
/// @throws std::runtime_error naming the path if it cannot be written.
void WriteFileAtomically(const std::string& path, const std::string& text);

/// "dir/run.h5" -> "dir/run.xmf" (kXdmf3) or "dir/run.xdmf2.xmf" (kXdmf2); the extension is
/// replaced (appended if there is none).
std::string XdmfPathFor(const std::string& h5_path, XdmfDialect dialect = XdmfDialect::kXdmf3);

/// Rebuilds the XdmfRun of a run file from its offset/count arrays (e.g. after a crash:
/// `arthrosim` can regenerate the sidecar of a killed run). Opens the file SWMR-read.
/// `interval_s` as XdmfRun::interval_s.
XdmfRun XdmfRunFromFile(const std::string& h5_path, double interval_s = kXdmfIntervalS);

}  // namespace arthrosim::io
