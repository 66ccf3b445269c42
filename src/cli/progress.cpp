#include "progress.h"

#include <fmt/core.h>
#include <unistd.h>

#include <cstdio>

namespace arthrosim::cli {

ProgressBar::ProgressBar(std::int64_t total, bool enabled)
    : total_(total > 0 ? total : 1),
      enabled_(enabled && isatty(STDERR_FILENO)),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_) {}

void ProgressBar::Update(std::int64_t done) {
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  if (done < total_ && now - last_draw_ < std::chrono::milliseconds(100)) return;
  last_draw_ = now;
  const double frac = static_cast<double>(done) / static_cast<double>(total_);
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  const double eta = frac > 0 ? elapsed * (1 - frac) / frac : 0;
  constexpr int kWidth = 30;
  const int filled = static_cast<int>(frac * kWidth);
  fmt::print(stderr, "\r[{}{}] {:5.1f}%  step {}/{}  ETA {:.0f}s ", std::string(filled, '#'),
             std::string(kWidth - filled, '.'), 100 * frac, done, total_, eta);
  std::fflush(stderr);
}

void ProgressBar::Finish() {
  if (enabled_) fmt::print(stderr, "\r{:80}\r", "");
}

}  // namespace arthrosim::cli
