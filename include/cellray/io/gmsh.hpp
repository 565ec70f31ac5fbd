#pragma once
// read_gmsh(path): gmsh's MSH format, versions 2.2 (2.0 and 2.1 read alike),
// 4.0 and 4.1, ASCII and binary (2.2 and 4.1) -- what `gmsh -3` writes by
// default, what `gmsh -3 -bin` or Mesh.Binary = 1 writes, and what
// gmshToFoam needs.
//
// Kept: the volume elements (tetrahedra, hexahedra, prisms and pyramids,
// higher-order ones as their corner cells) under VTK's node order (a gmsh
// prism's triangles run the other way round from a VTK wedge's: 0 2 1 3 5 4,
// as gmsh's own VTK export writes them), the nodes they may use, every
// $NodeData view as a point array (its first time step; others are listed as
// ignored) and every $ElementData view as a cell array. MSH 2.2's tags give
// the cell arrays "gmsh:physical" and "gmsh:geometrical", MSH 4's entity
// tags "gmsh:geometrical", as meshio names them. Points, lines, triangles and
// quadrangles (boundary and embedded elements) are not cells: counted and
// listed in the report as ignored.
//
// Binary files (gmsh reference manual, "MSH file format" and its MSH 2.2
// legacy section): the $MeshFormat line says "1 8" (binary, 8-byte doubles)
// and is followed by the int 1 in the writer's byte order -- read either way
// round, the other order byte-swapped. MSH 2.2: the $Nodes and $Elements
// counts are text lines, then per node an int tag and 3 doubles; elements
// come in groups, a header of 3 ints (type, elements following, tag count)
// then per element ints (number, tags, nodes). MSH 4.1: $Entities, $Nodes
// and $Elements are binary throughout, counts and node / element tags as
// 8-byte size_t, entity dimension, tag, type and parametric flag as int.
// $NodeData / $ElementData keep their string, real and integer tags as text
// lines, then per node or element an int tag and its doubles. Binary records
// are decoded into the same calls the ASCII text makes, so both forms of one
// mesh give the same grid; every count is checked against the bytes left
// before anything is allocated. Other binary sections ($Periodic,
// $PartitionedEntities...) are skipped up to their $End line. MSH 4.0
// (which gmsh 4.8 still writes with -format msh40, ASCII only) differs from
// 4.1 only in its $Nodes and $Elements headers and in keeping a node's
// coordinates on its tag's line; 4.0 binary is an error.

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "detail.hpp"

namespace cellray {
namespace io {

/// How a gmsh element type is read: VTK's linear cell type (0: not a volume
/// cell), the corner count, the node count (a binary element's record
/// size), and gmsh's name for it.
struct GmshElement {
  int vtk = 0;
  int corners = 0;
  bool higher_order = false;
  char const* name = "";
  int nodes = 0;
};

/// The gmsh element types cellray knows (gmsh's GmshDefines.h numbering,
/// node counts from the reference manual's element type list).
/// Returns false for a type it does not.
inline bool gmsh_element(int64_t type, GmshElement& e) {
  switch (type) {
    case 4: e = {10, 4, false, "4-node tetrahedron", 4}; return true;
    case 5: e = {12, 8, false, "8-node hexahedron", 8}; return true;
    case 6: e = {13, 6, false, "6-node prism", 6}; return true;
    case 7: e = {14, 5, false, "5-node pyramid", 5}; return true;
    case 11: e = {10, 4, true, "10-node tetrahedron", 10}; return true;
    case 29: e = {10, 4, true, "20-node tetrahedron", 20}; return true;
    case 30: e = {10, 4, true, "35-node tetrahedron", 35}; return true;
    case 31: e = {10, 4, true, "56-node tetrahedron", 56}; return true;
    case 12: e = {12, 8, true, "27-node hexahedron", 27}; return true;
    case 17: e = {12, 8, true, "20-node hexahedron", 20}; return true;
    case 92: e = {12, 8, true, "64-node hexahedron", 64}; return true;
    case 93: e = {12, 8, true, "125-node hexahedron", 125}; return true;
    case 13: e = {13, 6, true, "18-node prism", 18}; return true;
    case 18: e = {13, 6, true, "15-node prism", 15}; return true;
    case 14: e = {14, 5, true, "14-node pyramid", 14}; return true;
    case 19: e = {14, 5, true, "13-node pyramid", 13}; return true;
    default: break;
  }
  // Not volume cells: points, lines, triangles and quadrangles.
  int nodes = 0;
  switch (type) {
    case 15: e = {0, 1, false, "point", 1}; return true;
    case 1: nodes = 2; break;
    case 8: nodes = 3; break;
    case 26: nodes = 4; break;
    case 27: nodes = 5; break;
    case 28: nodes = 6; break;
    default: break;
  }
  if (nodes) return e = {0, 2, false, "line", nodes}, true;
  switch (type) {
    case 2: nodes = 3; break;
    case 9: nodes = 6; break;
    case 20: nodes = 9; break;
    case 21: nodes = 10; break;
    case 22: nodes = 12; break;
    case 23: nodes = 15; break;
    case 24: nodes = 15; break;
    case 25: nodes = 21; break;
    default: break;
  }
  if (nodes) return e = {0, 3, false, "triangle", nodes}, true;
  switch (type) {
    case 3: nodes = 4; break;
    case 10: nodes = 9; break;
    case 16: nodes = 8; break;
    case 36: nodes = 16; break;
    case 37: nodes = 25; break;
    case 38: nodes = 36; break;
    default: break;
  }
  if (nodes) return e = {0, 4, false, "quadrangle", nodes}, true;
  return false;
}

/// gmsh prism corners in VTK wedge order (gmsh's MPrism::getVertexVTK).
inline constexpr int gmsh_prism_to_vtk[6] = {0, 2, 1, 3, 5, 4};

/// Maps gmsh's tags (node or element numbers: positive, unique, possibly
/// sparse) to indices in reading order.
class TagMap {
 public:
  void add(int64_t tag) { tags_.push_back(tag); }
  uint64_t size() const { return tags_.size(); }
  /// The tag added `i`-th.
  int64_t tag(uint64_t i) const { return tags_[i]; }
  /// Builds the lookup; returns the first repeated tag, or 0.
  int64_t finish() {
    int64_t max_tag = 0;
    for (int64_t t : tags_) max_tag = std::max(max_tag, t);
    if (uint64_t(max_tag) <= 4 * tags_.size() + 1024) {  // dense, as gmsh writes them
      dense_.assign(size_t(max_tag) + 1, missing);
      for (size_t i = 0; i < tags_.size(); ++i) {
        if (dense_[size_t(tags_[i])] != missing) return tags_[i];
        dense_[size_t(tags_[i])] = uint32_t(i);
      }
    } else {
      sorted_.resize(tags_.size());
      for (size_t i = 0; i < tags_.size(); ++i) sorted_[i] = {tags_[i], uint32_t(i)};
      std::sort(sorted_.begin(), sorted_.end());
      for (size_t i = 1; i < sorted_.size(); ++i)
        if (sorted_[i].first == sorted_[i - 1].first) return sorted_[i].first;
    }
    return 0;
  }
  /// The index of `tag`, or `missing`.
  uint32_t find(int64_t tag) const {
    if (tag <= 0) return missing;
    if (!dense_.empty() || sorted_.empty()) return uint64_t(tag) < dense_.size() ? dense_[size_t(tag)] : missing;
    auto it = std::lower_bound(sorted_.begin(), sorted_.end(), std::pair<int64_t, uint32_t>(tag, 0));
    return it != sorted_.end() && it->first == tag ? it->second : missing;
  }
  static constexpr uint32_t missing = std::numeric_limits<uint32_t>::max();

