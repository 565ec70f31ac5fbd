#pragma once
// The framebuffer: RGBA floats in [0, 1], premultiplied alpha (colour
// already multiplied by coverage: what "over" compositing and IceT want),
// row 0 at the top. With an opaque background (alpha 1) premultiplied and
// straight are the same numbers; PNG output converts to straight alpha.
// FrameBuffer is the host's door: its own RGBA buffer (8-bit or float, any
// row stride) and optional depth buffers in and out.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "../error.hpp"
#include "../memory.hpp"

namespace cellray {

struct Image {
  int width = 0, height = 0;
  std::vector<float> rgba;  ///< 4 floats per pixel, row-major, top row first, premultiplied

  Image() = default;
  /// All pixels 0 (transparent black), zeroed from all threads (memory.hpp:
  /// a 1024x768 image is 12 MB of fresh pages, ~45 ms on one thread).
  Image(int w, int h) : width(w), height(h) {
    if (w < 0 || h < 0) throw InvalidArgument("negative image size");
    detail::resize_zeroed(rgba, size_t(w) * size_t(h) * 4);
  }
  float* pixel(int x, int y) { return rgba.data() + (size_t(y) * size_t(width) + size_t(x)) * 4; }
  float const* pixel(int x, int y) const { return rgba.data() + (size_t(y) * size_t(width) + size_t(x)) * 4; }

  /// 8-bit RGBA, each channel round(clamp(c, 0, 1) * 255), as stored
  /// (premultiplied); a NaN channel (a renderer bug: none is expected)
  /// becomes 0, never undefined behaviour.
  std::vector<uint8_t> to_rgba8() const {
    std::vector<uint8_t> out(rgba.size());
    for (size_t i = 0; i < rgba.size(); ++i) {
      float const c = rgba[i] > 0.f ? std::min(rgba[i], 1.f) : 0.f;
      out[i] = uint8_t(c * 255.f + 0.5f);
    }
    return out;
  }
  /// 8-bit RGBA with straight alpha (colour divided by alpha where 0 < alpha
  /// < 1), as PNG stores it.
  std::vector<uint8_t> to_straight_rgba8() const {
    std::vector<uint8_t> out(rgba.size());
    if (height > 0) straight_rgba8_rows(0, height, out.data());
    return out;
  }
  /// Rows [y0, y1) of to_straight_rgba8() into out[(y1 - y0) * width * 4]
  /// (the PNG writer converts row blocks in parallel). A NaN channel becomes 0.
  void straight_rgba8_rows(int y0, int y1, uint8_t* out) const {
    float const* s = pixel(0, y0);
    size_t const n = size_t(y1 - y0) * size_t(width) * 4;
    for (size_t i = 0; i < n; i += 4) {
      float const a = s[i + 3] > 0.f ? std::min(s[i + 3], 1.f) : 0.f;
      bool const divide = a > 0.f && a < 1.f;
      for (size_t k = 0; k < 3; ++k) {
        float c = divide ? s[i + k] / a : s[i + k];
        c = c > 0.f ? std::min(c, 1.f) : 0.f;
        out[i + k] = uint8_t(c * 255.f + 0.5f);
      }
      out[i + 3] = uint8_t(a * 255.f + 0.5f);
    }
  }
};

/// Where render_tile writes, owned by the host. Colours are premultiplied
/// RGBA in [0, 1] (8-bit: round(c * 255)). Depth is the distance along each
/// camera ray from the eye (the rays have unit directions), in world units.
struct FrameBuffer {
  enum class Format : uint8_t { rgba8, rgba32f };
  int width = 0, height = 0;  ///< must equal the camera's
  /// Pixel (x, y) at rgba + y * row_bytes + x * (4 bytes for rgba8, 16 for
  /// rgba32f); row 0 at the top. Only a tile's pixels are written.
  void* rgba = nullptr;
  Format format = Format::rgba32f;
  size_t row_bytes = 0;  ///< 0: rows of width pixels, no padding
  /// Optional: the host's opaque geometry, depth_in[y * depth_in_row + x]
  /// (+inf: none). Rays end there: the volume stops, isosurfaces behind it
  /// are hidden; what shows through is the host's to composite under the
  /// returned colour.
  float const* depth_in = nullptr;
  size_t depth_in_row = 0;  ///< floats per row; 0: width
  /// Optional out: where the accumulated opacity along the ray first
  /// reaches `depth_opacity` (isosurfaces: at a hit; DVR: within one step),
  /// +inf where it never does (ParaView's volume depth).
  float* depth_out = nullptr;
  size_t depth_out_row = 0;  ///< floats per row; 0: width
  float depth_opacity = 0.5f;

  /// A frame buffer over an Image (float RGBA, tight rows).
  static FrameBuffer of(Image& img) {
    FrameBuffer f;
    f.width = img.width, f.height = img.height, f.rgba = img.rgba.data();
    return f;
  }
};

}  // namespace cellray
