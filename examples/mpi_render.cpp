// cellray-mpi-render: cellray-render's isosurfaces and DVR on several MPI
// ranks, composited by IceT (issue #22). Run under mpirun:
//
//   mpirun -np 4 cellray-mpi-render mesh.vtk --mode dvr -o out.png
//   mpirun -np 4 cellray-mpi-render pieces.pvtu --mode dvr -o out.png
//
// Input. A single file (.vtk, .vtu) or the generated default scene: every
// rank reads it whole and keeps its region's cells. A ParaView .pvtu: rank
// r of k reads only pieces [r p / k, (r+1) p / k) and the ranks repartition
// the cells with MPI: the bounds and value range by MPI_Allreduce, a k-d
// tree every rank builds alike from a gathered sample of at most 2^20 cell
// centroids, then each cell sent (MPI_Alltoallv, 16 bytes per corner:
// position and the rendered value) to every region it overlaps, where
// equal corners are welded into one vertex again (pieces repeat the points
// on their borders). Memory per rank is then its pieces plus its region,
// never the whole mesh. Ghost cells (vtkGhostType) are dropped by the reader.
//
// Partition (cellray/mesh/partition.hpp): k = ranks regions tiling the mesh
// bounds, split by cell centroids; a cell straddling a region border goes
// to every region it touches. Each rank holds its region's cells with
// compact vertices, builds a BVH over those, renders them with its rays
// clipped exactly to its region's box and a clear background (premultiplied
// RGBA), and IceT blends the ranks' images in the regions' front-to-back
// order for the eye (ICET_COMPOSITE_MODE_BLEND, ICET_ORDERED_COMPOSITE).
// Rank 0 puts the background behind and writes the image. Ordered blending
// is exact for opaque isosurfaces too: the regions are disjoint boxes met in
// order along every ray, so the first opaque hit along a ray (opacity 1)
// hides what the later regions add, as a z-buffer would, with no depth
// buffer to send.
//
// What a rank cannot do alone: shadow and ambient-occlusion rays need the
// whole mesh (a ray leaving the region may be blocked elsewhere), so
// --shadows and --ao are refused. Smooth normals are exact: with them, a
// region also holds the cells within the largest cell extent of its box (a
// halo), which are all the cells around its cells' vertices, so its
// per-vertex gradients are the whole mesh's.
//
// Flags: a subset of cellray-render's, with the same meaning and defaults
// (so an image compares to cellray-render's with the same flags): mesh,
// --generate, --cells, --array, --mode, --iso, --iso-opacity, --normals,
// --tf (presets), --opacity, --unit-distance, --step, --dvr-mode,
// --background, --eye, --at, --up, --fov, --zoom, --azimuth, --elevation,
// --size, -o, --threads, --skip-unsupported, --stats (per-rank timings as
// JSON lines on rank 0's stdout). Tets, hexes or both; meshes whose
// coordinates or values need rescaling for float (cellray-render's Frame /
// ValueFrame) are refused with a message.
//
// Errors: every rank checks its own work; an MPI_Allreduce of an error code
// after each collective phase makes all ranks stop together (exit code as
// cellray-render's: 2 usage, 3 I/O, 4 invalid mesh, 1 other), rank 0
// printing the first failing rank's message: no rank waits for one that
// failed.

#include <mpi.h>

#include <IceT.h>
#include <IceTMPI.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include <CLI/CLI.hpp>
#include <tbb/global_control.h>

#include <cellray/bvh/build.hpp>
#include <cellray/cells/vertex_gradients.hpp>
#include <cellray/error.hpp>
#include <cellray/io/image_write.hpp>
#include <cellray/io/pvtu.hpp>
#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/mesh/neighbours.hpp>
#include <cellray/mesh/partition.hpp>
#include <cellray/mesh/validate.hpp>
#include <cellray/render/render.hpp>
#include <cellray/render/transfer_function.hpp>

#include "cli_common.hpp"
#include "framing.hpp"