 private:
  std::vector<int64_t> tags_;
  std::vector<uint32_t> dense_;
  std::vector<std::pair<int64_t, uint32_t>> sorted_;
};

/// One pass over an MSH file, ASCII or binary, section by section.
class GmshParser {
 public:
  GmshParser(Source const& src, ReadOptions const& opts) : src_(src), opts_(opts) {}

  UnstructuredGrid parse() {
    bool format = false, nodes = false, elements = false;
    while (skip_space(), pos_ < end()) {
      uint64_t const at = pos_;
      section_.clear();
      std::string_view const section = line();
      if (section.empty() || section[0] != '$') fail(at, "expected a section such as $Nodes, found " + in_quotes(section));
      std::string_view const name = section.substr(1);
      if (!format && name != "MeshFormat") fail(at, "an MSH file starts with $MeshFormat, not " + in_quotes(section));
      section_ = std::string(section);
      if (name == "MeshFormat") {
        // A view appended to a mesh file repeats the header: it must agree.
        int const major = major_, minor = minor_;
        bool const binary = binary_;
        read_format();
        if (format && (major != major_ || minor != minor_ || binary != binary_))
          fail(at, "a second $MeshFormat section says another version or file type than the first");
        format = true;
      } else if (name == "Nodes") read_nodes(at), nodes = true;
      else if (name == "Elements") {
        if (!nodes) fail(at, "$Elements before $Nodes");
        read_elements(at), elements = true;
      } else if (name == "NodeData" || name == "ElementData") {
        if (!elements) fail(at, "$" + std::string(name) + " before $Elements");
        read_data(at, name == "NodeData");
      } else if (name == "Entities" && binary_) {
        read_binary_entities();
      } else {
        skip_section(at, name);
      }
    }
    if (!format) throw IoError(src_.name + ": empty file (an MSH file starts with $MeshFormat)");
    if (!nodes || !elements) throw IoError(src_.name + ": no " + std::string(nodes ? "$Elements" : "$Nodes") + " section");
    return finish();
  }

 private:
  Source const& src_;
  ReadOptions const& opts_;
  uint64_t pos_ = 0;
  int major_ = 2, minor_ = 2;
  bool binary_ = false, swap_ = false;  ///< binary; in the other byte order than the host's
  std::string section_;                 ///< the section being read, for binary errors
  // Nodes.
  TagMap node_tags_;
  std::vector<double> xyz_;
  // Volume cells in file order: VTK type, corners (vertex indices, VTK order),
  // where each starts in the file; physical and geometrical tags.
  std::vector<int64_t> types_, conn_;
  std::vector<uint64_t> cell_at_;
  std::vector<double> physical_, geometrical_;
  TagMap element_tags_;              ///< every element's tag (volume or not)
  std::vector<uint32_t> element_cell_;  ///< element (reading order) -> volume cell, or TagMap::missing
  std::map<int64_t, uint64_t> not_cells_, skipped_;  ///< gmsh type -> count
  uint64_t higher_order_ = 0;
  struct Data {
    std::string name;
    int ncomp;
    std::vector<double> values;  ///< ncomp per vertex (point) or per volume cell
  };
  std::vector<Data> point_data_, cell_data_;
  std::vector<std::string> ignored_;

