#pragma once
// An 8-bit RGB image, rows top to bottom (the order of PNG files and of ffmpeg rawvideo), and
// the PNG and comparison helpers used by sinks and golden tests.
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace arthrosim::render {

/// Failure of the rendering or video environment (missing program, font, GL context, I/O).
class RenderError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// RGB8 image; pixel (x, y) with y = 0 the top row is at rgb[3 * (y * width + x)].
struct Image {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgb;  ///< 3 * width * height bytes

  /// Resizes to w x h and fills with black.
  void Resize(int w, int h) {
    width = w;
    height = h;
    rgb.assign(static_cast<std::size_t>(3) * w * h, 0);
  }
  /// Pointer to the 3 bytes of pixel (x, y); no bounds check.
  std::uint8_t* At(int x, int y) {
    return rgb.data() + 3 * (static_cast<std::size_t>(y) * width + x);
  }
  const std::uint8_t* At(int x, int y) const {
    return rgb.data() + 3 * (static_cast<std::size_t>(y) * width + x);
  }
};

/// Writes `image` as a PNG file. @throws RenderError if the file cannot be written.
void WritePng(const std::string& path, const Image& image);
/// Reads an RGB PNG file (alpha dropped). @throws RenderError if missing or not a PNG.
Image ReadPng(const std::string& path);
/// Peak signal-to-noise ratio in dB over all channels (peak 255); +infinity when identical.
/// @throws std::invalid_argument if the sizes differ.
double Psnr(const Image& a, const Image& b);

}  // namespace arthrosim::render
