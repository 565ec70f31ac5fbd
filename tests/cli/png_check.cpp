// png_check FILE W H [min_fraction]: exits 0 when FILE is a W x H PNG in
// which at least `min_fraction` (default 0.02) of the pixels differ from the
// top-left one (the background), i.e. something was drawn; else prints why
// and exits 1. Reads the file with stb_image, independently of the writer.
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

int main(int argc, char** argv) {
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
