#pragma once
// Internals shared by the VTK readers: error locations, typed number arrays
// over bounds-checked bytes, ASCII number parsing, cell building and array
// conversion. Everything here checks counts against the bytes present before
// allocating, so a header claiming 10^12 points fails without allocating.

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <new>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#if defined(__unix__) || defined(__APPLE__)
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#define CELLRAY_IO_MMAP 1
#endif

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include "../error.hpp"
#include "../memory.hpp"
#include "../mesh/vtk_cells.hpp"
#include "grid.hpp"

namespace cellray {
namespace io {

/// The bytes being parsed and the name errors carry. Lines are counted only
/// when an error is raised, so parsing never pays for them.
struct Source {
  std::string_view bytes;
  std::string name;

  uint64_t line_at(uint64_t offset) const {
    offset = std::min<uint64_t>(offset, bytes.size());
    return 1 + uint64_t(std::count(bytes.begin(), bytes.begin() + std::ptrdiff_t(offset), '\n'));
  }
  /// "file:LINE: " for text.
  std::string at_line(uint64_t offset) const { return name + ":" + std::to_string(line_at(offset)) + ": "; }
  /// "file: byte N: " for binary data.
  std::string at_byte(uint64_t offset) const { return name + ": byte " + std::to_string(offset) + ": "; }
  [[noreturn]] void fail_line(uint64_t offset, std::string const& msg) const { throw IoError(at_line(offset) + msg); }
  [[noreturn]] void fail_byte(uint64_t offset, std::string const& msg) const { throw IoError(at_byte(offset) + msg); }
};

/// Throws IoError unless `path` names a regular file (after symlinks): a
/// directory fails later with an obscure message, and opening a FIFO or a
/// terminal blocks until someone writes to it.
inline void require_regular_file(std::string const& path, char const* what = "file") {
  std::error_code ec;
  auto const st = std::filesystem::status(path, ec);
  if (ec || st.type() == std::filesystem::file_type::not_found)
    throw IoError(path + ": cannot open " + what + " (" + (ec ? ec.message() : std::string("no such file")) + ")");
  switch (st.type()) {
    case std::filesystem::file_type::regular: return;
    case std::filesystem::file_type::directory: throw IoError(path + ": is a directory, not a " + what);
    case std::filesystem::file_type::fifo: throw IoError(path + ": is a FIFO (named pipe), not a regular " + what);
    case std::filesystem::file_type::socket: throw IoError(path + ": is a socket, not a regular " + what);
    case std::filesystem::file_type::character:
    case std::filesystem::file_type::block: throw IoError(path + ": is a device, not a regular " + what);
    default: throw IoError(path + ": is not a regular " + what);
  }
}

/// The whole file in memory. @throws IoError naming the file when it cannot
/// be read or is not a regular file (see require_regular_file).
inline std::string read_file_bytes(std::string const& path) {
  require_regular_file(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path + ": cannot open file (" + std::generic_category().message(errno) + ")");
  in.seekg(0, std::ios::end);
  std::streamoff const size = in.tellg();
  if (size < 0) throw IoError(path + ": cannot determine the file size");
  std::string bytes(size_t(size), '\0');
  in.seekg(0, std::ios::beg);
  if (size > 0 && !in.read(bytes.data(), size)) throw IoError(path + ": read failed");
  return bytes;
}

/// Runs `read()`, turning an allocation failure into an IoError that names
/// the file: "out of memory" alone leaves a user guessing which input.
template <class Read> auto naming_out_of_memory(std::string const& name, Read&& read) -> decltype(read()) {
  try {
    return read();
  } catch (std::bad_alloc const&) {
    throw IoError(name + ": not enough memory to read it (the file declares more data than this machine can hold)");
  }
}

/// A whole file's bytes, read-only: mapped where the system can (POSIX
/// mmap), else read into memory. Mapping shares the page cache's pages, so a
/// large file costs no fresh memory: on the VMs measured in PROFILE.md a first
/// write to a fresh 4 KB page costs ~12 us, which made copying an 18.8 MB file
/// into a std::string 55-60 ms, a third of its load. The mapping is private
/// and sized when opened; a file truncated by another process while it is
/// being read ends that read with SIGBUS (as for any mmap reader).
/// @throws IoError naming the file (see read_file_bytes).
class FileBytes {
 public:
  explicit FileBytes(std::string const& path) {
#ifdef CELLRAY_IO_MMAP
    require_regular_file(path);
    int const fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) throw IoError(path + ": cannot open file (" + std::generic_category().message(errno) + ")");
    struct stat st {};
    if (::fstat(fd, &st) != 0) {
      ::close(fd);
      throw IoError(path + ": cannot determine the file size");
    }
    size_t const size = size_t(st.st_size);
    if (size > 0) {
      int flags = MAP_PRIVATE;
#ifdef MAP_POPULATE
      flags |= MAP_POPULATE;  // one call maps every cached page instead of a fault per 64 KB
#endif
      void* const p = ::mmap(nullptr, size, PROT_READ, flags, fd, 0);
      if (p != MAP_FAILED) {
        map_ = p;
        size_ = size;
        view_ = std::string_view(static_cast<char const*>(p), size);
      }
    }
    ::close(fd);
    if (map_) return;  // else (empty, or mmap refused) read it
#endif
    copy_ = naming_out_of_memory(path, [&] { return read_file_bytes(path); });
    view_ = copy_;
  }
  ~FileBytes() {
#ifdef CELLRAY_IO_MMAP
    if (map_) ::munmap(map_, size_);
#endif
  }
  FileBytes(FileBytes const&) = delete;
  FileBytes& operator=(FileBytes const&) = delete;

