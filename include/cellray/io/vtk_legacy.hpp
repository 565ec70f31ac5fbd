#pragma once
// Legacy VTK reader (".vtk", DATASET UNSTRUCTURED_GRID), versions 1.0 to 5.1,
// ASCII and BINARY (big-endian): the classic CELLS layout and the 5.1
// OFFSETS/CONNECTIVITY layout, CELL_TYPES, POINT_DATA / CELL_DATA with
// SCALARS, VECTORS, TENSORS and FIELD blocks; METADATA blocks, lookup tables,
// normals, texture coordinates, ids and string arrays are skipped and reported.
// Polyhedra (VTK 42) are read as VTK 9.1 writes them, their face stream
// [nFaces, nPts0, ids..., nPts1, ids...] as the cell's connectivity in either
// layout, and split as the VTU reader splits them (io/polyhedra.hpp).

#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <tbb/task_group.h>

#include "detail.hpp"
#include "grid.hpp"
#include "polyhedra.hpp"

namespace cellray {
namespace io {

/// Legacy type names (case-insensitive) to element types. `is_string` for
/// string arrays (skipped); false return for unknown names.
inline bool legacy_type(std::string_view tok, NumType& t, bool& is_string) {
  is_string = false;
  struct Name {
    char const* name;
    NumType type;
  };
  static constexpr Name names[] = {
      {"bit", NumType::bit},           {"unsigned_char", NumType::u8},    {"char", NumType::i8},
      {"signed_char", NumType::i8},    {"unsigned_short", NumType::u16},  {"short", NumType::i16},
      {"unsigned_int", NumType::u32},  {"int", NumType::i32},             {"vtkidtype", NumType::i32},
      {"unsigned_long", NumType::u64}, {"long", NumType::i64},            {"unsigned_long_long", NumType::u64},
      {"long_long", NumType::i64},     {"float", NumType::f32},           {"double", NumType::f64},
      {"vtktypeint8", NumType::i8},    {"vtktypeuint8", NumType::u8},     {"vtktypeint16", NumType::i16},
      {"vtktypeuint16", NumType::u16}, {"vtktypeint32", NumType::i32},    {"vtktypeuint32", NumType::u32},
      {"vtktypeint64", NumType::i64},  {"vtktypeuint64", NumType::u64},   {"vtktypefloat32", NumType::f32},
      {"vtktypefloat64", NumType::f64}};
  for (auto const& n : names)
    if (iequals(tok, n.name)) {
      t = n.type;
      return true;
    }
  if (iequals(tok, "string") || iequals(tok, "utf8_string")) {
    is_string = true;
    return true;
  }
  return false;
}

/// VTK writes spaces and other specials in names as %XX.
inline std::string decode_vtk_name(std::string_view s) {
  auto hex = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    c = ascii_lower(c);
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    return -1;
  };
  std::string out;
  out.reserve(s.size());
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '%' && i + 2 < s.size() && hex(s[i + 1]) >= 0 && hex(s[i + 2]) >= 0) {
      out += char(hex(s[i + 1]) * 16 + hex(s[i + 2]));
      i += 2;
    } else {
      out += s[i];
    }
  }
  return out;
}

/// Parser state for one legacy file. Internal: use read_vtk_legacy*().
class LegacyParser {
 public:
  LegacyParser(Source const& src, ReadOptions const& opts) : src_(src), opts_(opts) {}

  UnstructuredGrid parse() {
    header();
    for (;;) {
      std::string_view const tok = next_token();
      if (tok.empty()) break;
      uint64_t const at = tok_pos_;
      if (iequals(tok, "POINTS")) points(at);
      else if (iequals(tok, "CELLS")) cells(at);
      else if (iequals(tok, "CELL_TYPES")) cell_types(at);
      else if (iequals(tok, "POINT_DATA") || iequals(tok, "CELL_DATA")) section(tok, at);
      else if (iequals(tok, "FIELD")) field();
      else if (iequals(tok, "METADATA")) skip_metadata();
      else if (attribute(tok, at)) continue;
      else src_.fail_line(at, "unknown keyword " + in_quotes(tok));
    }
    return finish();
  }

