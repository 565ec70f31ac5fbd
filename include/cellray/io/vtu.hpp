#pragma once
// VTK XML unstructured grid reader (".vtu"): DataArrays in format "ascii",
// "binary" (base64) or "appended" (encoding "raw" or "base64"), UInt32 or
// UInt64 headers, optional vtkZLibDataCompressor blocks, either byte order.
// The XML is parsed with pugixml; raw appended data is never handed to the
// XML parser (it is not XML): the document is cut at the '_' marker.
// Needs pugixml and zlib at link time (CMake: pugixml::pugixml ZLIB::ZLIB).

#include <atomic>
#include <cassert>
#include <exception>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <pugixml.hpp>
#include <zlib.h>

#include "detail.hpp"
#include "grid.hpp"
#include "polyhedra.hpp"

namespace cellray {
namespace io {

/// 0..63 for a base64 symbol, 64 for '=', 65 for whitespace, 255 otherwise.
struct Base64Table {
  unsigned char cls[256];
  constexpr Base64Table() : cls() {
    for (int c = 0; c < 256; ++c) {
      unsigned char k = 255;
      if (c >= 'A' && c <= 'Z') k = (unsigned char)(c - 'A');
      else if (c >= 'a' && c <= 'z') k = (unsigned char)(c - 'a' + 26);
      else if (c >= '0' && c <= '9') k = (unsigned char)(c - '0' + 52);
      else if (c == '+') k = 62;
      else if (c == '/') k = 63;
      else if (c == '=') k = 64;
      else if (c == ' ' || c == '\n' || c == '\r' || c == '\t' || c == '\f' || c == '\v') k = 65;
      cls[c] = k;
    }
  }
};
inline constexpr Base64Table base64_table{};

/// Per position in a 4-symbol group, the symbol's 6 bits in place, or bit 24
/// for anything else (whitespace, '=', invalid): one OR per group tells
/// whether the fast path may decode it.
struct Base64Bits {
  uint32_t bits[4][256];
  constexpr Base64Bits() : bits() {
    for (int c = 0; c < 256; ++c) {
      unsigned const k = base64_table.cls[c];
      for (int i = 0; i < 4; ++i) bits[i][c] = k < 64 ? uint32_t(k) << (18 - 6 * i) : uint32_t(1) << 24;
    }
  }
};
inline constexpr Base64Bits base64_bits{};

/// Decodes up to `q` 4-symbol groups of plain symbols at `text` into 3 bytes
/// each at `out`; stops at the first group holding anything else (the
/// careful path takes over there). Returns the groups decoded.
inline uint64_t base64_decode_plain_serial(unsigned char const* text, uint64_t q, unsigned char* out) {
  auto const& t = base64_bits.bits;
  for (uint64_t i = 0; i < q; ++i, text += 4, out += 3) {
    uint32_t const v = t[0][text[0]] | t[1][text[1]] | t[2][text[2]] | t[3][text[3]];
    if (v >> 24) return i;
    out[0] = static_cast<unsigned char>(v >> 16);
    out[1] = static_cast<unsigned char>(v >> 8);
    out[2] = static_cast<unsigned char>(v);
  }
  return q;
}

/// base64_decode_plain_serial, in parallel for long runs (an 11 MB inline
/// array decodes at ~1 GB/s per thread). Chunks past the first one that
/// stops early are decoded for nothing; their bytes are rewritten by the
/// caller's careful path, which starts where the plain run ends.
inline uint64_t base64_decode_plain(unsigned char const* text, uint64_t q, unsigned char* out) {
  constexpr uint64_t chunk = uint64_t(1) << 16;  // groups per task: 192 KB of output
  if (q < 2 * chunk) return base64_decode_plain_serial(text, q, out);
  uint64_t const nchunks = (q + chunk - 1) / chunk;
  std::vector<uint64_t> done(nchunks);
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, nchunks, 1), [&](tbb::blocked_range<uint64_t> const& r) {
    for (uint64_t j = r.begin(); j < r.end(); ++j) {
      uint64_t const b = j * chunk, n = std::min(q, b + chunk) - b;
      done[j] = base64_decode_plain_serial(text + 4 * b, n, out + 3 * b);
    }
  });
  uint64_t total = 0;
  for (uint64_t j = 0; j < nchunks; ++j) {
    total += done[j];
    if (done[j] < std::min(q, (j + 1) * chunk) - j * chunk) break;
  }
  return total;
}

/// Decodes the 4-symbol groups [g0, g1) of the base64 text at `text` into
/// `out` (3 bytes a group) when all are plain symbols, except that the
/// last may end in padding when `may_pad` ("xxx=": 2 bytes, "xx==": 1).
/// Returns the bytes written, or -1 when a group holds anything else (the
/// careful path, which reads whitespace and reports errors, then takes over).
inline int64_t base64_decode_groups(unsigned char const* text, uint64_t g0, uint64_t g1, bool may_pad, unsigned char* out) {
  uint64_t const q = g1 - g0;
  uint64_t const done = base64_decode_plain_serial(text + 4 * g0, q, out);
  if (done == q) return int64_t(3 * q);
  if (done + 1 != q || !may_pad) return -1;
  unsigned char const* const g = text + 4 * (g1 - 1);
  unsigned const a = base64_table.cls[g[0]], b = base64_table.cls[g[1]], c = base64_table.cls[g[2]],
                 d = base64_table.cls[g[3]];
  if (a >= 64 || b >= 64 || d != 64 || (c >= 64 && c != 64)) return -1;
  unsigned char* const o = out + 3 * done;
  o[0] = static_cast<unsigned char>((a << 2) | (b >> 4));
  if (c == 64) return int64_t(3 * done + 1);
  o[1] = static_cast<unsigned char>(((b & 15) << 4) | (c >> 2));
  return int64_t(3 * done + 2);
}

/// Bytes of a DataArray payload: raw bytes of the file, or base64 text in it.
/// The base64 decoder accepts several padded streams back to back, because
/// VTK encodes a compressed array's header and its blocks separately.
/// Every read is bounds-checked; errors name the file byte offset.
class ByteStream {
 public:
  ByteStream(Source const& src, uint64_t begin, uint64_t end, bool base64, std::string what)
      : src_(src), pos_(begin), end_(end), base64_(base64), what_(std::move(what)) {}

