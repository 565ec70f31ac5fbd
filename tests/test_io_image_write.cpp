// Image writers (io/image_write.hpp): a failed write leaves the old file as
// it was and says why; a symlink is written through; the extension decides
// the format in any case (issue #24, items 6 and 7). The PNG encoder
// (parallel row blocks on zlib, issue #23) is checked by an independent
// decoder (stb_image) byte for byte, and its stream by zlib's own
// inflate (Adler-32) and every chunk's CRC.

#include <catch2/catch.hpp>

#include <sys/resource.h>

#include <csignal>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <tbb/task_arena.h>
#include <zlib.h>

#include <cellray/io/image_write.hpp>

#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_STATIC
#include <stb/stb_image.h>

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_io_image_write {

using namespace cellray;
namespace fs = std::filesystem;

namespace {

std::string slurp(std::string const& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

Image gradient_image(int w, int h) {
  Image img(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      float* p = img.pixel(x, y);
      p[0] = float(x) / float(w), p[1] = float(y) / float(h), p[2] = float((x * 7 + y * 13) % 17) / 17.f, p[3] = 1.f;
    }
  return img;
}

/// Random pixels (a quarter of them special: NaN, infinities, negative,
/// above 1, subnormal, exactly at rounding midpoints), with alpha 1, 0 or
/// partial, and flat runs: rectangles of one colour, the background rows of
/// a render.
Image mixed_image(int w, int h, uint32_t seed) {
  Image img(w, h);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-0.1f, 1.1f);
  float const special[] = {std::numeric_limits<float>::quiet_NaN(),
                           std::numeric_limits<float>::infinity(),
                           -std::numeric_limits<float>::infinity(),
                           -0.f,
                           0.f,
                           1.f,
                           1e-40f,
                           0.5f / 255.f,
                           254.5f / 255.f,
                           std::nextafter(1.f, 2.f),
                           2.f,
                           -1.f};
  int const n_special = int(sizeof(special) / sizeof(special[0]));
  for (size_t i = 0; i < img.rgba.size(); ++i) {
    uint32_t const r = rng() % 8;
    img.rgba[i] = r == 0 ? special[rng() % n_special] : r == 1 ? float(rng() % 256) / 255.f : u(rng);
    if (i % 4 == 3 && r >= 4) img.rgba[i] = r >= 6 ? 1.f : 0.f;
  }
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      if ((y / 7) % 3 == 0 || (x > w / 3 && x < w / 2)) {
        float* p = img.pixel(x, y);
        float const a = (y / 7) % 2 ? 1.f : 0.5f;
        p[0] = 0.25f * a, p[1] = 0.5f * a, p[2] = 0.75f * a, p[3] = a;
      }
  return img;
}

/// Decodes with stb_image (independent of the writer) and returns RGBA bytes,
/// empty when it fails or the size differs.
std::vector<uint8_t> decode(std::string const& png, int w, int h) {
  int dw = 0, dh = 0, channels = 0;
  unsigned char* px =
      stbi_load_from_memory(reinterpret_cast<unsigned char const*>(png.data()), int(png.size()), &dw, &dh, &channels, 4);
  std::vector<uint8_t> out;
  if (px && dw == w && dh == h && channels == 4) out.assign(px, px + size_t(w) * size_t(h) * 4);
  stbi_image_free(px);
  return out;
}

uint32_t be32(std::string const& s, size_t at) {
  auto b = [&](size_t i) { return uint32_t(uint8_t(s[at + i])); };
  return b(0) << 24 | b(1) << 16 | b(2) << 8 | b(3);
}

/// What stb_image does not check: the signature, IHDR, every chunk's CRC,
/// IDAT chunks of at most `idat_max` bytes, and the zlib stream (inflated
/// by zlib, which checks its Adler-32) holding h rows of 1 + 4w bytes,
/// each led by a valid filter type. Returns the number of IDAT chunks.
int check_png_structure(std::string const& png, int w, int h, size_t idat_max) {
  REQUIRE(png.size() > 8 + 25 + 12);
  REQUIRE(png.compare(0, 8, "\x89PNG\r\n\x1a\n", 8) == 0);
  std::string zdata, types;
  int idats = 0;
  for (size_t at = 8; at < png.size();) {
    REQUIRE(at + 12 <= png.size());
    uint32_t const n = be32(png, at);
    REQUIRE(at + 12 + n <= png.size());
    std::string const type = png.substr(at + 4, 4);
    uLong const crc = crc32(0L, reinterpret_cast<Bytef const*>(png.data() + at + 4), uInt(n + 4));
    INFO("chunk " << type << " at byte " << at);
    CHECK(crc == be32(png, at + 8 + n));
    if (type == "IHDR") {
      REQUIRE(n == 13);
      CHECK(be32(png, at + 8) == uint32_t(w));
      CHECK(be32(png, at + 12) == uint32_t(h));
      CHECK(png.substr(at + 16, 5) == std::string("\x08\x06\x00\x00\x00", 5));
    } else if (type == "IDAT") {
      CHECK(n <= idat_max);
      zdata.append(png, at + 8, n);
      ++idats;
    }
    types += type;
    at += 12 + n;
  }
  std::string want_types = "IHDR";
  for (int i = 0; i < idats; ++i) want_types += "IDAT";
  CHECK(types == want_types + "IEND");  // IDATs consecutive, IEND last
  size_t const line = size_t(w) * 4 + 1;
  std::vector<Bytef> raw(line * size_t(h) + 1);
  uLongf got = uLongf(raw.size());
  REQUIRE(uncompress(raw.data(), &got, reinterpret_cast<Bytef const*>(zdata.data()), uLong(zdata.size())) == Z_OK);
  CHECK(got == line * size_t(h));
  int bad_filters = 0;
  for (int y = 0; y < h; ++y) bad_filters += raw[size_t(y) * line] > 4;
  CHECK(bad_filters == 0);
  return idats;
}

/// A fresh folder under the temporary directory, removed at the end.
struct Scratch {
  std::string dir;
  explicit Scratch(char const* name) : dir((fs::temp_directory_path() / name).string()) {
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~Scratch() { fs::remove_all(dir); }
  size_t entries() const { return size_t(std::distance(fs::directory_iterator(dir), fs::directory_iterator())); }
};

}  // namespace

TEST_CASE("image_format and write_image agree on extensions in any case", "[io][image]") {
  CHECK(image_format("a.png") == "png");
  CHECK(image_format("a.PNG") == "png");
  CHECK(image_format("dir.png/a.Ppm") == "ppm");
  CHECK(image_format("a.jpg").empty());
  CHECK(image_format("png").empty());
  Scratch s("cellray_image_case");
  write_image(s.dir + "/x.PNG", gradient_image(8, 4));
  CHECK(slurp(s.dir + "/x.PNG").rfind("\x89PNG", 0) == 0);
  write_image(s.dir + "/x.PPM", gradient_image(8, 4));
  CHECK(slurp(s.dir + "/x.PPM").rfind("P6\n8 4\n255\n", 0) == 0);
  CHECK_THROWS_AS(write_image(s.dir + "/x.jpg", gradient_image(8, 4)), IoError);
}

TEST_CASE("a write that fails keeps the old file and leaves no temporary behind", "[io][image]") {
  Scratch s("cellray_image_fail");
  std::string const path = s.dir + "/old.png";
  write_png(path, gradient_image(16, 16));
  std::string const old = slurp(path);
  REQUIRE(old.size() > 100);

  SECTION("a file-size limit") {
    // write() fails with EFBIG instead of raising SIGXFSZ while it is ignored.
    auto const previous_handler = std::signal(SIGXFSZ, SIG_IGN);
    rlimit saved{};
    getrlimit(RLIMIT_FSIZE, &saved);
    rlimit tight = saved;
    tight.rlim_cur = 1024;
    REQUIRE(setrlimit(RLIMIT_FSIZE, &tight) == 0);
    bool threw = false;
    std::string msg;
    try {
      write_png(path, gradient_image(256, 256));
    } catch (IoError const& e) {
      threw = true;
      msg = e.what();
    }
    setrlimit(RLIMIT_FSIZE, &saved);
    std::signal(SIGXFSZ, previous_handler);
    CHECK(threw);
    CHECK_THAT(msg, Catch::StartsWith(path + ": cannot write"));
    CHECK(slurp(path) == old);
    CHECK(s.entries() == 1);
  }
  SECTION("a directory in the file's place") {
    fs::create_directory(s.dir + "/d.ppm");
    CHECK_THROWS_WITH(write_ppm(s.dir + "/d.ppm", gradient_image(4, 4)), Catch::Contains("is a directory"));
    CHECK(s.entries() == 2);
  }
  SECTION("a link to a device") {
    fs::create_symlink("/dev/full", s.dir + "/full.png");
    CHECK_THROWS_WITH(write_png(s.dir + "/full.png", gradient_image(4, 4)), Catch::Contains("not a regular file"));
    CHECK(fs::is_symlink(s.dir + "/full.png"));
  }
  SECTION("a missing folder") {
    CHECK_THROWS_WITH(write_png(s.dir + "/no/such/x.png", gradient_image(4, 4)),
                      Catch::StartsWith(s.dir + "/no/such/x.png: cannot write"));
  }
}

TEST_CASE("a symlink is written through: its target is replaced, the link stays", "[io][image]") {
  Scratch s("cellray_image_link");
  write_ppm(s.dir + "/target.ppm", gradient_image(4, 4));
  fs::create_symlink("target.ppm", s.dir + "/link.ppm");
  write_ppm(s.dir + "/link.ppm", gradient_image(6, 2));
  CHECK(fs::is_symlink(s.dir + "/link.ppm"));
  CHECK(slurp(s.dir + "/target.ppm").rfind("P6\n6 2\n", 0) == 0);
  CHECK(s.entries() == 2);
}

TEST_CASE("PNG: every byte decodes back, whatever the size, pixels and block split", "[io][image][png]") {
  // Rows per block: 128 KiB / (4w + 1) bytes, so 64x2500 is 5 blocks,
  // 1500x300 is 14 blocks of 21 rows and a last one of 6; 20000x3 is three
  // blocks of one row.
  struct Size {
    int w, h;
  };
  Size const sizes[] = {{1, 1}, {1, 13}, {13, 1}, {2, 3}, {7, 5}, {333, 97}, {64, 2500}, {1500, 300}, {20000, 3}};
  uint32_t seed = 1;
  for (Size const s : sizes) {
    Image const img = mixed_image(s.w, s.h, seed++);
    INFO(s.w << "x" << s.h);
    std::string const png = encode_png(img);
    CHECK(check_png_structure(png, s.w, s.h, size_t(1) << 30) == 1);
    auto const want = img.to_straight_rgba8();
    auto const got = decode(png, s.w, s.h);
    REQUIRE(got.size() == want.size());
    // The first mismatch, not the whole images (Catch would print them).
    size_t i = 0;
    while (i < got.size() && got[i] == want[i]) ++i;
    if (i < got.size())
      FAIL("byte " << i << " (pixel " << i / 4 << ", channel " << i % 4 << "): " << int(got[i]) << " != " << int(want[i]));
  }
}

TEST_CASE("PNG: the bytes do not depend on the thread count -- IDAT may be split", "[io][image][png]") {
  Image const img = mixed_image(517, 901, 42);
  std::string const many = encode_png(img);
  std::string one;
  tbb::task_arena(1).execute([&] { one = encode_png(img); });
  CHECK((one == many));  // (( )): a plain bool, so a failure does not print megabytes
  std::string const split = io::encode_png(img, 1000);
  CHECK(check_png_structure(split, 517, 901, 1000) > 1);
  CHECK((decode(split, 517, 901) == img.to_straight_rgba8()));
}

TEST_CASE("PNG: write_png writes encode_png's bytes -- flat images stay small", "[io][image][png]") {
  Scratch s("cellray_image_png");
  Image flat(1024, 768);
  for (size_t i = 0; i < flat.rgba.size(); ++i) flat.rgba[i] = i % 4 == 3 ? 1.f : 0.5f;
  write_png(s.dir + "/flat.png", flat);
  std::string const bytes = slurp(s.dir + "/flat.png");
  CHECK((bytes == encode_png(flat)));
  CHECK(bytes.size() < 16 * 1024);  // 3 MB of pixels; the Paeth residue is all zeros
  CHECK((decode(bytes, 1024, 768) == flat.to_straight_rgba8()));
  Image const grad = gradient_image(300, 200);
  write_png(s.dir + "/grad.png", grad);
  CHECK((decode(slurp(s.dir + "/grad.png"), 300, 200) == grad.to_straight_rgba8()));
  CHECK_THROWS_WITH(encode_png(Image(0, 5)), Catch::Contains("empty image"));
  CHECK_THROWS_WITH(write_png(s.dir + "/e.png", Image(5, 0)), Catch::StartsWith(s.dir + "/e.png: cannot write an empty image"));
  CHECK(s.entries() == 2);
}

TEST_CASE("NaN channels convert to 0, not undefined behaviour", "[io][image]") {
  Image img(2, 1);
  img.rgba = {std::numeric_limits<float>::quiet_NaN(), 2.f, -1.f, 0.5f, 1.f, 0.f, 0.25f, 1.f};
  auto const px = img.to_rgba8();
  CHECK(px == std::vector<uint8_t>{0, 255, 0, 128, 255, 0, 64, 255});
}

}  // namespace test_io_image_write