 private:
  enum class Section { none, point, cell };
  struct Pending {
    std::string name;
    NumArray data;
    int ncomp = 1;
    bool cell = false;
  };
  /// Where an array's values start, to point errors at value k later.
  struct Located {
    NumArray data;
    uint64_t start = 0;  ///< byte offset of the first value (binary) or of the text after the header (ASCII)
    uint64_t header = 0;
  };

  Source const& src_;
  ReadOptions opts_;
  uint64_t pos_ = 0, tok_pos_ = 0;
  bool binary_ = false;
  std::string version_;

  bool have_points_ = false, have_cells_ = false, have_types_ = false, new_layout_ = false;
  uint64_t npoints_ = 0, ncells_ = 0, points_at_ = 0;
  Located points_, cells_, offsets_, types_;
  Section section_ = Section::none;
  uint64_t point_data_n_ = 0, cell_data_n_ = 0, point_data_at_ = 0, cell_data_at_ = 0;
  bool have_point_data_ = false, have_cell_data_ = false;
  std::vector<Pending> pending_;
  std::vector<std::string> ignored_;

  uint64_t size() const { return src_.bytes.size(); }
  char at(uint64_t i) const { return src_.bytes[i]; }

  std::string_view next_token() {
    while (pos_ < size() && is_space(at(pos_))) ++pos_;
    tok_pos_ = pos_;
    while (pos_ < size() && !is_space(at(pos_))) ++pos_;
    return src_.bytes.substr(tok_pos_, pos_ - tok_pos_);
  }
  std::string_view peek_token() {
    uint64_t const p = pos_, t = tok_pos_;
    std::string_view const tok = next_token();
    pos_ = p;
    tok_pos_ = t;
    return tok;
  }
  std::string_view expect_token(std::string const& what) {
    std::string_view const tok = next_token();
    if (tok.empty()) src_.fail_line(size(), "the file ends where " + what + " was expected");
    return tok;
  }
  uint64_t expect_count(std::string const& what) {
    std::string_view const tok = expect_token(what);
    uint64_t n = 0;
    if (!parse_count(tok, n)) src_.fail_line(tok_pos_, what + " is " + in_quotes(tok) + ", not a count");
    return n;
  }
  void skip_line() {
    while (pos_ < size() && at(pos_) != '\n') ++pos_;
    if (pos_ < size()) ++pos_;
  }
  std::string_view rest_of_line() {
    uint64_t const b = pos_;
    skip_line();
    std::string_view s = src_.bytes.substr(b, pos_ - b);
    while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
    return s;
  }

  void header() {
    std::string_view const first = rest_of_line();
    constexpr std::string_view magic = "# vtk DataFile Version";
    if (first.size() < magic.size() || !iequals(first.substr(0, magic.size()), magic))
      src_.fail_line(0, "not a legacy VTK file (the first line must be '# vtk DataFile Version x.y')");
    std::string_view v = first.substr(magic.size());
    while (!v.empty() && is_space(v.front())) v.remove_prefix(1);
    version_ = std::string(v.substr(0, 16));
    skip_line();  // title
    std::string_view const enc = next_token();
    if (iequals(enc, "BINARY")) binary_ = true;
    else if (!iequals(enc, "ASCII")) src_.fail_line(tok_pos_, "expected ASCII or BINARY, found " + in_quotes(enc));
    std::string_view const ds = next_token();
    if (!iequals(ds, "DATASET")) src_.fail_line(tok_pos_, "expected DATASET, found " + in_quotes(ds));
    std::string_view const kind = next_token();
    if (!iequals(kind, "UNSTRUCTURED_GRID"))
      src_.fail_line(tok_pos_, "dataset type " + in_quotes(kind) + " is not supported (cellray reads UNSTRUCTURED_GRID)");
  }