  /// Upper bound of the bytes left (exact for raw data).
  uint64_t max_left() const { return base64_ ? (end_ - pos_) / 4 * 3 + uint64_t(npend_ - ipend_) : end_ - pos_; }
  uint64_t offset() const { return pos_; }
  bool base64() const { return base64_; }

  /// Base64 only: the text from here when the next byte starts a 4-symbol
  /// group (none is pending from the last), and the groups that fit before
  /// the end; byte k from here then lies in group k / 3.
  unsigned char const* group_text(uint64_t& groups) const {
    groups = (end_ - pos_) / 4;
    if (!base64_ || ipend_ < npend_) return nullptr;
    return reinterpret_cast<unsigned char const*>(src_.bytes.data()) + pos_;
  }
  /// Moves past `n` bytes that base64_decode_groups decoded from
  /// group_text(), leaving the stream as read(n) would.
  void skip_decoded(uint64_t n) {
    pos_ += 4 * (n / 3);
    if (n % 3) {
      quantum();
      ipend_ = int(n % 3);
    }
  }

  /// The next `n` raw bytes, in place (raw data only).
  unsigned char const* raw(uint64_t n) {
    if (n > end_ - pos_) truncated(n);
    auto const* p = reinterpret_cast<unsigned char const*>(src_.bytes.data()) + pos_;
    pos_ += n;
    return p;
  }
  void read(unsigned char* out, uint64_t n) {
    if (!base64_) {
      if (n) std::memcpy(out, raw(n), n);
      return;
    }
    if (n > max_left()) truncated(n);
    auto const* const text = reinterpret_cast<unsigned char const*>(src_.bytes.data());
    while (n > 0) {
      if (ipend_ < npend_) {
        *out++ = pend_[ipend_++];
        --n;
        continue;
      }
      if (n >= 3) {
        // Plain symbols (no whitespace or padding) go straight to the output,
        // as many whole groups as possible at once.
        uint64_t const q = std::min(n / 3, (end_ - pos_) / 4);
        uint64_t const done = base64_decode_plain(text + pos_, q, out);
        pos_ += 4 * done;
        out += 3 * done;
        n -= 3 * done;
        if (done > 0) continue;
      }
      quantum();
    }
  }

 private:
  [[noreturn]] void truncated(uint64_t n) const {
    src_.fail_byte(pos_, what_ + ": needs " + std::to_string(n) + " more bytes but the data ends (at most " +
                             std::to_string(max_left()) + " left)");
  }
  /// Decodes the next 4 symbols into pend_.
  void quantum() {
    unsigned char v[4];
    int n = 0;
    uint64_t const start = pos_;
    while (n < 4) {
      if (pos_ >= end_) src_.fail_byte(start, what_ + ": base64 data ends in the middle of a 4-character group");
      unsigned char const c = static_cast<unsigned char>(src_.bytes[pos_]);
      unsigned char const k = base64_table.cls[c];
      if (k == 255) {
        std::string shown = (c >= 32 && c < 127) ? std::string("'") + char(c) + "'" : "byte " + std::to_string(int(c));
        src_.fail_byte(pos_, what_ + ": invalid base64 character " + shown);
      }
      ++pos_;
      if (k == 65) continue;
      v[n++] = k;
    }
    // xxxx -> 3 bytes, xxx= -> 2, xx== -> 1; '=' anywhere else is invalid.
    int const pads = (v[3] == 64) + (v[2] == 64);
    if (v[0] == 64 || v[1] == 64 || (v[2] == 64 && v[3] != 64))
      src_.fail_byte(start, what_ + ": invalid base64 padding");
    uint32_t const bits = (uint32_t(v[0]) << 18) | (uint32_t(v[1]) << 12) | (uint32_t(pads >= 2 ? 0 : v[2]) << 6) |
                          uint32_t(pads >= 1 ? 0 : v[3]);
    pend_[0] = static_cast<unsigned char>(bits >> 16);
    pend_[1] = static_cast<unsigned char>(bits >> 8);
    pend_[2] = static_cast<unsigned char>(bits);
    npend_ = 3 - pads;
    ipend_ = 0;
  }

  Source const& src_;
  uint64_t pos_, end_;
  bool base64_;
  std::string what_;
  unsigned char pend_[3] = {0, 0, 0};
  int npend_ = 0, ipend_ = 0;
};

/// VTK XML type names to element types; false for unknown names.
inline bool xml_type(std::string_view name, NumType& t) {
  struct Name {
    char const* name;
    NumType type;
  };
  static constexpr Name names[] = {{"Int8", NumType::i8},     {"UInt8", NumType::u8},     {"Int16", NumType::i16},
                                   {"UInt16", NumType::u16},  {"Int32", NumType::i32},    {"UInt32", NumType::u32},
                                   {"Int64", NumType::i64},   {"UInt64", NumType::u64},   {"Float32", NumType::f32},
                                   {"Float64", NumType::f64}, {"Char", NumType::i8},      {"UChar", NumType::u8}};
  for (auto const& n : names)
    if (name == n.name) {
      t = n.type;
      return true;
    }
  return false;
}

/// deflate cannot expand data by more than 1032:1; a header claiming more
/// is corrupt (and must not make us allocate).
constexpr uint64_t zlib_max_ratio = 1032;

