// png_rmse A B MAX_RMSE MAX_DIFF: exits 0 when PNGs A and B have one size,
// the root mean square difference over every RGBA channel is at most
// MAX_RMSE and no channel differs by more than MAX_DIFF (both in 8-bit
// levels, 0-255); prints both figures. Reads with stb_image, independently of
// the writer.
#include <cmath>
#include <cstdio>
#include <cstdlib>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wunused-function"
#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_STATIC
#include <stb/stb_image.h>
#pragma GCC diagnostic pop

int main(int argc, char** argv) {
  if (argc != 5) {
    std::printf("usage: png_rmse A B MAX_RMSE MAX_DIFF\n");
    return 2;
  }
  int aw = 0, ah = 0, bw = 0, bh = 0, c = 0;
  unsigned char* a = stbi_load(argv[1], &aw, &ah, &c, 4);
  unsigned char* b = stbi_load(argv[2], &bw, &bh, &c, 4);
  int rc = 0;
  if (!a || !b) {
    std::printf("cannot decode %s\n", !a ? argv[1] : argv[2]);
    rc = 1;
  } else if (aw != bw || ah != bh) {
    std::printf("%s is %dx%d, %s is %dx%d\n", argv[1], aw, ah, argv[2], bw, bh);
    rc = 1;
  } else {
    double sum = 0;
    int worst = 0;
    long const n = 4L * aw * ah;
    for (long i = 0; i < n; ++i) {
      int const d = std::abs(int(a[i]) - int(b[i]));
      sum += double(d) * d;
      if (d > worst) worst = d;
    }
    double const rmse = std::sqrt(sum / double(n));
    double const max_rmse = std::atof(argv[3]);
    int const max_diff = std::atoi(argv[4]);
    std::printf("%s vs %s: rmse %.4f/255 (at most %.4f), max %d/255 (at most %d)\n", argv[1], argv[2], rmse, max_rmse,
                worst, max_diff);
    rc = rmse > max_rmse || worst > max_diff;
  }
  if (a) stbi_image_free(a);
  if (b) stbi_image_free(b);
  return rc;
}