  /// The values of an array whose header ends the current line. Binary data
  /// starts after that line's newline (as vtkDataReader reads it); ASCII data
  /// are the next `count` tokens.
  Located read_values(NumType type, uint64_t count, std::string const& what, bool ids) {
    Located r;
    r.header = tok_pos_;
    if (binary_) {
      skip_line();
      r.start = pos_;
      uint64_t const need = bytes_for(type, count);
      if (need > size() - pos_)
        src_.fail_byte(pos_, what + ": " + std::to_string(count) + " values need " + std::to_string(need) +
                                 " bytes but only " + std::to_string(size() - pos_) + " are left");
      // Legacy binary is big-endian; the host is little-endian unless told otherwise.
      r.data = NumArray::viewing(type, count, reinterpret_cast<unsigned char const*>(src_.bytes.data()) + pos_,
                                 host_is_little());
      pos_ += need;
    } else {
      r.start = pos_;
      if (ids || type == NumType::bit) r.data = NumArray::owning(parse_ascii_numbers<int64_t>(src_, pos_, count, what));
      else r.data = NumArray::owning(parse_ascii_numbers<double>(src_, pos_, count, what));
    }
    return r;
  }
  static bool host_is_little() {
    uint16_t const one = 1;
    unsigned char b;
    std::memcpy(&b, &one, 1);
    return b == 1;
  }

  NumType parse_type(std::string_view tok, std::string const& what, bool& is_string) {
    NumType t{};
    if (!legacy_type(tok, t, is_string)) {
      if (iequals(tok, "variant")) src_.fail_line(tok_pos_, what + ": variant arrays are not supported");
      src_.fail_line(tok_pos_, what + ": unknown data type " + in_quotes(tok));
    }
    return t;
  }
  NumType parse_numeric_type(std::string_view tok, std::string const& what) {
    bool is_string = false;
    NumType const t = parse_type(tok, what, is_string);
    if (is_string) src_.fail_line(tok_pos_, what + " cannot be a string array");
    return t;
  }

  /// Skips `count` strings (binary: VTK's length-prefixed form; ASCII: one per line).
  void skip_strings(uint64_t count, std::string const& what) {
    skip_line();
    if (count > size() - pos_)
      src_.fail_line(pos_, what + ": " + std::to_string(count) + " strings declared but only " +
                               std::to_string(size() - pos_) + " bytes are left");
    for (uint64_t i = 0; i < count; ++i) {
      if (pos_ >= size()) src_.fail_line(pos_, what + ": the file ends after " + std::to_string(i) + " strings");
      if (!binary_) {
        skip_line();
        continue;
      }
      unsigned char const first = static_cast<unsigned char>(at(pos_));
      int const kind = first >> 6;
      uint64_t const hdr = kind == 3 ? 1 : kind == 2 ? 2 : kind == 1 ? 4 : 8;
      if (hdr > size() - pos_) src_.fail_byte(pos_, what + ": truncated string length");
      uint64_t len = 0;
      for (uint64_t k = 0; k < hdr; ++k) len = (len << 8) | static_cast<unsigned char>(at(pos_ + k));
      if (kind != 0) len &= (uint64_t(1) << (8 * hdr - 2)) - 1;
      pos_ += hdr;
      if (len > size() - pos_) src_.fail_byte(pos_, what + ": a string of " + std::to_string(len) + " bytes runs past the end");
      pos_ += len;
    }
  }

  /// Reads `count` values of type token `type_tok`; false (values skipped) for strings.
  bool read_any(std::string_view type_tok, uint64_t count, std::string const& what, Located& out) {
    bool is_string = false;
    NumType const t = parse_type(type_tok, what, is_string);
    if (is_string) {
      skip_strings(count, what);
      return false;
    }
    out = read_values(t, count, what, false);
    return true;
  }

  void points(uint64_t at) {
    if (have_points_) src_.fail_line(at, "a second POINTS section");
    npoints_ = expect_count("the POINTS count");
    if (!point_count_fits(npoints_))
      src_.fail_line(at, std::to_string(npoints_) + " points: cellray uses 32-bit vertex ids (at most 4294967295 points)");
    NumType const t = parse_numeric_type(expect_token("the POINTS type"), "POINTS");
    points_at_ = at;
    points_ = read_values(t, 3 * npoints_, "POINTS", false);
    have_points_ = true;
  }

