#include "text.h"

#include <stb_truetype.h>

#include <cmath>
#include <fstream>
#include <iterator>

namespace arthrosim::render {
namespace {

stbtt_fontinfo* Info(void* p) { return static_cast<stbtt_fontinfo*>(p); }

// Moves the pen past byte i of text at scale s: its advance, then the kerning toward the next.
void AdvancePen(void* info, const std::string& text, std::size_t i, float s, float* pen) {
  const int cp = static_cast<unsigned char>(text[i]);
  int advance, lsb;
  stbtt_GetCodepointHMetrics(Info(info), cp, &advance, &lsb);
  *pen += advance * s;
  if (i + 1 < text.size()) {
    *pen +=
        s * stbtt_GetCodepointKernAdvance(Info(info), cp, static_cast<unsigned char>(text[i + 1]));
  }
}

}  // namespace

Font::Font(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw RenderError("overlay font '" + path +
                      "' not found: install the Debian package fonts-dejavu-core "
                      "(apt-get install fonts-dejavu-core)");
  }
  data_.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  auto* info = new stbtt_fontinfo{};
  const int offset = stbtt_GetFontOffsetForIndex(data_.data(), 0);
  if (data_.empty() || offset < 0 || !stbtt_InitFont(info, data_.data(), offset)) {
    delete info;
    throw RenderError("overlay font '" + path +
                      "' is not a TrueType font: reinstall the Debian package fonts-dejavu-core");
  }
  info_ = info;
}

Font::~Font() { delete Info(info_); }

float Font::Scale(int px) const {
  return stbtt_ScaleForPixelHeight(Info(info_), static_cast<float>(px));
}

const Font::Glyph& Font::GetGlyph(int codepoint, int px) {
  const auto key = std::make_pair(px, codepoint);
  auto it = cache_.find(key);
  if (it != cache_.end()) return it->second;
  Glyph g;
  const float s = Scale(px);
  int x0, y0, x1, y1;
  stbtt_GetCodepointBitmapBox(Info(info_), codepoint, s, s, &x0, &y0, &x1, &y1);
  g.x0 = x0;
  g.y0 = y0;
  g.w = x1 - x0;
  g.h = y1 - y0;
  if (g.w > 0 && g.h > 0) {
    g.alpha.assign(static_cast<std::size_t>(g.w) * g.h, 0);
    stbtt_MakeCodepointBitmap(Info(info_), g.alpha.data(), g.w, g.h, g.w, s, s, codepoint);
  }
  return cache_.emplace(key, std::move(g)).first->second;
}

int Font::TextWidth(const std::string& text, int px) {
  const float s = Scale(px);
  float pen = 0;
  for (std::size_t i = 0; i < text.size(); ++i) AdvancePen(info_, text, i, s, &pen);
  return static_cast<int>(std::ceil(pen));
}

void Font::Blend(const std::string& text, int x, int y, int px, const std::uint8_t rgb[3],
                 Image* image) {
  const float s = Scale(px);
  int ascent, descent, gap;
  stbtt_GetFontVMetrics(Info(info_), &ascent, &descent, &gap);
  const int baseline = y + static_cast<int>(std::lround(ascent * s));
  float pen = static_cast<float>(x);
  for (std::size_t i = 0; i < text.size(); ++i) {
    // bytes >= 128 are drawn as Latin-1 code points (overlay text is ASCII in practice)
    const int cp = static_cast<unsigned char>(text[i]);
    const Glyph& g = GetGlyph(cp, px);
    const int gx = static_cast<int>(std::lround(pen)) + g.x0, gy = baseline + g.y0;
    for (int row = 0; row < g.h; ++row) {
      const int iy = gy + row;
      if (iy < 0 || iy >= image->height) continue;
      for (int col = 0; col < g.w; ++col) {
        const int ix = gx + col;
        if (ix < 0 || ix >= image->width) continue;
        const int a = g.alpha[static_cast<std::size_t>(row) * g.w + col];
        if (a == 0) continue;
        std::uint8_t* p = image->At(ix, iy);
        for (int k = 0; k < 3; ++k)
          p[k] = static_cast<std::uint8_t>((rgb[k] * a + p[k] * (255 - a) + 127) / 255);
      }
    }
    AdvancePen(info_, text, i, s, &pen);
  }
}

void Font::Draw(const std::string& text, int x, int y, int px, const std::uint8_t rgb[3],
                Image* image) {
  static constexpr std::uint8_t kShadow[3] = {0, 0, 0};
  Blend(text, x + 1, y + 1, px, kShadow, image);
  Blend(text, x, y, px, rgb, image);
}

}  // namespace arthrosim::render