  uint64_t end() const { return src_.bytes.size(); }
  uint64_t left() const { return end() - pos_; }
  char const* base() const { return src_.bytes.data(); }
  /// "file:LINE: " in ASCII files, "file: byte N: $Section: " in binary ones.
  std::string at(uint64_t offset) const {
    if (!binary_) return src_.at_line(offset);
    return src_.at_byte(offset) + (section_.empty() ? std::string() : section_ + ": ");
  }
  [[noreturn]] void fail(uint64_t offset, std::string const& msg) const { throw IoError(at(offset) + msg); }
  void skip_space() {
    while (pos_ < end() && is_space(base()[pos_])) ++pos_;
  }
  /// The rest of the current line without its end (and a '\r'), moving past it.
  std::string_view line() {
    uint64_t const b = pos_;
    uint64_t e = b;
    while (e < end() && base()[e] != '\n') ++e;
    pos_ = e < end() ? e + 1 : e;
    if (e > b && base()[e - 1] == '\r') --e;
    return src_.bytes.substr(b, e - b);
  }
  /// The next whitespace-separated token (empty at the end of the file).
  std::string_view token() {
    skip_space();
    uint64_t const b = pos_;
    while (pos_ < end() && !is_space(base()[pos_])) ++pos_;
    return src_.bytes.substr(b, pos_ - b);
  }
  template <class T> T number(char const* what) {
    skip_space();
    uint64_t const at = pos_;
    T v{};
    char const* p = base() + pos_;
    if (pos_ >= end()) fail(at, std::string("file ends where ") + what + " should be");
    if (!parse_number(p, base() + end(), v)) fail(at, std::string("expected ") + what + ", found " + in_quotes(token_at(at)));
    pos_ = uint64_t(p - base());
    return v;
  }
  std::string_view token_at(uint64_t at) const {
    uint64_t e = at;
    while (e < end() && !is_space(base()[e]) && e - at < 40) ++e;
    return src_.bytes.substr(at, e - at);
  }
  uint64_t count(char const* what) {
    uint64_t const at = (skip_space(), pos_);
    int64_t const n = number<int64_t>(what);
    // Each item takes at least two bytes of text: a claim beyond that is a
    // broken header, refused before anything is allocated.
    if (n < 0 || uint64_t(n) > left() / 2 + 1)
      fail(at, std::string(what) + " " + std::to_string(n) + " does not fit in the " + std::to_string(left()) + " bytes left");
    return uint64_t(n);
  }
  void expect_end(std::string_view name) {
    skip_space();
    uint64_t const at = pos_;
    std::string_view const l = line();
    if (l != "$End" + std::string(name))
      fail(at, "expected $End" + std::string(name) + ", found " +
                   (l.empty() ? std::string("the end of the file") : in_quotes(l.substr(0, 40))));
  }
  void skip_section(uint64_t at, std::string_view name) {
    std::string const close = "$End" + std::string(name);
    while (pos_ < end()) {
      skip_space();
      if (line() == close) {
        ignored_.push_back("section $" + std::string(name));
        return;
      }
    }
    fail(at, "section $" + std::string(name) + " has no " + close);
  }

  // Binary values: each read checks the bytes are there first (`what`
  // stays a literal: this runs per value).
  void need(uint64_t bytes, char const* what) const {
    if (bytes > left())
      fail(pos_, std::string("the file ends inside ") + what + " (" + std::to_string(bytes) + " bytes needed, " +
                     std::to_string(left()) + " left)");
  }
  /// `n` records of at least `bytes` each: refused before anything is
  /// allocated unless they fit in the bytes left.
  void need_records(uint64_t at, uint64_t n, uint64_t bytes, std::string const& what) const {
    if (n > left() / bytes)
      fail(at, what + " " + std::to_string(n) + " does not fit in the " + std::to_string(left()) + " bytes left (" +
                   std::to_string(bytes) + " bytes each at least)");
  }
  template <class U> U load(uint64_t at) const {
    U u;
    std::memcpy(&u, base() + at, sizeof(U));
    return swap_ ? byte_swap(u) : u;
  }
  int64_t bin_int(char const* what) {
    need(4, what);
    int64_t const v = int32_t(load<uint32_t>(pos_));
    pos_ += 4;
    return v;
  }
  /// A size_t (MSH 4.1: 8 bytes); tags beyond int64 read as negative, which
  /// every check refuses.
  int64_t bin_size(char const* what) {
    need(8, what);
    int64_t const v = int64_t(load<uint64_t>(pos_));
    pos_ += 8;
    return v;
  }
  uint64_t bin_count(char const* what, uint64_t bytes_each) {
    uint64_t const at = pos_;
    int64_t const n = bin_size(what);
    if (n < 0) fail(at, std::string(what) + " " + std::to_string(uint64_t(n)) + " is not a count");
    need_records(at, uint64_t(n), bytes_each, what);
    return uint64_t(n);
  }
  double bin_double(char const* what) {
    need(8, what);
    uint64_t const u = load<uint64_t>(pos_);
    double v;
    std::memcpy(&v, &u, 8);
    pos_ += 8;
    return v;
  }

