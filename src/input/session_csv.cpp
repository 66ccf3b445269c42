// Session CSV reader and writer (docs/trajectory-format.md).
#include <fmt/format.h>

#include <array>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

#include "arthrosim/core/error.h"
#include "arthrosim/core/input_file.h"
#include "arthrosim/input/session.h"

namespace arthrosim::input {
namespace {

enum Column : int {
  kT,
  kDevice,
  kInstrument,
  kX,
  kY,
  kZ,
  kQw,
  kQx,
  kQy,
  kQz,
  kJaw,
  kButtons,
  kLensRoll,
  kHeadRoll,
  kColumnCount
};
constexpr std::array<const char*, kColumnCount> kColumnNames = {
    "t",  "device", "instrument", "x",   "y",       "z",         "qw",
    "qx", "qy",     "qz",         "jaw", "buttons", "lens_roll", "head_roll"};
constexpr int kRequiredColumns = kButtons + 1;

std::string Trim(std::string_view s) {
  std::size_t b = 0, e = s.size();
  while (b < e && (s[b] == ' ' || s[b] == '\t')) ++b;
  while (e > b && (s[e - 1] == ' ' || s[e - 1] == '\t' || s[e - 1] == '\r')) --e;
  return std::string(s.substr(b, e - b));
}

std::vector<std::string> SplitFields(std::string_view line) {
  std::vector<std::string> out;
  std::size_t start = 0;
  for (std::size_t i = 0; i <= line.size(); ++i) {
    if (i == line.size() || line[i] == ',') {
      out.push_back(Trim(line.substr(start, i - start)));
      start = i + 1;
    }
  }
  return out;
}

struct Cursor {
  const std::string& file;
  int line;
  const std::vector<int>& column_of;  // column kind -> field index, -1 absent
  const std::vector<std::string>& fields;

  [[noreturn]] void Fail(int col, const std::string& msg) const {
    throw InputError(file, line, kColumnNames[col],
                     fmt::format("column {}: {}", column_of[col] + 1, msg));
  }
  bool Has(int col) const { return column_of[col] >= 0 && !fields[column_of[col]].empty(); }
  const std::string& Text(int col) const { return fields[column_of[col]]; }

