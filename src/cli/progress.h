#pragma once
// A progress bar with ETA on stderr, drawn only when stderr is a terminal and not --quiet.
#include <chrono>
#include <cstdint>

namespace arthrosim::cli {

class ProgressBar {
 public:
  /// total: number of steps; enabled: false silences it (--quiet or not a terminal).
  ProgressBar(std::int64_t total, bool enabled);
  /// Redraws at most ~10 times per second.
  void Update(std::int64_t done);
  /// Clears the line.
  void Finish();

 private:
  std::int64_t total_;
  bool enabled_;
  std::chrono::steady_clock::time_point start_, last_draw_;
};

}  // namespace arthrosim::cli