  void read_format() {
    skip_space();
    uint64_t const at = pos_;
    std::string_view const version = token();
    int64_t const file_type = number<int64_t>("the file type (0: ASCII, 1: binary)");
    int64_t const data_size = number<int64_t>("the data size");
    if (version.substr(0, 2) == "2.") major_ = 2, minor_ = 2;
    else if (version == "4.1") major_ = 4, minor_ = 1;
    else if (version == "4" || version == "4.0") major_ = 4, minor_ = 0;
    else
      fail(at, "MSH version " + in_quotes(version) +
                   " is not read (cellray reads MSH 2.2, 4.0 and 4.1: gmsh -format msh22 or msh41)");
    if (file_type != 0 && file_type != 1) fail(at, "file type " + std::to_string(file_type) + " (0: ASCII, 1: binary)");
    line();
    if (file_type == 1) {
      if (major_ == 4 && minor_ == 0) fail(at, "binary MSH 4.0 is not read (write MSH 4.1: gmsh -format msh41 -bin)");
      if (data_size != 8)
        fail(at, "binary MSH with data size " + std::to_string(data_size) +
                     " is not read (cellray reads 8-byte doubles, as gmsh writes them; write ASCII: gmsh -bin 0)");
      binary_ = true;
      uint64_t const check = pos_;
      if (left() < 4) fail(check, "the file ends where the byte order check (the int 1) should be");
      uint32_t const one = load<uint32_t>(check);
      if (one != 1 && byte_swap(one) != 1)
        fail(check, "the byte order check reads " + std::to_string(one) + ", not the int 1: a damaged binary MSH file");
      swap_ = one != 1;
      pos_ += 4;
      line();
    }
    expect_end("MeshFormat");
  }

  /// MSH 4.1 binary $Entities: checked and passed over, as ASCII ones are
  /// (MSH 4 keeps physical groups there, not read).
  void read_binary_entities() {
    uint64_t counts[4];
    for (uint64_t& n : counts) n = bin_count("an entity count", 36);
    for (int dim = 0; dim < 4; ++dim)
      for (uint64_t i = 0; i < counts[dim]; ++i) {
        if (uint64_t(4 + (dim ? 48 : 24)) > left())
          fail(pos_, "the file ends inside entity " + std::to_string(i + 1) + " of dimension " + std::to_string(dim));
        pos_ += 4 + (dim ? 48 : 24);  // tag, point or bounding box
        uint64_t const phys = bin_count("a physical tag count", 4);
        pos_ += 4 * phys;
        if (dim) pos_ += 4 * bin_count("a bounding entity count", 4);
      }
    expect_end("Entities");
    ignored_.push_back("section $Entities");
  }

  void add_node(uint64_t at, int64_t tag) {
    if (tag <= 0) fail(at, "node tag " + std::to_string(tag) + " is not positive");
    node_tags_.add(tag);
  }
  void read_nodes(uint64_t at) {
    if (node_tags_.size()) fail(at, "a second $Nodes section");
    if (major_ == 2) {
      uint64_t const n = count("the node count");
      if (binary_) {
        line();
        need_records(pos_, n, 28, "the node count");
        xyz_.reserve(3 * n);
        for (uint64_t i = 0; i < n; ++i) {
          uint64_t const l = pos_;
          add_node(l, bin_int("a node tag"));
          for (int k = 0; k < 3; ++k) xyz_.push_back(bin_double("a node's coordinates"));
        }
      } else {
        xyz_.reserve(3 * n);
        for (uint64_t i = 0; i < n; ++i) {
          skip_space();
          uint64_t const l = pos_;
          add_node(l, number<int64_t>("a node tag"));
          for (int k = 0; k < 3; ++k) xyz_.push_back(number<double>("a coordinate"));
        }
      }
    } else if (binary_) {
      uint64_t const blocks = bin_count("the entity block count", 20);
      uint64_t const n = bin_count("the node count", 32);
      bin_size("the smallest node tag");
      bin_size("the largest node tag");
      xyz_.reserve(3 * n);
      for (uint64_t b = 0; b < blocks; ++b) {
        uint64_t const block_at = pos_;
        int64_t const dim = bin_int("an entity dimension");
        bin_int("an entity tag");
        bool const parametric = bin_int("the parametric flag") != 0;
        int64_t const params = parametric ? std::max<int64_t>(0, std::min<int64_t>(dim, 3)) : 0;
        uint64_t const m = bin_count("the block's node count", 32 + 8 * uint64_t(params));
        if (m > n - std::min(n, node_tags_.size()))
          fail(block_at,
               "node block " + std::to_string(b + 1) + " holds " + std::to_string(m) + " nodes, more than $Nodes announces");
        for (uint64_t i = 0; i < m; ++i) {
          uint64_t const l = pos_;
          add_node(l, bin_size("a node tag"));
        }
        for (uint64_t i = 0; i < m; ++i) {
          for (int k = 0; k < 3; ++k) xyz_.push_back(bin_double("a node's coordinates"));
          for (int64_t k = 0; k < params; ++k) bin_double("a parametric coordinate");
        }
      }
      if (node_tags_.size() != n)
        fail(at, "$Nodes announces " + std::to_string(n) + " nodes, its blocks hold " + std::to_string(node_tags_.size()));
    } else {
      // 4.1: blocks, nodes, smallest and largest tag; per block dimension,
      // entity, parametric flag, count; the tags, then the coordinates.
      // 4.0: blocks, nodes; per block entity, dimension, parametric flag,
      // count; a line per node: tag, coordinates.
      uint64_t const blocks = count("the entity block count");
      uint64_t const n = count("the node count");
      if (minor_ == 1) {
        number<int64_t>("the smallest node tag");
        number<int64_t>("the largest node tag");
      }
      xyz_.reserve(3 * n);
      for (uint64_t b = 0; b < blocks; ++b) {
        int64_t dim;
        if (minor_ == 1) {
          dim = number<int64_t>("an entity dimension");
          number<int64_t>("an entity tag");
        } else {
          number<int64_t>("an entity tag");
          dim = number<int64_t>("an entity dimension");
        }
        bool const parametric = number<int64_t>("the parametric flag") != 0;
        uint64_t const m = count("the block's node count");
        int64_t const params = parametric ? std::min<int64_t>(dim, 3) : 0;
        if (minor_ == 1) {
          for (uint64_t i = 0; i < m; ++i) {
            skip_space();
            add_node(pos_, number<int64_t>("a node tag"));
          }
          for (uint64_t i = 0; i < m; ++i) {
            for (int k = 0; k < 3; ++k) xyz_.push_back(number<double>("a coordinate"));
            for (int64_t k = 0; k < params; ++k) number<double>("a parametric coordinate");
          }
        } else {
          for (uint64_t i = 0; i < m; ++i) {
            skip_space();
            add_node(pos_, number<int64_t>("a node tag"));
            for (int k = 0; k < 3; ++k) xyz_.push_back(number<double>("a coordinate"));
            for (int64_t k = 0; k < params; ++k) number<double>("a parametric coordinate");
          }
        }
      }
      if (node_tags_.size() != n)
        fail(at, "$Nodes announces " + std::to_string(n) + " nodes, its blocks hold " + std::to_string(node_tags_.size()));
    }
    if (!point_count_fits(node_tags_.size())) fail(at, "more than 2^32-1 nodes");
    if (int64_t const dup = node_tags_.finish()) fail(at, "node tag " + std::to_string(dup) + " appears twice");
    expect_end("Nodes");
  }

