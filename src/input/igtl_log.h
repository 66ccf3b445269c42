#pragma once
// Internal: the live server's log, limited per kind of line so that a flood of bad messages or
// connections cannot fill a disk or stall the network thread on a slow stderr.
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <string>

namespace arthrosim::input {

class RateLimitedLog {
 public:
  using Clock = std::chrono::steady_clock;
  /// Lines go to `sink`; at most `per_second` lines of one kind are written in any window of one
  /// second (starting at the kind's first line of the window).
  RateLimitedLog(std::function<void(const std::string&)> sink, int per_second);

  /// Writes `line` if fewer than per_second lines of `kind` were written in its current window;
  /// otherwise only counts it for the summary line Tick writes when the window ends.
  void Write(const std::string& kind, const std::string& line, Clock::time_point now);
  /// For every kind whose window has ended by `now` (every kind if `all`) and held lines back:
  /// writes "<kind>: N more in the last S s, not logged one by one" and starts a new window.
  void Tick(Clock::time_point now, bool all = false);
  /// Writes `line` with no limit (start-up and shutdown summaries).
  void Always(const std::string& line) const { sink_(line); }

 private:
  struct Window {
    Clock::time_point start;
    int written = 0;
    std::uint64_t held = 0;
  };
  void Summarise(const std::string& kind, Window* w, Clock::time_point now);

  std::function<void(const std::string&)> sink_;
  int per_second_;
  std::map<std::string, Window> windows_;
};

}  // namespace arthrosim::input