  void cells(uint64_t at) {
    if (have_cells_) src_.fail_line(at, "a second CELLS section");
    uint64_t const a = expect_count("the CELLS cell count");
    uint64_t const b = expect_count("the CELLS size");
    if (iequals(peek_token(), "OFFSETS")) {
      // 5.x: CELLS <offsets count> <connectivity count>, then two typed arrays.
      new_layout_ = true;
      next_token();
      NumType const to = parse_numeric_type(expect_token("the OFFSETS type"), "OFFSETS");
      if (!is_integer(to)) src_.fail_line(tok_pos_, "OFFSETS must have an integer type");
      offsets_ = read_values(to, a, "OFFSETS", true);
      std::string_view const k = expect_token("CONNECTIVITY");
      if (!iequals(k, "CONNECTIVITY")) src_.fail_line(tok_pos_, "expected CONNECTIVITY after OFFSETS, found " + in_quotes(k));
      NumType const tc = parse_numeric_type(expect_token("the CONNECTIVITY type"), "CONNECTIVITY");
      if (!is_integer(tc)) src_.fail_line(tok_pos_, "CONNECTIVITY must have an integer type");
      cells_ = read_values(tc, b, "CONNECTIVITY", true);
      ncells_ = a == 0 ? 0 : a - 1;
      check_offsets();
    } else {
      if (a > b) src_.fail_line(at, "CELLS declares " + std::to_string(a) + " cells in a list of only " + std::to_string(b) + " entries");
      ncells_ = a;
      cells_ = read_values(NumType::i32, b, "CELLS", true);
      classic_starts();
    }
    have_cells_ = true;
  }

  /// Error prefix for value k of a located array.
  std::string where_value(Located const& l, uint64_t k) const {
    if (binary_) return src_.at_byte(l.start + bytes_for(l.data.type, k));
    // ASCII: walk the tokens again (only when reporting an error).
    uint64_t p = l.start;
    for (uint64_t i = 0;; ++i) {
      while (p < size() && is_space(at(p))) ++p;
      if (i == k || p >= size()) break;
      while (p < size() && !is_space(at(p))) ++p;
    }
    return src_.at_line(p);
  }

  void check_offsets() {
    NumArray const& o = offsets_.data;
    if (!is_integer(o.type)) src_.fail_line(offsets_.header, "OFFSETS must be integers");
    if (o.count == 0) {
      if (cells_.data.count != 0) src_.fail_line(offsets_.header, "CONNECTIVITY has entries but there are no OFFSETS");
      return;
    }
    if (o.as_int(0) != 0) throw IoError(where_value(offsets_, 0) + "the first offset is " + std::to_string(o.as_int(0)) + ", not 0");
    for (uint64_t c = 1; c < o.count; ++c)
      if (o.as_int(c) < o.as_int(c - 1))
        throw IoError(where_value(offsets_, c) + "offset " + std::to_string(c) + " (" + std::to_string(o.as_int(c)) +
                      ") is smaller than the one before");
    if (uint64_t(o.as_int(o.count - 1)) != cells_.data.count)
      throw IoError(where_value(offsets_, o.count - 1) + "the last offset is " + std::to_string(o.as_int(o.count - 1)) +
                    " but CONNECTIVITY has " + std::to_string(cells_.data.count) + " entries");
  }

