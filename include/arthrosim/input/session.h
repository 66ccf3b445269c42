#pragma once
// Recorded sessions: one row per device sample, as read from CSV or HDF5 and before resampling
// (docs/trajectory-format.md). Rows keep instrument names, so a session can be checked, streamed
// or converted without a Model; RecordedSource resolves the names against a Model.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "arthrosim/core/types.h"
#include "arthrosim/input/input_source.h"

namespace arthrosim::input {

/// One sample of one device. Units: s, mm, rad.
struct SessionRow {
  double t_s = 0;
  Device device = Device::kSlot0;
  std::string instrument;           ///< Model instrument name; "" = withdrawn (and the scope)
  Vec3 position_mm = Vec3::Zero();  ///< tool tip / scope tip, world
  Quat orientation = Quat::Identity();
  double jaw = 0;            ///< 0 open ... 1 closed
  std::uint8_t buttons = 0;  ///< bit 0 = button 1, bit 1 = button 2
  double lens_roll_rad = 0;  ///< scope only
  double head_roll_rad = 0;  ///< scope only
  int line = 0;              ///< CSV line / HDF5 row (1-based) it came from, for messages
};

/// What to do when one device's consecutive samples are further apart than max_gap_s.
enum class GapPolicy : std::uint8_t {
  kError,  ///< InputError naming the line (default)
  kHold,   ///< warn and hold the earlier sample until the later one (no invented motion)
};

struct SessionOptions {
  double max_gap_s = 0.25;  ///< longest allowed gap between samples of one device; <= 0: no limit
  GapPolicy gap_policy = GapPolicy::kError;
  double time_offset_s = 0;  ///< subtracted from every timestamp (e.g. absolute device clocks)
};

/// A whole session: rows in file order (per device, times never decrease).
struct SessionTable {
  std::string file;  ///< where it was read from (for messages)
  std::vector<SessionRow> rows;
  std::vector<std::string> warnings;  ///< repairs made while reading ("file:line: ...")
};

/// Reads a session CSV (docs/trajectory-format.md). Throws InputError naming file, line and
/// column on bad data; documented repairs are listed in SessionTable::warnings.
SessionTable ReadSessionCsv(const std::string& path, const SessionOptions& options = {});
/// Same, from text already in memory; `file` is used in messages only.
SessionTable ParseSessionCsv(const std::string& text, const std::string& file,
                             const SessionOptions& options = {});
/// Reads the HDF5 form (groups /slot0, /slot1, /scope). Same checks; "line" = 1-based row.
SessionTable ReadSessionHdf5(const std::string& path, const SessionOptions& options = {});
/// Same, from an HDF5 file image of `size` bytes in memory (a copy is opened with the core
/// driver, nothing touches disk); `file` is used in messages only.
SessionTable ParseSessionHdf5(const void* image, std::size_t size, const std::string& file,
                              const SessionOptions& options = {});
/// Reads .csv or .h5/.hdf5 by extension.
SessionTable ReadSession(const std::string& path, const SessionOptions& options = {});

/// Checks per-device time order, gaps and quaternion norms; normalises near-unit quaternions
/// (| |q| - 1 | <= 1e-3) with a warning. Called by the readers; exposed for tables built in code.
void ValidateSession(SessionTable* table, const SessionOptions& options = {});

/// Writes the table as CSV with every double printed round-trip exact (17 significant digits).
void WriteSessionCsv(const std::string& path, const SessionTable& table);
/// Writes the table in the HDF5 form.
void WriteSessionHdf5(const std::string& path, const SessionTable& table);

/// The CSV header line written by this library (no newline).
const char* SessionCsvHeader();
/// One CSV line for a row (no newline), doubles round-trip exact.
std::string FormatSessionCsvRow(const SessionRow& row);

/// Appends the three rows (slot0, slot1, scope) that reproduce `frame` at time t_s.
void AppendFrameRows(const Model& model, double t_s, const InputFrame& frame,
                     std::vector<SessionRow>* rows);

}  // namespace arthrosim::input