  /// The file cell ids (UnstructuredGrid::tet_file_cells) of a gmsh file
  /// are its element tags, which gmsh shows, not positions; none when a
  /// tag passes 2^32 - 1.
  void name_cells_by_tag(CellKinds const& kinds, UnstructuredGrid& grid) const {
    std::vector<int64_t> tag_of(kinds.size(), 0);
    for (uint64_t e = 0; e < element_cell_.size(); ++e)
      if (element_cell_[e] != TagMap::missing) tag_of[element_cell_[e]] = element_tags_.tag(e);
    grid.tet_file_cells.clear();
    grid.hex_file_cells.clear();
    if (std::any_of(tag_of.begin(), tag_of.end(), [](int64_t t) { return t > int64_t(std::numeric_limits<uint32_t>::max()); }))
      return;
    grid.tet_file_cells.reserve(grid.tet_count());
    grid.hex_file_cells.reserve(grid.hex_count());
    for (uint64_t c = 0; c < kinds.size(); ++c) {
      if (kinds[c] == 0) grid.tet_file_cells.push_back(uint32_t(tag_of[c]));
      else if (kinds[c] == 1) grid.hex_file_cells.push_back(uint32_t(tag_of[c]));
    }
  }

  /// An element's tag and type: true when it is a volume cell, to be
  /// added by add_cell with its nodes; otherwise counted and passed over.
  bool begin_element(uint64_t at, int64_t tag, int64_t type, GmshElement& e) {
    if (tag <= 0) fail(at, "element tag " + std::to_string(tag) + " is not positive");
    element_tags_.add(tag);
    if (!gmsh_element(type, e)) {
      if (!opts_.skip_unsupported_cells)
        fail(at, "element " + std::to_string(tag) + " has gmsh element type " + std::to_string(type) +
                     ", which cellray does not read (it reads tetrahedra, hexahedra, prisms and pyramids, "
                     "linear or higher order; set ReadOptions::skip_unsupported_cells to skip such elements)");
      ++skipped_[type];
      element_cell_.push_back(TagMap::missing);
      return false;
    }
    if (!e.vtk) {
      ++not_cells_[type];
      element_cell_.push_back(TagMap::missing);
      return false;
    }
    return true;
  }
  /// A volume cell: `have` node tags were listed, the first
  /// min(have, e.corners) of them in `node`.
  void add_cell(uint64_t at, int64_t tag, GmshElement const& e, int64_t const* node, int64_t have, double physical,
                double geometrical) {
    if (have < e.corners)
      fail(at, "element " + std::to_string(tag) + " (" + e.name + ") lists " + std::to_string(have) + " nodes, needs at least " +
                   std::to_string(e.corners));
    int64_t corner[8];
    for (int k = 0; k < e.corners; ++k) {
      uint32_t const v = node_tags_.find(node[k]);
      if (v == TagMap::missing)
        fail(at, "element " + std::to_string(tag) + " names node " + std::to_string(node[k]) + ", which $Nodes does not list");
      corner[k] = int64_t(v);
    }
    element_cell_.push_back(uint32_t(types_.size()));
    types_.push_back(e.vtk);
    for (int k = 0; k < e.corners; ++k) conn_.push_back(corner[e.vtk == 13 ? gmsh_prism_to_vtk[k] : k]);
    cell_at_.push_back(at);
    physical_.push_back(physical);
    geometrical_.push_back(geometrical);
    higher_order_ += e.higher_order;
  }
  /// One element's text after its tag (and, in 2.2, its type and tags): its node tags.
  void add_element(uint64_t at, int64_t tag, int64_t type, std::string_view rest, double physical, double geometrical) {
    GmshElement e;
    if (!begin_element(at, tag, type, e)) return;
    int64_t node[8];
    char const* p = rest.data();
    char const* const stop = rest.data() + rest.size();
    int64_t have = 0;
    for (;; ++have) {
      while (p < stop && is_space(*p)) ++p;
      if (p == stop) break;
      int64_t v = 0;
      char const* const q = p;
      if (!parse_number(p, stop, v))
        fail(at, "expected a node tag, found " + in_quotes(std::string_view(q, size_t(std::min<ptrdiff_t>(stop - q, 40)))));
      if (have < e.corners) node[have] = v;
    }
    add_cell(at, tag, e, node, have, physical, geometrical);
  }
  /// A binary element type's node count, failing for a type cellray cannot
  /// size (its records cannot be passed over).
  GmshElement binary_type(uint64_t at, int64_t type, int64_t first_tag) {
    GmshElement e;
    if (gmsh_element(type, e)) return e;
    if (!opts_.skip_unsupported_cells) begin_element(at, first_tag, type, e);  // fails naming the element
    fail(at, "element type " + std::to_string(type) +
                 " is not one cellray knows: its node count, hence its binary records' size, is unknown");
  }
  /// `m` binary element records of `e`'s type from pos_, tags and nodes
  /// `width` bytes each, after `ntags` tags (2.2).
  void read_binary_elements(uint64_t m, int64_t type, GmshElement const& e, int width, int64_t ntags, double geometrical) {
    for (uint64_t i = 0; i < m; ++i) {
      uint64_t const l = pos_;
      int64_t const tag = width == 4 ? bin_int("an element") : bin_size("an element");
      double physical = std::numeric_limits<double>::quiet_NaN(), geom = geometrical;
      for (int64_t k = 0; k < ntags; ++k) {
        double const t = double(bin_int("an element's tags"));
        if (k == 0) physical = t;
        if (k == 1) geom = t;
      }
      GmshElement known;
      if (!begin_element(l, tag, type, known)) {
        need(uint64_t(e.nodes) * uint64_t(width), "an element's nodes");
        pos_ += uint64_t(e.nodes) * uint64_t(width);
        continue;
      }
      int64_t node[8];
      for (int k = 0; k < e.nodes; ++k) {
        int64_t const v = width == 4 ? bin_int("an element's nodes") : bin_size("an element's nodes");
        if (k < e.corners) node[k] = v;
      }
      add_cell(l, tag, e, node, e.nodes, physical, geom);
    }
  }

