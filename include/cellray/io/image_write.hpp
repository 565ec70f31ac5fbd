#pragma once
// Image writers: binary PPM (no dependency) and PNG (zlib, which io/ links
// for the VTU reader anyway). Both encode in memory, then replace the file in
// one step (write_file_replacing): a failed write leaves the old file as it
// was.

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "../error.hpp"
#include "../render/image.hpp"

#if __has_include(<zlib.h>)
#define CELLRAY_HAS_PNG 1
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <zlib.h>
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

#if CELLRAY_HAS_PNG
namespace io {

/// PNG filter 4 (Paeth, PNG spec §9.4) of one RGBA row: out[i] = cur[i] -
/// predictor(left, up, up-left), `prev` all zeros above the first row.
/// Branch-free so that the compiler vectorises it (the decoder's side is
/// serial, the encoder's is not).
inline void paeth_filter_row(uint8_t const* cur, uint8_t const* prev, size_t n, uint8_t* out) {
  for (size_t i = 0; i < std::min<size_t>(4, n); ++i) out[i] = uint8_t(cur[i] - prev[i]);  // left = up-left = 0
  for (size_t i = 4; i < n; ++i) {
    int const a = cur[i - 4], b = prev[i], c = prev[i - 4];
    int const pa = std::abs(b - c), pb = std::abs(a - c), pc = std::abs(a + b - 2 * c);
    int const pred = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
    out[i] = uint8_t(cur[i] - pred);
  }
}

/// One thread's buffers while encoding PNG row blocks: two converted rows
/// (this and the one above), one filtered row, the block's compressed bytes
/// and a raw-deflate stream reused block after block (deflateReset). Few
/// fresh pages: a 4 KB page's first write costs ~14.5 us on the VMs users
/// run on (PROFILE.md), more than deflating it.
struct PngScratch {
  std::vector<uint8_t> row[2], filtered;
  std::unique_ptr<unsigned char[]> out;  // uninitialised: pages are touched only as written
  size_t out_size = 0;
  std::unique_ptr<z_stream> z;  // deflate keeps a pointer to it: never moved
  ~PngScratch() {
    if (z) deflateEnd(z.get());
  }
};

/// Target uncompressed bytes per independently deflated block (whole rows,
/// at least one): 128 KiB is 32 rows of 1024 pixels, 24 blocks for 1024x768.
/// Smaller blocks add ~5-10 bytes each (sync flush, new Huffman block) and a
/// 64 KB hash clear; 32 KiB made the component8 image 2% bigger, no faster.
constexpr size_t png_block_bytes = size_t(1) << 17;

/// `img` as a PNG file in memory: 8-bit RGBA, straight alpha
/// (Image::straight_rgba8_rows), every row Paeth-filtered, deflated by zlib with
/// Z_RLE (runs of one distance: flat colour after the filter; measured on
/// rendered 1024x768 images at ~0.6-0.7x the bytes of stb_image_write's
/// level 8 and ~5x faster on one core). Row blocks are converted, filtered
/// and deflated in parallel on TBB the way Mark Adler's pigz does: each block
/// a raw deflate stream ending byte-aligned on Z_SYNC_FLUSH, the last on
/// Z_FINISH, concatenated after one zlib header, the Adler-32 trailer
/// combined from the blocks' (adler32_combine). IDAT chunks hold at most
/// `idat_max` bytes each. @throws IoError when zlib fails (out of memory).
inline std::string encode_png(Image const& img, size_t idat_max = size_t(1) << 30) {
  if (img.width < 1 || img.height < 1) throw IoError("cannot write an empty image as PNG");
  size_t const row_bytes = size_t(img.width) * 4, line = row_bytes + 1;
  int const rows_per_block = int(std::clamp<size_t>(png_block_bytes / line, 1, size_t(img.height)));
  int const blocks = (img.height + rows_per_block - 1) / rows_per_block;
  std::vector<std::string> deflated(static_cast<size_t>(blocks));
  std::vector<uLong> adlers(size_t(blocks), 0);
  tbb::enumerable_thread_specific<PngScratch> scratch;

  tbb::parallel_for(0, blocks, [&](int b) {
    PngScratch& t = scratch.local();
    if (!t.z) {
      t.z = std::make_unique<z_stream>();
      // Raw deflate (windowBits < 0): the zlib header and trailer are written once, around all blocks.
      if (deflateInit2(t.z.get(), 1, Z_DEFLATED, -15, 8, Z_RLE) != Z_OK) {
        t.z.reset();
        throw IoError("cannot encode the image as PNG (zlib: out of memory)");
      }
      t.row[0].assign(row_bytes, 0);
      t.row[1].assign(row_bytes, 0);
      t.filtered.assign(line, 4);  // filter type 4 (Paeth) leads every row
      t.out_size = deflateBound(t.z.get(), uLong(line) * uLong(rows_per_block)) + 64;
      t.out.reset(new unsigned char[t.out_size]);
    } else if (deflateReset(t.z.get()) != Z_OK) {
      throw IoError("cannot encode the image as PNG (zlib: deflateReset)");
    }
    z_stream& z = *t.z;
    size_t used = 0;
    // Runs deflate until it has taken all of z.next_in (and, on a flush, has
    // written everything out), growing the output buffer when it fills.
    auto run = [&](int flush) {
      for (;;) {
        if (used == t.out_size) {
          size_t const bigger = t.out_size * 2;
          std::unique_ptr<unsigned char[]> grown(new unsigned char[bigger]);
          std::memcpy(grown.get(), t.out.get(), used);
          t.out = std::move(grown);
          t.out_size = bigger;
        }
        z.next_out = t.out.get() + used;
        z.avail_out = uInt(std::min<size_t>(t.out_size - used, uInt(-1)));
        uInt const avail = z.avail_out;
        int const r = deflate(&z, flush);
        used += avail - z.avail_out;
        if (r == Z_STREAM_ERROR) throw IoError("cannot encode the image as PNG (zlib: deflate)");
        if (flush == Z_FINISH ? r == Z_STREAM_END : z.avail_in == 0 && z.avail_out != 0) return;
      }
    };
    int const y0 = b * rows_per_block, y1 = std::min(img.height, y0 + rows_per_block);
    if (y0 > 0) img.straight_rgba8_rows(y0 - 1, y0, t.row[(y0 - 1) & 1].data());
    else std::fill(t.row[1].begin(), t.row[1].end(), uint8_t(0));  // "row -1": zeros
    uLong adler = adler32_z(0, nullptr, 0);
    for (int y = y0; y < y1; ++y) {
      uint8_t* const cur = t.row[y & 1].data();
      img.straight_rgba8_rows(y, y + 1, cur);
      paeth_filter_row(cur, t.row[(y + 1) & 1].data(), row_bytes, t.filtered.data() + 1);
      adler = adler32_z(adler, t.filtered.data(), line);
      z.next_in = t.filtered.data();
      for (size_t left = line; left > 0;) {  // avail_in is 32-bit
        z.avail_in = uInt(std::min<size_t>(left, uInt(1) << 30));
        left -= z.avail_in;
        run(Z_NO_FLUSH);
      }
    }
    // A sync flush ends the block on a byte boundary with the final bit unset,
    // so the next block's stream continues it; the last block ends the stream.
    run(b + 1 == blocks ? Z_FINISH : Z_SYNC_FLUSH);
    deflated[size_t(b)].assign(reinterpret_cast<char const*>(t.out.get()), used);
    adlers[size_t(b)] = adler;
  });

  std::string zdata("\x78\x01", 2);  // deflate, 32 KiB window, "fastest" (RFC 1950 §2.2)
  size_t total = 2 + 4;
  for (auto const& d : deflated) total += d.size();
  zdata.reserve(total);
  uLong adler = adler32_z(0, nullptr, 0);
  for (int b = 0; b < blocks; ++b) {
    zdata += deflated[size_t(b)];
    std::string().swap(deflated[size_t(b)]);
    size_t const rows = size_t(std::min(img.height, (b + 1) * rows_per_block) - b * rows_per_block);
    adler = adler32_combine(adler, adlers[size_t(b)], z_off_t(rows * line));
  }
  for (int k = 3; k >= 0; --k) zdata += char(uint8_t(adler >> (8 * k)));

  std::string png("\x89PNG\r\n\x1a\n", 8);
  idat_max = std::clamp<size_t>(idat_max, 1, size_t(0x7fffffff));
  png.reserve(8 + 25 + zdata.size() + 12 * (zdata.size() / idat_max + 1) + 12);
  auto be32 = [&](uint32_t v) {
    char const c[4] = {char(v >> 24), char(v >> 16), char(v >> 8), char(v)};
    png.append(c, 4);
  };
  auto chunk = [&](char const* type, char const* data, size_t n) {
    be32(uint32_t(n));
    size_t const at = png.size();
    png.append(type, 4);
    png.append(data, n);
    be32(uint32_t(crc32_z(crc32_z(0, nullptr, 0), reinterpret_cast<Bytef const*>(png.data() + at), n + 4)));
  };
  char ihdr[13] = {};
  for (int k = 0; k < 4; ++k) {
    ihdr[k] = char(uint32_t(img.width) >> (24 - 8 * k));
    ihdr[4 + k] = char(uint32_t(img.height) >> (24 - 8 * k));
  }
  ihdr[8] = 8;  // bits per channel; colour type 6 (RGBA), deflate, adaptive filters, no interlace
  ihdr[9] = 6;
  chunk("IHDR", ihdr, 13);
  for (size_t at = 0; at < zdata.size(); at += idat_max)
    chunk("IDAT", zdata.data() + at, std::min(idat_max, zdata.size() - at));
  chunk("IEND", "", 0);
  return png;
}

}  // namespace io

/// `img` as an 8-bit RGBA PNG file in memory (straight alpha; io::encode_png).
/// @throws IoError for an empty image or when zlib fails.
inline std::string encode_png(Image const& img) { return io::encode_png(img); }
#endif

/// Writes `img` as 8-bit RGBA PNG (straight alpha), replacing `path` only once the whole file
/// is written (write_file_replacing). @throws IoError on failure or when
/// built without zlib.
inline void write_png(std::string const& path, Image const& img) {
#if CELLRAY_HAS_PNG
  if (img.width < 1 || img.height < 1) throw IoError(path + ": cannot write an empty image as PNG");
  std::string png;
  try {
    png = io::encode_png(img);
  } catch (IoError const& e) {
    throw IoError(path + ": " + e.what());
  }
  write_file_replacing(path, png);
#else
  (void)img;
  throw IoError(path + ": PNG support needs zlib.h (Debian: zlib1g-dev)");
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