/// Inflates the zlib stream [z, z + zsize) and appends exactly `want` bytes
/// to `out`, growing it 1 MiB at a time as the stream produces them. Returns
/// "" on success, else what went wrong (the stream is corrupt, ends early or
/// holds more than `want` bytes); `out` may then hold part of the block.
inline std::string inflate_append(unsigned char const* z, uint64_t zsize, uint64_t want, cellray::detail::LargeVector<unsigned char>& out) {
  constexpr uint64_t grow = uint64_t(1) << 20;
  constexpr uint64_t max_feed = std::numeric_limits<uInt>::max();
  z_stream zs{};
  if (inflateInit(&zs) != Z_OK) return "zlib cannot start";
  uint64_t in_left = zsize, produced = 0;
  std::string err;
  for (;;) {
    if (zs.avail_in == 0 && in_left > 0) {
      uint64_t const feed = std::min(in_left, max_feed);
      zs.next_in = const_cast<Bytef*>(z + (zsize - in_left));
      zs.avail_in = uInt(feed);
      in_left -= feed;
    }
    unsigned char spare = 0;
    uint64_t const room = std::min(grow, want - produced);
    size_t const at = out.size();
    if (room > 0) {
      out.resize(at + size_t(room));
      zs.next_out = out.data() + at;
      zs.avail_out = uInt(room);
    } else {  // all bytes are in: the stream must end here
      zs.next_out = &spare;
      zs.avail_out = 1;
    }
    int const rc = inflate(&zs, Z_NO_FLUSH);
    uint64_t const got = (room > 0 ? room : 1) - zs.avail_out;
    if (room > 0) out.resize(at + size_t(got));
    if (room == 0 && got > 0) {
      err = "it holds more";
      break;
    }
    produced += got;
    if (rc == Z_STREAM_END) {
      if (produced != want) err = "got " + std::to_string(produced);
      break;
    }
    if (rc == Z_BUF_ERROR && zs.avail_in == 0 && in_left == 0) {
      err = "the data ends after " + std::to_string(produced) + " bytes";
      break;
    }
    if (rc != Z_OK && rc != Z_BUF_ERROR) {
      err = zs.msg ? zs.msg : zError(rc);
      break;
    }
  }
  inflateEnd(&zs);
  return err;
}

/// Inflates the zlib stream [z, z + zsize) into exactly `want` bytes at
/// `dst` (room for `want` bytes). Returns "" on success, else what went
/// wrong, in inflate_append's words.
inline std::string inflate_into(unsigned char const* z, uint64_t zsize, uint64_t want, unsigned char* dst) {
  constexpr uint64_t max_feed = std::numeric_limits<uInt>::max();
  if (zsize > max_feed || want > max_feed) {  // blocks are 32 KiB in VTK: not worth a loop
    cellray::detail::LargeVector<unsigned char> out;
    std::string err = inflate_append(z, zsize, want, out);
    if (err.empty()) std::memcpy(dst, out.data(), size_t(want));
    return err;
  }
  z_stream zs{};
  if (inflateInit(&zs) != Z_OK) return "zlib cannot start";
  zs.next_in = const_cast<Bytef*>(z);
  zs.avail_in = uInt(zsize);
  zs.next_out = dst;
  zs.avail_out = uInt(want);
  int rc = want > 0 ? inflate(&zs, Z_NO_FLUSH) : Z_OK;
  uint64_t const produced = want - zs.avail_out;
  bool holds_more = false;
  if (rc == Z_OK) {  // all `want` bytes are in, or the input ran out: the stream must end here
    unsigned char spare = 0;
    zs.next_out = &spare;
    zs.avail_out = 1;
    rc = inflate(&zs, Z_NO_FLUSH);
    holds_more = zs.avail_out == 0;
  }
  std::string err;
  if (holds_more) err = "it holds more";
  else if (rc == Z_STREAM_END) err = produced == want ? "" : "got " + std::to_string(produced);
  else if (rc == Z_OK || rc == Z_BUF_ERROR) err = "the data ends after " + std::to_string(produced) + " bytes";
  else err = zs.msg ? zs.msg : zError(rc);
  inflateEnd(&zs);
  return err;
}

/// `xml` with the inline text of every DataArray element replaced by one
/// 'x', into `out`: that text (base64 or numbers) is nearly all of a file
/// with inline data, and handing it to pugixml cost a copy into fresh memory
/// plus a character scan (~20% of the 11 MB flange's load). The readers take
/// array text from the file itself (the PCDATA node only locates it). Text
/// that is blank, holds a NUL byte or runs to the end is kept, so pugixml
/// sees the same nodes and reports the same errors at the same places. `shifts` maps offsets back: from out offset `first` on, the
/// file offset is offset + `second` (sorted by `first`).
inline void xml_skeleton(std::string_view xml, std::string& out, std::vector<std::pair<uint64_t, uint64_t>>& shifts) {
  out.clear();
  shifts.clear();
  size_t const size = xml.size(), npos = std::string_view::npos;
  size_t copied = 0, i = 0;
  auto skip_to = [&](size_t from, std::string_view end_mark) {
    size_t const e = xml.find(end_mark, from);
    return e == npos ? npos : e + end_mark.size();
  };
  while ((i = xml.find('<', i)) != npos) {
    std::string_view const rest = xml.substr(i);
    if (rest.substr(0, 4) == "<!--") i = skip_to(i + 4, "-->");
    else if (rest.substr(0, 9) == "<![CDATA[") i = skip_to(i + 9, "]]>");
    else if (rest.substr(0, 2) == "<?") i = skip_to(i + 2, "?>");
    else if (rest.size() > 10 && rest.substr(0, 10) == "<DataArray" &&
             (is_space(rest[10]) || rest[10] == '>' || rest[10] == '/')) {
      size_t j = i + 10;  // the start tag's '>', outside quoted attribute values
      for (char q = 0; j < size; ++j) {
        char const c = xml[j];
        if (q) q = c == q ? 0 : q;
        else if (c == '"' || c == '\'') q = c;
        else if (c == '>') break;
      }
      if (j >= size) break;
      size_t const t = j + 1;
      size_t const lt = xml.find('<', t);
      if (lt == npos) break;  // text up to the end: pugixml's error points into it
      i = lt;
      if (xml[j - 1] == '/' || lt - t < 2) continue;
      size_t first = t;
      while (first < lt && is_space(xml[first])) ++first;
      if (first == lt || std::memchr(xml.data() + t, 0, lt - t)) continue;
      out.append(xml.substr(copied, t - copied));
      out += 'x';
      shifts.emplace_back(out.size(), lt - out.size());
      copied = lt;
      continue;
    } else ++i;
    if (i == npos) break;
  }
  out.append(xml.substr(copied));
}

/// Parser state for one .vtu document. Internal: use read_vtu*().
class VtuParser {
 public:
  VtuParser(Source const& src, ReadOptions const& opts) : src_(src), opts_(opts) {}