  /// Classic layout: checks that the `ncells_` counts and their ids fill the
  /// list exactly. Cells are found again by walking the counts (ClassicSpans),
  /// not from a stored index: 8 bytes per cell of fresh memory cost more than
  /// the walk (PROFILE.md, first-touch pages).
  void classic_starts() {
    NumArray const& d = cells_.data;
    uint64_t k = 0;
    with_ints(d, [&](auto const get) {
      for (uint64_t c = 0; c < ncells_; ++c) {
        if (k >= d.count)
          throw IoError(where_value(cells_, k) + "CELLS: the list of " + std::to_string(d.count) + " entries ends after " +
                        std::to_string(c) + " of " + std::to_string(ncells_) + " cells");
        int64_t const n = get(k);
        if (n < 0 || uint64_t(n) > d.count - k - 1)
          throw IoError(where_value(cells_, k) + "CELLS: cell " + std::to_string(c) + " claims " + std::to_string(n) +
                        " vertices, more than the " + std::to_string(d.count - k - 1) + " entries left");
        k += uint64_t(n) + 1;
      }
    });
    if (k != d.count)
      src_.fail_line(cells_.header, "CELLS declares " + std::to_string(d.count) + " entries but its " +
                                        std::to_string(ncells_) + " cells use " + std::to_string(k));
  }
  /// span(c) of the classic layout for c rising (as build_cells asks), from
  /// the last cell found; going back restarts at cell 0. Checked by classic_starts().
  struct ClassicSpans {
    NumArray const* d;
    uint64_t cell = 0, k = 0;
    std::pair<uint64_t, uint64_t> operator()(uint64_t c) {
      if (c < cell) cell = k = 0;
      for (; cell < c; ++cell) k += uint64_t(count(k)) + 1;
      return {k + 1, k + 1 + uint64_t(count(k))};
    }
    int64_t count(uint64_t i) const {
      if (d->type != NumType::i32) return d->as_int(i);  // ASCII: int64
      return d->swap ? load_at<int32_t, true>(d->data, i) : load_at<int32_t, false>(d->data, i);
    }
  };

  void cell_types(uint64_t at) {
    if (have_types_) src_.fail_line(at, "a second CELL_TYPES section");
    uint64_t const n = expect_count("the CELL_TYPES count");
    types_ = read_values(NumType::i32, n, "CELL_TYPES", true);
    have_types_ = true;
  }

  void section(std::string_view tok, uint64_t at) {
    bool const cell = iequals(tok, "CELL_DATA");
    uint64_t const n = expect_count(std::string(tok) + " count");
    // Checked here, not only at the end: a short count would otherwise send
    // the parser into the rest of the values as if they were keywords.
    if (cell && have_cells_ && n != ncells_)
      src_.fail_line(at, "CELL_DATA declares " + std::to_string(n) + " values for " + std::to_string(ncells_) + " cells");
    if (!cell && have_points_ && n != npoints_)
      src_.fail_line(at, "POINT_DATA declares " + std::to_string(n) + " values for " + std::to_string(npoints_) + " points");
    if (cell) {
      if (have_cell_data_) src_.fail_line(at, "a second CELL_DATA section");
      have_cell_data_ = true;
      cell_data_n_ = n;
      cell_data_at_ = at;
      section_ = Section::cell;
    } else {
      if (have_point_data_) src_.fail_line(at, "a second POINT_DATA section");
      have_point_data_ = true;
      point_data_n_ = n;
      point_data_at_ = at;
      section_ = Section::point;
    }
  }
  uint64_t section_n() const { return section_ == Section::cell ? cell_data_n_ : point_data_n_; }
  char const* section_name() const { return section_ == Section::cell ? "cell" : "point"; }

  void keep(std::string name, Located&& l, int ncomp) {
    Pending p;
    p.name = std::move(name);
    p.data = std::move(l.data);
    p.ncomp = ncomp;
    p.cell = section_ == Section::cell;
    pending_.push_back(std::move(p));
  }
  void ignore(std::string what) { ignored_.push_back(std::move(what)); }