  double Number(int col, bool required) const {
    if (!Has(col)) {
      if (required) Fail(col, "missing value, expected a number");
      return 0.0;
    }
    const std::string& s = Text(col);
    double v = 0;
    const char* begin = s.data();
    if (!s.empty() && s[0] == '+') ++begin;
    auto [ptr, ec] = std::from_chars(begin, s.data() + s.size(), v);
    if (ec != std::errc() || ptr != s.data() + s.size()) {
      Fail(col, fmt::format("'{}' is not a number", s));
    }
    if (!std::isfinite(v)) Fail(col, fmt::format("non-finite value '{}'", s));
    return v;
  }
};

}  // namespace

const char* SessionCsvHeader() {
  return "t,device,instrument,x,y,z,qw,qx,qy,qz,jaw,buttons,lens_roll,head_roll";
}

std::string FormatSessionCsvRow(const SessionRow& r) {
  const Quat& q = r.orientation;
  return fmt::format(
      "{:.17g},{},{},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{},{:.17g},{:."
      "17g}",
      r.t_s, DeviceName(r.device), r.instrument.empty() ? "none" : r.instrument, r.position_mm.x(),
      r.position_mm.y(), r.position_mm.z(), q.w(), q.x(), q.y(), q.z(), r.jaw,
      static_cast<int>(r.buttons), r.lens_roll_rad, r.head_roll_rad);
}

SessionTable ParseSessionCsv(const std::string& text, const std::string& file,
                             const SessionOptions& options) {
  SessionTable table;
  table.file = file;
  std::vector<int> column_of(kColumnCount, -1);
  std::size_t header_fields = 0;
  bool have_header = false;
  int line_no = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t nl = text.find('\n', pos);
    const bool terminated = nl != std::string::npos;
    if (!terminated) nl = text.size();
    const std::string_view raw(text.data() + pos, nl - pos);
    pos = nl + 1;
    ++line_no;
    const std::string line = Trim(raw);
    if (line.empty() || line[0] == '#') continue;
    std::vector<std::string> fields = SplitFields(line);

    if (!have_header) {
      for (std::size_t i = 0; i < fields.size(); ++i) {
        int kind = -1;
        for (int c = 0; c < kColumnCount; ++c) {
          if (fields[i] == kColumnNames[c]) kind = c;
        }
        if (kind < 0) {
          throw InputError(file, line_no, fields[i],
                           fmt::format("column {}: unknown column '{}' in header; expected {}",
                                       i + 1, fields[i], SessionCsvHeader()));
        }
        if (column_of[kind] >= 0) {
          throw InputError(file, line_no, fields[i],
                           fmt::format("column {}: duplicate column '{}'", i + 1, fields[i]));
        }
        column_of[kind] = static_cast<int>(i);
      }
      for (int c = 0; c < kRequiredColumns; ++c) {
        if (column_of[c] < 0) {
          throw InputError(file, line_no, kColumnNames[c],
                           fmt::format("header lacks required column '{}'; expected {}",
                                       kColumnNames[c], SessionCsvHeader()));
        }
      }
      header_fields = fields.size();
      have_header = true;
      continue;
    }

    if (fields.size() != header_fields) {
      // A logger killed mid-write leaves a partial last line without a newline: drop it.
      if (!terminated && fields.size() < header_fields) {
        table.warnings.push_back(
            fmt::format("{}:{}: truncated last line ({} of {} columns) dropped", file, line_no,
                        fields.size(), header_fields));
        break;
      }
      throw InputError(
          file, line_no, "",
          fmt::format("column {}: expected {} columns as in the header, found {}",
                      std::min(fields.size(), header_fields) + 1, header_fields, fields.size()));
    }
    const Cursor c{file, line_no, column_of, fields};
    SessionRow row;
    row.line = line_no;
    row.t_s = c.Number(kT, true) - options.time_offset_s;
    const std::optional<Device> dev = ParseDevice(c.Text(kDevice));
    if (!dev)
      c.Fail(kDevice,
             fmt::format("unknown device '{}'; expected slot0, slot1 or scope", c.Text(kDevice)));
    row.device = *dev;
    std::string instrument = c.Has(kInstrument) ? c.Text(kInstrument) : "";
    if (instrument == "none" || (row.device == Device::kScope && instrument == "scope")) {
      instrument.clear();
    }
    if (row.device == Device::kScope && !instrument.empty()) {
      c.Fail(kInstrument,
             fmt::format("the scope row carries no instrument (found '{}'); leave it empty",
                         instrument));
    }
    row.instrument = instrument;
    row.position_mm = Vec3(c.Number(kX, true), c.Number(kY, true), c.Number(kZ, true));
    row.orientation =
        Quat(c.Number(kQw, true), c.Number(kQx, true), c.Number(kQy, true), c.Number(kQz, true));
    row.jaw = c.Number(kJaw, false);
    if (row.jaw < 0.0 || row.jaw > 1.0) c.Fail(kJaw, fmt::format("jaw {} outside [0, 1]", row.jaw));
    const double b = c.Number(kButtons, false);
    if (b != std::floor(b) || b < 0 || b > 3) {
      c.Fail(
          kButtons,
          fmt::format("buttons '{}' is not an integer in 0..3 (bit 0 = button 1, bit 1 = button 2)",
                      c.Text(kButtons)));
    }
    row.buttons = static_cast<std::uint8_t>(b);
    row.lens_roll_rad = column_of[kLensRoll] >= 0 ? c.Number(kLensRoll, false) : 0.0;
    row.head_roll_rad = column_of[kHeadRoll] >= 0 ? c.Number(kHeadRoll, false) : 0.0;
    if (row.device != Device::kScope && (row.lens_roll_rad != 0.0 || row.head_roll_rad != 0.0)) {
      c.Fail(c.Has(kLensRoll) && row.lens_roll_rad != 0.0 ? kLensRoll : kHeadRoll,
             "lens_roll/head_roll belong to the scope; leave them empty or 0 on slot rows");
    }
    if (row.device == Device::kScope && (row.jaw != 0.0 || row.buttons != 0)) {
      c.Fail(row.jaw != 0.0 ? kJaw : kButtons,
             "the scope has no jaw or buttons; leave them empty or 0");
    }
    table.rows.push_back(std::move(row));
  }
  if (!have_header)
    throw InputError(file, line_no, "", "empty file: expected a header line and samples");
  if (table.rows.empty()) throw InputError(file, line_no, "", "no samples after the header");
  ValidateSession(&table, options);
  return table;
}

SessionTable ReadSessionCsv(const std::string& path, const SessionOptions& options) {
  return ParseSessionCsv(ReadInputFile(path, "", "cannot open session file"), path, options);
}

void WriteSessionCsv(const std::string& path, const SessionTable& table) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw InputError(path, 0, "", "cannot create session file");
  out << SessionCsvHeader() << '\n';
  for (const SessionRow& r : table.rows) out << FormatSessionCsvRow(r) << '\n';
  if (!out) throw InputError(path, 0, "", "write failed");
}

SessionTable ReadSession(const std::string& path, const SessionOptions& options) {
  auto ends_with = [&](const char* ext) {
    const std::string e(ext);
    return path.size() >= e.size() && path.compare(path.size() - e.size(), e.size(), e) == 0;
  };
  if (ends_with(".h5") || ends_with(".hdf5")) return ReadSessionHdf5(path, options);
  if (ends_with(".csv")) return ReadSessionCsv(path, options);
  throw InputError(path, 0, "", "unknown session file type; expected .csv, .h5 or .hdf5");
}

}  // namespace arthrosim::input
