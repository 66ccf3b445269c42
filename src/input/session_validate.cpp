// Checks shared by the CSV and HDF5 session readers.
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

#include "arthrosim/core/error.h"
#include "arthrosim/input/session.h"

namespace arthrosim::input {
namespace {

// Below this the quaternion is taken as written (bit-exact replay of recorded sessions).
constexpr double kUnitTolerance = 1e-9;
// Up to this it is normalised with a warning (6-digit logs); beyond, it is an error.
constexpr double kRepairTolerance = 1e-3;

// Throws when, at some time, one instrument is in both tool slots: each slot holds the
// instrument of its latest row, and rows with the same timestamp take effect together (so a
// swap between the slots within one instant is fine).
void CheckInstrumentInOneSlot(const SessionTable& table) {
  std::vector<std::size_t> order(table.rows.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return table.rows[a].t_s < table.rows[b].t_s;
  });
  std::array<const SessionRow*, kToolSlots> held{};
  for (std::size_t i = 0; i < order.size();) {
    const double t = table.rows[order[i]].t_s;
    for (; i < order.size() && table.rows[order[i]].t_s == t; ++i) {
      const SessionRow& r = table.rows[order[i]];
      const int d = static_cast<int>(r.device);
      if (d < kToolSlots) held[static_cast<std::size_t>(d)] = &r;
    }
    const SessionRow* a = held[0];
    const SessionRow* b = held[1];
    if (a == nullptr || b == nullptr || a->instrument.empty() || a->instrument != b->instrument)
      continue;
    const SessionRow& later = a->line > b->line ? *a : *b;
    const SessionRow& earlier = a->line > b->line ? *b : *a;
    throw InputError(table.file, later.line, "instrument",
                     fmt::format("'{}' is in slot0 and slot1 at the same time ({} s; the other "
                                 "slot took it at line {}); an instrument is in one slot at a time",
                                 a->instrument, t, earlier.line));
  }
}

}  // namespace

void ValidateSession(SessionTable* table, const SessionOptions& options) {
  std::array<const SessionRow*, kDeviceCount> last{};
  std::array<int, kDeviceCount> normalised{};
  std::array<double, kDeviceCount> worst{};
  std::array<int, kDeviceCount> first_line{};
  for (SessionRow& r : table->rows) {
    const int d = static_cast<int>(r.device);
    if (!std::isfinite(r.t_s)) {
      throw InputError(table->file, r.line, "t", "non-finite timestamp");
    }
    const double n = r.orientation.norm();
    const double dev = std::abs(n - 1.0);
    if (!(dev <= kRepairTolerance)) {
      throw InputError(table->file, r.line, "qw",
                       fmt::format("orientation quaternion has norm {:.6g}; expected a unit "
                                   "quaternion (w, x, y, z) within 1e-3",
                                   n));
    }
    if (dev > kUnitTolerance) {
      r.orientation.normalize();
      if (normalised[d]++ == 0) first_line[d] = r.line;
      worst[d] = std::max(worst[d], dev);
    }
    if (last[d] != nullptr) {
      const SessionRow& p = *last[d];
      if (r.t_s < p.t_s) {
        throw InputError(table->file, r.line, "t",
                         fmt::format("timestamp {} of device {} goes back in time (line {} had {})",
                                     r.t_s, DeviceName(r.device), p.line, p.t_s));
      }
      if (options.max_gap_s > 0 && r.t_s - p.t_s > options.max_gap_s) {
        const std::string msg =
            fmt::format("gap of {:.6g} s in device {} since line {} exceeds the limit of {} s",
                        r.t_s - p.t_s, DeviceName(r.device), p.line, options.max_gap_s);
        if (options.gap_policy == GapPolicy::kError) {
          throw InputError(table->file, r.line, "t", msg);
        }
        table->warnings.push_back(fmt::format("{}:{}: {}; holding the earlier sample across it",
                                              table->file, r.line, msg));
      }
    }
    last[d] = &r;
  }
  CheckInstrumentInOneSlot(*table);
  for (int d = 0; d < kDeviceCount; ++d) {
    if (normalised[d] > 0) {
      table->warnings.push_back(fmt::format(
          "{}:{}: {} orientation(s) of device {} normalised (largest | |q| - 1 | = {:.3g})",
          table->file, first_line[d], normalised[d], DeviceName(static_cast<Device>(d)), worst[d]));
    }
  }
}

void AppendFrameRows(const Model& model, double t_s, const InputFrame& frame,
                     std::vector<SessionRow>* rows) {
  for (int s = 0; s < kToolSlots; ++s) {
    const ToolCommand& tc = frame.tools[s];
    SessionRow r;
    r.t_s = t_s;
    r.device = static_cast<Device>(s);
    if (tc.instrument >= 0 && tc.instrument < static_cast<int>(model.instruments.size())) {
      r.instrument = model.instruments[tc.instrument].name;
    }
    r.position_mm = tc.pose.position_mm;
    r.orientation = tc.pose.orientation;
    r.jaw = tc.jaw;
    r.buttons = tc.buttons;
    rows->push_back(std::move(r));
  }
  SessionRow c;
  c.t_s = t_s;
  c.device = Device::kScope;
  c.position_mm = frame.camera.pose.position_mm;
  c.orientation = frame.camera.pose.orientation;
  c.lens_roll_rad = frame.camera.lens_roll_rad;
  c.head_roll_rad = frame.camera.head_roll_rad;
  rows->push_back(std::move(c));
}

}  // namespace arthrosim::input