  /// Attribute blocks inside POINT_DATA / CELL_DATA. False for other keywords.
  bool attribute(std::string_view tok, uint64_t at) {
    static constexpr char const* known[] = {"SCALARS", "VECTORS", "NORMALS", "TENSORS", "TENSORS6", "TEXTURE_COORDINATES",
                                            "COLOR_SCALARS", "LOOKUP_TABLE", "GLOBAL_IDS", "PEDIGREE_IDS"};
    bool is_attr = false;
    for (char const* k : known) is_attr |= iequals(tok, k);
    if (!is_attr) return false;
    if (section_ == Section::none) src_.fail_line(at, std::string(tok) + " outside POINT_DATA / CELL_DATA");
    uint64_t const n = section_n();
    std::string const name = decode_vtk_name(expect_token(std::string(tok) + " name"));
    std::string const what = std::string(tok) + " " + in_quotes(name);
    if (iequals(tok, "SCALARS")) {
      NumType const t = parse_numeric_type(expect_token(what + " type"), what);
      std::string_view key = expect_token("LOOKUP_TABLE");
      uint64_t ncomp = 1;
      if (!iequals(key, "LOOKUP_TABLE")) {
        if (!parse_count(key, ncomp) || ncomp < 1 || ncomp > 4)
          src_.fail_line(tok_pos_, what + ": expected a component count (1 to 4) or LOOKUP_TABLE, found " + in_quotes(key));
        key = expect_token("LOOKUP_TABLE");
        if (!iequals(key, "LOOKUP_TABLE")) src_.fail_line(tok_pos_, what + ": expected LOOKUP_TABLE, found " + in_quotes(key));
      }
      expect_token("the lookup table name");
      uint64_t count = 0;
      if (!checked_mul(n, ncomp, count)) src_.fail_line(at, what + ": too many values");
      keep(name, read_values(t, count, what, false), int(ncomp));
      return true;
    }
    if (iequals(tok, "COLOR_SCALARS") || iequals(tok, "LOOKUP_TABLE")) {
      // COLOR_SCALARS name nValues / LOOKUP_TABLE name size: unsigned bytes in
      // binary files, floats in [0,1] in ASCII ones.
      uint64_t const m = expect_count(what + " size");
      uint64_t count = 0;
      if (!checked_mul(iequals(tok, "LOOKUP_TABLE") ? 4 : n, m, count)) src_.fail_line(at, what + ": too many values");
      read_values(binary_ ? NumType::u8 : NumType::f64, count, what, false);
      ignore(std::string(section_name()) + " " + what + " (colours)");
      return true;
    }
    uint64_t ncomp = 3;
    if (iequals(tok, "TENSORS")) ncomp = 9;
    else if (iequals(tok, "TENSORS6")) ncomp = 6;
    else if (iequals(tok, "GLOBAL_IDS") || iequals(tok, "PEDIGREE_IDS")) ncomp = 1;
    else if (iequals(tok, "TEXTURE_COORDINATES")) {
      ncomp = expect_count(what + " dimension");
      if (ncomp < 1 || ncomp > 3) src_.fail_line(tok_pos_, what + ": dimension must be 1 to 3");
    }
    uint64_t count = 0;
    if (!checked_mul(n, ncomp, count)) src_.fail_line(at, what + ": too many values");
    Located l;
    if (!read_any(expect_token(what + " type"), count, what, l)) {
      ignore(std::string(section_name()) + " " + what + " (strings)");
      return true;
    }
    if (iequals(tok, "VECTORS") || iequals(tok, "TENSORS") || iequals(tok, "TENSORS6")) keep(name, std::move(l), int(ncomp));
    else ignore(std::string(section_name()) + " " + what + " (not a scalar field)");
    return true;
  }

  /// FIELD name n, then n arrays "name ncomp ntuples type" (or NULL_ARRAY).
  void field() {
    std::string const fname = decode_vtk_name(expect_token("the FIELD name"));
    uint64_t const narrays = expect_count("the FIELD array count");
    for (uint64_t i = 0; i < narrays; ++i) {
      std::string_view const tok = expect_token("FIELD " + in_quotes(fname) + " array " + std::to_string(i));
      if (iequals(tok, "NULL_ARRAY")) continue;
      std::string const name = decode_vtk_name(tok);
      std::string const what = "FIELD array " + in_quotes(name);
      uint64_t const ncomp = expect_count(what + " component count");
      uint64_t const header = tok_pos_;
      uint64_t const ntuples = expect_count(what + " tuple count");
      uint64_t count = 0;
      if (!checked_mul(ncomp, ntuples, count)) src_.fail_line(header, what + ": too many values");
      if (ncomp > 1024) src_.fail_line(header, what + ": " + std::to_string(ncomp) + " components");
      Located l;
      bool const numeric = read_any(expect_token(what + " type"), count, what, l);
      if (section_ == Section::none) {
        ignore("field " + in_quotes(name) + " (dataset field data)");
      } else if (ntuples != section_n()) {
        src_.fail_line(header, what + " has " + std::to_string(ntuples) + " tuples but " +
                                   (section_ == Section::cell ? "CELL_DATA" : "POINT_DATA") + " declares " +
                                   std::to_string(section_n()));
      } else if (!numeric) {
        ignore(std::string(section_name()) + " " + in_quotes(name) + " (strings)");
      } else if (ncomp == 0) {
        ignore(std::string(section_name()) + " " + in_quotes(name) + " (no components)");
      } else {
        keep(name, std::move(l), int(ncomp));
      }
      if (iequals(peek_token(), "METADATA")) {
        next_token();
        skip_metadata();
      }
    }
  }