  void read_elements(uint64_t at) {
    if (element_tags_.size()) fail(at, "a second $Elements section");
    if (major_ == 2 && binary_) {
      // Groups: a header of 3 ints (type, elements following, tag count),
      // then per element its number, tags and nodes as ints.
      uint64_t const n = count("the element count");
      line();
      need_records(pos_, n, 8, "the element count");
      for (uint64_t read = 0; read < n;) {
        uint64_t const g = pos_;
        int64_t const type = bin_int("an element group header");
        int64_t const follow = bin_int("an element group header");
        int64_t const ntags = bin_int("an element group header");
        if (follow <= 0 || uint64_t(follow) > n - read)
          fail(g, "an element group of " + std::to_string(follow) + " elements, " + std::to_string(n - read) +
                      " of the announced " + std::to_string(n) + " being left");
        if (ntags < 0 || ntags > 1000) fail(g, "an element group claims " + std::to_string(ntags) + " tags per element");
        GmshElement const e = binary_type(g, type, left() >= 4 ? int32_t(load<uint32_t>(pos_)) : 0);
        need_records(g, uint64_t(follow), 4 * (1 + uint64_t(ntags) + uint64_t(e.nodes)), "an element group's count");
        read_binary_elements(uint64_t(follow), type, e, 4, ntags, std::numeric_limits<double>::quiet_NaN());
        read += uint64_t(follow);
      }
    } else if (major_ == 2) {
      uint64_t const n = count("the element count");
      for (uint64_t i = 0; i < n; ++i) {
        skip_space();
        uint64_t const l = pos_;
        int64_t const tag = number<int64_t>("an element tag");
        int64_t const type = number<int64_t>("an element type");
        int64_t const ntags = number<int64_t>("the element's tag count");
        if (ntags < 0 || ntags > 1000) fail(l, "element " + std::to_string(tag) + " claims " + std::to_string(ntags) + " tags");
        double physical = std::numeric_limits<double>::quiet_NaN(), geometrical = physical;
        for (int64_t k = 0; k < ntags; ++k) {
          double const t = double(number<int64_t>("an element tag value"));
          if (k == 0) physical = t;
          if (k == 1) geometrical = t;
        }
        add_element(l, tag, type, line(), physical, geometrical);
      }
    } else if (binary_) {
      uint64_t const blocks = bin_count("the entity block count", 20);
      uint64_t const n = bin_count("the element count", 16);
      bin_size("the smallest element tag");
      bin_size("the largest element tag");
      for (uint64_t b = 0; b < blocks; ++b) {
        uint64_t const block_at = pos_;
        bin_int("an entity dimension");
        double const entity = double(bin_int("an entity tag"));
        int64_t const type = bin_int("an element type");
        uint64_t const m_at = pos_;
        uint64_t const m = bin_count("the block's element count", 16);
        if (m > n - std::min(n, element_tags_.size()))
          fail(block_at, "element block " + std::to_string(b + 1) + " holds " + std::to_string(m) +
                             " elements, more than $Elements announces");
        GmshElement const e = binary_type(block_at, type, left() >= 8 ? int64_t(load<uint64_t>(pos_)) : 0);
        need_records(m_at, m, 8 * (1 + uint64_t(e.nodes)), "the block's element count");
        read_binary_elements(m, type, e, 8, 0, entity);
      }
      if (element_tags_.size() != n)
        fail(at,
             "$Elements announces " + std::to_string(n) + " elements, its blocks hold " + std::to_string(element_tags_.size()));
    } else {
      // 4.1: blocks, elements, smallest and largest tag; per block dimension,
      // entity, type, count. 4.0: blocks, elements; per block entity,
      // dimension, type, count.
      uint64_t const blocks = count("the entity block count");
      uint64_t const n = count("the element count");
      if (minor_ == 1) {
        number<int64_t>("the smallest element tag");
        number<int64_t>("the largest element tag");
      }
      for (uint64_t b = 0; b < blocks; ++b) {
        double entity;
        if (minor_ == 1) {
          number<int64_t>("an entity dimension");
          entity = double(number<int64_t>("an entity tag"));
        } else {
          entity = double(number<int64_t>("an entity tag"));
          number<int64_t>("an entity dimension");
        }
        int64_t const type = number<int64_t>("an element type");
        uint64_t const m = count("the block's element count");
        line();
        for (uint64_t i = 0; i < m; ++i) {
          skip_space();
          uint64_t const l = pos_;
          int64_t const tag = number<int64_t>("an element tag");
          add_element(l, tag, type, line(), std::numeric_limits<double>::quiet_NaN(), entity);
        }
      }
      if (element_tags_.size() != n)
        fail(at,
             "$Elements announces " + std::to_string(n) + " elements, its blocks hold " + std::to_string(element_tags_.size()));
    }
    if (int64_t const dup = element_tags_.finish()) fail(at, "element tag " + std::to_string(dup) + " appears twice");
    expect_end("Elements");
  }

