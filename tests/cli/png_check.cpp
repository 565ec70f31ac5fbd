// png_check FILE W H [min_fraction]: exits 0 when FILE is a W x H PNG in
// which at least `min_fraction` (default 0.02) of the pixels differ from the
// top-left one (the background), i.e. something was drawn; else prints why
// and exits 1. Reads the file with stb_image, independently of the writer.
// png_check --compare A B MAX_PIXELS [LEVELS]: exits 0 when PNGs A and B have
// one size and at most MAX_PIXELS pixels differ by more than LEVELS (default
// 8) of 255 in some channel.
// png_check --extent FILE MIN MAX: exits 0 when the bounding box of the
// pixels that differ from the top-left one spans, at its longer side, a
// fraction in [MIN, MAX] of the image's shorter side, and its centre lies
// within 3% of that side from the image's centre (the framing of the drawn
// mesh); prints the box, the fraction and the offset.
// png_check --diff-within A B X0 Y0 X1 Y1 MIN_PIXELS: exits 0 when PNGs A
// and B have one size, at least MIN_PIXELS pixels differ, and every
// differing pixel lies in [X0, X1) x [Y0, Y1); coordinates are fractions of
// the width and height (an overlay drawn into one region, nothing else
// changed).
// png_check --occluded GEOMETRY LAYER COMPOSITE MIN_HIDDEN MIN_SHOWN: a
// host's opaque geometry, a layer drawn alone (alpha: its coverage without
// the geometry) and the two composited, one size. A pixel is "changed" when
// COMPOSITE differs from GEOMETRY by more than 2/255 in some channel; exits
// 0 when at least MIN_HIDDEN pixels where the layer is clearly there (alpha
// >= 64/255) are unchanged (the geometry is in front of it), at least
// MIN_SHOWN pixels changed, and no pixel changed where the layer has alpha 0.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wunused-function"
#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_STATIC
#include <stb/stb_image.h>
#pragma GCC diagnostic pop

int compare(char const* a_path, char const* b_path, long max_pixels, int levels) {
  int aw = 0, ah = 0, bw = 0, bh = 0, c = 0;
  unsigned char* a = stbi_load(a_path, &aw, &ah, &c, 4);
  unsigned char* b = stbi_load(b_path, &bw, &bh, &c, 4);
  int rc = 0;
  if (!a || !b) {
    std::printf("cannot decode %s\n", !a ? a_path : b_path);
    rc = 1;
  } else if (aw != bw || ah != bh) {
    std::printf("%s is %dx%d, %s is %dx%d\n", a_path, aw, ah, b_path, bw, bh);
    rc = 1;
  } else {
    long differ = 0;
    for (long i = 0; i < long(aw) * ah; ++i)
      for (int k = 0; k < 4; ++k)
        if (std::abs(int(a[4 * i + k]) - int(b[4 * i + k])) > levels) {
          ++differ;
          break;
        }
    std::printf("%s vs %s: %ld of %ld pixels differ by more than %d/255 (at most %ld allowed)\n", a_path, b_path, differ,
                long(aw) * ah, levels, max_pixels);
    rc = differ > max_pixels;
  }
  if (a) stbi_image_free(a);
  if (b) stbi_image_free(b);
  return rc;
}

int extent(char const* path, double min_fraction, double max_fraction) {
  int w = 0, h = 0, c = 0;
  unsigned char* px = stbi_load(path, &w, &h, &c, 4);
  if (!px) {
    std::printf("cannot decode %s\n", path);
    return 1;
  }
  int x0 = w, y0 = h, x1 = -1, y1 = -1;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      if (std::memcmp(px + 4 * (long(y) * w + x), px, 4) != 0)
        x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
  stbi_image_free(px);
  if (x1 < 0) {
    std::printf("%s: nothing drawn\n", path);
    return 1;
  }
  double const side = double(std::min(w, h));
  double const fraction = double(std::max(x1 - x0 + 1, y1 - y0 + 1)) / side;
  double const offset = std::max(std::abs(0.5 * (x0 + x1) - 0.5 * (w - 1)), std::abs(0.5 * (y0 + y1) - 0.5 * (h - 1))) / side;
  std::printf("%s: %dx%d, drawn box x [%d, %d] y [%d, %d], longer side %.1f%% of the shorter image side (want %.1f%% to "
              "%.1f%%), centre off by %.1f%% of it (at most 3%%)\n",
              path, w, h, x0, x1, y0, y1, 100.0 * fraction, 100.0 * min_fraction, 100.0 * max_fraction, 100.0 * offset);
  return fraction >= min_fraction && fraction <= max_fraction && offset <= 0.03 ? 0 : 1;
}

