#pragma once
// Image writers: binary PPM (no dependency) and PNG (stb_image_write, a
// Debian header; this header compiles a private copy of it per translation
// unit, so hosts need no separate implementation file).

#include <cstdio>
#include <memory>
#include <string>

#include "../error.hpp"
#include "../render/image.hpp"

#if __has_include(<stb/stb_image_write.h>)
#define CELLRAY_HAS_PNG 1
#ifndef STB_IMAGE_WRITE_STATIC
#define STB_IMAGE_WRITE_STATIC
#endif
#define STB_IMAGE_WRITE_IMPLEMENTATION
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wunused-function"
#include <stb/stb_image_write.h>
#pragma GCC diagnostic pop
#else
#define CELLRAY_HAS_PNG 0
#endif

namespace cellray {

/// Writes `img` as binary PPM (P6, RGB, alpha dropped).
/// @throws IoError naming the path when it cannot be written.
inline void write_ppm(std::string const& path, Image const& img) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "wb"), &std::fclose);
  if (!f) throw IoError(path + ": cannot open for writing");
  std::fprintf(f.get(), "P6\n%d %d\n255\n", img.width, img.height);
  auto const px = img.to_rgba8();
  std::string rgb;
  rgb.reserve(px.size() / 4 * 3);
  for (size_t i = 0; i < px.size(); i += 4) rgb.append(reinterpret_cast<char const*>(&px[i]), 3);
  if (std::fwrite(rgb.data(), 1, rgb.size(), f.get()) != rgb.size()) throw IoError(path + ": write failed");
}

/// Writes `img` as 8-bit RGBA PNG. @throws IoError on failure or when built
/// without stb.
inline void write_png(std::string const& path, Image const& img) {
#if CELLRAY_HAS_PNG
  auto const px = img.to_rgba8();
  if (img.width < 1 || img.height < 1) throw IoError(path + ": cannot write an empty image as PNG");
  if (!stbi_write_png(path.c_str(), img.width, img.height, 4, px.data(), img.width * 4))
    throw IoError(path + ": cannot write PNG");
#else
  (void)img;
  throw IoError(path + ": PNG support needs stb_image_write.h (Debian: libstb-dev)");
#endif
}

/// PNG for ".png", PPM for ".ppm"; anything else is an error naming the extension.
inline void write_image(std::string const& path, Image const& img) {
  auto ends_with = [&](char const* ext) {
    std::string const e(ext);
    return path.size() >= e.size() && path.compare(path.size() - e.size(), e.size(), e) == 0;
  };
  if (ends_with(".png")) write_png(path, img);
  else if (ends_with(".ppm")) write_ppm(path, img);
  else throw IoError(path + ": unknown image extension (use .png or .ppm)");
}

}  // namespace cellray