  /// $NodeData / $ElementData: string tags (the view's name first), real
  /// tags (the time), integer tags (time step, components, count), then one
  /// line per node or element: its tag and its components (binary: an int
  /// and doubles).
  void read_data(uint64_t at, bool point) {
    char const* const section = point ? "NodeData" : "ElementData";
    std::vector<std::string> strings;
    for (uint64_t k = 0, n = count("the string tag count"); k < n; ++k) {
      skip_space();
      std::string_view s = line();
      if (s.size() >= 2 && s.front() == '"' && s.back() == '"') s = s.substr(1, s.size() - 2);
      strings.emplace_back(s);
    }
    for (uint64_t k = 0, n = count("the real tag count"); k < n; ++k) number<double>("a real tag");
    std::vector<int64_t> ints;
    for (uint64_t k = 0, n = count("the integer tag count"); k < n; ++k) ints.push_back(number<int64_t>("an integer tag"));
    if (ints.size() < 3) fail(at, "$" + std::string(section) + " needs 3 integer tags (time step, components, count)");
    std::string const name =
        strings.empty() || strings[0].empty() ? std::string(point ? "node data" : "element data") : strings[0];
    int64_t const ncomp = ints[1], n = ints[2];
    if (ncomp < 1 || ncomp > 9) fail(at, "view " + in_quotes(name) + " has " + std::to_string(ncomp) + " components (1 to 9)");
    if (binary_) line();  // the records start on the next line
    uint64_t const record = binary_ ? 4 + 8 * uint64_t(ncomp) : 2;
    if (n < 0 || uint64_t(n) > left() / record + (binary_ ? 0 : 1))
      fail(at, "view " + in_quotes(name) + " claims " + std::to_string(n) + " values, more than the " + std::to_string(left()) +
                   " bytes left hold");
    std::vector<Data>& list = point ? point_data_ : cell_data_;
    bool const repeat = std::any_of(list.begin(), list.end(), [&](Data const& d) { return d.name == name; });
    uint64_t const items = point ? node_tags_.size() : types_.size();
    Data d{name, int(ncomp), std::vector<double>(repeat ? 0 : items * uint64_t(ncomp), std::numeric_limits<double>::quiet_NaN())};
    for (int64_t i = 0; i < n; ++i) {
      if (!binary_) skip_space();
      uint64_t const l = pos_;
      int64_t const tag =
          binary_ ? bin_int(point ? "a node tag" : "an element tag") : number<int64_t>(point ? "a node tag" : "an element tag");
      uint32_t const index = point ? node_tags_.find(tag) : element_tags_.find(tag);
      if (index == TagMap::missing)
        fail(l, "view " + in_quotes(name) + " names " + (point ? "node " : "element ") + std::to_string(tag) +
                    ", which the mesh does not have");
      uint32_t const slot = point ? index : element_cell_[index];
      for (int64_t k = 0; k < ncomp; ++k) {
        double const v = binary_ ? bin_double("a value") : number<double>("a value");
        if (!repeat && slot != TagMap::missing) d.values[uint64_t(slot) * uint64_t(ncomp) + uint64_t(k)] = v;
      }
    }
    expect_end(section);
    if (repeat)
      ignored_.push_back(std::string(point ? "point '" : "cell '") + name + "' at time step " + std::to_string(ints[0]) +
                         " (the first $" + section + " of a view is read)");
    else list.push_back(std::move(d));
  }