  UnstructuredGrid parse() {
    load_xml();
    pugi::xml_node const root = doc_.child("VTKFile");
    if (!root) src_.fail_line(0, "not a VTK XML file (no VTKFile element)");
    std::string_view const type = root.attribute("type").value();
    if (type != "UnstructuredGrid")
      src_.fail_line(offset(root), "VTK XML type " + in_quotes(type) + " is not supported (cellray reads UnstructuredGrid)");
    std::string_view const order = root.attribute("byte_order").value();
    if (order == "BigEndian") big_endian_ = true;
    else if (!order.empty() && order != "LittleEndian") src_.fail_line(offset(root), "unknown byte_order " + in_quotes(order));
    uint16_t const one = 1;
    unsigned char b0;
    std::memcpy(&b0, &one, 1);
    swap_ = big_endian_ == (b0 == 1);
    std::string_view const header = root.attribute("header_type").value();
    if (header == "UInt64") header_size_ = 8;
    else if (!header.empty() && header != "UInt32")
      src_.fail_line(offset(root), "unknown header_type " + in_quotes(header) + " (UInt32 or UInt64)");
    std::string_view const compressor = root.attribute("compressor").value();
    if (compressor == "vtkZLibDataCompressor") compressed_ = true;
    else if (!compressor.empty())
      src_.fail_line(offset(root), "compressor " + in_quotes(compressor) + " is not supported (only vtkZLibDataCompressor)");
    if (appended_) {
      pugi::xml_node const app = root.child("AppendedData");
      std::string_view const enc = app.attribute("encoding").value();
      if (enc == "base64") appended_base64_ = true;
      else if (enc != "raw") src_.fail_line(offset(app), "AppendedData encoding " + in_quotes(enc) + " (raw or base64 expected)");
    }

    pugi::xml_node const ug = root.child("UnstructuredGrid");
    if (!ug) src_.fail_line(offset(root), "no UnstructuredGrid element");
    pugi::xml_node piece;
    int pieces = 0;
    for (pugi::xml_node p : ug.children("Piece")) {
      if (!pieces) piece = p;
      ++pieces;
    }
    if (pieces == 0) src_.fail_line(offset(ug), "no Piece element");
    if (pieces > 1) src_.fail_line(offset(ug), std::to_string(pieces) + " pieces: cellray reads single-piece files only");

    UnstructuredGrid grid;
    grid.report.file = src_.name;
    uint64_t const np = count_attr(piece, "NumberOfPoints");
    uint64_t const nc = count_attr(piece, "NumberOfCells");
    if (!point_count_fits(np))
      src_.fail_line(offset(piece), std::to_string(np) + " points: cellray uses 32-bit vertex ids (at most 4294967295 points)");

    pugi::xml_node const pts = piece.child("Points").child("DataArray");
    if (!pts) src_.fail_line(offset(piece), "no Points/DataArray element");
    if (components(pts) != 3) src_.fail_line(offset(pts), "Points must have NumberOfComponents=\"3\"");
    uint64_t n3 = 0;
    checked_mul(np, 3, n3);
    NumArray xyz = decode(pts, n3, "Points");

    pugi::xml_node const cells = piece.child("Cells");
    if (!cells) src_.fail_line(offset(piece), "no Cells element");
    pugi::xml_node const conn_el = named(cells, "connectivity"), off_el = named(cells, "offsets"), type_el = named(cells, "types");
    // Checked on the declared type: ASCII data is decoded to Int64 or Float64,
    // which would name the wrong type.
    for (auto const& [el, what] : {std::pair(off_el, "offsets"), std::pair(conn_el, "connectivity"), std::pair(type_el, "types")}) {
      NumType t{};
      if (el && xml_type(el.attribute("type").value(), t) && !is_integer(t))
        src_.fail_line(offset(el), std::string(what) + " is stored as " + num_name(t) + ", not integers");
    }
    NumArray const offsets = decode(off_el, nc, "offsets");
    // VTU offsets are end offsets: cell c uses [offsets[c-1], offsets[c]).
    int64_t prev = 0;
    for (uint64_t c = 0; c < nc; ++c) {
      int64_t const o = offsets.as_int(c);
      if (o < prev)
        src_.fail_line(offset(off_el), "offsets: cell " + std::to_string(c) + " ends at " + std::to_string(o) +
                                           ", before its start " + std::to_string(prev));
      prev = o;
    }
    NumArray const conn = decode(conn_el, uint64_t(prev), "connectivity");
    NumArray const types = decode(type_el, nc, "types");
    pugi::xml_node const faces_el = optional_named(cells, "faces"), face_offsets_el = optional_named(cells, "faceoffsets");
    FileCellCounts const file = count_file_cells(types);  // upper bounds, for reserving storage
    if (file.polyhedra) {
      plan_faces_el_ = faces_el;
      plan_face_offsets_el_ = face_offsets_el;
      try {
        plan_polyhedra(types, faces_el, face_offsets_el, cells);
      } catch (IoError const&) {
        plan_.failed = std::current_exception();
      }
      if (!plan_.failed) {
        PolyPlan const& pp = plan_.plan;
        grid.tets.reserve(4 * (file.tets + pp.new_tets()));
        grid.hexes.reserve(8 * (file.hexes + pp.new_hexes()));
        grid.xyz.reserve(3 * (np + pp.polys.size()));
        poly_spare_ = Spare{pp.polys.size(), pp.new_tets(), pp.new_hexes()};
      }
    }
    CellLocator where;
    where.conn = [&](uint64_t) { return src_.at_line(offset(conn_el)) + "connectivity: "; };
    where.type = [&](uint64_t) { return src_.at_line(offset(type_el)) + "types: "; };
    CellKinds const kinds = build_cells(
        nc, types, conn,
        [&offsets](uint64_t c) {
          return std::pair<uint64_t, uint64_t>(c ? uint64_t(offsets.as_int(c - 1)) : 0, uint64_t(offsets.as_int(c)));
        },
        np, opts_, grid, where, /*polyhedra=*/true);
    set_positions(grid, std::move(xyz), np);

    for (pugi::xml_node a : piece.child("PointData").children()) array(grid, a, np, false, kinds);
    for (pugi::xml_node a : piece.child("CellData").children()) array(grid, a, nc, true, kinds);
    if (std::find(kinds.begin(), kinds.end(), uint8_t(3)) != kinds.end())
      split_polyhedra(grid);
    for (pugi::xml_node a : ug.child("FieldData").children())
      grid.report.arrays_ignored.push_back("field " + in_quotes(a.attribute("Name").value()) + " (dataset field data)");

    std::string enc;
    for (auto const& f : formats_) enc += (enc.empty() ? "" : ", ") + f;
    grid.report.format = "VTK XML " + std::string(root.attribute("version").value()) + " UnstructuredGrid (" + enc +
                         (header_size_ == 8 ? ", UInt64 headers" : ", UInt32 headers") + (compressed_ ? ", zlib" : "") +
                         (big_endian_ ? ", big-endian" : "") + ")";
    return grid;
  }

