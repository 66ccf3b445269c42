#include "arthrosim/render/image.h"

#include <stb_image.h>
#include <stb_image_write.h>

#include <cmath>
#include <limits>
#include <stdexcept>

namespace arthrosim::render {

void WritePng(const std::string& path, const Image& image) {
  if (image.width <= 0 || image.height <= 0 ||
      image.rgb.size() != static_cast<std::size_t>(3) * image.width * image.height) {
    throw RenderError("WritePng '" + path + "': image has no pixels or a wrong buffer size");
  }
  if (!stbi_write_png(path.c_str(), image.width, image.height, 3, image.rgb.data(),
                      3 * image.width)) {
    throw RenderError("cannot write PNG file '" + path + "'");
  }
}

Image ReadPng(const std::string& path) {
  int w = 0, h = 0, channels = 0;
  unsigned char* data = stbi_load(path.c_str(), &w, &h, &channels, 3);
  if (data == nullptr) {
    throw RenderError("cannot read PNG file '" + path +
                      "': " + (stbi_failure_reason() ? stbi_failure_reason() : "unknown error"));
  }
  Image image;
  image.width = w;
  image.height = h;
  image.rgb.assign(data, data + static_cast<std::size_t>(3) * w * h);
  stbi_image_free(data);
  return image;
}

double Psnr(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height || a.rgb.size() != b.rgb.size()) {
    throw std::invalid_argument("Psnr: images differ in size");
  }
  double sum = 0;
  for (std::size_t i = 0; i < a.rgb.size(); ++i) {
    const double d = double(a.rgb[i]) - double(b.rgb[i]);
    sum += d * d;
  }
  if (sum == 0) return std::numeric_limits<double>::infinity();
  const double mse = sum / static_cast<double>(a.rgb.size());
  return 10.0 * std::log10(255.0 * 255.0 / mse);
}

}  // namespace arthrosim::render
