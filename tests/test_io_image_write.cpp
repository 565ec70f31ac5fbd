// Image writers (io/image_write.hpp): a failed write leaves the old file as
// it was and says why; a symlink is written through; the extension decides
// the format in any case (issue #24, items 6 and 7).

#include <catch2/catch.hpp>

#include <sys/resource.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include <cellray/io/image_write.hpp>

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

TEST_CASE("NaN channels convert to 0, not undefined behaviour", "[io][image]") {
  Image img(2, 1);
  img.rgba = {std::numeric_limits<float>::quiet_NaN(), 2.f, -1.f, 0.5f, 1.f, 0.f, 0.25f, 1.f};
  auto const px = img.to_rgba8();
  CHECK(px == std::vector<uint8_t>{0, 255, 0, 128, 255, 0, 64, 255});
}

}  // namespace test_io_image_write