 private:
  Source const& src_;
  ReadOptions opts_;
  pugi::xml_document doc_;
  std::string xml_;                                     // what pugixml parses (xml_skeleton)
  std::vector<std::pair<uint64_t, uint64_t>> shifts_;  // xml_skeleton's offset map
  bool appended_ = false, appended_base64_ = false, compressed_ = false, big_endian_ = false, swap_ = false;
  uint64_t appended_base_ = 0, appended_end_ = 0, header_size_ = 4;
  std::set<std::string> formats_;
  PolyhedraValues polyhedra_values_;  // per cell array
  // Decoded base64 arrays, one after another in one buffer sized for all of
  // them (3 bytes per 4 of file): it is huge pages from 4 MB (memory.hpp),
  // where a buffer per array cost ~2,000 first-write faults of 4 KB (~30 ms)
  // on the 11 MB flange. Only what is decoded is ever touched. The arrays
  // viewing it live no longer than the parser.
  cellray::detail::LargeVector<unsigned char> arena_;
  uint64_t arena_used_ = 0;

  /// `n` bytes of arena_, 64-byte aligned, or null when they do not fit (an
  /// appended array decoded twice, or inflated data).
  unsigned char* arena_take(uint64_t n) {
    if (arena_.empty()) arena_.resize(src_.bytes.size() / 4 * 3 + 64);  // unset, untouched
    uint64_t const at = (arena_used_ + 63) & ~uint64_t(63);
    if (at > arena_.size() || n > arena_.size() - at) return nullptr;
    arena_used_ = at + n;
    return arena_.data() + at;
  }

  uint64_t offset(pugi::xml_node n) const {
    ptrdiff_t const o = n.offset_debug();
    return o < 0 ? 0 : file_offset(uint64_t(o));
  }

  /// Raw appended data is binary, not XML: parse only the document up to
  /// the '_' marker, closed by hand. Offsets stay those of the file.
  void load_xml() {
    std::string_view const b = src_.bytes;
    size_t const tag = b.find("<AppendedData");
    std::string_view xml = b;
    if (tag != std::string_view::npos) {
      size_t const gt = b.find('>', tag);
      if (gt == std::string_view::npos) src_.fail_line(tag, "unterminated AppendedData tag");
      if (b[gt - 1] != '/') {
        size_t u = gt + 1;
        while (u < b.size() && is_space(b[u])) ++u;
        if (u >= b.size() || b[u] != '_') src_.fail_line(u, "AppendedData must start with '_'");
        appended_ = true;
        appended_base_ = u + 1;
        appended_end_ = b.size();
        xml = b.substr(0, gt + 1);
      }
    }
    xml_skeleton(xml, xml_, shifts_);
    if (appended_) xml_ += "</AppendedData></VTKFile>";
    pugi::xml_parse_result const r = doc_.load_buffer(xml_.data(), xml_.size(), pugi::parse_default, pugi::encoding_utf8);
    if (!r) src_.fail_line(file_offset(uint64_t(std::max<ptrdiff_t>(r.offset, 0))), std::string("XML error: ") + r.description());
  }

  /// The file offset of offset `o` in xml_ (see xml_skeleton).
  uint64_t file_offset(uint64_t o) const {
    auto const it = std::upper_bound(shifts_.begin(), shifts_.end(), std::pair<uint64_t, uint64_t>(o, ~uint64_t(0)));
    return it == shifts_.begin() ? o : o + std::prev(it)->second;
  }

  uint64_t count_attr(pugi::xml_node n, char const* name) const {
    pugi::xml_attribute const a = n.attribute(name);
    if (!a) src_.fail_line(offset(n), std::string("missing ") + name);
    std::string_view v = a.value();
    while (!v.empty() && is_space(v.front())) v.remove_prefix(1);
    while (!v.empty() && is_space(v.back())) v.remove_suffix(1);
    uint64_t c = 0;
    if (!parse_count(v, c)) src_.fail_line(offset(n), std::string(name) + " is " + in_quotes(a.value()) + ", not a count");
    return c;
  }
  int components(pugi::xml_node n) const {
    if (!n.attribute("NumberOfComponents")) return 1;
    uint64_t const c = count_attr(n, "NumberOfComponents");
    if (c < 1 || c > 1024) src_.fail_line(offset(n), "NumberOfComponents must be 1 to 1024");
    return int(c);
  }
  pugi::xml_node named(pugi::xml_node cells, char const* name) const {
    if (pugi::xml_node a = optional_named(cells, name)) return a;
    src_.fail_line(offset(cells), std::string("Cells has no DataArray named '") + name + "'");
  }
  static pugi::xml_node optional_named(pugi::xml_node cells, char const* name) {
    for (pugi::xml_node a : cells.children("DataArray"))
      if (std::string_view(a.attribute("Name").value()) == name) return a;
    return {};
  }

  /// The [begin, end) file range of an element's inline text (first PCDATA).
  std::pair<uint64_t, uint64_t> inline_text(pugi::xml_node el) const {
    for (pugi::xml_node c : el.children()) {
      if (c.type() == pugi::node_cdata) src_.fail_line(offset(c), "CDATA array data is not supported");
      if (c.type() != pugi::node_pcdata) continue;
      uint64_t const b = offset(c);
      size_t e = src_.bytes.find('<', b);
      return {b, e == std::string_view::npos ? src_.bytes.size() : e};
    }
    return {offset(el), offset(el)};  // no text: errors point at the element
  }

  uint64_t header_int(ByteStream& s) {
    unsigned char b[8];
    s.read(b, header_size_);
    uint64_t v = 0;
    for (uint64_t i = 0; i < header_size_; ++i) {
      uint64_t const k = big_endian_ ? i : header_size_ - 1 - i;
      v = (v << 8) | b[k];
    }
    return v;
  }

  static constexpr uint64_t unknown = ~uint64_t(0);

