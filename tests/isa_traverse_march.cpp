// MarchProbe (tests/support/march_probe.hpp) for one ISA: compiled once per
// ISA with that ISA's flags. Drives CellMarch as the renderer does
// (dvr_integrators_impl.hpp, integrate_march), without the integration.

#include <cellray/traverse/march.hpp>

#include "support/march_probe.hpp"

namespace cellray::test {

namespace {

template <class Arch, int N>
void march_probe(CellMesh<N> const& mesh, MinMaxBvh const& bvh, FaceNeighbours<N> const& nb,
                 ValueWindows const& windows, Ray const* rays, int n, int how, int max_faint, MarchProbeOut* out) {
  constexpr int W = width<Arch>;
  TreeView const tree(bvh);
  for (int first = 0; first < n; first += W) {
    int const m = n - first < W ? n - first : W;
    RayPacket<Arch> const r = load_rays<Arch>(rays + first, m);
    CellMarch<Arch, N> march(tree, mesh, nb, r, windows, r.tmin, r.tmax);
    march.max_faint = max_faint;
    vmask<Arch> live = simd::mask_from_bits<Arch>(m >= 32 ? ~0u : (1u << m) - 1u);
    for (int l = 0; l < m; ++l) out[first + l] = MarchProbeOut{};
    while (simd::any(live)) {
      vmask<Arch> const has = live && march.has_cell();
      vmask<Arch> const need = live && !has;
      if (simd::any(need)) {  // locate as soon as any lane needs it: the renderer's order differs, not its result
        for (uint32_t b = simd::movemask(need); b; b &= b - 1) ++out[first + __builtin_ctz(b)].locates;
        live = live && !march.locate(need, Traversal(how), W / 2);
        continue;
      }
      auto const cells = simd::to_array<Arch>(march.cell);
      auto const st = march.step(has, false);
      auto const tin = simd::to_array<Arch>(st.k.t_in), tout = simd::to_array<Arch>(st.k.t_out);
      auto const sin = simd::to_array<Arch>(st.k.s_in), sout = simd::to_array<Arch>(st.k.s_out);
      uint32_t const vis = simd::movemask(st.visible);
      for (uint32_t b = simd::movemask(has); b; b &= b - 1) {
        int const l = __builtin_ctz(b);
        MarchProbeOut& o = out[first + l];
        ++o.steps;
        if (((vis >> l) & 1u) && o.count < march_capacity)
          o.seg[o.count++] = CellSegment{tin[size_t(l)], tout[size_t(l)], sin[size_t(l)], sout[size_t(l)], 0,
                                         uint64_t(uint32_t(cells[size_t(l)]))};
      }
      live = live && march.t < march.t_end;
    }
  }
}

}  // namespace

template <class Arch>
void MarchProbe<Arch>::run(TetMesh const& mesh, MinMaxBvh const& bvh, TetNeighbours const& nb,
                           ValueWindows const& windows, Ray const* rays, int n, int how, int max_faint,
                           MarchProbeOut* out) {
  march_probe<Arch>(mesh, bvh, nb, windows, rays, n, how, max_faint, out);
}

template <class Arch>
void MarchProbe<Arch>::run(HexMesh const& mesh, MinMaxBvh const& bvh, HexNeighbours const& nb,
                           ValueWindows const& windows, Ray const* rays, int n, int how, int max_faint,
                           MarchProbeOut* out) {
  march_probe<Arch>(mesh, bvh, nb, windows, rays, n, how, max_faint, out);
}

CELLRAY_INSTANTIATE_ENTRY(MarchProbe)

template <class Arch>
void MixedMarchProbe<Arch>::run(TetMesh const& tets, MinMaxBvh const& tet_bvh, TetNeighbours const& tet_nb,
                                HexMesh const& hexes, MinMaxBvh const& hex_bvh, HexNeighbours const& hex_nb,
                                Ray const* rays, int n, int how, MixedMarchProbeOut* out) {
  constexpr int W = width<Arch>;
  TreeView const tet_tree(tet_bvh), hex_tree(hex_bvh);
  ValueWindows const all;
  for (int first = 0; first < n; first += W) {
    int const m = n - first < W ? n - first : W;
    RayPacket<Arch> const r = load_rays<Arch>(rays + first, m);
    MixedMarch<Arch> march(tet_tree, tets, tet_nb, hex_tree, hexes, hex_nb, r, all, r.tmin, r.tmax);
    vmask<Arch> live = simd::mask_from_bits<Arch>(m >= 32 ? ~0u : (1u << m) - 1u);
    for (int l = 0; l < m; ++l) out[first + l] = MixedMarchProbeOut{};
    int last_part[W];
    for (int l = 0; l < W; ++l) last_part[l] = -1;  // -1: just located
    while (simd::any(live)) {
      vmask<Arch> const has = live && march.has_cell();
      vmask<Arch> const need = live && !has;
      if (simd::any(need)) {
        for (uint32_t b = simd::movemask(need); b; b &= b - 1) {
          ++out[first + __builtin_ctz(b)].locates;
          last_part[__builtin_ctz(b)] = -1;
        }
        live = live && !march.locate(need, Traversal(how), W / 2);
        continue;
      }
      auto const tet_cells = simd::to_array<Arch>(march.tets.cell), hex_cells = simd::to_array<Arch>(march.hexes.cell);
      auto const st = march.step(has, false);
      uint32_t const in_hex = simd::movemask(st.in_hex);
      for (uint32_t b = simd::movemask(has); b; b &= b - 1) {
        int const l = __builtin_ctz(b);
        bool const hex = (in_hex >> l) & 1u;
        auto const& k = hex ? st.hex.k : st.tet.k;
        bool const vis = (simd::movemask(hex ? st.hex.visible : st.tet.visible) >> l) & 1u;
        MixedMarchProbeOut& o = out[first + l];
        ++o.steps;
        o.crossings += last_part[l] >= 0 && last_part[l] != int(hex);
        last_part[l] = int(hex);
        if (vis && o.count < march_capacity)
          o.seg[o.count++] = CellSegment{simd::to_array<Arch>(k.t_in)[size_t(l)], simd::to_array<Arch>(k.t_out)[size_t(l)],
                                         simd::to_array<Arch>(k.s_in)[size_t(l)], simd::to_array<Arch>(k.s_out)[size_t(l)],
                                         uint32_t(hex), uint64_t(uint32_t(hex ? hex_cells[size_t(l)] : tet_cells[size_t(l)]))};
      }
      live = live && march.t < march.tets.t_end;
    }
  }
}

CELLRAY_INSTANTIATE_ENTRY(MixedMarchProbe)

namespace {

template <class Arch, int N>
void march_occlusion(CellMesh<N> const& mesh, MinMaxBvh const& bvh, FaceNeighbours<N> const& nb, Ray const* rays,
                     int32_t const* start, int n, IsoSet const& isos, uint8_t* occluded, uint8_t* undecided,
                     float* t_done) {
  constexpr int W = width<Arch>;
  TreeView const tree(bvh);
  CellIsoOptions const exact;
  for (int first = 0; first < n; first += W) {
    int const m = n - first < W ? n - first : W;
    RayPacket<Arch> const r = load_rays<Arch>(rays + first, m);
    alignas(64) int32_t cells[W] = {};
    for (int l = 0; l < m; ++l) cells[l] = start[first + l];
    vmask<Arch> const active = simd::mask_from_bits<Arch>(m >= 32 ? ~0u : (1u << m) - 1u);
    vmask<Arch> und;
    vfloat<Arch> done;
    uint32_t const occ = simd::movemask(
        march_occluded<Arch>(tree, mesh, nb, r, active, simd::load<Arch>(cells), isos, exact, und, done));
    uint32_t const ub = simd::movemask(und);
    auto const d = simd::to_array<Arch>(done);
    for (int l = 0; l < m; ++l) {
      occluded[first + l] = uint8_t(occ >> l & 1u);
      undecided[first + l] = uint8_t(ub >> l & 1u);
      t_done[first + l] = d[size_t(l)];
    }
  }
}

}  // namespace

template <class Arch>
void MarchOcclusionProbe<Arch>::run(TetMesh const& mesh, MinMaxBvh const& bvh, TetNeighbours const& nb,
                                    Ray const* rays, int32_t const* start, int n, IsoSet const& isos,
                                    uint8_t* occluded, uint8_t* undecided, float* t_done) {
  march_occlusion<Arch>(mesh, bvh, nb, rays, start, n, isos, occluded, undecided, t_done);
}

template <class Arch>
void MarchOcclusionProbe<Arch>::run(HexMesh const& mesh, MinMaxBvh const& bvh, HexNeighbours const& nb,
                                    Ray const* rays, int32_t const* start, int n, IsoSet const& isos,
                                    uint8_t* occluded, uint8_t* undecided, float* t_done) {
  march_occlusion<Arch>(mesh, bvh, nb, rays, start, n, isos, occluded, undecided, t_done);
}

CELLRAY_INSTANTIATE_ENTRY(MarchOcclusionProbe)

namespace {

template <class Arch, int N>
void first_cells(CellMesh<N> const& mesh, MinMaxBvh const& bvh, ValueWindows const& windows, Ray const* rays, int n,
                 FirstCellsOut* grouped, FirstCellsOut* alone) {
  constexpr int W = width<Arch>, K = 4;
  TreeView const tree(bvh);
  auto keep = [](FirstCellQuery<Arch, N> const& q, FirstCellsOut* out) {
    auto const cells = simd::to_array<Arch>(q.cell);
    auto const t = simd::to_array<Arch>(q.best_t);
    for (int l = 0; l < W; ++l) out[l] = FirstCellsOut{cells[size_t(l)], t[size_t(l)]};
  };
  for (int first = 0; first + K * W <= n; first += K * W) {
    RayPacket<Arch> r[K];
    vmask<Arch> lanes[K];
    for (int k = 0; k < K; ++k) r[k] = load_rays<Arch>(rays + first + k * W, W), lanes[k] = simd::all_lanes<Arch>();
    auto query = [&](int k) { return FirstCellQuery<Arch, N>(tree, mesh, r[k], windows, r[k].tmin, r[k].tmax); };
    auto q = make_array<K>(query);
    FirstCellGroup<Arch, N, K> group(q.data(), r, lanes);
    traverse_packets<Arch, K>(tree, r, lanes, group);
    for (int k = 0; k < K; ++k) {
      keep(q[size_t(k)], grouped + first + k * W);
      FirstCellQuery<Arch, N> one(tree, mesh, r[k], windows, r[k].tmin, r[k].tmax);
      traverse_packet<Arch>(tree, r[k], lanes[k], one);
      keep(one, alone + first + k * W);
    }
  }
}

}  // namespace

template <class Arch>
void FirstCellsProbe<Arch>::run(TetMesh const& mesh, MinMaxBvh const& bvh, ValueWindows const& windows,
                                Ray const* rays, int n, FirstCellsOut* grouped, FirstCellsOut* alone) {
  first_cells<Arch>(mesh, bvh, windows, rays, n, grouped, alone);
}

template <class Arch>
void FirstCellsProbe<Arch>::run(HexMesh const& mesh, MinMaxBvh const& bvh, ValueWindows const& windows,
                                Ray const* rays, int n, FirstCellsOut* grouped, FirstCellsOut* alone) {
  first_cells<Arch>(mesh, bvh, windows, rays, n, grouped, alone);
}

CELLRAY_INSTANTIATE_ENTRY(FirstCellsProbe)

}  // namespace cellray::test
