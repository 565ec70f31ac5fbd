#pragma once
// Image writers: binary PPM (no dependency) and PNG (stb_image_write, a
// Debian header; this header compiles a private copy of it per translation
// unit, so hosts need no separate implementation file). Both encode in
// memory, then replace the file in one step (write_file_replacing): a failed
// write leaves the old file as it was.

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <string_view>

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

/// Writes `bytes` to `path` through a temporary file in the same folder,
/// checking every write and the close, then renames it over `path`: readers
/// see the old file or the whole new one, never a truncated one, and a
/// failure (disk full, file-size limit, no permission) leaves the old file
/// untouched. A symlink is followed (its target is replaced, the link stays);
/// a path that names a directory, device or FIFO is refused. A new file gets
/// the usual 0666 & ~umask permissions, a replaced one keeps its own.
/// Exceeding a file-size limit raises SIGXFSZ, which kills a process unless it
/// ignores the signal (cellray-render does, to report the error instead).
/// @throws IoError naming the path and the system's reason.
inline void write_file_replacing(std::string const& path, std::string_view bytes) {
  namespace fs = std::filesystem;
  auto fail = [&](std::string const& why) -> void { throw IoError(path + ": cannot write (" + why + ")"); };
  std::error_code ec;
  fs::path target(path);
  if (fs::is_symlink(fs::symlink_status(target, ec))) {
    target = fs::weakly_canonical(target, ec);
    if (ec) fail("cannot resolve the symbolic link: " + ec.message());
  }
  auto const st = fs::status(target, ec);
  bool const exists = !ec && st.type() != fs::file_type::not_found;
  if (exists && st.type() != fs::file_type::regular)
    fail(st.type() == fs::file_type::directory ? "it is a directory" : "it is not a regular file");
  fs::path const dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::string tmp = (dir / ("." + target.filename().string() + ".XXXXXX")).string();
  int const fd = ::mkstemp(tmp.data());
  if (fd < 0) fail(std::strerror(errno));
  auto give_up = [&](std::string const& why) {
    ::unlink(tmp.c_str());
    fail(why);
  };
  mode_t mode = 0666;
  struct stat old {};
  if (exists && ::stat(target.c_str(), &old) == 0) {
    mode = old.st_mode & 07777;
  } else {
    mode_t const mask = ::umask(0);  // read it back (no portable getter)
    ::umask(mask);
    mode &= ~mask;
  }
  if (::fchmod(fd, mode) != 0) {
    int const e = errno;
    ::close(fd);
    give_up(std::strerror(e));
  }
  for (size_t done = 0; done < bytes.size();) {
    ssize_t const n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      int const e = n < 0 ? errno : EIO;
      ::close(fd);
      give_up(std::strerror(e) + std::string(" after ") + std::to_string(done) + " of " +
              std::to_string(bytes.size()) + " bytes");
    }
    done += size_t(n);
  }
  if (::close(fd) != 0) give_up(std::strerror(errno));
  if (::rename(tmp.c_str(), target.c_str()) != 0) give_up(std::strerror(errno));
}

/// `img` encoded as binary PPM (P6, RGB, alpha dropped: the premultiplied
/// colour, i.e. the image over black).
inline std::string encode_ppm(Image const& img) {
  std::string out = "P6\n" + std::to_string(img.width) + " " + std::to_string(img.height) + "\n255\n";
  auto const px = img.to_rgba8();
  out.reserve(out.size() + px.size() / 4 * 3);
  for (size_t i = 0; i < px.size(); i += 4) out.append(reinterpret_cast<char const*>(&px[i]), 3);
  return out;
}

/// Writes `img` as binary PPM (P6, RGB, alpha dropped), replacing `path`
/// only once the whole file is written (write_file_replacing).
/// @throws IoError naming the path when it cannot be written.
inline void write_ppm(std::string const& path, Image const& img) { write_file_replacing(path, encode_ppm(img)); }

/// Writes `img` as 8-bit RGBA PNG (straight alpha), replacing `path` only once the whole file
/// is written (write_file_replacing). @throws IoError on failure or when
/// built without stb.
inline void write_png(std::string const& path, Image const& img) {
#if CELLRAY_HAS_PNG
  if (img.width < 1 || img.height < 1) throw IoError(path + ": cannot write an empty image as PNG");
  auto const px = img.to_straight_rgba8();  // PNG stores straight alpha; Image holds premultiplied
  std::string png;
  auto append = [](void* to, void* data, int size) {
    static_cast<std::string*>(to)->append(static_cast<char const*>(data), size_t(size));
  };
  if (!stbi_write_png_to_func(append, &png, img.width, img.height, 4, px.data(), img.width * 4))
    throw IoError(path + ": cannot encode the image as PNG");
  write_file_replacing(path, png);
#else
  (void)img;
  throw IoError(path + ": PNG support needs stb_image_write.h (Debian: libstb-dev)");
#endif
}

/// The image format a path's extension asks for ("png", "ppm"; any case),
/// or "" for any other extension. One rule for the early check of a command
/// line and for write_image.
inline std::string image_format(std::string const& path) {
  auto const dot = path.find_last_of("./");
  if (dot == std::string::npos || path[dot] != '.') return "";
  std::string ext = path.substr(dot + 1);
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext == "png" || ext == "ppm" ? ext : "";
}

/// PNG for ".png", PPM for ".ppm" (any case); anything else is an error
/// naming the extension.
inline void write_image(std::string const& path, Image const& img) {
  std::string const format = image_format(path);
  if (format == "png") write_png(path, img);
  else if (format == "ppm") write_ppm(path, img);
  else throw IoError(path + ": unknown image extension (use .png or .ppm)");
}

}  // namespace cellray