  /// The values of DataArray `el`: `expected` values, or as many as the data
  /// hold when `expected` is `unknown`.
  NumArray decode(pugi::xml_node el, uint64_t expected, std::string const& what) {
    NumType t{};
    std::string_view const tname = el.attribute("type").value();
    if (!xml_type(tname, t)) src_.fail_line(offset(el), what + ": unknown DataArray type " + in_quotes(tname));
    std::string_view const format = el.attribute("format").value();
    if (format == "ascii" || format.empty()) {
      formats_.insert("ascii");
      auto [b, e] = inline_text(el);
      uint64_t n = expected;
      if (n == unknown) n = count_tokens(b, e);
      uint64_t p = b;
      NumArray a = is_integer(t) ? NumArray::owning(parse_ascii_numbers<int64_t>(src_, p, n, what, e))
                                 : NumArray::owning(parse_ascii_numbers<double>(src_, p, n, what, e));
      while (p < e && is_space(src_.bytes[p])) ++p;
      if (p < e) src_.fail_line(p, what + ": more values than the " + std::to_string(n) + " expected");
      return a;
    }
    if (format == "binary") {
      formats_.insert("binary base64");
      auto [b, e] = inline_text(el);
      ByteStream s(src_, b, e, true, what);
      return payload(s, t, expected, what);
    }
    if (format == "appended") {
      if (!appended_) src_.fail_line(offset(el), what + ": format=\"appended\" but the file has no AppendedData");
      formats_.insert(appended_base64_ ? "appended base64" : "appended raw");
      uint64_t const off = count_attr(el, "offset");
      if (off > appended_end_ - appended_base_)
        src_.fail_line(offset(el), what + ": offset " + std::to_string(off) + " lies beyond the appended data");
      ByteStream s(src_, appended_base_ + off, appended_end_, appended_base64_, what);
      return payload(s, t, expected, what);
    }
    src_.fail_line(offset(el), what + ": unknown format " + in_quotes(format));
  }

  uint64_t count_tokens(uint64_t b, uint64_t e) const {
    uint64_t n = 0;
    bool in = false;
    for (uint64_t i = b; i < e; ++i) {
      bool const sp = is_space(src_.bytes[i]);
      n += (!sp && !in);
      in = !sp;
    }
    return n;
  }

  /// Header + data of a binary array (VTK's layout: one byte count, or for
  /// zlib: nblocks, block size, last block size, compressed block sizes).
  NumArray payload(ByteStream& s, NumType t, uint64_t expected, std::string const& what) {
    uint64_t const esize = num_size(t);
    uint64_t const start = s.offset();
    auto check_size = [&](uint64_t bytes) {
      if (expected != unknown && bytes != bytes_for(t, expected))
        src_.fail_byte(start, what + ": the header says " + std::to_string(bytes) + " bytes, expected " +
                                  std::to_string(bytes_for(t, expected)) + " (" + std::to_string(expected) + " " +
                                  num_name(t) + " values)");
      if (bytes % esize)
        src_.fail_byte(start, what + ": " + std::to_string(bytes) + " bytes is not a whole number of " + num_name(t) + " values");
    };
    if (!compressed_) {
      uint64_t const bytes = header_int(s);
      check_size(bytes);
      if (bytes > s.max_left())
        src_.fail_byte(s.offset(), what + ": " + std::to_string(bytes) + " bytes declared but at most " +
                                       std::to_string(s.max_left()) + " are left");
      if (!s.base64()) return NumArray::viewing(t, bytes / esize, s.raw(bytes), swap_);
      if (unsigned char* const p = arena_take(bytes)) {
        s.read(p, bytes);
        return NumArray::viewing(t, bytes / esize, p, swap_);
      }
      cellray::detail::LargeVector<unsigned char> out(bytes);
      s.read(out.data(), bytes);
      return NumArray::owning_bytes(t, bytes / esize, std::move(out), swap_);
    }
    uint64_t const nblocks = header_int(s);
    if (nblocks > s.max_left() / header_size_)
      src_.fail_byte(start, what + ": " + std::to_string(nblocks) + " compressed blocks declared, more than the data can hold");
    uint64_t const block = header_int(s);
    uint64_t const last = header_int(s);
    std::vector<uint64_t> csize(nblocks);
    uint64_t ctotal = 0;
    for (auto& c : csize) {
      c = header_int(s);
      if (c > s.max_left()) src_.fail_byte(start, what + ": a compressed block of " + std::to_string(c) + " bytes runs past the data");
      ctotal += c;
    }
    if (ctotal > s.max_left())
      src_.fail_byte(start, what + ": compressed blocks of " + std::to_string(ctotal) + " bytes run past the data");
    uint64_t const last_size = last ? last : block;
    if (nblocks && (last > block || block > max_count || nblocks > max_count / (block + 1)))
      src_.fail_byte(start, what + ": inconsistent block sizes (" + std::to_string(block) + ", last " + std::to_string(last) + ")");
    uint64_t const total = nblocks ? (nblocks - 1) * block + last_size : 0;
    check_size(total);
    if (total > zlib_max_ratio * ctotal + 64 * nblocks)
      src_.fail_byte(start, what + ": " + std::to_string(total) + " bytes cannot come from " + std::to_string(ctotal) +
                                " compressed bytes (corrupt header)");
    // The output grows only as blocks inflate: a header's claim allocates
    // nothing until compressed data backs it (VTK's header is not a promise).
    // A claim within what the serial loop would reserve anyway is allocated
    // at once and its blocks inflate in parallel.
    uint64_t const trusted = 8 * ctotal + (uint64_t(1) << 20);
    if (nblocks >= 2 && total <= trusted) return inflate_blocks(s, t, csize, ctotal, block, last_size, total, what);
    cellray::detail::LargeVector<unsigned char> out;
    std::vector<unsigned char> tmp;
    out.reserve(size_t(std::min(total, trusted)));
    for (uint64_t i = 0; i < nblocks; ++i) {
      uint64_t const here = s.offset();
      unsigned char const* z;
      if (s.base64()) {
        tmp.resize(csize[i]);
        s.read(tmp.data(), csize[i]);
        z = tmp.data();
      } else {
        z = s.raw(csize[i]);
      }
      uint64_t const want = i + 1 == nblocks ? last_size : block;
      std::string const err = inflate_append(z, csize[i], want, out);
      if (!err.empty()) fail_block(here, what, i, nblocks, want, err);
    }
    return NumArray::owning_bytes(t, total / esize, std::move(out), swap_);
  }