  /// METADATA ends at the first empty line (vtkDataReader does the same).
  void skip_metadata() {
    skip_line();
    while (pos_ < size()) {
      std::string_view const line = rest_of_line();
      bool blank = true;
      for (char c : line) blank &= is_space(c);
      if (blank) break;
    }
  }

  /// The polyhedra (VTK 42) among the cells, each with its face stream's
  /// range in the connectivity, and where their new cells go; reserves the
  /// grid's storage for the file's cells and theirs. The ranges were
  /// checked by cells() (check_offsets, classic_starts).
  void plan_polyhedra(UnstructuredGrid& grid, PolyPlan& poly) {
    FileCellCounts const file = count_file_cells(types_.data);
    if (!file.polyhedra) return;
    NumArray const& t = types_.data;
    if (new_layout_) {
      NumArray const& o = offsets_.data;
      for (uint64_t c = 0; c < ncells_; ++c)
        if (t.as_int(c) == vtk_polyhedron) poly.polys.push_back({c, uint64_t(o.as_int(c)), uint64_t(o.as_int(c + 1))});
    } else {
      ClassicSpans span{&cells_.data};
      for (uint64_t c = 0; c < ncells_; ++c)
        if (t.as_int(c) == vtk_polyhedron) {
          auto const [b, e] = span(c);
          poly.polys.push_back({c, b, e});
        }
    }
    count_polyhedron_cells(cells_.data, poly);
    grid.tets.reserve(4 * (file.tets + poly.new_tets()));
    grid.hexes.reserve(8 * (file.hexes + poly.new_hexes()));
    grid.xyz.reserve(3 * (npoints_ + poly.polys.size()));
  }

  /// Splits the planned polyhedra (io/polyhedra.hpp); an error names the
  /// cell and the start of its face stream in the file.
  void split_polyhedra(UnstructuredGrid& grid, PolyPlan const& poly, PolyhedraValues const& values) {
    PolySplitError const e = io::split_polyhedra(grid, cells_.data, poly, values, /*whole=*/true);
    if (!e) return;
    char const* const list = new_layout_ ? "CONNECTIVITY: " : "CELLS: ";
    if (e.too_many) src_.fail_line(cells_.header, std::string(list) + "the polyhedra's centre points pass 2^32 - 1 vertices");
    PolyRange const& p = poly.polys[e.at];
    throw IoError(where_value(cells_, p.begin) + list + "polyhedron cell " + std::to_string(p.cell) + e.what);
  }

