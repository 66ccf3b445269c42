#include "igtl_log.h"

#include <fmt/format.h>

namespace arthrosim::input {
namespace {

constexpr std::chrono::seconds kWindow{1};

}  // namespace

RateLimitedLog::RateLimitedLog(std::function<void(const std::string&)> sink, int per_second)
    : sink_(std::move(sink)), per_second_(per_second) {}

void RateLimitedLog::Summarise(const std::string& kind, Window* w, Clock::time_point now) {
  if (w->held > 0) {
    const double s = std::chrono::duration<double>(now - w->start).count();
    sink_(fmt::format("{}: {} more in the last {:.1f} s, not logged one by one", kind, w->held, s));
  }
  *w = Window{now, 0, 0};
}

void RateLimitedLog::Write(const std::string& kind, const std::string& line,
                           Clock::time_point now) {
  auto [it, added] = windows_.try_emplace(kind, Window{now, 0, 0});
  Window& w = it->second;
  if (!added && now - w.start >= kWindow) Summarise(kind, &w, now);
  if (w.written < per_second_) {
    ++w.written;
    sink_(line);
  } else {
    ++w.held;
  }
}

void RateLimitedLog::Tick(Clock::time_point now, bool all) {
  for (auto& [kind, w] : windows_) {
    if (w.held > 0 && (all || now - w.start >= kWindow)) Summarise(kind, &w, now);
  }
}

}  // namespace arthrosim::input
