#include "overlay.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace arthrosim::render {
namespace {

void FillRect(int x0, int y0, int w, int h, const std::uint8_t rgb[3], Image* image) {
  for (int y = std::max(0, y0); y < std::min(image->height, y0 + h); ++y) {
    for (int x = std::max(0, x0); x < std::min(image->width, x0 + w); ++x) {
      std::uint8_t* p = image->At(x, y);
      p[0] = rgb[0];
      p[1] = rgb[1];
      p[2] = rgb[2];
    }
  }
}

std::string Format(const char* fmt, double value) {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, value);
  return buf;
}

}  // namespace

void DrawOverlay(const Overlay& overlay, Font* font, Image* image) {
  static constexpr std::uint8_t kWhite[3] = {240, 240, 240};
  static constexpr std::uint8_t kYellow[3] = {250, 220, 90};
  static constexpr std::uint8_t kFrame[3] = {90, 90, 90};
  static constexpr std::uint8_t kTrack[3] = {25, 25, 25};
  const int px = std::max(9, image->height / 26);
  const int line = px + px / 4;
  const int margin = std::max(2, px / 2);

  // top left: time and instruments
  int y = margin;
  font->Draw(Format("t = %.2f s", overlay.time_s), margin, y, px, kWhite, image);
  y += line;
  for (const ToolOverlay& t : overlay.tools) {
    std::string text = std::to_string(t.slot + 1) + ": " + t.instrument;
    if (t.kind != t.instrument) text += " (" + t.kind + ")";
    font->Draw(text, margin, y, px, kWhite, image);
    y += line;
  }

  // top right: plan step and verdict, right-aligned
  int yr = margin;
  for (const std::string* s : {&overlay.plan_step, &overlay.verdict}) {
    if (s->empty()) continue;
    const int w = font->TextWidth(*s, px);
    font->Draw(*s, std::max(margin, image->width - margin - w), yr, px,
               s == &overlay.verdict ? kYellow : kWhite, image);
    yr += line;
  }

  // bottom left: one contact-force bar per instrument, green -> red with force
  const int bar_w = std::max(20, image->width / 5), bar_h = std::max(4, px / 2);
  int yb = image->height - margin - line * static_cast<int>(overlay.tools.size());
  for (const ToolOverlay& t : overlay.tools) {
    std::string label = "F";  // appended: GCC 12 -Wrestrict false positive on "lit" + string
    label += std::to_string(t.slot + 1);
    font->Draw(label, margin, yb, px, kWhite, image);
    const int x0 = margin + font->TextWidth("F0 ", px);
    const int by = yb + (px - bar_h) / 2 + 1;
    FillRect(x0 - 1, by - 1, bar_w + 2, bar_h + 2, kFrame, image);
    FillRect(x0, by, bar_w, bar_h, kTrack, image);
    const double f = std::clamp(t.force_n / kForceBarFullScaleN, 0.0, 1.0);
    const std::uint8_t color[3] = {static_cast<std::uint8_t>(std::lround(60 + 195 * f)),
                                   static_cast<std::uint8_t>(std::lround(200 - 150 * f)), 40};
    FillRect(x0, by, static_cast<int>(std::lround(f * bar_w)), bar_h, color, image);
    font->Draw(Format("%.1f N", t.force_n), x0 + bar_w + margin, yb, px, kWhite, image);
    yb += line;
  }
}

}  // namespace arthrosim::render