  UnstructuredGrid finish() {
    UnstructuredGrid grid;
    grid.report.file = src_.name;
    grid.report.format = "legacy VTK " + version_ + (binary_ ? " BINARY" : " ASCII");
    if (!have_points_) src_.fail_line(size(), "no POINTS section");
    if (!have_cells_) src_.fail_line(size(), "no CELLS section");
    if (!have_types_) src_.fail_line(size(), "no CELL_TYPES section");
    if (types_.data.count != ncells_)
      src_.fail_line(types_.header, "CELL_TYPES lists " + std::to_string(types_.data.count) + " cells but CELLS has " +
                                        std::to_string(ncells_));
    if (have_point_data_ && point_data_n_ != npoints_)
      src_.fail_line(point_data_at_, "POINT_DATA declares " + std::to_string(point_data_n_) + " values for " +
                                         std::to_string(npoints_) + " points");
    if (have_cell_data_ && cell_data_n_ != ncells_)
      src_.fail_line(cell_data_at_, "CELL_DATA declares " + std::to_string(cell_data_n_) + " values for " +
                                        std::to_string(ncells_) + " cells");
    CellLocator where;
    where.conn = [this](uint64_t k) { return where_value(cells_, k); };
    where.type = [this](uint64_t c) { return where_value(types_, c); };
    // Polyhedra: planned before any cell is stored, so that the cells',
    // positions' and point arrays' storage is reserved once for the file's
    // and the split's (io/polyhedra.hpp).
    PolyPlan poly;
    plan_polyhedra(grid, poly);
    uint64_t const npoly = poly.polys.size();
    // Points and point arrays need nothing from the cells: they are converted
    // in a task while the cells are checked (a serial walk), so their fresh
    // pages are first written on the other core.
    std::vector<std::vector<float>> point_values(pending_.size());
    auto convert_points = [&] {
      set_positions(grid, points_.data, npoints_);
      for (size_t i = 0; i < pending_.size(); ++i)
        if (!pending_[i].cell) point_values[i] = io::point_values(pending_[i].data, pending_[i].ncomp, npoints_, npoly);
    };
    tbb::task_group points_task;
    bool const small = 3 * npoints_ <= convert_grain && ncells_ <= cell_grain;  // not worth waking the thread pool
    if (small) convert_points();
    else points_task.run(convert_points);
    CellKinds kinds;
    try {
      if (new_layout_) {
        NumArray const& o = offsets_.data;
        kinds = build_cells(
            ncells_, types_.data, cells_.data,
            [&o](uint64_t c) { return std::pair<uint64_t, uint64_t>(uint64_t(o.as_int(c)), uint64_t(o.as_int(c + 1))); },
            npoints_, opts_, grid, where, /*polyhedra=*/true);
      } else {
        kinds = build_cells(ncells_, types_.data, cells_.data, ClassicSpans{&cells_.data}, npoints_, opts_, grid, where,
                            /*polyhedra=*/true);
      }
    } catch (...) {
      points_task.wait();
      throw;
    }
    points_task.wait();
    PolyhedraValues poly_values;  // per cell array, its polyhedra's values
    for (size_t i = 0; i < pending_.size(); ++i) {
      Pending& p = pending_[i];
      if (p.cell) {
        std::vector<float> values;
        size_t const before = grid.cell_arrays.size();
        add_cell_array(grid, p.name, p.data, p.ncomp, kinds, npoly ? &values : nullptr, poly.new_tets(), poly.new_hexes());
        if (npoly && grid.cell_arrays.size() > before) poly_values.emplace_back(std::move(p.name), std::move(values));
      } else {
        add_point_array(grid, std::move(p.name), std::move(point_values[i]), p.ncomp);
      }
    }
    if (npoly) split_polyhedra(grid, poly, poly_values);
    for (auto& s : ignored_) grid.report.arrays_ignored.push_back(std::move(s));
    return grid;
  }
};

}  // namespace io

/// Reads a legacy VTK unstructured grid held in memory; `name_for_errors`
/// starts every error message. Thread-safe (no shared state).
/// @throws IoError naming the file and line (text) or byte offset (binary
///         data) on any malformed, truncated or unsupported content; no
///         partial grid is ever returned.
inline UnstructuredGrid read_vtk_legacy_from_memory(std::string_view bytes, std::string name_for_errors,
                                                    ReadOptions const& opts = {}) {
  io::Source const src{bytes, std::move(name_for_errors)};
  return io::naming_out_of_memory(src.name, [&] { return io::LegacyParser(src, opts).parse(); });
}

/// Reads a legacy VTK (".vtk") unstructured grid file, versions 1.0 to 5.1,
/// ASCII or BINARY. See UnstructuredGrid for what is kept.
/// @throws IoError as read_vtk_legacy_from_memory, or when the file cannot be read.
inline UnstructuredGrid read_vtk_legacy(std::string const& path, ReadOptions const& opts = {}) {
  io::FileBytes const file(path);
  return read_vtk_legacy_from_memory(file.bytes(), path, opts);
}

}  // namespace cellray
