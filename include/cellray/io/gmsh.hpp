#pragma once
// read_gmsh(path): gmsh's MSH format, versions 2.2 (2.0 and 2.1 read alike)
// and 4.1, ASCII -- what `gmsh -3` writes by default, and what
// gmshToFoam needs.
//
// Kept: the volume elements (tetrahedra, hexahedra, prisms and pyramids,
// higher-order ones as their corner cells) under VTK's node order (a gmsh
// prism's triangles run the other way round from a VTK wedge's: 0 2 1 3 5 4,
// as gmsh's own VTK export writes them), the nodes they may use, every
// $NodeData view as a point array (its first time step; others are listed as
// ignored) and every $ElementData view as a cell array. MSH 2.2's tags give
// the cell arrays "gmsh:physical" and "gmsh:geometrical", MSH 4.1's entity
// tags "gmsh:geometrical", as meshio names them. Points, lines, triangles and
// quadrangles (boundary and embedded elements) are not cells: counted and
// listed in the report as ignored. Binary MSH and MSH 4.0 are an error that
// says how to write a file this reads.

#include <algorithm>
#include <cstdint>
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
/// cell), the corner count, and gmsh's name for it.
struct GmshElement {
  int vtk = 0;
  int corners = 0;
  bool higher_order = false;
  char const* name = "";
};

/// The gmsh element types cellray knows (gmsh's GmshDefines.h numbering).
/// Returns false for a type it does not.
inline bool gmsh_element(int64_t type, GmshElement& e) {
  switch (type) {
    case 4: e = {10, 4, false, "4-node tetrahedron"}; return true;
    case 5: e = {12, 8, false, "8-node hexahedron"}; return true;
    case 6: e = {13, 6, false, "6-node prism"}; return true;
    case 7: e = {14, 5, false, "5-node pyramid"}; return true;
    case 11: e = {10, 4, true, "10-node tetrahedron"}; return true;
    case 29: e = {10, 4, true, "20-node tetrahedron"}; return true;
    case 30: e = {10, 4, true, "35-node tetrahedron"}; return true;
    case 31: e = {10, 4, true, "56-node tetrahedron"}; return true;
    case 12: e = {12, 8, true, "27-node hexahedron"}; return true;
    case 17: e = {12, 8, true, "20-node hexahedron"}; return true;
    case 92: e = {12, 8, true, "64-node hexahedron"}; return true;
    case 93: e = {12, 8, true, "125-node hexahedron"}; return true;
    case 13: e = {13, 6, true, "18-node prism"}; return true;
    case 18: e = {13, 6, true, "15-node prism"}; return true;
    case 14: e = {14, 5, true, "14-node pyramid"}; return true;
    case 19: e = {14, 5, true, "13-node pyramid"}; return true;
    // Not volume cells: points, lines, triangles and quadrangles.
    case 15: e = {0, 1, false, "point"}; return true;
    case 1: case 8: case 26: case 27: case 28: e = {0, 2, false, "line"}; return true;
    case 2: case 9: case 20: case 21: case 22: case 23: case 24: case 25: e = {0, 3, false, "triangle"}; return true;
    case 3: case 10: case 16: case 36: case 37: case 38: e = {0, 4, false, "quadrangle"}; return true;
    default: return false;
  }
}

/// gmsh prism corners in VTK wedge order (gmsh's MPrism::getVertexVTK).
inline constexpr int gmsh_prism_to_vtk[6] = {0, 2, 1, 3, 5, 4};

/// Maps gmsh's tags (node or element numbers: positive, unique, possibly
/// sparse) to indices in reading order.
class TagMap {
 public:
  void add(int64_t tag) { tags_.push_back(tag); }
  uint64_t size() const { return tags_.size(); }
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

/// One pass over an ASCII MSH file, section by section.
class GmshParser {
 public:
  GmshParser(Source const& src, ReadOptions const& opts) : src_(src), opts_(opts) {}