  /// zlib blocks inflated in parallel into one buffer of `total` bytes
  /// (inflate is nearly all of loading a compressed file). Errors are those
  /// of the serial loop, in its order: the first block that fails to
  /// inflate, unless reading an earlier block's bytes failed first.
  NumArray inflate_blocks(ByteStream& s, NumType t, std::vector<uint64_t> const& csize, uint64_t ctotal, uint64_t block,
                          uint64_t last_size, uint64_t total, std::string const& what) {
    if (s.base64())
      if (auto a = inflate_blocks_in_place(s, t, csize, ctotal, block, last_size, total, what)) return std::move(*a);
    uint64_t const nblocks = csize.size();
    std::vector<unsigned char const*> z(nblocks);
    std::vector<uint64_t> at(nblocks);
    cellray::detail::LargeVector<unsigned char> text;  // base64 streams: every block's bytes, decoded
    if (s.base64()) text.resize(size_t(ctotal));
    uint64_t nread = 0, coff = 0;
    std::exception_ptr read_failed;
    try {
      for (; nread < nblocks; ++nread) {
        at[nread] = s.offset();
        if (s.base64()) {
          s.read(text.data() + coff, csize[nread]);
          z[nread] = text.data() + coff;
        } else {
          z[nread] = s.raw(csize[nread]);
        }
        coff += csize[nread];
      }
    } catch (IoError const&) {
      read_failed = std::current_exception();
    }
    InflatedBytes out = inflated_room(t, total);
    std::vector<std::string> err(nread);
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, nread, 1), [&](tbb::blocked_range<uint64_t> const& r) {
      for (uint64_t i = r.begin(); i < r.end(); ++i)
        err[i] = inflate_into(z[i], csize[i], i + 1 == nblocks ? last_size : block, out.data() + i * block);
    });
    for (uint64_t i = 0; i < nread; ++i)
      if (!err[i].empty()) fail_block(at[i], what, i, nblocks, i + 1 == nblocks ? last_size : block, err[i]);
    if (read_failed) std::rethrow_exception(read_failed);
    return inflated_array(t, total, std::move(out));
  }

  /// Room for `total` inflated bytes of type t: Float32 in the host's order
  /// as floats, which a grid can adopt (NumArray::take_floats), zeroed from
  /// all threads (a std::vector's elements are always set; zeroing them in
  /// parallel shares the first-write faults); anything else unset.
  struct InflatedBytes {
    std::vector<float> floats;
    cellray::detail::LargeVector<unsigned char> bytes;
    unsigned char* data() { return floats.empty() ? bytes.data() : reinterpret_cast<unsigned char*>(floats.data()); }
  };
  InflatedBytes inflated_room(NumType t, uint64_t total) const {
    InflatedBytes b;
    if (t == NumType::f32 && !swap_ && total >= 4) cellray::detail::resize_zeroed(b.floats, total / 4);
    else {
      b.bytes.resize(size_t(total));
      if (total >= cellray::detail::populate_bytes) cellray::detail::populate_pages(b.bytes.data(), total);
    }
    return b;
  }
  NumArray inflated_array(NumType t, uint64_t total, InflatedBytes&& b) const {
    if (!b.floats.empty()) return NumArray::owning_floats(std::move(b.floats));
    return NumArray::owning_bytes(t, total / num_size(t), std::move(b.bytes), swap_);
  }

  /// inflate_blocks for base64 text that is one run of plain symbols (as
  /// VTK writes it): each task decodes its own blocks from the file's text
  /// into a small buffer and inflates them, instead of one thread decoding
  /// every block into a buffer of all the compressed bytes first (its fresh
  /// pages took a quarter of a zlib .vtu's first-write faults while
  /// loading, and one thread decoded). Empty when a block's text
  /// is not plain (line breaks, streams back to back); inflate_blocks'
  /// careful path then reads it all again and reports what it finds.
  std::optional<NumArray> inflate_blocks_in_place(ByteStream& s, NumType t, std::vector<uint64_t> const& csize,
                                                  uint64_t ctotal, uint64_t block, uint64_t last_size, uint64_t total,
                                                  std::string const& what) {
    uint64_t groups = 0;
    unsigned char const* const text = s.group_text(groups);
    uint64_t const nblocks = csize.size();
    if (!text || (ctotal + 2) / 3 > groups) return std::nullopt;
    std::vector<uint64_t> first(nblocks + 1, 0);  // compressed bytes before each block
    for (uint64_t i = 0; i < nblocks; ++i) first[i + 1] = first[i] + csize[i];
    InflatedBytes out = inflated_room(t, total);
    std::vector<std::string> err(nblocks);
    std::atomic<bool> plain{true};
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, nblocks, 1), [&](tbb::blocked_range<uint64_t> const& r) {
      std::vector<unsigned char> z;
      for (uint64_t i = r.begin(); i < r.end() && plain.load(std::memory_order_relaxed); ++i) {
        uint64_t const g0 = first[i] / 3, g1 = (first[i + 1] + 2) / 3;
        z.resize(3 * (g1 - g0));
        int64_t const got = base64_decode_groups(text, g0, g1, i + 1 == nblocks, z.data());
        uint64_t const skip = first[i] - 3 * g0;
        if (got < 0 || uint64_t(got) < skip + csize[i]) {
          plain.store(false, std::memory_order_relaxed);
          return;
        }
        err[i] = inflate_into(z.data() + skip, csize[i], i + 1 == nblocks ? last_size : block, out.data() + i * block);
      }
    });
    if (!plain.load()) return std::nullopt;
    for (uint64_t i = 0; i < nblocks; ++i)  // named where the serial reader stood when it began the block
      if (!err[i].empty())
        fail_block(s.offset() + 4 * ((first[i] + 2) / 3), what, i, nblocks, i + 1 == nblocks ? last_size : block, err[i]);
    s.skip_decoded(ctotal);
    return inflated_array(t, total, std::move(out));
  }

  /// A zlib block that does not inflate to its size, named at byte `at`.
  [[noreturn]] void fail_block(uint64_t at, std::string const& what, uint64_t i, uint64_t nblocks, uint64_t want,
                               std::string const& err) const {
    src_.fail_byte(at, what + ": zlib block " + std::to_string(i) + " of " + std::to_string(nblocks) +
                           " does not inflate to " + std::to_string(want) + " bytes (" + err + ")");
  }

  /// One PointData / CellData child: a numeric DataArray becomes an array,
  /// anything else is reported as ignored.
  void array(UnstructuredGrid& grid, pugi::xml_node a, uint64_t tuples, bool cell, CellKinds const& kinds) {
    if (a.type() != pugi::node_element) return;
    char const* where = cell ? "cell" : "point";
    std::string name = a.attribute("Name").value();
    if (name.empty()) name = std::string("unnamed_") + where + "_" + std::to_string(cell ? grid.cell_arrays.size() : grid.point_arrays.size());
    NumType t{};
    if (std::string_view(a.name()) != "DataArray" || !xml_type(a.attribute("type").value(), t)) {
      grid.report.arrays_ignored.push_back(std::string(where) + " " + in_quotes(name) + " (" + a.name() + " of type " +
                                           in_quotes(a.attribute("type").value()) + ")");
      return;
    }
    int const ncomp = components(a);
    if (a.attribute("NumberOfTuples") && count_attr(a, "NumberOfTuples") != tuples)
      src_.fail_line(offset(a), std::string(where) + " array " + in_quotes(name) + ": NumberOfTuples is not " + std::to_string(tuples));
    uint64_t count = 0;
    if (!checked_mul(tuples, uint64_t(ncomp), count)) src_.fail_line(offset(a), in_quotes(name) + ": too many values");
    NumArray data = decode(a, count, std::string(where) + " array " + in_quotes(name));
    if (cell) {
      std::vector<float> poly;
      size_t const before = grid.cell_arrays.size();
      add_cell_array(grid, name, std::move(data), ncomp, kinds, &poly, poly_spare_.tets, poly_spare_.hexes);
      if (grid.cell_arrays.size() > before) polyhedra_values_.emplace_back(name, std::move(poly));  // not a duplicate name
    } else {
      add_point_array(grid, std::move(name), std::move(data), ncomp, poly_spare_.points);
    }
  }

  /// Each polyhedron (kind 3) becomes tetrahedra and pyramids around an
  /// added centre point (io/polyhedra.hpp). plan_polyhedra runs before any
  /// cell is stored, so that their storage is reserved once; its errors are
  /// kept in `failed` and thrown by split_polyhedra, so errors come in the
  /// order they always did.
  struct VtuPolyhedra {
    NumArray faces, face_offsets;
    PolyPlan plan;            // the polyhedra in file order, up to order_error
    std::string order_error;  // a faceoffsets error after plan.polys
    std::exception_ptr failed;
  };
  VtuPolyhedra plan_;
  pugi::xml_node plan_faces_el_, plan_face_offsets_el_;
  struct Spare {
    uint64_t points = 0, tets = 0, hexes = 0;
  };
  Spare poly_spare_;  // what the polyhedra add: room reserved in the arrays read before the split

  void plan_polyhedra(NumArray const& types, pugi::xml_node faces_el, pugi::xml_node face_offsets_el, pugi::xml_node cells) {
    if (!faces_el || !face_offsets_el)
      src_.fail_line(offset(cells), "polyhedra (VTK type 42) need the DataArrays 'faces' and 'faceoffsets'");
    uint64_t const nc = types.count;
    VtuPolyhedra& p = plan_;
    p.face_offsets = decode(face_offsets_el, nc, "faceoffsets");
    NumArray const& face_offsets = p.face_offsets;
    int64_t end = 0;
    for (uint64_t c = 0; c < nc; ++c) end = std::max(end, face_offsets.as_int(c));
    p.faces = decode(faces_el, uint64_t(end), "faces");

    // Each polyhedron's face stream, in file order (cheap). A faceoffsets
    // error is kept, not thrown, so that an error in an earlier
    // polyhedron's faces is still the one reported, as in a serial walk.
    // Polyhedra are the cells of type 42 (build_cells' kind 3).
    int64_t prev_end = 0;
    for (uint64_t c = 0; c < nc; ++c) {
      int64_t const stop = face_offsets.as_int(c);
      if (types.as_int(c) != 42) {
        if (stop >= 0) prev_end = stop;
        continue;
      }
      if (stop < prev_end) {
        p.order_error = "faceoffsets: polyhedron cell " + std::to_string(c) + " ends at " + std::to_string(stop) +
                        ", before its start " + std::to_string(prev_end);
        break;
      }
      p.plan.polys.push_back({c, uint64_t(prev_end), uint64_t(stop)});
      prev_end = stop;
    }
    count_polyhedron_cells(p.faces, p.plan);
  }

  void split_polyhedra(UnstructuredGrid& grid) {
    if (plan_.failed) std::rethrow_exception(plan_.failed);
    if (PolySplitError const e = io::split_polyhedra(grid, plan_.faces, plan_.plan, polyhedra_values_)) {
      std::string const at = src_.at_line(offset(plan_faces_el_)) + "faces: ";
      if (e.too_many) throw IoError(at + "the polyhedra's centre points pass 2^32 - 1 vertices");
      throw IoError(at + "polyhedron cell " + std::to_string(plan_.plan.polys[e.at].cell) + e.what);
    }
    if (!plan_.order_error.empty()) src_.fail_line(offset(plan_face_offsets_el_), plan_.order_error);
  }
};

}  // namespace io

/// Reads a VTK XML unstructured grid held in memory; `name_for_errors`
/// starts every error message. Thread-safe (no shared state).
/// @throws IoError naming the file and the line (XML, ASCII data) or byte
///         offset (binary data) on malformed, truncated or unsupported
///         content, bad base64 or zlib data; never returns a partial grid.
inline UnstructuredGrid read_vtu_from_memory(std::string_view bytes, std::string name_for_errors,
                                             ReadOptions const& opts = {}) {
  io::Source const src{bytes, std::move(name_for_errors)};
  return io::naming_out_of_memory(src.name, [&] { return io::VtuParser(src, opts).parse(); });
}

/// Reads a VTK XML unstructured grid file (".vtu"). See UnstructuredGrid.
/// @throws IoError as read_vtu_from_memory, or when the file cannot be read.
inline UnstructuredGrid read_vtu(std::string const& path, ReadOptions const& opts = {}) {
  io::FileBytes const file(path);
  return read_vtu_from_memory(file.bytes(), path, opts);
}

}  // namespace cellray
