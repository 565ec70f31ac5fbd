#pragma once
// The VTU reader as it was on main at 234e888 (before issue #23's loader
// work), for bench_io's old-vs-new comparison only. Verbatim but for the
// namespace and the decode buffers' type, which NumArray now takes as
// LargeVector (zero-filled here, as main's std::vector was).

#include <cellray/io/vtu.hpp>

namespace cellray::io::main_234e888 {


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
      if (n >= 3 && end_ - pos_ >= 4) {
        // Fast path: four plain symbols straight to the output.
        unsigned const a = base64_table.cls[text[pos_]], b = base64_table.cls[text[pos_ + 1]],
                       c = base64_table.cls[text[pos_ + 2]], d = base64_table.cls[text[pos_ + 3]];
        if ((a | b | c | d) < 64) {
          uint32_t const bits = (a << 18) | (b << 12) | (c << 6) | d;
          out[0] = static_cast<unsigned char>(bits >> 16);
          out[1] = static_cast<unsigned char>(bits >> 8);
          out[2] = static_cast<unsigned char>(bits);
          out += 3;
          n -= 3;
          pos_ += 4;
          continue;
        }
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

// xml_type: io's (unchanged; found by ADL on NumType anyway).

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
    NumArray const xyz = decode(pts, n3, "Points");

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
    CellLocator where;
    where.conn = [&](uint64_t) { return src_.at_line(offset(conn_el)) + "connectivity: "; };
    where.type = [&](uint64_t) { return src_.at_line(offset(type_el)) + "types: "; };
    pugi::xml_node const faces_el = optional_named(cells, "faces"), face_offsets_el = optional_named(cells, "faceoffsets");
    CellKinds const kinds = build_cells(
        nc, types, conn,
        [&offsets](uint64_t c) {
          return std::pair<uint64_t, uint64_t>(c ? uint64_t(offsets.as_int(c - 1)) : 0, uint64_t(offsets.as_int(c)));
        },
        np, opts_, grid, where, /*polyhedra=*/true);
    set_positions(grid, xyz, np);

    for (pugi::xml_node a : piece.child("PointData").children()) array(grid, a, np, false, kinds);
    for (pugi::xml_node a : piece.child("CellData").children()) array(grid, a, nc, true, kinds);
    if (std::find(kinds.begin(), kinds.end(), uint8_t(3)) != kinds.end())
      split_polyhedra(grid, kinds, faces_el, face_offsets_el, cells);
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
  std::string xml_;
  bool appended_ = false, appended_base64_ = false, compressed_ = false, big_endian_ = false, swap_ = false;
  uint64_t appended_base_ = 0, appended_end_ = 0, header_size_ = 4;
  std::set<std::string> formats_;
  std::vector<std::pair<std::string, std::vector<float>>> polyhedra_values_;  // per cell array

  uint64_t offset(pugi::xml_node n) const {
    ptrdiff_t const o = n.offset_debug();
    return o < 0 ? 0 : uint64_t(o);
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
        xml_.reserve(gt + 40);
        xml_.assign(b.substr(0, gt + 1));
        xml_ += "</AppendedData></VTKFile>";
        xml = xml_;
      }
    }
    pugi::xml_parse_result const r = doc_.load_buffer(xml.data(), xml.size(), pugi::parse_default, pugi::encoding_utf8);
    if (!r) src_.fail_line(uint64_t(std::max<ptrdiff_t>(r.offset, 0)), std::string("XML error: ") + r.description());
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
      cellray::detail::LargeVector<unsigned char> out(bytes, 0);  // main zero-filled a std::vector
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
    cellray::detail::LargeVector<unsigned char> out;
    std::vector<unsigned char> tmp;
    out.reserve(size_t(std::min(total, 8 * ctotal + (uint64_t(1) << 20))));
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
      if (!err.empty())
        src_.fail_byte(here, what + ": zlib block " + std::to_string(i) + " of " + std::to_string(nblocks) +
                                 " does not inflate to " + std::to_string(want) + " bytes (" + err + ")");
    }
    return NumArray::owning_bytes(t, total / esize, std::move(out), swap_);
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
    NumArray const data = decode(a, count, std::string(where) + " array " + in_quotes(name));
    if (cell) {
      std::vector<float> poly;
      size_t const before = grid.cell_arrays.size();
      add_cell_array(grid, name, data, ncomp, kinds, &poly);
      if (grid.cell_arrays.size() > before) polyhedra_values_.emplace_back(name, std::move(poly));  // not a duplicate name
    } else {
      add_point_array(grid, std::move(name), data, ncomp);
    }
  }

  /// Each polyhedron (kind 3) becomes tetrahedra and pyramids (collapsed
  /// hexahedra) around an added centre point (mesh/vtk_cells.hpp), appended
  /// after the file's cells, as foamToVTK -poly-decomp and ParaView do. The
  /// centre is the volume centroid; its value in a point array is the
  /// polyhedron's own value when a cell array has the same name (foamToVTK:
  /// the cell's value at the cell centre), else the mean of its vertices.
  /// The new cells carry the polyhedron's cell-array values.
  void split_polyhedra(UnstructuredGrid& grid, CellKinds const& kinds, pugi::xml_node faces_el,
                       pugi::xml_node face_offsets_el, pugi::xml_node cells) {
    if (!faces_el || !face_offsets_el)
      src_.fail_line(offset(cells), "polyhedra (VTK type 42) need the DataArrays 'faces' and 'faceoffsets'");
    uint64_t const nc = kinds.size(), np = grid.vertex_count();
    NumArray const face_offsets = decode(face_offsets_el, nc, "faceoffsets");
    int64_t end = 0;
    for (uint64_t c = 0; c < nc; ++c) end = std::max(end, face_offsets.as_int(c));
    NumArray const faces = decode(faces_el, uint64_t(end), "faces");
    std::string const at = src_.at_line(offset(faces_el)) + "faces: ";
    // Each polyhedron's cell-array values, in polyhedron order.
    std::vector<std::pair<std::string, std::vector<float>>> const& cell_values = polyhedra_values_;
    std::vector<float> centre_xyz;
    std::vector<std::vector<float>> centre_values(grid.point_arrays.size());
    std::vector<CellArray*> cell_arrays;  // the array each entry of cell_values fills
    for (auto const& cv : cell_values)
      for (auto& a : grid.cell_arrays)
        if (a.name == cv.first) cell_arrays.push_back(&a);
    uint64_t k = 0;  // polyhedron index
    int64_t prev_end = 0;
    PolyhedronFaces f;
    for (uint64_t c = 0; c < nc; ++c) {
      int64_t const stop = face_offsets.as_int(c);
      if (kinds[c] != 3) {
        if (stop >= 0) prev_end = stop;
        continue;
      }
      if (stop < prev_end)
        src_.fail_line(offset(face_offsets_el), "faceoffsets: polyhedron cell " + std::to_string(c) + " ends at " +
                                                    std::to_string(stop) + ", before its start " + std::to_string(prev_end));
      // [nfaces, n0, ids..., n1, ids...] in faces[prev_end, stop)
      uint64_t i = uint64_t(prev_end);
      auto next = [&]() -> int64_t {
        if (i >= uint64_t(stop))
          throw IoError(at + "polyhedron cell " + std::to_string(c) + ": its face stream ends early");
        return faces.as_int(i++);
      };
      int64_t const nfaces = next();
      if (nfaces < 4 || nfaces > stop - prev_end)
        throw IoError(at + "polyhedron cell " + std::to_string(c) + " declares " + std::to_string(nfaces) + " faces");
      f.ids.clear();
      f.offsets.assign(1, 0);
      for (int64_t j = 0; j < nfaces; ++j) {
        int64_t const n = next();
        if (n < 3 || n > stop - int64_t(i))
          throw IoError(at + "polyhedron cell " + std::to_string(c) + ": face " + std::to_string(j) + " declares " +
                        std::to_string(n) + " vertices");
        for (int64_t q = 0; q < n; ++q) f.ids.push_back(uint64_t(next()));  // negative: huge, caught below
        f.offsets.push_back(f.ids.size());
      }
      if (std::string const bad = check_polyhedron(f, np); !bad.empty())
        throw IoError(at + "polyhedron cell " + std::to_string(c) + " " + bad);
      uint64_t const centre = np + k;
      if (centre > std::numeric_limits<uint32_t>::max())
        throw IoError(at + "the polyhedra's centre points pass 2^32 - 1 vertices");
      PolyhedronSplit const split = decompose_polyhedron(f, grid.xyz.data(), centre);
      for (int a = 0; a < 3; ++a) centre_xyz.push_back(float(split.centre[a]));
      std::vector<uint64_t> verts(f.ids);
      std::sort(verts.begin(), verts.end());
      verts.erase(std::unique(verts.begin(), verts.end()), verts.end());
      for (size_t a = 0; a < grid.point_arrays.size(); ++a) {
        PointArray const& pa = grid.point_arrays[a];
        float value = 0;
        bool from_cell = false;
        for (auto const& [name, values] : cell_values)
          if (name == pa.name) value = values[k], from_cell = true;
        if (!from_cell) {
          double sum = 0;
          for (uint64_t v : verts) sum += pa.values[v];
          value = float(sum / double(verts.size()));
        }
        centre_values[a].push_back(value);
      }
      for (auto const& t : split.tets)
        for (uint64_t v : t) grid.tets.push_back(uint32_t(v));
      for (auto const& h : split.hexes)
        for (uint64_t v : h) grid.hexes.push_back(uint32_t(v));
      for (size_t a = 0; a < cell_arrays.size(); ++a) {
        float const v = cell_values[a].second[k];
        cell_arrays[a]->tet_values.insert(cell_arrays[a]->tet_values.end(), split.tets.size(), v);
        cell_arrays[a]->hex_values.insert(cell_arrays[a]->hex_values.end(), split.hexes.size(), v);
      }
      grid.report.polyhedron_tets += split.tets.size();
      grid.report.polyhedron_pyramids += split.hexes.size();
      ++k;
      prev_end = stop;
    }
    grid.report.polyhedra_split = k;
    grid.xyz.insert(grid.xyz.end(), centre_xyz.begin(), centre_xyz.end());
    for (size_t a = 0; a < grid.point_arrays.size(); ++a)
      grid.point_arrays[a].values.insert(grid.point_arrays[a].values.end(), centre_values[a].begin(),
                                         centre_values[a].end());
  }
};


/// read_vtu as on main.
inline UnstructuredGrid read_vtu(std::string const& path, ReadOptions const& opts = {}) {
  FileBytes const file(path);
  Source const src{file.bytes(), path};
  return VtuParser(src, opts).parse();
}

}  // namespace cellray::io::main_234e888
