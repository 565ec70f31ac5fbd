#pragma once
// The framebuffer: RGBA floats in [0, 1], straight (not premultiplied)
// alpha, row 0 at the top.

#include <algorithm>
#include <cstdint>
#include <vector>

#include "../error.hpp"

namespace cellray {

struct Image {
  int width = 0, height = 0;
  std::vector<float> rgba;  ///< 4 floats per pixel, row-major, top row first

  Image() = default;
  Image(int w, int h) : width(w), height(h), rgba(size_t(w) * size_t(h) * 4, 0.f) {
    if (w < 0 || h < 0) throw InvalidArgument("negative image size");
  }
  float* pixel(int x, int y) { return rgba.data() + (size_t(y) * size_t(width) + size_t(x)) * 4; }
  float const* pixel(int x, int y) const { return rgba.data() + (size_t(y) * size_t(width) + size_t(x)) * 4; }

  /// 8-bit RGBA, each channel round(clamp(c, 0, 1) * 255); a NaN channel
  /// (a renderer bug: none is expected) becomes 0, never undefined behaviour.
  std::vector<uint8_t> to_rgba8() const {
    std::vector<uint8_t> out(rgba.size());
    for (size_t i = 0; i < rgba.size(); ++i) {
      float const c = rgba[i] > 0.f ? std::min(rgba[i], 1.f) : 0.f;
      out[i] = uint8_t(c * 255.f + 0.5f);
    }
    return out;
  }
};

}  // namespace cellray
