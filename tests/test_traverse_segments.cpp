// The per-ray segment list of cell-segment DVR (traverse/segments.hpp): a
// window holding more cells than the list must keep the nearest ones and
// say exactly where it was cut, whatever order the traversal finds them in
// (the next window starts there; a wrong cut stalled component8 renders).

#include <catch2/catch.hpp>

#include <algorithm>
#include <limits>
#include <memory>
#include <numeric>
#include <random>
#include <vector>

#include <cellray/traverse/segments.hpp>

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_traverse_segments {

using namespace cellray;

namespace {

/// A one-lane segment query over nothing: only its list (add, count, cut) is used.
struct ListOnly {
  TreeView tree;
  TetMesh mesh;
  RayPacket<scalar> rays{};
  ValueWindows windows;
  std::unique_ptr<SegmentQuery<scalar, 4>> query(float t_lo, float t_hi) const {
    return std::make_unique<SegmentQuery<scalar, 4>>(tree, mesh, rays, windows, t_lo, t_hi);
  }
};

}  // namespace

TEST_CASE("segment lists keep the nearest max_segments per ray in any arrival order", "[traverse][segments]") {
  ListOnly const f;
  auto q = f.query(0.f, 1000.f);
  int const total = max_segments + 25;
  std::vector<int> order(size_t(total), 0);
  std::iota(order.begin(), order.end(), 0);
  std::mt19937 rng(7);
  for (int round = 0; round < 20; ++round) {
    std::shuffle(order.begin(), order.end(), rng);
    q->reset(f.tree, f.mesh, f.rays, 0.f, 1000.f);
    for (int i : order) {
      FieldSegment s{};
      s.s.t_in = float(i), s.s.t_out = float(i) + 1.f, s.s.cell = uint64_t(i);
      q->add(0, s);
    }
    REQUIRE(q->count[0] == max_segments);
    // Every segment before the cut is kept, the cut is the first one dropped.
    CHECK(q->cut[0] == float(max_segments));
    std::vector<uint64_t> kept;
    for (int k = 0; k < q->count[0]; ++k) kept.push_back(q->seg[0][k].s.cell);
    std::sort(kept.begin(), kept.end());
    for (int k = 0; k < max_segments; ++k) CHECK(kept[size_t(k)] == uint64_t(k));
  }
}

TEST_CASE("segment lists below capacity keep everything and no cut", "[traverse][segments]") {
  ListOnly const f;
  auto q = f.query(0.f, 10.f);
  for (int i = 5; i > 0; --i) {
    FieldSegment s{};
    s.s.t_in = float(i), s.s.t_out = float(i) + 1.f;
    q->add(0, s);
  }
  CHECK(q->count[0] == 5);
  CHECK(q->cut[0] == std::numeric_limits<float>::infinity());
}

}  // namespace test_traverse_segments