  UnstructuredGrid finish() {
    section_ = "$Elements";  // where the cells' errors point
    UnstructuredGrid grid;
    grid.report.file = src_.name;
    grid.report.format = std::string("gmsh MSH ") +
                         (major_ == 2   ? "2.2"
                          : minor_ == 0 ? "4.0"
                                        : "4.1") +
                         (binary_ ? " binary" : " ASCII");
    uint64_t const npoints = node_tags_.size(), ncells = types_.size();
    if (!ncells) {
      std::string what;
      for (auto const& [type, n] : not_cells_) {
        GmshElement e;
        gmsh_element(type, e);
        what += (what.empty() ? "" : ", ") + std::to_string(n) + " " + e.name;
      }
      throw IoError(src_.name + ": no volume elements (tetrahedra, hexahedra, prisms or pyramids)" +
                    (what.empty() ? std::string() : "; the file has " + what));
    }
    set_positions(grid, NumArray::owning(xyz_), npoints);
    std::vector<uint64_t> offsets(ncells + 1, 0);
    for (uint64_t c = 0; c < ncells; ++c) {
      uint64_t nodes;
      bool exact;
      classify_cell(types_[c], nodes, exact);
      offsets[c + 1] = offsets[c] + nodes;
    }
    NumArray const types = NumArray::owning(types_), conn = NumArray::owning(conn_);
    CellLocator where;
    where.type = [this](uint64_t c) { return at(cell_at_[std::min<uint64_t>(c, cell_at_.size() - 1)]); };
    where.conn = [this, &offsets](uint64_t k) {
      uint64_t const c = uint64_t(std::upper_bound(offsets.begin(), offsets.end(), k) - offsets.begin()) - 1;
      return at(cell_at_[std::min<uint64_t>(c, cell_at_.size() - 1)]);
    };
    CellKinds const kinds = build_cells(
        ncells, types, conn, [&offsets](uint64_t c) { return std::pair<uint64_t, uint64_t>(offsets[c], offsets[c + 1]); },
        npoints, opts_, grid, where);
    name_cells_by_tag(kinds, grid);
    grid.report.reduced_to_linear += higher_order_;
    for (auto& d : point_data_)
      add_point_array(grid, std::move(d.name), point_values(NumArray::owning(d.values), d.ncomp, npoints), d.ncomp);
    bool const has_physical = std::any_of(physical_.begin(), physical_.end(), [](double v) { return v == v; });
    if (has_physical) add_cell_array(grid, "gmsh:physical", NumArray::owning(physical_), 1, kinds);
    add_cell_array(grid, "gmsh:geometrical", NumArray::owning(geometrical_), 1, kinds);
    for (auto& d : cell_data_) add_cell_array(grid, std::move(d.name), NumArray::owning(d.values), d.ncomp, kinds);
    for (auto const& [type, n] : not_cells_) {
      GmshElement e;
      gmsh_element(type, e);
      grid.report.other_ignored.push_back(std::to_string(n) + " " + e.name + " elements (gmsh type " + std::to_string(type) +
                                          "): not volume cells");
    }
    for (auto const& [type, n] : skipped_) {
      grid.report.other_ignored.push_back(std::to_string(n) + " elements of gmsh type " + std::to_string(type) +
                                          " (a type cellray does not read: skipped)");
      grid.report.other_cells_skipped += n;
    }
    for (auto& s : ignored_) grid.report.other_ignored.push_back(std::move(s));
    return grid;
  }
};

}  // namespace io

/// Reads a gmsh MSH file held in memory (see read_gmsh); `name_for_errors`
/// starts every error message. Thread-safe.
/// @throws IoError naming the file and line (binary files: byte offset and
///         section) on malformed, truncated or unsupported content; no
///         partial grid is ever returned.
inline UnstructuredGrid read_gmsh_from_memory(std::string_view bytes, std::string name_for_errors,
                                              ReadOptions const& opts = {}) {
  io::Source const src{bytes, std::move(name_for_errors)};
  return io::naming_out_of_memory(src.name, [&] { return io::GmshParser(src, opts).parse(); });
}

/// Reads a gmsh ".msh" file, MSH 2.2, 4.0 or 4.1, ASCII or binary (see the file comment
/// for what is kept).
/// @throws IoError as read_gmsh_from_memory, or when the file cannot be read.
inline UnstructuredGrid read_gmsh(std::string const& path, ReadOptions const& opts = {}) {
  io::FileBytes const file(path);
  return read_gmsh_from_memory(file.bytes(), path, opts);
}

}  // namespace cellray