  std::string_view bytes() const { return view_; }

 private:
  void* map_ = nullptr;
  size_t size_ = 0;
  std::string copy_;
  std::string_view view_;
};

inline std::string in_quotes(std::string_view s) { return "'" + std::string(s.substr(0, 80)) + (s.size() > 80 ? "...'" : "'"); }

inline char ascii_lower(char c) { return (c >= 'A' && c <= 'Z') ? char(c - 'A' + 'a') : c; }
inline bool iequals(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (ascii_lower(a[i]) != ascii_lower(b[i])) return false;
  return true;
}
inline bool is_space(char c) { return c == ' ' || c == '\n' || c == '\r' || c == '\t' || c == '\f' || c == '\v'; }

/// Element types of VTK arrays. `bit` packs 8 values per byte, most significant first.
enum class NumType : uint8_t { bit, i8, u8, i16, u16, i32, u32, i64, u64, f32, f64 };

inline uint64_t num_size(NumType t) {
  switch (t) {
    case NumType::bit: return 0;  // see bytes_for()
    case NumType::i8: case NumType::u8: return 1;
    case NumType::i16: case NumType::u16: return 2;
    case NumType::i32: case NumType::u32: case NumType::f32: return 4;
    default: return 8;
  }
}
inline bool is_integer(NumType t) { return t != NumType::f32 && t != NumType::f64; }
inline char const* num_name(NumType t) {
  constexpr char const* names[] = {"Bit", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64", "Float32", "Float64"};
  return names[int(t)];
}
/// Bytes `count` values of type `t` take.
inline uint64_t bytes_for(NumType t, uint64_t count) { return t == NumType::bit ? (count + 7) / 8 : count * num_size(t); }

/// Largest count whose byte size cannot overflow uint64 arithmetic anywhere below.
constexpr uint64_t max_count = uint64_t(1) << 56;

/// `a * b`, or false when it exceeds `max_count`.
inline bool checked_mul(uint64_t a, uint64_t b, uint64_t& out) {
  if (a != 0 && b > max_count / a) return false;
  out = a * b;
  return out <= max_count;
}

template <class T> T load_value(unsigned char const* p, bool swap) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, p, sizeof(T));
  if (swap) std::reverse(b, b + sizeof(T));
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

/// `count` numbers of one type over bytes already checked to be present,
/// either in the file buffer (zero-copy) or owned. Move-only so `data` never
/// dangles into a copied vector.
struct NumArray {
  NumType type = NumType::f64;
  bool swap = false;  ///< bytes are in the other byte order than the host's
  uint64_t count = 0;
  unsigned char const* data = nullptr;
  /// Decoded bytes: resize() leaves them unset (they are written next), and
  /// large ones are huge pages (memory.hpp), so a decoded array costs no
  /// zeroing pass and few first-write faults.
  cellray::detail::LargeVector<unsigned char> owned;
  /// Decoded Float32 values in the host's order, in the container a grid
  /// keeps them in, so that a reader can adopt them (take_floats) instead of
  /// converting them into fresh memory.
  std::vector<float> floats;

  NumArray() = default;
  NumArray(NumArray&&) = default;
  NumArray& operator=(NumArray&&) = default;
  NumArray(NumArray const&) = delete;
  NumArray& operator=(NumArray const&) = delete;

  /// Values parsed from text: doubles (or int64 when `integers`), native order.
  template <class T> static NumArray owning(std::vector<T> const& v) {
    static_assert(std::is_same_v<T, double> || std::is_same_v<T, int64_t>);
    NumArray a;
    a.type = std::is_same_v<T, double> ? NumType::f64 : NumType::i64;
    a.count = v.size();
    a.owned.resize(v.size() * sizeof(T));
    if (!v.empty()) std::memcpy(a.owned.data(), v.data(), a.owned.size());
    a.data = a.owned.data();
    return a;
  }
  /// A view over `bytes_for(type, count)` bytes at `p` that outlive it.
  static NumArray viewing(NumType type, uint64_t count, unsigned char const* p, bool swap) {
    NumArray a;
    a.type = type;
    a.count = count;
    a.data = p;
    a.swap = swap;
    return a;
  }
  /// Takes ownership of decoded bytes.
  static NumArray owning_bytes(NumType type, uint64_t count, cellray::detail::LargeVector<unsigned char> bytes, bool swap) {
    NumArray a;
    a.type = type;
    a.count = count;
    a.owned = std::move(bytes);
    a.data = a.owned.data();
    a.swap = swap;
    return a;
  }

  /// Float32 values owned as a std::vector<float>.
  static NumArray owning_floats(std::vector<float> v) {
    NumArray a;
    a.type = NumType::f32;
    a.count = v.size();
    a.floats = std::move(v);
    a.data = reinterpret_cast<unsigned char const*>(a.floats.data());
    return a;
  }
  /// Moves the values out as floats when they are owned as such and number
  /// `n`, leaving this array empty; false (and nothing moved) otherwise.
  bool take_floats(uint64_t n, std::vector<float>& out) {
    if (floats.empty() || floats.size() != n || count != n) return false;
    out = std::move(floats);
    floats = {};
    count = 0;
    data = nullptr;
    return true;
  }