int diff_within(char const* a_path, char const* b_path, double fx0, double fy0, double fx1, double fy1,
                long min_pixels) {
  int aw = 0, ah = 0, bw = 0, bh = 0, c = 0;
  unsigned char* a = stbi_load(a_path, &aw, &ah, &c, 4);
  unsigned char* b = stbi_load(b_path, &bw, &bh, &c, 4);
  int rc = 0;
  if (!a || !b) {
    std::printf("cannot decode %s\n", !a ? a_path : b_path);
    rc = 1;
  } else if (aw != bw || ah != bh) {
    std::printf("%s is %dx%d, %s is %dx%d\n", a_path, aw, ah, b_path, bw, bh);
    rc = 1;
  } else {
    double const X0 = fx0 * aw, X1 = fx1 * aw, Y0 = fy0 * ah, Y1 = fy1 * ah;
    long inside = 0, outside = 0;
    int ox = -1, oy = -1;
    for (int y = 0; y < ah; ++y)
      for (int x = 0; x < aw; ++x) {
        long const i = 4 * (long(y) * aw + x);
        if (std::memcmp(a + i, b + i, 4) == 0) continue;
        if (x >= X0 && x < X1 && y >= Y0 && y < Y1) {
          ++inside;
        } else {
          if (!outside) ox = x, oy = y;
          ++outside;
        }
      }
    std::printf("%s vs %s: %ld pixels differ inside [%.0f, %.0f) x [%.0f, %.0f) (at least %ld wanted), %ld outside",
                a_path, b_path, inside, X0, X1, Y0, Y1, min_pixels, outside);
    if (outside) std::printf(" (the first at %d, %d)", ox, oy);
    std::printf("\n");
    rc = inside < min_pixels || outside > 0;
  }
  if (a) stbi_image_free(a);
  if (b) stbi_image_free(b);
  return rc;
}

int occluded(char const* g_path, char const* l_path, char const* c_path, long min_hidden, long min_shown) {
  int w[3] = {}, h[3] = {}, ch = 0;
  char const* paths[3] = {g_path, l_path, c_path};
  unsigned char* px[3] = {};
  int rc = 0;
  for (int k = 0; k < 3; ++k)
    if (!(px[k] = stbi_load(paths[k], &w[k], &h[k], &ch, 4))) {
      std::printf("cannot decode %s\n", paths[k]);
      rc = 1;
    }
  if (!rc && (w[0] != w[1] || w[0] != w[2] || h[0] != h[1] || h[0] != h[2])) {
    std::printf("%s, %s and %s differ in size\n", g_path, l_path, c_path);
    rc = 1;
  }
  if (!rc) {
    long hidden = 0, shown = 0, stray = 0;
    for (long i = 0; i < long(w[0]) * h[0]; ++i) {
      bool changed = false;
      for (int k = 0; k < 4; ++k) changed |= std::abs(int(px[0][4 * i + k]) - int(px[2][4 * i + k])) > 2;
      int const alpha = px[1][4 * i + 3];
      hidden += !changed && alpha >= 64;
      shown += changed;
      stray += changed && alpha == 0;
    }
    std::printf("%s: %ld pixels hidden by the geometry (at least %ld wanted), %ld changed by the layer "
                "(at least %ld), %ld changed where the layer is empty (none allowed)\n",
                c_path, hidden, min_hidden, shown, min_shown, stray);
    rc = hidden < min_hidden || shown < min_shown || stray > 0;
  }
  for (auto* p : px)
    if (p) stbi_image_free(p);
  return rc;
}

int main(int argc, char** argv) {
  if (argc == 7 && std::strcmp(argv[1], "--occluded") == 0)
    return occluded(argv[2], argv[3], argv[4], std::atol(argv[5]), std::atol(argv[6]));
  if (argc == 5 && std::strcmp(argv[1], "--extent") == 0) return extent(argv[2], std::atof(argv[3]), std::atof(argv[4]));
  if (argc == 9 && std::strcmp(argv[1], "--diff-within") == 0)
    return diff_within(argv[2], argv[3], std::atof(argv[4]), std::atof(argv[5]), std::atof(argv[6]), std::atof(argv[7]),
                       std::atol(argv[8]));
  if (argc >= 5 && std::strcmp(argv[1], "--compare") == 0)
    return compare(argv[2], argv[3], std::atol(argv[4]), argc > 5 ? std::atoi(argv[5]) : 8);
  if (argc < 4) {
    std::fprintf(stderr, "usage: png_check FILE W H [min_fraction]\n");
    return 2;
  }
  int const want_w = std::atoi(argv[2]), want_h = std::atoi(argv[3]);
  double const min_fraction = argc > 4 ? std::atof(argv[4]) : 0.02;
  unsigned char sig[8] = {};
  if (std::FILE* f = std::fopen(argv[1], "rb")) {
    size_t const n = std::fread(sig, 1, 8, f);
    std::fclose(f);
    if (n != 8 || std::memcmp(sig, "\x89PNG\r\n\x1a\n", 8) != 0) {
      std::printf("%s: not a PNG file\n", argv[1]);
      return 1;
    }
  } else {
    std::printf("%s: missing\n", argv[1]);
    return 1;
  }
  int w = 0, h = 0, channels = 0;
  unsigned char* px = stbi_load(argv[1], &w, &h, &channels, 4);
  if (!px) {
    std::printf("%s: cannot decode (%s)\n", argv[1], stbi_failure_reason());
    return 1;
  }
  if (w != want_w || h != want_h) {
    std::printf("%s: %dx%d, expected %dx%d\n", argv[1], w, h, want_w, want_h);
    stbi_image_free(px);
    return 1;
  }
  long differ = 0;
  for (long i = 0; i < long(w) * h; ++i) differ += std::memcmp(px + 4 * i, px, 4) != 0;
  stbi_image_free(px);
  double const fraction = double(differ) / (double(w) * h);
  std::printf("%s: %dx%d, %.1f%% of the pixels differ from the background\n", argv[1], w, h, 100.0 * fraction);
  if (fraction < min_fraction) {
    std::printf("%s: nearly flat, expected at least %.1f%%\n", argv[1], 100.0 * min_fraction);
    return 1;
  }
  return 0;
}
