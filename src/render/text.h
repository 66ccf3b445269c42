#pragma once
// TrueType text rasterised on the CPU with stb_truetype and alpha-blended into an Image.
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "arthrosim/render/image.h"

namespace arthrosim::render {

class Font {
 public:
  /// Loads a .ttf file. @throws RenderError naming the Debian package fonts-dejavu-core if the
  /// file is missing or not a TrueType font.
  explicit Font(const std::string& path);
  ~Font();
  Font(const Font&) = delete;
  Font& operator=(const Font&) = delete;

  /// Width in pixels of `text` at pixel height `px`.
  int TextWidth(const std::string& text, int px);
  /// Draws `text` with its top-left corner at (x, y), colour rgb, with a 1-pixel dark shadow.
  void Draw(const std::string& text, int x, int y, int px, const std::uint8_t rgb[3], Image* image);

 private:
  struct Glyph {
    int x0 = 0, y0 = 0, w = 0, h = 0;  // bitmap box relative to the pen on the baseline
    std::vector<std::uint8_t> alpha;
  };
  const Glyph& GetGlyph(int codepoint, int px);
  void Blend(const std::string& text, int x, int y, int px, const std::uint8_t rgb[3],
             Image* image);
  float Scale(int px) const;

  std::vector<unsigned char> data_;
  void* info_ = nullptr;  // stbtt_fontinfo, kept out of this header
  std::map<std::pair<int, int>, Glyph> cache_;
};

}  // namespace arthrosim::render