  double as_double(uint64_t i) const {
    switch (type) {
      case NumType::bit: return double((data[i / 8] >> (7 - i % 8)) & 1);
      case NumType::i8: return double(int8_t(data[i]));
      case NumType::u8: return double(data[i]);
      case NumType::i16: return double(load_value<int16_t>(data + 2 * i, swap));
      case NumType::u16: return double(load_value<uint16_t>(data + 2 * i, swap));
      case NumType::i32: return double(load_value<int32_t>(data + 4 * i, swap));
      case NumType::u32: return double(load_value<uint32_t>(data + 4 * i, swap));
      case NumType::i64: return double(load_value<int64_t>(data + 8 * i, swap));
      case NumType::u64: return double(load_value<uint64_t>(data + 8 * i, swap));
      case NumType::f32: return double(load_value<float>(data + 4 * i, swap));
      case NumType::f64: return load_value<double>(data + 8 * i, swap);
    }
    return 0.0;
  }
  /// Integer value (only for integer types); uint64 values beyond int64 map to
  /// int64 max so that range checks reject them.
  int64_t as_int(uint64_t i) const {
    switch (type) {
      case NumType::bit: return int64_t((data[i / 8] >> (7 - i % 8)) & 1);
      case NumType::i8: return int8_t(data[i]);
      case NumType::u8: return data[i];
      case NumType::i16: return load_value<int16_t>(data + 2 * i, swap);
      case NumType::u16: return load_value<uint16_t>(data + 2 * i, swap);
      case NumType::i32: return load_value<int32_t>(data + 4 * i, swap);
      case NumType::u32: return load_value<uint32_t>(data + 4 * i, swap);
      case NumType::i64: return load_value<int64_t>(data + 8 * i, swap);
      case NumType::u64: {
        uint64_t const v = load_value<uint64_t>(data + 8 * i, swap);
        return v > uint64_t(std::numeric_limits<int64_t>::max()) ? std::numeric_limits<int64_t>::max() : int64_t(v);
      }
      default: return 0;
    }
  }
};

inline uint32_t byte_swap(uint32_t u) {
  return (u >> 24) | ((u >> 8) & 0xff00u) | ((u << 8) & 0xff0000u) | (u << 24);
}
inline uint64_t byte_swap(uint64_t u) { return (uint64_t(byte_swap(uint32_t(u))) << 32) | byte_swap(uint32_t(u >> 32)); }

/// Value i of 4- or 8-byte values at `p`, byte order fixed at compile time so
/// that loops over it vectorise (the swap compiles to bswap / vpshufb).
template <class T, bool Swap> inline T load_at(unsigned char const* p, uint64_t i) {
  static_assert(sizeof(T) == 4 || sizeof(T) == 8);
  using U = std::conditional_t<sizeof(T) == 4, uint32_t, uint64_t>;
  U u;
  std::memcpy(&u, p + sizeof(T) * i, sizeof(T));
  if constexpr (Swap) u = byte_swap(u);
  T v;
  std::memcpy(&v, &u, sizeof(T));
  return v;
}

/// Calls `f(get)` once, `get(i)` returning value i of `a` as a double: one
/// switch on the element type per array instead of one per value. Float32 and
/// Float64 in either byte order get their own loop, other types as_double().
template <class F> void with_doubles(NumArray const& a, F&& f) {
  unsigned char const* const p = a.data;
  if (a.type == NumType::f32 && a.swap) f([p](uint64_t i) { return double(load_at<float, true>(p, i)); });
  else if (a.type == NumType::f32) f([p](uint64_t i) { return double(load_at<float, false>(p, i)); });
  else if (a.type == NumType::f64 && a.swap) f([p](uint64_t i) { return load_at<double, true>(p, i); });
  else if (a.type == NumType::f64) f([p](uint64_t i) { return load_at<double, false>(p, i); });
  else f([&a](uint64_t i) { return a.as_double(i); });
}
/// As with_doubles for integer arrays: `get(i)` is a.as_int(i); Int32 and
/// Int64 in either byte order and UInt8 get their own loop.
template <class F> void with_ints(NumArray const& a, F&& f) {
  unsigned char const* const p = a.data;
  if (a.type == NumType::i32 && a.swap) f([p](uint64_t i) { return int64_t(load_at<int32_t, true>(p, i)); });
  else if (a.type == NumType::i32) f([p](uint64_t i) { return int64_t(load_at<int32_t, false>(p, i)); });
  else if (a.type == NumType::i64 && a.swap) f([p](uint64_t i) { return load_at<int64_t, true>(p, i); });
  else if (a.type == NumType::i64) f([p](uint64_t i) { return load_at<int64_t, false>(p, i); });
  else if (a.type == NumType::u8) f([p](uint64_t i) { return int64_t(p[i]); });
  else f([&a](uint64_t i) { return a.as_int(i); });
}

/// Values per parallel task when converting arrays: large enough that a task
/// is ~100 us, small enough that both of two cores first-touch the output
/// (a fresh page's first write dominates loading; PROFILE.md).
constexpr uint64_t convert_grain = uint64_t(1) << 16;

/// double to float without undefined behaviour: out-of-range values become +-inf.
inline float to_float(double d) {
  constexpr double fmax = double(std::numeric_limits<float>::max());
  if (d > fmax) return std::numeric_limits<float>::infinity();
  if (d < -fmax) return -std::numeric_limits<float>::infinity();
  return float(d);
}

/// Parses one number from [p, end); the number must end at whitespace or
/// `end`. Accepts a leading '+', "nan", "inf" (from_chars).
inline bool parse_number(char const*& p, char const* end, double& out) {
  char const* q = p;
  if (q < end && *q == '+') ++q;
  auto r = std::from_chars(q, end, out);
  if (r.ec == std::errc::result_out_of_range) {
    // Denormal or overflowing text: from_chars leaves `out` untouched; take
    // the limit VTK's strtod would give.
    out = (q < end && *q == '-') ? -HUGE_VAL : HUGE_VAL;
    for (char const* s = q; s < r.ptr; ++s)
      if (*s == 'e' || *s == 'E') {
        if (s + 1 < r.ptr && s[1] == '-') out = 0.0;
        break;
      }
  } else if (r.ec != std::errc()) {
    return false;
  }
  if (r.ptr < end && !is_space(*r.ptr)) return false;
  p = r.ptr;
  return true;
}
inline bool parse_number(char const*& p, char const* end, int64_t& out) {
  char const* q = p;
  if (q < end && *q == '+') ++q;
  auto r = std::from_chars(q, end, out);
  if (r.ec != std::errc()) return false;
  if (r.ptr < end && !is_space(*r.ptr)) return false;
  p = r.ptr;
  return true;
}
/// A whole token as a non-negative count (at most `max_count`).
inline bool parse_count(std::string_view tok, uint64_t& out) {
  if (tok.empty()) return false;
  auto r = std::from_chars(tok.data(), tok.data() + tok.size(), out);
  return r.ec == std::errc() && r.ptr == tok.data() + tok.size() && out <= max_count;
}
inline bool parse_int_token(std::string_view tok, int64_t& out) {
  char const* p = tok.data();
  return parse_number(p, tok.data() + tok.size(), out) && p == tok.data() + tok.size();
}

/// Reads `count` whitespace-separated numbers from `text` starting at `pos`
/// (advanced past them). `T` is double for data, int64_t for ids. Checks the
/// count against the text left before allocating. Errors name the line.
template <class T>
std::vector<T> parse_ascii_numbers(Source const& src, uint64_t& pos, uint64_t count, std::string const& what,
                                   uint64_t text_end = std::numeric_limits<uint64_t>::max()) {
  char const* const base = src.bytes.data();
  uint64_t const end_off = std::min<uint64_t>(text_end, src.bytes.size());
  // Each number needs at least one character and one separator.
  if (count > (end_off - std::min(pos, end_off) + 1) / 2)
    src.fail_line(pos, what + ": " + std::to_string(count) + " values declared but only " +
                           std::to_string(end_off - std::min(pos, end_off)) + " bytes of text are left");
  std::vector<T> out(count);
  char const* p = base + pos;
  char const* const end = base + end_off;
  for (uint64_t i = 0; i < count; ++i) {
    while (p < end && is_space(*p)) ++p;
    if (p == end)
      src.fail_line(uint64_t(p - base), what + ": the data ends after " + std::to_string(i) + " of " +
                                            std::to_string(count) + " values");
    char const* const start = p;
    if (!parse_number(p, end, out[i])) {
      char const* e = start;
      while (e < end && !is_space(*e) && e - start < 40) ++e;
      src.fail_line(uint64_t(start - base), what + ": value " + std::to_string(i) + " is " +
                                                in_quotes(std::string_view(start, size_t(e - start))) + ", not " +
                                                (std::is_same_v<T, double> ? "a number" : "an integer"));
    }
  }
  pos = uint64_t(p - base);
  return out;
}

/// How a VTK cell type is read.
enum class CellKind : uint8_t { tet, hex, voxel, polyhedron, unsupported, unknown };

/// Kind of a VTK cell type id and the vertex count it needs (`exact`) or at
/// least needs (`!exact`, Lagrange/Bezier of any order).
inline CellKind classify_cell(int64_t type, uint64_t& nodes, bool& exact) {
  exact = true;
  switch (type) {
    case 10: nodes = 4; return CellKind::tet;
    case 24: nodes = 10; return CellKind::tet;
    case 71: case 78: nodes = 4; exact = false; return CellKind::tet;
    case 12: nodes = 8; return CellKind::hex;
    case 11: nodes = 8; return CellKind::voxel;
    case 25: nodes = 20; return CellKind::hex;
    case 29: nodes = 27; return CellKind::hex;
    case 33: nodes = 24; return CellKind::hex;
    case 72: case 79: nodes = 8; exact = false; return CellKind::hex;
    // Wedges and pyramids become collapsed hexahedra (mesh/vtk_cells.hpp:
    // VTK's own interpolation); quadratic and higher-order ones keep their corners.
    case 13: nodes = 6; return CellKind::hex;
    case 26: nodes = 15; return CellKind::hex;
    case 32: nodes = 18; return CellKind::hex;
    case 73: case 80: nodes = 6; exact = false; return CellKind::hex;
    case 14: nodes = 5; return CellKind::hex;
    case 42: nodes = 4; exact = false; return CellKind::polyhedron;  // its distinct points; faces apart
    case 27: nodes = 13; return CellKind::hex;
    default:
      nodes = 0;
      if (type < 0 || type > 81) return CellKind::unknown;
      return std::string_view(vtk_cell_type_name(int(type))) == "unknown" ? CellKind::unknown : CellKind::unsupported;
  }
}

/// Where hexahedron corner k of a kept hex-kind cell of VTK type `type` is
/// in the cell's vertex list: voxels reorder, wedges and pyramids repeat.
inline int const* hex_corner_order(int64_t type) {
  static constexpr int identity[8] = {0, 1, 2, 3, 4, 5, 6, 7};
  switch (type) {
    case 11: return voxel_as_hex.data();
    case 13: case 26: case 32: case 73: case 80: return wedge_as_hex.data();
    case 14: case 27: return pyramid_as_hex.data();
    default: return identity;
  }
}

/// Per original cell: 0 = kept tet, 1 = kept hex, 2 = skipped, 3 = polyhedron
/// (decomposed by the reader afterwards; for splitting cell arrays).
using CellKinds = std::vector<uint8_t>;

/// Where errors about cells point: `conn(k)` for connectivity entry k,
/// `type(c)` for the type of cell c; each returns a "file:...: " prefix.
struct CellLocator {
  std::function<std::string(uint64_t)> conn;
  std::function<std::string(uint64_t)> type;
};

/// Second pass of build_cells: copies the vertex ids of kept cells, tasks of
/// `cell_grain` cells in parallel (each starts at its cell's output slot,
/// counted from `kinds`). Every id is checked, once per cell with one compare
/// against `npoints`; when any is out of range the cells are walked again in
/// order so the error names the first bad id, as a serial reader would.
/// Where each task of fill_cells starts, recorded by build_cells' first pass:
/// the span function left at the task's first cell (a cursor, as the legacy
/// classic layout's, then walks the list once in all) and the kept tets and
/// hexes before it.
template <class SpanFn> struct CellTasks {
  std::vector<SpanFn> walks;
  std::vector<uint64_t> first_tet, first_hex;
};
/// Cells per task of fill_cells.
constexpr uint64_t cell_grain = uint64_t(1) << 14;

template <class SpanFn>
void fill_cells(uint64_t ncells, NumArray const& types, NumArray const& conn, SpanFn const& span, uint64_t npoints,
                UnstructuredGrid& grid, CellLocator const& where, CellKinds const& kinds, CellTasks<SpanFn> const& tasks) {
  uint64_t const nchunks = tasks.walks.size();
  auto const& first_tet = tasks.first_tet;
  auto const& first_hex = tasks.first_hex;
  auto const& walks = tasks.walks;
  bool bad = false;
  with_ints(conn, [&](auto const get) {
    std::vector<unsigned char> chunk_bad(nchunks, 0);
    auto fill = [&](tbb::blocked_range<uint64_t> const& r) {
      for (uint64_t j = r.begin(); j < r.end(); ++j) {
        SpanFn walk = walks[j];
        uint32_t* tet = grid.tets.data() + 4 * first_tet[j];
        uint32_t* hex = grid.hexes.data() + 8 * first_hex[j];
        uint64_t out_of_range = 0;
        for (uint64_t c = j * cell_grain, e = std::min(ncells, c + cell_grain); c < e; ++c) {
          if (kinds[c] >= 2) continue;
          uint64_t const b = walk(c).first;
          if (kinds[c] == 0) {
            for (int k = 0; k < 4; ++k) {
              int64_t const v = get(b + uint64_t(k));
              out_of_range |= uint64_t(uint64_t(v) >= npoints);  // negative ids wrap to huge
              tet[k] = uint32_t(v);
            }
            tet += 4;
          } else {
            // Voxels, wedges and pyramids: their corners in hexahedron order.
            int const* order = hex_corner_order(types.as_int(c));
            for (int k = 0; k < 8; ++k) {
              int64_t const v = get(b + uint64_t(order[k]));
              out_of_range |= uint64_t(uint64_t(v) >= npoints);
              hex[k] = uint32_t(v);
            }
            hex += 8;
          }
        }
        chunk_bad[j] = out_of_range != 0;
      }
    };
    tbb::blocked_range<uint64_t> const all(0, nchunks, 1);
    if (nchunks <= 1) fill(all);
    else tbb::parallel_for(all, fill);
    for (unsigned char b : chunk_bad) bad |= b != 0;
  });
  if (!bad) return;
  SpanFn walk = span;
  for (uint64_t c = 0; c < ncells; ++c) {
    if (kinds[c] >= 2) continue;
    uint64_t const b = walk(c).first;
    int const* order = kinds[c] == 1 ? hex_corner_order(types.as_int(c)) : nullptr;
    for (int k = 0; k < (kinds[c] == 0 ? 4 : 8); ++k) {
      uint64_t const at = b + uint64_t(order ? order[k] : k);
      int64_t const v = conn.as_int(at);
      if (v < 0 || uint64_t(v) >= npoints)
        throw IoError(where.conn(at) + "cell " + std::to_string(c) + " uses vertex id " + std::to_string(v) +
                      ", outside [0, " + std::to_string(npoints) + ")");
    }
  }
}

/// Builds `grid.tets` / `grid.hexes` from VTK cells: cell c has type
/// `types.as_int(c)` and vertex ids `conn[span(c).first, span(c).second)`,
/// ranges already checked to lie within `conn`. Checks types, vertex counts
/// per type and every kept vertex id against `npoints`; fills the cell counts
/// of the report. Returns the kind of each cell.
/// Distinct vertex ids among n.
inline int distinct_ids(uint32_t const* v, int n) {
  int d = 0;
  for (int i = 0; i < n; ++i) {
    bool seen = false;
    for (int j = 0; j < i; ++j) seen = seen || v[j] == v[i];
    d += !seen;
  }
  return d;
}

/// A kept cell with fewer than 4 distinct vertices (a collapsed hexahedron,
/// wedge or tetrahedron: no volume, no shape to render) is an error naming
/// the cell and its place in the file, or with skip_unsupported_cells a
/// skip counted under its type. Cells with repeated ids and 4 or more
/// distinct ones are kept: they are the shape they really are (a hex with
/// a collapsed face is a wedge or a pyramid, mesh/vtk_cells.hpp).
template <class SpanFn>
void drop_collapsed_cells(uint64_t ncells, NumArray const& types, SpanFn span, ReadOptions const& opts,
                          UnstructuredGrid& grid, CellLocator const& where, CellKinds& kinds) {
  uint64_t const nt = grid.tet_count(), nh = grid.hex_count();
  auto bad_tet = [&](uint64_t i) { return distinct_ids(grid.tets.data() + 4 * i, 4) < 4; };
  auto bad_hex = [&](uint64_t i) { return distinct_ids(grid.hexes.data() + 8 * i, 8) < 4; };
  bool const any = tbb::parallel_reduce(
      tbb::blocked_range<uint64_t>(0, nt + nh, uint64_t(1) << 14), false,
      [&](tbb::blocked_range<uint64_t> const& r, bool acc) {
        for (uint64_t i = r.begin(); i < r.end() && !acc; ++i) acc = i < nt ? bad_tet(i) : bad_hex(i - nt);
        return acc;
      },
      [](bool a, bool b) { return a || b; });
  if (!any) return;
  // Rare: walk the file's cells in order, name the first or drop them all.
  std::vector<uint32_t> tets, hexes;
  uint64_t ti = 0, hi = 0;
  for (uint64_t c = 0; c < ncells; ++c) {
    if (kinds[c] != 0 && kinds[c] != 1) continue;
    bool const tet = kinds[c] == 0;
    bool const bad = tet ? bad_tet(ti) : bad_hex(hi);
    if (bad) {
      int64_t const t = types.as_int(c);
      if (!opts.skip_unsupported_cells) {
        uint32_t const* v = tet ? grid.tets.data() + 4 * ti : grid.hexes.data() + 8 * hi;
        throw IoError(where.conn(span(c).first) + "cell " + std::to_string(c) + " (" + vtk_cell_type_name(int(t)) +
                      ") has " + std::to_string(distinct_ids(v, tet ? 4 : 8)) +
                      " distinct vertices: a collapsed cell needs at least 4 to have a volume "
                      "(set ReadOptions::skip_unsupported_cells to skip such cells)");
      }
      ++grid.report.cells_skipped[int(t)];
      kinds[c] = 2;
    } else if (tet) {
      tets.insert(tets.end(), grid.tets.begin() + long(4 * ti), grid.tets.begin() + long(4 * ti + 4));
    } else {
      hexes.insert(hexes.end(), grid.hexes.begin() + long(8 * hi), grid.hexes.begin() + long(8 * hi + 8));
    }
    (tet ? ti : hi) += 1;
  }
  grid.tets = std::move(tets);
  grid.hexes = std::move(hexes);
}

/// The file cell ids of the tets and hexahedra kept (kinds 0 and 1) into
/// `grid` (UnstructuredGrid::tet_file_cells), unless the cells are of one
/// kind with none skipped (each one's index is its id) or too many for
/// 32-bit ids. Polyhedra (kind 3) count as out of order: their pieces come
/// after the other cells (io/polyhedra.hpp adds their ids).
inline void record_file_cells(CellKinds const& kinds, UnstructuredGrid& grid) {
  uint64_t const n = kinds.size();
  if (n == 0 || n > std::numeric_limits<uint32_t>::max()) return;
  uint8_t const k0 = kinds[0];
  if ((k0 == 0 || k0 == 1) && std::all_of(kinds.begin(), kinds.end(), [k0](uint8_t k) { return k == k0; })) return;
  grid.tet_file_cells.clear();
  grid.hex_file_cells.clear();
  grid.tet_file_cells.reserve(grid.tet_count());
  grid.hex_file_cells.reserve(grid.hex_count());
  for (uint64_t c = 0; c < n; ++c) {
    if (kinds[c] == 0) grid.tet_file_cells.push_back(uint32_t(c));
    else if (kinds[c] == 1) grid.hex_file_cells.push_back(uint32_t(c));
  }
}

/// Polyhedra (VTK 42) are kind 3 when the format gives their faces
/// (`polyhedra`: VTU, legacy VTK), else unsupported; their ids are not
/// checked here (io/polyhedra.hpp checks their faces). Records the file
/// cell ids (record_file_cells).
template <class SpanFn>
CellKinds build_cells(uint64_t ncells, NumArray const& types, NumArray const& conn, SpanFn span, uint64_t npoints,
                      ReadOptions const& opts, UnstructuredGrid& grid, CellLocator const& where,
                      bool polyhedra = false) {
  if (!is_integer(types.type)) throw IoError(where.type(0) + "cell types are stored as " + num_name(types.type) + ", not integers");
  if (!is_integer(conn.type))
    throw IoError(where.conn(0) + "cell connectivity is stored as " + num_name(conn.type) + ", not integers");
  uint64_t per_type[82] = {};
  uint64_t first_unsupported[82] = {};
  uint64_t ntets = 0, nhexes = 0, nunsupported = 0;
  CellKinds kinds(ncells);
  CellTasks<SpanFn> tasks;
  with_ints(types, [&](auto const type_of) {
  for (uint64_t c = 0; c < ncells; ++c) {
    if (c % cell_grain == 0) {
      tasks.first_tet.push_back(ntets);
      tasks.first_hex.push_back(nhexes);
    }
    int64_t const t = type_of(c);
    uint64_t nodes = 0;
    bool exact = true;
    CellKind kind = classify_cell(t, nodes, exact);
    if (kind == CellKind::polyhedron && !polyhedra) kind = CellKind::unsupported;
    if (kind == CellKind::unknown)
      throw IoError(where.type(c) + "cell " + std::to_string(c) + " has unknown VTK cell type " + std::to_string(t));
    auto const [b, e] = span(c);
    if (c % cell_grain == 0) tasks.walks.push_back(span);
    uint64_t const have = e - b;
    if (kind != CellKind::unsupported && (exact ? have != nodes : have < nodes))
      throw IoError(where.conn(b) + "cell " + std::to_string(c) + " (" + vtk_cell_type_name(int(t)) + ") has " +
                    std::to_string(have) + " vertex ids, needs " + (exact ? "" : "at least ") + std::to_string(nodes));
    if (per_type[t]++ == 0) first_unsupported[t] = c;
    if (kind == CellKind::tet) {
      ++ntets;
      kinds[c] = 0;
    } else if (kind == CellKind::hex || kind == CellKind::voxel) {
      ++nhexes;
      kinds[c] = 1;
    } else if (kind == CellKind::polyhedron) {
      kinds[c] = 3;
    } else {
      ++nunsupported;
      kinds[c] = 2;
    }
  }
  });
  for (int t = 0; t < 82; ++t)
    if (per_type[t]) grid.report.cells_read[t] = per_type[t];
  if (nunsupported && !opts.skip_unsupported_cells) {
    std::string list;
    uint64_t first = ncells;
    for (int t = 0; t < 82; ++t) {
      uint64_t nodes;
      bool exact;
      CellKind const k = classify_cell(t, nodes, exact);
      if (per_type[t] && (k == CellKind::unsupported || (k == CellKind::polyhedron && !polyhedra))) {
        list += (list.empty() ? "" : ", ") + std::to_string(per_type[t]) + " " + vtk_cell_type_name(t) +
                " (VTK type " + std::to_string(t) + ")";
        first = std::min(first, first_unsupported[t]);
      }
    }
    throw IoError(where.type(first) + "unsupported cells: " + list + "; cellray reads tetrahedra, pyramids, wedges and hexahedra, and polyhedra from .vtu and legacy .vtk files " +
                  "(set ReadOptions::skip_unsupported_cells to skip them)");
  }
  for (int t = 0; t < 82; ++t) {
    uint64_t nodes;
    bool exact;
    CellKind const k = classify_cell(t, nodes, exact);
    if (!per_type[t]) continue;
    if (k == CellKind::unsupported || (k == CellKind::polyhedron && !polyhedra)) grid.report.cells_skipped[t] = per_type[t];
    if (t != 10 && t != 12 && t != 13 && t != 14 && (k == CellKind::tet || k == CellKind::hex || k == CellKind::voxel))
      grid.report.reduced_to_linear += per_type[t];
  }
  // Counts were checked against the connectivity present (each kept cell has
  // >= 4 ids there), so these allocations are bounded by the file size.
  cellray::detail::resize_zeroed(grid.tets, 4 * ntets);
  cellray::detail::resize_zeroed(grid.hexes, 8 * nhexes);
  tasks.first_tet.push_back(ntets);
  tasks.first_hex.push_back(nhexes);
  fill_cells(ncells, types, conn, span, npoints, grid, where, kinds, tasks);
  drop_collapsed_cells(ncells, types, span, opts, grid, where, kinds);
  record_file_cells(kinds, grid);
  return kinds;
}

/// Euclidean magnitude of tuple i (the value itself with one component), `get` as with_doubles gives.
template <class Get> float tuple_value(Get const& get, uint64_t i, int ncomp) {
  if (ncomp == 1) return to_float(get(i));
  double s = 0.0;
  for (int k = 0; k < ncomp; ++k) {
    double const v = get(i * uint64_t(ncomp) + uint64_t(k));
    s += v * v;
  }
  return to_float(std::sqrt(s));
}
inline float tuple_value(NumArray const& a, uint64_t i, int ncomp) {
  return tuple_value([&a](uint64_t k) { return a.as_double(k); }, i, ncomp);
}

/// out[i] = tuple_value(a, i, ncomp) for i < out.size(), in parallel.
inline void convert_tuples(NumArray const& a, int ncomp, std::vector<float>& out) {
  with_doubles(a, [&](auto const get) {
    auto convert = [&](tbb::blocked_range<uint64_t> const& r) {
      for (uint64_t i = r.begin(); i < r.end(); ++i) out[i] = tuple_value(get, i, ncomp);
    };
    tbb::blocked_range<uint64_t> const all(0, out.size(), convert_grain);
    if (out.size() <= convert_grain) convert(all);  // small: not worth waking the thread pool
    else tbb::parallel_for(all, convert);
  });
}

inline std::string describe_array(char const* where, std::string const& name, int ncomp) {
  std::string s = std::string(where) + " '" + name + "'";
  if (ncomp > 1) s += " (" + std::to_string(ncomp) + " components, magnitude)";
  return s;
}

/// The values of a point array of `npoints` tuples, one per vertex
/// (tuple_value), with room for `spare` more (vertices a reader adds later).
inline std::vector<float> point_values(NumArray const& a, int ncomp, uint64_t npoints, uint64_t spare = 0) {
  std::vector<float> v;
  if (spare) v.reserve(npoints + spare);
  cellray::detail::resize_zeroed(v, npoints);
  convert_tuples(a, ncomp, v);
  return v;
}

/// Adds a point array of converted values (point_values), one per vertex.
inline void add_point_array(UnstructuredGrid& grid, std::string name, std::vector<float> values, int ncomp) {
  if (grid.point_array(name)) {
    grid.report.arrays_ignored.push_back("point '" + name + "' (a second point array with that name)");
    return;
  }
  PointArray p;
  p.name = std::move(name);
  p.components = ncomp;
  p.values = std::move(values);
  grid.report.arrays_read.push_back(describe_array("point", p.name, ncomp));
  grid.point_arrays.push_back(std::move(p));
}

/// Adds a point array of `tuples` = vertex count tuples (checked by the
/// caller), with room for `spare` more values.
inline void add_point_array(UnstructuredGrid& grid, std::string name, NumArray const& a, int ncomp, uint64_t spare = 0) {
  std::vector<float> values;
  if (!grid.point_array(name)) values = point_values(a, ncomp, grid.vertex_count(), spare);
  add_point_array(grid, std::move(name), std::move(values), ncomp);
}

/// add_point_array for an array the caller gives up: Float32 values owned
/// as floats (NumArray::take_floats) become the point array as they are.
inline void add_point_array(UnstructuredGrid& grid, std::string name, NumArray&& a, int ncomp, uint64_t spare = 0) {
  std::vector<float> values;
  if (ncomp == 1 && spare == 0 && !grid.point_array(name) && a.take_floats(grid.vertex_count(), values))
    add_point_array(grid, std::move(name), std::move(values), ncomp);
  else
    add_point_array(grid, std::move(name), static_cast<NumArray const&>(a), ncomp, spare);
}

/// Adds a cell array with one tuple per file cell, split by `kinds`; the
/// values of polyhedra (kind 3) go to `polyhedra_values` when given, and
/// the tet and hex values get room for `spare_tets` / `spare_hexes` more.
inline void add_cell_array(UnstructuredGrid& grid, std::string name, NumArray const& a, int ncomp, CellKinds const& kinds,
                           std::vector<float>* polyhedra_values = nullptr, uint64_t spare_tets = 0,
                           uint64_t spare_hexes = 0) {
  if (grid.cell_array(name)) {
    grid.report.arrays_ignored.push_back("cell '" + name + "' (a second cell array with that name)");
    return;
  }
  CellArray c;
  c.name = std::move(name);
  c.components = ncomp;
  if (grid.tet_count() == kinds.size() || grid.hex_count() == kinds.size()) {
    // One kind of cell, none skipped: a straight conversion.
    std::vector<float>& out = grid.tet_count() == kinds.size() ? c.tet_values : c.hex_values;
    cellray::detail::resize_zeroed(out, kinds.size());
    convert_tuples(a, ncomp, out);
  } else {
    c.tet_values.reserve(grid.tet_count() + spare_tets);
    c.hex_values.reserve(grid.hex_count() + spare_hexes);
    with_doubles(a, [&](auto const get) {
      for (uint64_t i = 0; i < kinds.size(); ++i) {
        if (kinds[i] == 0) c.tet_values.push_back(tuple_value(get, i, ncomp));
        else if (kinds[i] == 1) c.hex_values.push_back(tuple_value(get, i, ncomp));
        else if (kinds[i] == 3 && polyhedra_values) polyhedra_values->push_back(tuple_value(get, i, ncomp));
      }
    });
  }
  grid.report.arrays_read.push_back(describe_array("cell", c.name, ncomp));
  grid.cell_arrays.push_back(std::move(c));
}

/// add_cell_array for an array the caller gives up: Float32 values owned as
/// floats become the values of a mesh of one kind as they are.
inline void add_cell_array(UnstructuredGrid& grid, std::string name, NumArray&& a, int ncomp, CellKinds const& kinds,
                           std::vector<float>* polyhedra_values = nullptr, uint64_t spare_tets = 0,
                           uint64_t spare_hexes = 0) {
  bool const one_kind = grid.tet_count() == kinds.size() || grid.hex_count() == kinds.size();
  if (ncomp == 1 && one_kind && spare_tets == 0 && spare_hexes == 0 && !grid.cell_array(name)) {
    CellArray c;
    std::vector<float>& out = grid.tet_count() == kinds.size() ? c.tet_values : c.hex_values;
    if (a.take_floats(kinds.size(), out)) {
      c.name = std::move(name);
      c.components = ncomp;
      grid.report.arrays_read.push_back(describe_array("cell", c.name, ncomp));
      grid.cell_arrays.push_back(std::move(c));
      return;
    }
  }
  add_cell_array(grid, std::move(name), static_cast<NumArray const&>(a), ncomp, kinds, polyhedra_values, spare_tets,
                 spare_hexes);
}

/// Positions from a 3-component array of `npoints` tuples.
inline void set_positions(UnstructuredGrid& grid, NumArray const& a, uint64_t npoints);

/// set_positions for an array the caller gives up: Float32 values owned as
/// floats become the positions as they are, unless room was reserved for
/// points a reader adds (polyhedra's centres), which adopting would drop.
inline void set_positions(UnstructuredGrid& grid, NumArray&& a, uint64_t npoints) {
  if (grid.xyz.capacity() <= 3 * npoints && a.take_floats(3 * npoints, grid.xyz)) return;
  set_positions(grid, static_cast<NumArray const&>(a), npoints);
}

inline void set_positions(UnstructuredGrid& grid, NumArray const& a, uint64_t npoints) {
  cellray::detail::resize_zeroed(grid.xyz, 3 * npoints);
  float* const out = grid.xyz.data();
  with_doubles(a, [&](auto const get) {
    auto convert = [&](tbb::blocked_range<uint64_t> const& r) {
      for (uint64_t i = r.begin(); i < r.end(); ++i) out[i] = to_float(get(i));
    };
    tbb::blocked_range<uint64_t> const all(0, 3 * npoints, convert_grain);
    if (3 * npoints <= convert_grain) convert(all);
    else tbb::parallel_for(all, convert);
  });
}

/// Vertex ids are 32-bit (UnstructuredGrid); a larger point count is refused.
inline bool point_count_fits(uint64_t npoints) { return npoints <= uint64_t(std::numeric_limits<uint32_t>::max()); }

}  // namespace io
}  // namespace cellray