  UnstructuredGrid parse() {
    bool format = false, nodes = false, elements = false;
    while (skip_space(), pos_ < end()) {
      uint64_t const at = pos_;
      std::string_view const section = line();
      if (section.empty() || section[0] != '$') src_.fail_line(at, "expected a section such as $Nodes, found " + in_quotes(section));
      std::string_view const name = section.substr(1);
      if (!format && name != "MeshFormat") src_.fail_line(at, "an MSH file starts with $MeshFormat, not " + in_quotes(section));
      if (name == "MeshFormat") read_format(), format = true;
      else if (name == "Nodes") read_nodes(at), nodes = true;
      else if (name == "Elements") {
        if (!nodes) src_.fail_line(at, "$Elements before $Nodes");
        read_elements(at), elements = true;
      } else if (name == "NodeData" || name == "ElementData") {
        if (!elements) src_.fail_line(at, "$" + std::string(name) + " before $Elements");
        read_data(at, name == "NodeData");
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
  int major_ = 2;
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
  char const* base() const { return src_.bytes.data(); }
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
    if (pos_ >= end()) src_.fail_line(at, std::string("file ends where ") + what + " should be");
    if (!parse_number(p, base() + end(), v)) src_.fail_line(at, std::string("expected ") + what + ", found " + in_quotes(token_at(at)));
    pos_ = uint64_t(p - base());
    return v;
  }
  std::string_view token_at(uint64_t at) const {
    uint64_t e = at;
    while (e < end() && !is_space(base()[e])) ++e;
    return src_.bytes.substr(at, e - at);
  }
  uint64_t count(char const* what) {
    uint64_t const at = (skip_space(), pos_);
    int64_t const n = number<int64_t>(what);
    // Each item takes at least two bytes of text: a claim beyond that is a
    // broken header, refused before anything is allocated.
    if (n < 0 || uint64_t(n) > (end() - pos_) / 2 + 1)
      src_.fail_line(at, std::string(what) + " " + std::to_string(n) + " does not fit in the " +
                             std::to_string(end() - pos_) + " bytes left");
    return uint64_t(n);
  }
  void expect_end(std::string_view name) {
    skip_space();
    uint64_t const at = pos_;
    std::string_view const l = line();
    if (l != "$End" + std::string(name))
      src_.fail_line(at, "expected $End" + std::string(name) + ", found " + (l.empty() ? std::string("the end of the file") : in_quotes(l)));
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
    src_.fail_line(at, "section $" + std::string(name) + " has no " + close);
  }

  void read_format() {
    skip_space();
    uint64_t const at = pos_;
    std::string_view const version = token();
    int64_t const file_type = number<int64_t>("the file type (0: ASCII)");
    number<int64_t>("the data size");
    if (version.substr(0, 2) == "2.") major_ = 2;
    else if (version == "4.1") major_ = 4;
    else src_.fail_line(at, "MSH version " + in_quotes(version) + " is not read (cellray reads MSH 2.2 and 4.1: gmsh -format msh22 or msh41)");
    if (file_type != 0)
      src_.fail_line(at, "binary MSH is not read yet (write ASCII: gmsh -bin 0, or Mesh.Binary = 0)");
    line();
    expect_end("MeshFormat");
  }

  void add_node(uint64_t at, int64_t tag) {
    if (tag <= 0) src_.fail_line(at, "node tag " + std::to_string(tag) + " is not positive");
    node_tags_.add(tag);
  }
  void read_nodes(uint64_t at) {
    if (node_tags_.size()) src_.fail_line(at, "a second $Nodes section");
    if (major_ == 2) {
      uint64_t const n = count("the node count");
      xyz_.reserve(3 * n);
      for (uint64_t i = 0; i < n; ++i) {
        skip_space();
        uint64_t const l = pos_;
        add_node(l, number<int64_t>("a node tag"));
        for (int k = 0; k < 3; ++k) xyz_.push_back(number<double>("a coordinate"));
      }
    } else {
      uint64_t const blocks = count("the entity block count");
      uint64_t const n = count("the node count");
      number<int64_t>("the smallest node tag");
      number<int64_t>("the largest node tag");
      xyz_.reserve(3 * n);
      for (uint64_t b = 0; b < blocks; ++b) {
        int64_t const dim = number<int64_t>("an entity dimension");
        number<int64_t>("an entity tag");
        bool const parametric = number<int64_t>("the parametric flag") != 0;
        uint64_t const m = count("the block's node count");
        for (uint64_t i = 0; i < m; ++i) {
          skip_space();
          add_node(pos_, number<int64_t>("a node tag"));
        }
        for (uint64_t i = 0; i < m; ++i) {
          for (int k = 0; k < 3; ++k) xyz_.push_back(number<double>("a coordinate"));
          if (parametric)
            for (int64_t k = 0; k < std::min<int64_t>(dim, 3); ++k) number<double>("a parametric coordinate");
        }
      }
      if (node_tags_.size() != n)
        src_.fail_line(at, "$Nodes announces " + std::to_string(n) + " nodes, its blocks hold " + std::to_string(node_tags_.size()));
    }
    if (!point_count_fits(node_tags_.size())) src_.fail_line(at, "more than 2^32-1 nodes");
    if (int64_t const dup = node_tags_.finish()) src_.fail_line(at, "node tag " + std::to_string(dup) + " appears twice");
    expect_end("Nodes");
  }

  /// One element: its line holds its tag, then (2.2) its type and tags,
  /// then its node tags.
  void add_element(uint64_t at, int64_t tag, int64_t type, std::string_view rest, double physical, double geometrical) {
    if (tag <= 0) src_.fail_line(at, "element tag " + std::to_string(tag) + " is not positive");
    element_tags_.add(tag);
    GmshElement e;
    if (!gmsh_element(type, e)) {
      if (!opts_.skip_unsupported_cells)
        src_.fail_line(at, "element " + std::to_string(tag) + " has gmsh element type " + std::to_string(type) +
                               ", which cellray does not read (it reads tetrahedra, hexahedra, prisms and pyramids, "
                               "linear or higher order; set ReadOptions::skip_unsupported_cells to skip such elements)");
      ++skipped_[type];
      element_cell_.push_back(TagMap::missing);
      return;
    }
    if (!e.vtk) {
      ++not_cells_[type];
      element_cell_.push_back(TagMap::missing);
      return;
    }
    int64_t corner[8];
    char const* p = rest.data();
    char const* const stop = rest.data() + rest.size();
    int have = 0;
    for (;; ++have) {
      while (p < stop && is_space(*p)) ++p;
      if (p == stop) break;
      int64_t node = 0;
      char const* const q = p;
      if (!parse_number(p, stop, node)) src_.fail_line(at, "expected a node tag, found " + in_quotes(std::string_view(q, size_t(stop - q))));
      if (have < e.corners) {
        uint32_t const v = node_tags_.find(node);
        if (v == TagMap::missing)
          src_.fail_line(at, "element " + std::to_string(tag) + " names node " + std::to_string(node) + ", which $Nodes does not list");
        corner[have] = int64_t(v);
      }
    }
    if (have < e.corners)
      src_.fail_line(at, "element " + std::to_string(tag) + " (" + e.name + ") lists " + std::to_string(have) +
                             " nodes, needs at least " + std::to_string(e.corners));
    element_cell_.push_back(uint32_t(types_.size()));
    types_.push_back(e.vtk);
    for (int k = 0; k < e.corners; ++k) conn_.push_back(corner[e.vtk == 13 ? gmsh_prism_to_vtk[k] : k]);
    cell_at_.push_back(at);
    physical_.push_back(physical);
    geometrical_.push_back(geometrical);
    higher_order_ += e.higher_order;
  }

  void read_elements(uint64_t at) {
    if (element_tags_.size()) src_.fail_line(at, "a second $Elements section");
    if (major_ == 2) {
      uint64_t const n = count("the element count");
      for (uint64_t i = 0; i < n; ++i) {
        skip_space();
        uint64_t const l = pos_;
        int64_t const tag = number<int64_t>("an element tag");
        int64_t const type = number<int64_t>("an element type");
        int64_t const ntags = number<int64_t>("the element's tag count");
        if (ntags < 0 || ntags > 1000) src_.fail_line(l, "element " + std::to_string(tag) + " claims " + std::to_string(ntags) + " tags");
        double physical = std::numeric_limits<double>::quiet_NaN(), geometrical = physical;
        for (int64_t k = 0; k < ntags; ++k) {
          double const t = double(number<int64_t>("an element tag value"));
          if (k == 0) physical = t;
          if (k == 1) geometrical = t;
        }
        add_element(l, tag, type, line(), physical, geometrical);
      }
    } else {
      uint64_t const blocks = count("the entity block count");
      uint64_t const n = count("the element count");
      number<int64_t>("the smallest element tag");
      number<int64_t>("the largest element tag");
      for (uint64_t b = 0; b < blocks; ++b) {
        number<int64_t>("an entity dimension");
        double const entity = double(number<int64_t>("an entity tag"));
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
        src_.fail_line(at, "$Elements announces " + std::to_string(n) + " elements, its blocks hold " +
                               std::to_string(element_tags_.size()));
    }
    if (int64_t const dup = element_tags_.finish()) src_.fail_line(at, "element tag " + std::to_string(dup) + " appears twice");
    expect_end("Elements");
  }

  /// $NodeData / $ElementData: string tags (the view's name first), real
  /// tags (the time), integer tags (time step, components, count), then one
  /// line per node or element: its tag and its components.
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
    if (ints.size() < 3) src_.fail_line(at, "$" + std::string(section) + " needs 3 integer tags (time step, components, count)");
    std::string const name = strings.empty() || strings[0].empty() ? std::string(point ? "node data" : "element data") : strings[0];
    int64_t const ncomp = ints[1], n = ints[2];
    if (ncomp < 1 || ncomp > 9) src_.fail_line(at, "view " + in_quotes(name) + " has " + std::to_string(ncomp) + " components (1 to 9)");
    if (n < 0 || uint64_t(n) > (end() - pos_) / 2 + 1) src_.fail_line(at, "view " + in_quotes(name) + " claims " + std::to_string(n) + " values");
    std::vector<Data>& list = point ? point_data_ : cell_data_;
    bool const repeat = std::any_of(list.begin(), list.end(), [&](Data const& d) { return d.name == name; });
    uint64_t const items = point ? node_tags_.size() : types_.size();
    Data d{name, int(ncomp), std::vector<double>(repeat ? 0 : items * uint64_t(ncomp), std::numeric_limits<double>::quiet_NaN())};
    for (int64_t i = 0; i < n; ++i) {
      skip_space();
      uint64_t const l = pos_;
      int64_t const tag = number<int64_t>(point ? "a node tag" : "an element tag");
      uint32_t const index = point ? node_tags_.find(tag) : element_tags_.find(tag);
      if (index == TagMap::missing)
        src_.fail_line(l, "view " + in_quotes(name) + " names " + (point ? "node " : "element ") + std::to_string(tag) +
                              ", which the mesh does not have");
      uint32_t const slot = point ? index : element_cell_[index];
      for (int64_t k = 0; k < ncomp; ++k) {
        double const v = number<double>("a value");
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
    UnstructuredGrid grid;
    grid.report.file = src_.name;
    grid.report.format = major_ == 2 ? "gmsh MSH 2.2 ASCII" : "gmsh MSH 4.1 ASCII";
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
    where.type = [this](uint64_t c) { return src_.at_line(cell_at_[std::min<uint64_t>(c, cell_at_.size() - 1)]); };
    where.conn = [this, &offsets](uint64_t k) {
      uint64_t const c = uint64_t(std::upper_bound(offsets.begin(), offsets.end(), k) - offsets.begin()) - 1;
      return src_.at_line(cell_at_[std::min<uint64_t>(c, cell_at_.size() - 1)]);
    };
    CellKinds const kinds = build_cells(
        ncells, types, conn, [&offsets](uint64_t c) { return std::pair<uint64_t, uint64_t>(offsets[c], offsets[c + 1]); },
        npoints, opts_, grid, where);
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
/// @throws IoError naming the file and line on malformed, truncated or
///         unsupported content; no partial grid is ever returned.
inline UnstructuredGrid read_gmsh_from_memory(std::string_view bytes, std::string name_for_errors,
                                              ReadOptions const& opts = {}) {
  io::Source const src{bytes, std::move(name_for_errors)};
  return io::naming_out_of_memory(src.name, [&] { return io::GmshParser(src, opts).parse(); });
}

/// Reads a gmsh ".msh" file, MSH 2.2 or 4.1 ASCII (see the file comment
/// for what is kept).
/// @throws IoError as read_gmsh_from_memory, or when the file cannot be read.
inline UnstructuredGrid read_gmsh(std::string const& path, ReadOptions const& opts = {}) {
  io::FileBytes const file(path);
  return read_gmsh_from_memory(file.bytes(), path, opts);
}

}  // namespace cellray