namespace {

using namespace cellray;
using namespace cellray_cli;

struct Options {
  std::string mesh_path;
  std::string generate = "tets";
  uint64_t cells = 300000;
  std::string array;
  std::string mode = "iso";
  std::string iso, iso_opacity;
  std::string normals = "smooth";
  std::string tf = "cool-warm";
  float opacity = -1.f;
  float unit_distance = 0.f;
  float step = 0.f;
  std::string dvr_mode = "segments";
  std::string background;
  std::string eye, at, up;
  float fov = 30.f;
  float zoom = 1.f, azimuth = 0.f, elevation = 0.f;
  std::string size = "1024x768";
  std::string out = "cellray.png";
  int threads = 0;
  bool skip_unsupported = false;
  bool stats = false;
  bool shadows = false;
  int ao = 0;
};

/// The error of one rank, carried to the collective check.
struct Failure {
  int code = exit_ok;
  std::string message;
};

template <class F> Failure attempt(F&& f) {
  try {
    f();
    return {};
  } catch (UsageError const& e) {
    return {exit_usage, e.what()};
  } catch (InvalidArgument const& e) {
    return {exit_usage, e.what()};
  } catch (IoError const& e) {
    return {exit_io, e.what()};
  } catch (InvalidMesh const& e) {
    return {exit_invalid_mesh, e.what()};
  } catch (std::bad_alloc const&) {
    return {exit_other, "out of memory"};
  } catch (std::exception const& e) {
    return {exit_other, e.what()};
  }
}

/// Collective: every rank learns whether any rank failed. Returns the exit
/// code (0: none failed); rank 0 prints the lowest failing rank's message.
int agree(Failure const& f, int rank, int ranks) {
  int const mine = f.code != exit_ok ? rank : ranks;
  int first = ranks;
  MPI_Allreduce(&mine, &first, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  if (first == ranks) return exit_ok;
  int code = f.code;
  MPI_Bcast(&code, 1, MPI_INT, first, MPI_COMM_WORLD);
  int len = int(f.message.size());
  MPI_Bcast(&len, 1, MPI_INT, first, MPI_COMM_WORLD);
  std::string msg = f.message;
  msg.resize(size_t(len));
  MPI_Bcast(msg.data(), len, MPI_CHAR, first, MPI_COMM_WORLD);
  if (rank == 0) {
    std::replace(msg.begin(), msg.end(), '\n', ' ');
    std::cerr << "cellray-mpi-render: error";
    if (ranks > 1) std::cerr << " (rank " << first << ")";
    std::cerr << ": " << msg << "\n";
  }
  return code;
}

/// Collective: runs `f` on every rank, then agree()s. Work between two
/// collectives goes through this, so no rank enters a collective that a
/// failed rank will never reach.
template <class F> int phase(int rank, int ranks, F&& f) { return agree(attempt(std::forward<F>(f)), rank, ranks); }

/// The rank's region, as a mesh of its own: the cells whose boxes overlap
/// its k-d box (plus a halo for smooth normals), with compact vertices.
/// From a single file every rank read whole, a subset of it (tets and
/// hexahedra over one compact vertex array); from a .pvtu, the cells other
/// ranks sent, their vertices welded (pvtu pieces repeat the points on
/// their borders: equal position and value is one vertex, which restores
/// face neighbours across pieces).
struct Region {
  CellSubset<4> tet_sub;
  CellSubset<8> hex_sub;
  MixedCellSubset mixed_sub;  // both types
  UnstructuredGrid received;
  TetMesh tets;
  HexMesh hexes;
  bool march = false;  // DVR segments march through face neighbours
  uint64_t vertex_count() const {  // views of one vertex array count it once
    return tets.vertex_count() + (tets.positions() == hexes.positions() ? 0 : hexes.vertex_count());
  }
};

/// What every rank holds: its input (the whole mesh, or its pieces of a
/// .pvtu), the partition, its region and the render set-up.
struct Setup {
  bool distributed = false;  // a .pvtu: each rank holds only its pieces
  std::optional<UnstructuredGrid> grid;
  std::optional<GeneratedMesh<4>> gen_tets;
  std::optional<GeneratedMesh<8>> gen_hexes;
  TetMesh tets;   // the input's cells, the chosen array active
  HexMesh hexes;
  std::string name, array;
  float vlo = 0.f, vhi = 0.f;
  CellExtents tet_boxes, hex_boxes;
  glm::vec3 lo{0.f}, hi{0.f}, halo{0.f};
  KdPartition part;
  Region region;
  MinMaxBvh tet_bvh, hex_bvh;
  TetNeighbours neighbours;
  HexNeighbours hex_neighbours;
  VertexGradients tet_gradients, hex_gradients;
  Scene scene;  // empty when the region has no cells
  Camera cam;
  IsoParams ip;
  DvrParams dp;
  glm::vec4 background{1.f};
  double read_ms = 0, partition_ms = 0, exchange_ms = 0, build_ms = 0;
};

bool ends_with_pvtu(std::string const& path) {
  return path.size() >= 5 && io::iequals(std::string_view(path).substr(path.size() - 5), ".pvtu");
}

/// Reads this rank's input: the generated scene or a single file (every
/// rank reads it whole) or, from a .pvtu, the pieces [r p / k, (r+1) p / k)
/// (some ranks read none when there are fewer pieces than ranks). Chooses
/// the array and validates the cells read. No collectives.
void read_input(Options const& o, int rank, int ranks, Setup& s) {
  if (o.shadows || o.ao > 0)
    throw UsageError(std::string(o.shadows ? "--shadows" : "--ao") +
                     ": shadow and ambient-occlusion rays need the whole mesh, which no rank holds alone "
                     "(render them with cellray-render)");
  int width = 0, height = 0;
  parse_size(o.size, width, height);
  if (image_format(o.out).empty()) throw UsageError("-o: '" + o.out + "' must end in .png or .ppm");
  if (o.mode != "iso" && o.mode != "dvr") throw UsageError("--mode: iso or dvr, got '" + o.mode + "'");

  // Test hook: CELLRAY_MPI_FAIL_RANK=r makes rank r fail to read, as a
  // rank whose file is unreadable would (tests/mpi: the others must not hang).
  if (char const* fail = std::getenv("CELLRAY_MPI_FAIL_RANK"); fail && std::atoi(fail) == rank)
    throw IoError("rank " + std::to_string(rank) + ": cannot read the mesh (CELLRAY_MPI_FAIL_RANK)");
  s.name = "default scene";
  std::vector<std::string> arrays;
  if (o.mesh_path.empty()) {
    if (o.generate == "hexes") s.gen_hexes = generate_hexes(o.cells), s.hexes = s.gen_hexes->mesh();
    else s.gen_tets = generate_tets(o.cells), s.tets = s.gen_tets->mesh();
    for (auto const& a : (s.gen_hexes ? s.hexes.arrays() : s.tets.arrays())) arrays.push_back(a.name);
  } else {
    s.name = o.mesh_path;
    ReadOptions ro;
    ro.skip_unsupported_cells = o.skip_unsupported;
    if (ends_with_pvtu(o.mesh_path)) {
      s.distributed = true;
      PvtuIndex const index = read_pvtu_index(o.mesh_path);
      size_t const p = index.pieces.size(), k = size_t(ranks), r = size_t(rank);
      std::vector<UnstructuredGrid> mine;
      for (size_t i = r * p / k; i < (r + 1) * p / k; ++i) mine.push_back(read_pvtu_piece(index, i, ro));
      s.grid = merge_grids(std::move(mine));
      arrays = index.point_arrays;
    } else {
      s.grid = read_mesh(o.mesh_path, ro);
      if (s.grid->empty()) throw InvalidMesh(s.name + " holds no tetrahedra or hexahedra");
      for (auto const& a : s.grid->point_arrays) arrays.push_back(a.name);
    }
    s.tets = s.grid->tet_mesh();
    s.hexes = s.grid->hex_mesh();
  }
  if (arrays.empty()) throw InvalidMesh(s.name + " has no point arrays to render");
  s.array = arrays.front();
  if (!o.array.empty()) {
    if (std::find(arrays.begin(), arrays.end(), o.array) == arrays.end())
      throw UsageError("--array: " + s.name + " has no point array '" + o.array + "'");
    s.array = o.array;
  }
  s.vlo = std::numeric_limits<float>::infinity(), s.vhi = -s.vlo;
  auto check = [&](auto& mesh) {
    if (mesh.empty()) return;
    mesh = mesh.with_array(s.array);
    ValidationReport const rep = validate(mesh);
    if (!rep.ok()) throw InvalidMesh(s.name + " failed validation: " + rep.message());
    s.vlo = std::min(s.vlo, rep.value_min), s.vhi = std::max(s.vhi, rep.value_max);
  };
  check(s.tets);
  check(s.hexes);
  s.tet_boxes = cell_extents(s.tets);
  s.hex_boxes = cell_extents(s.hexes);
}

/// What one rank sends another: the cells of the receiver's region (with
/// the halo) among the sender's, as 32-bit words: a header (vertices, tets,
/// hexes), each vertex once (x, y, z, value) and the cells' corners as
/// indices into those vertices.
std::vector<uint32_t> pack_region(TetMesh const& tets, std::vector<uint64_t> const& tet_ids, HexMesh const& hexes,
                                  std::vector<uint64_t> const& hex_ids, std::vector<uint32_t>& stamp,
                                  std::vector<uint32_t>& local, uint32_t mark) {
  std::vector<uint32_t> msg(3), verts, cells;
  uint32_t count = 0;
  auto add = [&](auto const& mesh, std::vector<uint64_t> const& ids) {
    constexpr int n = std::decay_t<decltype(mesh)>::corners;
    for (uint64_t c : ids)
      for (int j = 0; j < n; ++j) {
        uint64_t const v = mesh.vertex(c, j);
        if (stamp[v] != mark) {
          stamp[v] = mark, local[v] = count++;
          float const f[4] = {mesh.position(v).x, mesh.position(v).y, mesh.position(v).z, mesh.value(v)};
          uint32_t w[4];
          std::memcpy(w, f, sizeof w);
          verts.insert(verts.end(), w, w + 4);
        }
        cells.push_back(local[v]);
      }
  };
  add(tets, tet_ids);
  add(hexes, hex_ids);
  msg[0] = count, msg[1] = uint32_t(tet_ids.size()), msg[2] = uint32_t(hex_ids.size());
  msg.insert(msg.end(), verts.begin(), verts.end());
  msg.insert(msg.end(), cells.begin(), cells.end());
  return msg;
}

/// Collective: sends each rank the words in out[rank], returns what all
/// ranks sent this one and where each sender's message starts.
std::vector<uint32_t> send_to_regions(std::vector<std::vector<uint32_t>> const& out, int ranks,
                                      std::vector<int>& recv_at) {
  size_t const k = static_cast<size_t>(ranks);
  std::vector<int> send_count(k), recv_count(k), send_at(k);
  recv_at.assign(k, 0);
  std::vector<uint32_t> send;
  for (size_t r = 0; r < k; ++r) {
    send_at[r] = int(send.size());
    send_count[r] = int(out[r].size());
    send.insert(send.end(), out[r].begin(), out[r].end());
  }
  MPI_Alltoall(send_count.data(), 1, MPI_INT, recv_count.data(), 1, MPI_INT, MPI_COMM_WORLD);
  int64_t total = 0;
  for (size_t r = 0; r < k; ++r) recv_at[r] = int(total), total += recv_count[r];
  std::vector<uint32_t> recv(static_cast<size_t>(total));
  MPI_Alltoallv(send.data(), send_count.data(), send_at.data(), MPI_UINT32_T, recv.data(), recv_count.data(),
                recv_at.data(), MPI_UINT32_T, MPI_COMM_WORLD);
  return recv;
}

/// Welds the vertices of the received messages: equal bits of (x, y, z,
/// value) are one vertex (pieces repeat the points on their borders). An
/// open-addressing table of vertex ids sized to twice the vertices received:
/// a few bytes per vertex, one probe or two per lookup.
void weld_messages(std::vector<uint32_t> const& in, std::vector<int> const& at, std::string const& array,
                   UnstructuredGrid& grid) {
  uint64_t received = 0;
  for (int start : at)
    if (size_t(start) < in.size()) received += in[size_t(start)];
  size_t cap = 16;
  while (cap < 2 * received) cap *= 2;
  constexpr uint32_t empty = std::numeric_limits<uint32_t>::max();
  std::vector<uint32_t> table(cap, empty);
  std::vector<uint32_t> words;  // 4 per welded vertex
  words.reserve(size_t(received) * 4);
  auto hash = [](uint32_t const* w) {
    uint64_t h = 0x9e3779b97f4a7c15ull;
    for (int i = 0; i < 4; ++i) h = (h ^ w[i]) * 0xff51afd7ed558ccdull;
    return size_t(h ^ (h >> 29));
  };
  std::vector<uint32_t> remap;
  for (size_t m = 0; m < at.size(); ++m) {
    size_t const start = size_t(at[m]), end = m + 1 < at.size() ? size_t(at[m + 1]) : in.size();
    if (start >= end) continue;
    uint32_t const nv = in[start], nt = in[start + 1], nh = in[start + 2];
    uint32_t const* v = &in[start + 3];
    remap.resize(nv);
    for (uint32_t i = 0; i < nv; ++i) {
      uint32_t const* key = v + 4 * size_t(i);
      size_t slot = hash(key) & (cap - 1);
      while (table[slot] != empty && !std::equal(key, key + 4, &words[4 * size_t(table[slot])]))
        slot = (slot + 1) & (cap - 1);
      if (table[slot] == empty) {
        if (words.size() / 4 == empty - 1) throw InvalidMesh("a region holds more than 2^32 - 2 vertices; use more ranks");
        table[slot] = uint32_t(words.size() / 4);
        words.insert(words.end(), key, key + 4);
      }
      remap[i] = table[slot];
    }
    uint32_t const* c = v + 4 * size_t(nv);
    for (size_t i = 0; i < size_t(nt) * 4; ++i) grid.tets.push_back(remap[c[i]]);
    c += size_t(nt) * 4;
    for (size_t i = 0; i < size_t(nh) * 8; ++i) grid.hexes.push_back(remap[c[i]]);
  }
  size_t const n = words.size() / 4;
  grid.xyz.resize(3 * n);
  std::vector<float> values(n);
  for (size_t i = 0; i < n; ++i) {
    std::memcpy(&grid.xyz[3 * i], &words[4 * i], 3 * sizeof(float));
    std::memcpy(&values[i], &words[4 * i + 3], sizeof(float));
  }
  grid.point_arrays.push_back({array, 1, std::move(values)});
}

/// Collective: the global bounds, value range and halo; the k-d partition
/// (every rank builds the same tree from the same centroids: all of them
/// from a single file, a gathered sample of at most 2^20 from a .pvtu); the
/// rank's region.
int partition_and_exchange(Options const& o, int rank, int ranks, Setup& s) {
  auto const t0 = Clock::now();
  bool const smooth = o.mode == "iso" && o.normals == "smooth";
  float lo_hi[8] = {-s.tet_boxes.bounds_lo.x, -s.tet_boxes.bounds_lo.y, -s.tet_boxes.bounds_lo.z,
                    s.tet_boxes.bounds_hi.x,  s.tet_boxes.bounds_hi.y,  s.tet_boxes.bounds_hi.z, -s.vlo, s.vhi};
  for (int a = 0; a < 3; ++a) {
    if (s.tets.empty()) lo_hi[a] = lo_hi[3 + a] = -std::numeric_limits<float>::infinity();
    if (!s.hexes.empty()) {
      lo_hi[a] = std::max(lo_hi[a], -s.hex_boxes.bounds_lo[a]);
      lo_hi[3 + a] = std::max(lo_hi[3 + a], s.hex_boxes.bounds_hi[a]);
    }
  }
  float global[8];
  MPI_Allreduce(lo_hi, global, 8, MPI_FLOAT, MPI_MAX, MPI_COMM_WORLD);
  s.lo = {-global[0], -global[1], -global[2]}, s.hi = {global[3], global[4], global[5]};
  s.vlo = -global[6], s.vhi = global[7];
  float ext[3], global_ext[3];
  for (int a = 0; a < 3; ++a) ext[a] = std::max(s.tet_boxes.largest_extent[a], s.hex_boxes.largest_extent[a]);
  MPI_Allreduce(ext, global_ext, 3, MPI_FLOAT, MPI_MAX, MPI_COMM_WORLD);
  if (smooth) s.halo = {global_ext[0], global_ext[1], global_ext[2]};
  uint64_t const local_cells = s.tets.cell_count() + s.hexes.cell_count();
  uint64_t total_cells = local_cells;
  if (s.distributed) MPI_Allreduce(&local_cells, &total_cells, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);

  int code = phase(rank, ranks, [&] {
    if (total_cells == 0) throw InvalidMesh(s.name + " holds no tetrahedra or hexahedra");
    if (!(s.vlo <= s.vhi)) throw InvalidMesh(s.name + ": point array '" + s.array + "' has no finite value");
    if (std::max(std::fabs(s.vlo), std::fabs(s.vhi)) > 0x1p+40f)
      throw UsageError(s.name + ": values need rescaling for float ray tracing (cellray-render does it; this program does not)");
    float const extent = std::max({s.hi.x - s.lo.x, s.hi.y - s.lo.y, s.hi.z - s.lo.z});
    float const reach = std::max({std::fabs(s.lo.x), std::fabs(s.lo.y), std::fabs(s.lo.z), std::fabs(s.hi.x),
                                  std::fabs(s.hi.y), std::fabs(s.hi.z)});
    if (!(extent >= 0x1p-20f && extent <= 0x1p+20f && reach <= 0x1p+8f * extent))
      throw UsageError(s.name + ": coordinates need rescaling for float ray tracing (cellray-render does it; this program does not)");
  });
  if (code) return code;

  // The partition's points: every centroid, or an even sample of them.
  std::vector<glm::vec3> points;
  uint64_t const budget = uint64_t(1) << 20;
  uint64_t const stride = s.distributed ? std::max<uint64_t>(1, (total_cells + budget - 1) / budget) : 1;
  for (CellExtents const* b : {&s.tet_boxes, &s.hex_boxes})
    for (uint64_t c = 0; c < b->size(); c += stride) points.push_back(b->centroid[c]);
  if (s.distributed) {
    int const mine = int(points.size() * 3);
    std::vector<int> count(static_cast<size_t>(ranks)), at(static_cast<size_t>(ranks));
    MPI_Allgather(&mine, 1, MPI_INT, count.data(), 1, MPI_INT, MPI_COMM_WORLD);
    int total = 0;
    for (int r = 0; r < ranks; ++r) at[size_t(r)] = total, total += count[size_t(r)];
    std::vector<glm::vec3> all(size_t(total / 3));
    MPI_Allgatherv(points.data(), mine, MPI_FLOAT, all.data(), count.data(), at.data(), MPI_FLOAT, MPI_COMM_WORLD);
    points = std::move(all);
  }
  s.part = kd_tree(points, s.lo, s.hi, ranks);
  s.partition_ms = ms_since(t0);

  auto const t1 = Clock::now();
  Region& reg = s.region;
  if (!s.distributed) {
    code = phase(rank, ranks, [&] {
      if (!s.tets.empty() && !s.hexes.empty()) {
        reg.mixed_sub = subset_cells(s.tets, assign_cells(s.part, s.tet_boxes, s.halo)[size_t(rank)], s.hexes,
                                     assign_cells(s.part, s.hex_boxes, s.halo)[size_t(rank)]);
        reg.tets = reg.mixed_sub.tets();
        reg.hexes = reg.mixed_sub.hexes();
        return;
      }
      if (!s.tets.empty()) {
        reg.tet_sub = subset_cells(s.tets, assign_cells(s.part, s.tet_boxes, s.halo)[size_t(rank)]);
        reg.tets = reg.tet_sub.mesh();
      }
      if (!s.hexes.empty()) {
        reg.hex_sub = subset_cells(s.hexes, assign_cells(s.part, s.hex_boxes, s.halo)[size_t(rank)]);
        reg.hexes = reg.hex_sub.mesh();
      }
    });
    s.exchange_ms = ms_since(t1);
    return code;
  }
  // A .pvtu: send each cell to every region it overlaps, then weld.
  std::vector<std::vector<uint32_t>> out(static_cast<size_t>(ranks));
  code = phase(rank, ranks, [&] {
    std::vector<std::vector<uint64_t>> const tet_ids = assign_cells(s.part, s.tet_boxes, s.halo);
    std::vector<std::vector<uint64_t>> const hex_ids = assign_cells(s.part, s.hex_boxes, s.halo);
    uint64_t const nv = std::max(s.tets.vertex_count(), s.hexes.vertex_count());  // one vertex array (the grid's)
    std::vector<uint32_t> stamp(nv, std::numeric_limits<uint32_t>::max()), local(nv);
    uint64_t words = 0;
    for (int r = 0; r < ranks; ++r) {
      out[size_t(r)] = pack_region(s.tets, tet_ids[size_t(r)], s.hexes, hex_ids[size_t(r)], stamp, local, uint32_t(r));
      words += out[size_t(r)].size();
    }
    if (words > uint64_t(std::numeric_limits<int>::max()))
      throw InvalidMesh("rank " + std::to_string(rank) + " would send more than 2^31 words; use more ranks");
  });
  if (code) return code;
  std::vector<int> at;
  std::vector<uint32_t> const in = send_to_regions(out, ranks, at);
  out = {};
  s.grid.reset();  // the pieces read: their cells are where they belong now
  s.tets = {}, s.hexes = {};
  code = phase(rank, ranks, [&] {
    weld_messages(in, at, s.array, reg.received);
    reg.tets = reg.received.tet_mesh();
    reg.hexes = reg.received.hex_mesh();
  });
  s.exchange_ms = ms_since(t1);
  return code;
}

/// Camera, parameters and the region's BVHs, neighbours and gradients. No collectives.
void prepare_render(Options const& o, int rank, Setup& s) {
  auto const t0 = Clock::now();
  int width = 0, height = 0;
  parse_size(o.size, width, height);
  KdRegion const& region = s.part.regions[size_t(rank)];
  glm::vec3 const lo = s.lo, hi = s.hi;
  float const vlo = s.vlo, vhi = s.vhi;
  // Camera: cellray-render's default view of the whole mesh's bounds.
  float const framing = o.mesh_path.empty() ? 0.75f : 1.f;
  glm::vec3 const centre = 0.5f * (lo + hi);
  glm::dvec3 const fit_lo(centre + framing * (lo - centre)), fit_hi(centre + framing * (hi - centre));
  glm::dvec3 const dir = cellray_render::view_direction(o.azimuth, o.elevation);
  double const fit = cellray_render::fit_distance(fit_lo, fit_hi, dir, 0.9 * o.zoom, o.fov, width, height);
  s.cam = cellray_render::box_camera(fit_lo, fit_hi, dir, fit, o.fov, width, height);
  if (!o.eye.empty() || !o.at.empty() || !o.up.empty())
    s.cam = Camera::look_at(o.eye.empty() ? s.cam.eye : parse_vec3(o.eye, "--eye"),
                            o.at.empty() ? centre : parse_vec3(o.at, "--at"),
                            o.up.empty() ? glm::vec3(0.f, 1.f, 0.f) : parse_vec3(o.up, "--up"), o.fov, width, height);
  float const diagonal = glm::length(hi - lo);
  std::optional<glm::vec4> background;
  if (!o.background.empty()) background = parse_background(o.background);

  bool const smooth = o.mode == "iso" && o.normals == "smooth";
  if (o.mode == "iso") {
    std::vector<float> values, opacity;
    if (!o.iso.empty()) values = parse_floats(o.iso, "--iso");
    else if (o.mesh_path.empty()) values = {0.3f, 0.45f, 0.6f};
    else
      for (double t : {0.25, 0.5, 0.75}) values.push_back(float(vlo + t * (double(vhi) - vlo)));
    if (values.size() > 8) throw UsageError("--iso: at most 8 isovalues");
    if (!o.iso_opacity.empty()) opacity = parse_floats(o.iso_opacity, "--iso-opacity");
    if (!opacity.empty() && opacity.size() != 1 && opacity.size() != values.size())
      throw UsageError("--iso-opacity: give one opacity or one per isovalue");
    for (float a : opacity)
      if (a < 0.f || a > 1.f) throw UsageError("--iso-opacity: opacities must lie in [0, 1]");
    for (size_t i = 0; i < values.size(); ++i)
      s.ip.surfaces.push_back({values[i], iso_color(i),
                               opacity.empty()       ? (i + 1 == values.size() ? 1.f : 0.4f)
                               : opacity.size() == 1 ? opacity[0]
                                                     : opacity[i]});
    if (o.normals != "smooth" && o.normals != "flat" && o.normals != "central")
      throw UsageError("--normals: smooth, flat or central, got '" + o.normals + "'");
    s.ip.normals = o.normals == "central" ? GradientMethod::central
                   : o.normals == "flat"  ? GradientMethod::analytic
                                          : GradientMethod::smooth;
    s.background = background.value_or(s.ip.background);
    s.ip.background = {0.f, 0.f, 0.f, 0.f};
    s.ip.clip.planes = clip_box(region.lo, region.hi);
  } else {
    if (o.tf != "cool-warm" && o.tf != "viridis" && o.tf != "inferno" && o.tf != "grayscale")
      throw UsageError("--tf: presets only (cool-warm, viridis, inferno, grayscale), got '" + o.tf + "'");
    if (o.dvr_mode != "segments" && o.dvr_mode != "samples")
      throw UsageError("--dvr-mode: segments or samples, got '" + o.dvr_mode + "'");
    float const max_alpha = o.opacity >= 0.f ? o.opacity : 0.8f;
    s.dp.tf = transfer_function_preset(o.tf, vlo, vhi, max_alpha);
    double const span = vhi > vlo ? double(vhi) - vlo : 1.0;  // cellray-render's linear opacity ramp
    for (size_t i = 0; i < s.dp.tf.values.size(); ++i)
      s.dp.tf.rgba[i].a = max_alpha * float(std::clamp((s.dp.tf.values[i] - double(vlo)) / span, 0.0, 1.0));
    s.dp.tf.unit_distance = o.unit_distance > 0.f ? o.unit_distance : std::max(diagonal / 10.f, 1e-30f);
    s.dp.mode = o.dvr_mode == "samples" ? DvrMode::samples : DvrMode::segments;
    // The whole mesh's default step, not the region's.
    s.dp.step = o.step > 0.f ? o.step : default_dvr_step(s.dp.mode, diagonal);
    s.background = background.value_or(glm::vec4(0.08f, 0.08f, 0.1f, 1.f));
    s.dp.background = {0.f, 0.f, 0.f, 0.f};
    s.dp.clip.planes = clip_box(region.lo, region.hi);
  }

  // The region's own structures. Smooth normals: the region holds every
  // cell around its vertices (the halo), so its gradients are the whole mesh's.
  Region const& reg = s.region;
  // DVR segments march through face neighbours, as cellray-render's: one
  // type, or tets and hexahedra over one vertex array (a single file's
  // mixed subset, a .pvtu's welded region), linked.
  bool const both = !reg.tets.empty() && !reg.hexes.empty();
  bool const march = o.mode == "dvr" && s.dp.mode == DvrMode::segments &&
                     (!both || reg.tets.positions() == reg.hexes.positions());
  s.region.march = march;
  // One image: the Morton build, as cellray-render's --builder auto picks
  // for one image (2-3x faster to build; docs/cli.md).
  BuildOptions one_image;
  one_image.builder = BvhBuilder::morton;
  if (!reg.tets.empty()) {
    s.tet_bvh = build_minmax_bvh(reg.tets, one_image);
    if (march) s.neighbours = build_tet_neighbours(reg.tets);
    if (smooth) s.tet_gradients = build_vertex_gradients(reg.tets);
    s.scene.tets.push_back({reg.tets, &s.tet_bvh, nullptr, march ? &s.neighbours : nullptr,
                            smooth ? &s.tet_gradients : nullptr});
  }
  if (!reg.hexes.empty()) {
    s.hex_bvh = build_minmax_bvh(reg.hexes, one_image);
    if (march) s.hex_neighbours = build_hex_neighbours(reg.hexes);
    if (smooth) s.hex_gradients = build_vertex_gradients(reg.hexes);
    s.scene.hexes.push_back({reg.hexes, &s.hex_bvh, nullptr, smooth ? &s.hex_gradients : nullptr,
                             march ? &s.hex_neighbours : nullptr});
  }
  if (march && both) link_face_neighbours(reg.tets, s.neighbours, reg.hexes, s.hex_neighbours);
  s.build_ms = ms_since(t0);
}

int run(Options const& o, int rank, int ranks) {
  std::optional<tbb::global_control> limit;
  if (o.threads > 0) limit.emplace(tbb::global_control::max_allowed_parallelism, size_t(o.threads));
  auto const t_start = Clock::now();
  Setup s;
  auto const t_read = Clock::now();
  if (int const code = phase(rank, ranks, [&] { read_input(o, rank, ranks, s); })) return code;
  s.read_ms = ms_since(t_read);
  if (int const code = partition_and_exchange(o, rank, ranks, s)) return code;
  if (int const code = phase(rank, ranks, [&] { prepare_render(o, rank, s); })) return code;

  // Render this rank's region: premultiplied RGBA over a clear background.
  Image image;
  double render_ms = 0;
  Failure f = attempt([&] {
    auto const t0 = Clock::now();
    if (s.scene.cell_count() == 0) image = Image(s.cam.width, s.cam.height);  // an empty region adds nothing
    else image = o.mode == "iso" ? render_iso(s.scene, s.cam, s.ip) : render_dvr(s.scene, s.cam, s.dp);
    render_ms = ms_since(t0);
  });
  if (int const code = agree(f, rank, ranks)) return code;

  // IceT: ordered blending of the ranks' images, front to back for the eye.
  MPI_Barrier(MPI_COMM_WORLD);  // the composite time then excludes waiting for slower renders
  auto const t_comp = Clock::now();
  IceTCommunicator comm = icetCreateMPICommunicator(MPI_COMM_WORLD);
  IceTContext context = icetCreateContext(comm);
  icetDiagnostics(ICET_DIAG_ERRORS);
  icetSetColorFormat(ICET_IMAGE_COLOR_RGBA_FLOAT);
  icetSetDepthFormat(ICET_IMAGE_DEPTH_NONE);
  icetCompositeMode(ICET_COMPOSITE_MODE_BLEND);
  icetStrategy(ICET_STRATEGY_REDUCE);
  icetSingleImageStrategy(ICET_SINGLE_IMAGE_STRATEGY_AUTOMATIC);
  icetResetTiles();
  icetAddTile(0, 0, s.cam.width, s.cam.height, 0);
  icetEnable(ICET_ORDERED_COMPOSITE);
  std::vector<IceTInt> order;
  for (int r : s.part.front_to_back(s.cam.eye)) order.push_back(IceTInt(r));
  icetCompositeOrder(order.data());
  IceTDouble const identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  IceTFloat const clear[4] = {0.f, 0.f, 0.f, 0.f};
  IceTImage composite = icetCompositeImage(image.rgba.data(), nullptr, nullptr, identity, identity, clear);
  if (rank == 0) {
    IceTFloat const* c = icetImageGetColorcf(composite);
    std::copy(c, c + image.rgba.size(), image.rgba.begin());
  }
  double const composite_ms = ms_since(t_comp);
  icetDestroyContext(context);
  icetDestroyMPICommunicator(comm);

  // Rank 0: the background behind the composite, as cellray-render's
  // renderer puts it (C + (1 - A) background, premultiplied), then the file.
  f = attempt([&] {
    if (rank != 0) return;
    for (size_t i = 0; i < image.rgba.size(); i += 4) {
      float const t = 1.f - image.rgba[i + 3];
      for (size_t k = 0; k < 4; ++k) image.rgba[i + k] += t * s.background[int(k)];
    }
    write_image(o.out, image);
  });
  if (int const code = agree(f, rank, ranks)) return code;

  if (o.stats) {
    double const total_ms = ms_since(t_start);
    constexpr int n = 10;
    double const mine[n] = {s.read_ms,
                            s.partition_ms,
                            s.exchange_ms,
                            s.build_ms,
                            render_ms,
                            composite_ms,
                            total_ms,
                            double(s.scene.cell_count()),
                            double(s.region.vertex_count()),
                            s.region.march ? 1.0 : 0.0};
    std::vector<double> all(size_t(n * ranks));
    MPI_Gather(mine, n, MPI_DOUBLE, all.data(), n, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    if (rank == 0)
      for (int r = 0; r < ranks; ++r) {
        double const* m = &all[size_t(n * r)];
        std::printf("{\"rank\": %d, \"ranks\": %d, \"cells\": %.0f, \"vertices\": %.0f, \"read_ms\": %.1f, "
                    "\"partition_ms\": %.1f, \"exchange_ms\": %.1f, \"build_ms\": %.1f, \"render_ms\": %.1f, "
                    "\"composite_ms\": %.1f, \"total_ms\": %.1f, \"march\": %s}\n",
                    r, ranks, m[7], m[8], m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[9] != 0 ? "true" : "false");
      }
  }
  return exit_ok;
}

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  int rank = 0, ranks = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &ranks);

  CLI::App app{"cellray-mpi-render: cellray-render's isosurfaces and DVR over MPI ranks, composited by IceT.\n"
               "Run as: mpirun -np N cellray-mpi-render [mesh] [flags]"};
  app.footer("Exit codes: 0 success; 1 other error; 2 usage; 3 I/O; 4 invalid mesh (all ranks exit with it).");
  Options o;
  app.add_option("mesh", o.mesh_path, "Legacy .vtk, .vtu or .pvtu (each rank reads its pieces); none: the generated default scene");
  app.add_option("--generate", o.generate, "Default scene cell type")->check(CLI::IsMember({"tets", "hexes"}));
  app.add_option("--cells", o.cells, "Default scene size in cells (approximate)")->check(CLI::Range(uint64_t(1), uint64_t(1) << 31));
  app.add_option("--array", o.array, "Point array to render (default: the first)");
  app.add_option("--mode", o.mode, "iso or dvr")->check(CLI::IsMember({"iso", "dvr"}));
  app.add_option("--iso", o.iso, "Isovalues V1,V2,... (default: 3 spread over the value range)");
  app.add_option("--iso-opacity", o.iso_opacity, "One opacity, or one per isovalue (default: 0.4, the last 1)");
  app.add_option("--normals", o.normals, "smooth, flat or central")->check(CLI::IsMember({"smooth", "flat", "central"}));
  app.add_option("--tf", o.tf, "Transfer function preset: cool-warm, viridis, inferno, grayscale");
  app.add_option("--opacity", o.opacity, "Largest DVR opacity per unit distance (default 0.8)")->check(finite_in(0.f, 1.f));
  app.add_option("--unit-distance", o.unit_distance, "DVR opacity unit distance (default: diagonal / 10)")->check(positive_finite);
  app.add_option("--step", o.step, "DVR step, world units (default: the whole mesh's diagonal / 125 or / 500)")
      ->check(positive_finite);
  app.add_option("--dvr-mode", o.dvr_mode, "segments or samples")->check(CLI::IsMember({"segments", "samples"}));
  app.add_option("--background", o.background, "R,G,B[,A] in [0,1], or white, black, transparent");
  app.add_option("--eye", o.eye, "Camera position X,Y,Z");
  app.add_option("--at", o.at, "Look-at point X,Y,Z");
  app.add_option("--up", o.up, "Up vector X,Y,Z");
  app.add_option("--fov", o.fov, "Vertical field of view, degrees")->check(finite_in(0.01f, 179.f));
  app.add_option("--zoom", o.zoom, "Default view: scale of the fitted mesh")->check(finite_in(1e-3f, 1e3f));
  app.add_option("--azimuth", o.azimuth, "Default view: degrees about +y")->check(finite_in(-36000.f, 36000.f));
  app.add_option("--elevation", o.elevation, "Default view: degrees up")->check(finite_in(-89.f, 89.f));
  app.add_option("--size", o.size, "Image size WxH");
  app.add_option("-o,--output", o.out, "Output image, .png or .ppm (written by rank 0)");
  app.add_option("--threads", o.threads, "Worker threads per rank (default: all cores)")->check(CLI::Range(1, 4096));
  app.add_flag("--skip-unsupported", o.skip_unsupported, "Skip cells cellray cannot read (2D cells, other non-linear 3D types...)");
  app.add_flag("--stats", o.stats, "Per-rank timings as JSON lines on rank 0's stdout");
  app.add_flag("--shadows", o.shadows, "Refused: shadow rays need the whole mesh");
  app.add_option("--ao", o.ao, "Refused: ambient-occlusion rays need the whole mesh");

  int code = exit_ok;
  try {
    app.parse(argc, argv);
    code = run(o, rank, ranks);
  } catch (CLI::CallForHelp const& e) {
    code = rank == 0 ? app.exit(e) : 0;
  } catch (CLI::ParseError const& e) {
    if (rank == 0) std::cerr << "cellray-mpi-render: error: " << e.what() << " (see --help)\n";
    code = exit_usage;  // every rank parses the same flags: all fail alike
  }
  MPI_Finalize();
  return code;
}
