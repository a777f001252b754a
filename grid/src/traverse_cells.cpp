// traverse_cells.cpp — the traversal with the occlusion buffer on: the cell
// pyramid (cells.h) front to back, a cell at a time.
//
// From the top cell down, a cell's children are visited front to back:
// ordered along each axis by their distance (in cells) from the one holding
// the eye, z outermost, then y, then x. Any cell that can hide part of
// another lies between it and the eye, so along every axis no farther from
// the eye's cell: it comes first in that order, as it does in the paper's
// chess-metric shells (both orders extend the same partial order). A child
// is entered only when it holds something (its bit in its parent's masks:
// static content below it, or live dynamic entries), meets the frustum and
// is not hidden: the buffer proves its box hidden, tile maxima first, or,
// once every pixel holds a bound, it lies beyond the farthest of them. So
// empty space is skipped a cell at a time without being looked at, and
// hidden regions are skipped whole at the coarsest level that shows them
// hidden: the cost follows what is visible, not the grid's resolution.
//
// Far from the eye, where a brick covers only a few pixels of the buffer, a
// brick's own test costs about what the tests of the one or two objects it
// holds cost, and bricks are many (twice the grid's resolution, four times
// the bricks on a surface and eight in a volume). There a cell of bricks is
// taken whole: its bricks holding something are entered without a test of
// their own unless they hold enough to make one pay (kSmallBrickLoad), and
// its voxels are recorded seen without tests; what each brick holds is
// tested as everywhere else. This is what keeps a finer grid's frame near
// the coarser one's: the cells tested follow the image, not the grid.
//
// In a cell entered, the objects stored in it are tested one by one
// (frustum, front neighbours, buffer) and drawn into the buffer when they
// may be visible (collect.h); in a brick, so are the objects of its voxels,
// and the opaque boxes owning its opaque voxels are drawn. The TBVs a cell
// holds are tested last, once its children are drawn; a coarser cell may
// hold a TBV whole and tests its part in the cell (docs/design.md, "Where
// TBVs are stored"). The buffer only
// proves things hidden, in any order (occlusion_buffer.h), so the order
// affects how much is culled and how early, never whether the answer is
// conservative.
#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

#include "numeric.h"
#include "traverse.h"
#include "voxvis/inspect.h"

namespace voxvis::detail {
namespace {

/// A cell of bricks is taken whole when its bricks, at the cell's least
/// depth, are narrower than this share of the buffer's width (16 pixels of
/// a buffer 160 wide).
constexpr double kSmallBrickWidth = 0.1;
/// In a cell taken whole, a brick holding at least this many list entries
/// (objects, opaque boxes, dynamic entries) is still tested first.
constexpr std::ptrdiff_t kSmallBrickLoad = 4;

class CellTraversal {
 public:
  CellTraversal(const Scene::Impl& s, Scratch::Impl& w, const WorldFrustum& wf, FrameStats& st, Collector& col)
      : s_(s), w_(w), wf_(wf), st_(st), col_(col), eg_(s.to_grid(wf.eye)), has_dyn_(!s.bricks.empty()) {
    // A brick's edge, in pixels of the buffer, at unit depth.
    const Vec3& v = s.spec.voxel_size;
    const double edge = static_cast<double>(1 << kCellShift) * std::fmax(v.x, std::fmax(v.y, v.z));
    brick_pixels_ = edge * std::fmax(0.5 * w.ob.width() / wf.tan_x, 0.5 * w.ob.height() / wf.tan_y);
    small_pixels_ = kSmallBrickWidth * w.ob.width();
  }

  void run() { enter(s_.pyr.levels - 1, glm::ivec3(0), true); }

 private:
  /// Enters cell c of level l if it meets the frustum and is not hidden;
  /// `full`: it holds something (else it is only recorded as seen).
  void enter(int l, const glm::ivec3& c, bool full);
  /// Whether cell c of level l misses the frustum or is hidden (counted in
  /// the stats); else its least depth along the view direction in *zmin.
  bool skipped(int l, const glm::ivec3& c, bool full, double* zmin);
  /// `zmin`: the cell's least depth along the view direction.
  void visit(int l, const glm::ivec3& c, double zmin);
  /// Tests and takes the objects and dynamic objects stored in cell ci of
  /// level l.
  void take_contents(int l, std::size_t ci);
  /// Tests the TBVs stored in cell ci of level l and reveals those that may
  /// show: after the cell's own contents and children are drawn.
  void take_tbvs(int l, const glm::ivec3& c, std::size_t ci);
  /// Whether the level-2 cell over brick c holds live dynamic entries (TBVs
  /// held whole there, or objects wholly inside it).
  bool coarse_tbvs_over(const glm::ivec3& c) const {
    return has_dyn_ && s_.coarse_dyn_live > 0 && s_.pyr.levels > 2 &&
           s_.coarse_dyn[2][s_.pyr.index(2, c >> kCellShift)].live > 0;
  }
  /// The dynamic entries of cell ci of level l, when it has live ones.
  const Brick* dyn_cell(int l, std::size_t ci) const {
    if (!has_dyn_) return nullptr;
    const Brick& cell = l == 1 ? s_.bricks[ci] : s_.coarse_dyn[static_cast<std::size_t>(l)][ci];
    return cell.live > 0 ? &cell : nullptr;
  }
  /// `layers`: record its voxels seen a layer at a time (see_layers), else
  /// whole, unless `record` is false (the caller records it).
  void visit_brick(const glm::ivec3& c, bool layers, bool record = true);
  /// The children of cell c of level l that hold something (bit x + 4y + 16z).
  std::uint64_t held_mask(int l, std::size_t ci) const {
    return s_.static_mask[static_cast<std::size_t>(l)][ci] | (has_dyn_ ? s_.dyn_mask[static_cast<std::size_t>(l)][ci] : 0);
  }
  /// Calls fn(child, bit) for the children of cell c of level l within the
  /// grid, front to back (see `order`); bit: the child's in the masks.
  template <class Fn>
  void for_children(int l, const glm::ivec3& c, Fn&& fn) const;
  /// Takes cell c of bricks (level 2, index ci) whole (see the top of this file).
  void take_whole(const glm::ivec3& c, std::size_t ci);
  /// A brick's list entries: the objects stored in it and in its voxels, its
  /// opaque boxes and its live dynamic entries.
  std::ptrdiff_t brick_load(std::size_t bi) const;
  /// The order of the 4 children along axis a of a cell whose first child
  /// along a starts at voxel `first`, children `size` voxels wide.
  void order(int a, int first, int size, int out[4]) const;
  /// Records the voxels of a brick in view as seen, a layer at a time
  /// across the axis nearest the view direction: the layers the buffer hides
  /// at the brick's far side (behind a wall the brick holds) are left out,
  /// so that TBVs of objects behind the wall may grow up to it without being
  /// revealed.
  void see_layers(const glm::ivec3& c, std::size_t bi);
  /// Whether every pixel holds a bound and `zmin` lies beyond all of them.
  bool beyond_buffer(double zmin);
  /// Records cell c of level l in the frame's trace (w.trace, voxvis/inspect.h)
  /// as visited or occluded; the caller tests w.trace, once per cell.
  void trace(int l, const glm::ivec3& c, bool visited) const {
    const VoxBox b = s_.pyr.span(l, c, 0);
    (visited ? w_.trace->visited : w_.trace->occluded).push_back(VoxelBox{b.lo, b.hi});
  }

  const Scene::Impl& s_;
  Scratch::Impl& w_;
  const WorldFrustum& wf_;
  FrameStats& st_;
  Collector& col_;
  const Vec3 eg_;
  const bool has_dyn_;
  double brick_pixels_ = 0.0;  ///< A brick's edge in pixels of the buffer at depth 1.
  double small_pixels_ = 0.0;  ///< Bricks narrower than this are small (kSmallBrickWidth).
  std::uint64_t bound_writes_ = ~std::uint64_t{0};  ///< The buffer's writes when far_bound_ was taken.
  double far_bound_ = 0.0;
};

bool CellTraversal::beyond_buffer(double zmin) {
  const OcclusionBuffer& ob = w_.ob;
  if (ob.writes() != bound_writes_) {
    bound_writes_ = ob.writes();
    far_bound_ = ob.farthest_bound();
  }
  return zmin > far_bound_;
}

void CellTraversal::enter(int l, const glm::ivec3& c, bool full) {
  double zmin = 0.0;
  // An empty brick in a cell holding TBVs whole (Scene::Impl::
  // tbv_coarse_cells) may hold part of one: tested and recorded as a brick
  // holding something is, so that a wall keeps the space behind it unseen.
  const bool tbv_part = !full && l == 1 && coarse_tbvs_over(c);
  if (skipped(l, c, full || tbv_part, &zmin)) return;
  if (!full) {
    if (w_.trace != nullptr) trace(l, c, true);
    // Empty space in view: TBVs made after this frame keep clear of it.
    if (l >= 2) {
      col_.see_cell(l, c);
    } else if (tbv_part) {
      see_layers(c, s_.pyr.index(1, c));
    } else {
      col_.see_brick(s_.pyr.index(1, c));
    }
    return;
  }
  visit(l, c, zmin);
}

bool CellTraversal::skipped(int l, const glm::ivec3& c, bool full, double* zmin_out) {
  const GridSpec& g = s_.spec;
  const int sh = kCellShift * l;
  const Vec3 lo = g.bounds_min + Vec3(c << sh) * g.voxel_size;
  const Vec3 hi = g.bounds_min + Vec3(glm::min((c + 1) << sh, s_.res)) * g.voxel_size;
  if (!wf_.may_intersect_box(lo, hi)) return true;
  // The box's least depth: everything beyond the whole buffer's farthest
  // bound is hidden (the early end: what is left of the frustum is covered).
  double zmin = glm::dot(wf_.f, lo - wf_.eye);
  for (int a = 0; a < 3; ++a) zmin += least(0.0, wf_.f[a] * (hi[a] - lo[a]));
  const double tol = 1e-12 * (max_abs(lo) + max_abs(hi) + max_abs(wf_.eye) + 1.0);
  const bool beyond = beyond_buffer(zmin - 4.0 * tol);
  // In a scene with dynamic objects, a brick holding something is tested
  // fine (over each pixel at its own depth there): a brick behind a wall
  // seen at a slant is then skipped, and its voxels stay out of the seen
  // record, which keeps TBVs of the objects behind the wall from being cut
  // short (or, cut too short, left whole and revealed). Elsewhere cells are
  // tested at their least depth: a visible one is the usual case, and the
  // fine test of a visible box costs more.
  if (beyond || w_.ob.hides_world(lo, hi, has_dyn_ && full && l == 1)) {
    st_.early_exit = st_.early_exit || beyond;
    ++st_.cells_hidden;
    const VoxBox b = s_.pyr.span(l, c, 0);
    const glm::ivec3 n = b.hi - b.lo + 1;
    st_.ob_voxels_culled += static_cast<std::uint64_t>(n.x) * static_cast<std::uint64_t>(n.y) * static_cast<std::uint64_t>(n.z);
    if (w_.trace != nullptr) trace(l, c, false);
    return true;
  }
  *zmin_out = zmin;
  return false;
}

void CellTraversal::order(int a, int first, int size, int out[4]) const {
  const double k = std::floor((eg_[a] - first) / size);
  if (!(k > 0.0)) {
    out[0] = 0, out[1] = 1, out[2] = 2, out[3] = 3;
  } else if (k >= 3.0) {
    out[0] = 3, out[1] = 2, out[2] = 1, out[3] = 0;
  } else if (k == 1.0) {
    out[0] = 1, out[1] = 0, out[2] = 2, out[3] = 3;
  } else {
    out[0] = 2, out[1] = 1, out[2] = 3, out[3] = 0;
  }
}

void CellTraversal::take_contents(int l, std::size_t ci) {
  // The static objects stored in the cell: they touch every voxel of it.
  const IdLists& lists = s_.static_lists[static_cast<std::size_t>(l)];
  if (lists.any())
    for (const std::uint32_t* p = lists.begin(ci); p != lists.end(ci); ++p) col_.add(*p);
  // Its dynamic objects.
  if (const Brick* cell = dyn_cell(l, ci))
    for (const BrickEntry& e : cell->entries)
      if (!(e.key & 1u) && s_.current(e)) col_.add(e.key >> 1);
}

void CellTraversal::take_tbvs(int l, const glm::ivec3& c, std::size_t ci) {
  const Brick* cell = dyn_cell(l, ci);
  if (cell == nullptr) return;
  // A coarser cell may hold a TBV's entry whole while holding only part of
  // it (Scene::Impl::tbv_coarse_cells): its part in the cell is tested.
  Vec3 lo{0.0}, hi{0.0};
  if (l >= 2) {
    const GridSpec& g = s_.spec;
    const VoxBox b = s_.pyr.span(l, c, 0);
    lo = g.bounds_min + Vec3(b.lo) * g.voxel_size;
    hi = g.bounds_min + Vec3(b.hi + 1) * g.voxel_size;
  }
  for (const BrickEntry& e : cell->entries) {
    if (!(e.key & 1u) || !s_.current(e)) continue;
    const std::uint32_t slot = e.key >> 1;
    const Obj& o = s_.objs[slot];
    if (!wf_.may_intersect_box(o.tbv_lo, o.tbv_hi)) continue;
    if (l >= 2) {
      col_.reveal_part(slot, lo, hi);
    } else {
      col_.reveal(slot);
    }
  }
}

void CellTraversal::visit(int l, const glm::ivec3& c, double zmin) {
  ++st_.cells_visited;
  const std::size_t ci = s_.pyr.index(l, c);
  take_contents(l, ci);
  if (l == 1) {
    if (w_.trace != nullptr) trace(l, c, true);
    visit_brick(c, has_dyn_);
  } else if (l == 2 && zmin > 0.0 && brick_pixels_ < small_pixels_ * zmin) {
    take_whole(c, ci);
  } else {
    const std::uint64_t held = held_mask(l, ci);
    for_children(l, c, [&](const glm::ivec3& child, int bit) {
      const bool full = (held >> bit & 1u) != 0;
      if (full || has_dyn_) enter(l - 1, child, full);
    });
  }
  // The cell's TBVs last, against everything the cell itself holds that
  // occludes them (a wall between the eye and a TBV in the same cell).
  take_tbvs(l, c, ci);
}

template <class Fn>
void CellTraversal::for_children(int l, const glm::ivec3& c, Fn&& fn) const {
  const int size = 1 << (kCellShift * (l - 1));
  const glm::ivec3 first = c << kCellShift;
  const glm::ivec3 res = s_.pyr.res[static_cast<std::size_t>(l - 1)];
  int ox[4], oy[4], oz[4];
  order(0, first.x * size, size, ox);
  order(1, first.y * size, size, oy);
  order(2, first.z * size, size, oz);
  for (int iz : oz) {
    if (first.z + iz >= res.z) continue;
    for (int iy : oy) {
      if (first.y + iy >= res.y) continue;
      for (int ix : ox) {
        if (first.x + ix >= res.x) continue;
        fn(first + glm::ivec3(ix, iy, iz), ix | iy << 2 | iz << 4);
      }
    }
  }
}

void CellTraversal::see_layers(const glm::ivec3& c, std::size_t bi) {
  static constexpr std::uint64_t kLayer0[3] = {0x1111111111111111ull, 0x000F000F000F000Full, 0xFFFFull};
  int a = 0;
  for (int k = 1; k < 3; ++k)
    if (std::fabs(wf_.f[k]) > std::fabs(wf_.f[a])) a = k;
  const GridSpec& g = s_.spec;
  const glm::ivec3 o = c << kCellShift;
  const glm::ivec3 end = glm::min(o + (1 << kCellShift), s_.res);
  // From the farthest layer towards the eye: once one is not hidden, the
  // nearer ones are taken as seen untested (a layer recorded as seen only
  // keeps TBVs out of it: conservative), so a brick without a wall costs one
  // test, not one a layer.
  const int layers = std::min(1 << kCellShift, end[a] - o[a]);
  const bool ascending = wf_.f[a] < 0.0;  // Then the first layer is the farthest.
  std::uint64_t mask = 0;
  bool seen = false;
  for (int step = 0; step < layers; ++step) {
    const int k = ascending ? step : layers - 1 - step;
    if (!seen) {
      glm::ivec3 lo = o, hi = end;
      lo[a] = o[a] + k;
      hi[a] = o[a] + k + 1;
      seen = !w_.ob.hides_world(g.bounds_min + Vec3(lo) * g.voxel_size, g.bounds_min + Vec3(hi) * g.voxel_size);
    }
    if (seen) mask |= kLayer0[a] << (k << (2 * a));
  }
  col_.see_brick(bi, mask);
}

void CellTraversal::visit_brick(const glm::ivec3& c, bool layers, bool record) {
  const std::size_t bi = s_.pyr.index(1, c);
  // The static objects of its voxels' own lists, and the opaque boxes
  // owning its opaque voxels (Scene::Impl::brick_static, brick_boxes).
  st_.voxels_visited += static_cast<std::uint64_t>(__builtin_popcountll(s_.static_mask[1][bi]));
  for (const std::uint32_t* p = s_.brick_boxes.begin(bi); p != s_.brick_boxes.end(bi); ++p)
    col_.render_opaque_box_at(*p);
  // The static mesh triangles meeting it. Drawn before its objects are
  // tested: a mesh's own triangles lie inside its box, never strictly
  // before it, so they cannot hide it (docs/design.md, "Meshes").
  col_.render_brick_triangles(bi);
  for (const std::uint32_t* p = s_.brick_static.begin(bi); p != s_.brick_static.end(bi); ++p) col_.add(*p);
  // After its own occluders are drawn: a wall hides the layers behind it.
  if (layers) {
    see_layers(c, bi);
  } else if (has_dyn_ && record) {
    col_.see_brick(bi);
  }
}

std::ptrdiff_t CellTraversal::brick_load(std::size_t bi) const {
  const IdLists& own = s_.static_lists[1];
  const std::ptrdiff_t tris =
      s_.brick_tri_offsets.empty() ? 0 : std::ptrdiff_t{s_.brick_tri_offsets[bi + 1]} - s_.brick_tri_offsets[bi];
  return tris + (s_.brick_static.end(bi) - s_.brick_static.begin(bi)) + (s_.brick_boxes.end(bi) - s_.brick_boxes.begin(bi)) +
         (own.any() ? own.end(bi) - own.begin(bi) : 0) + (has_dyn_ ? std::ptrdiff_t{s_.bricks[bi].live} : 0);
}

void CellTraversal::take_whole(const glm::ivec3& c, std::size_t ci) {
  ++st_.cells_whole;
  const std::uint64_t held = held_mask(2, ci);
  // Every brick of the cell is recorded seen whole but those a test hid:
  // empty ones untested (more seen space only keeps TBVs out of more
  // space). With none hidden, the cell is recorded once instead of its
  // bricks one by one (the seen record reads the two alike).
  std::uint64_t hidden = 0;
  for_children(2, c, [&](const glm::ivec3& b, int bit) {
    if (!(held >> bit & 1u)) return;
    const std::size_t bi = s_.pyr.index(1, b);
    double zmin = 0.0;
    if (brick_load(bi) >= kSmallBrickLoad && skipped(1, b, true, &zmin)) {
      hidden |= std::uint64_t{1} << bit;
      return;
    }
    ++st_.cells_visited;
    take_contents(1, bi);
    visit_brick(b, false, false);
    take_tbvs(1, b, bi);
  });
  // The trace counts the cell visited whole, less its bricks proven hidden
  // (or missing the frustum), as the seen record below does.
  if (w_.trace != nullptr) {
    if (hidden == 0) {
      trace(2, c, true);
    } else {
      for_children(2, c, [&](const glm::ivec3& b, int bit) {
        if (!(hidden >> bit & 1u)) trace(1, b, true);
      });
    }
  }
  if (!has_dyn_) return;
  if (hidden == 0) {
    col_.see_cell(2, c);
    return;
  }
  for_children(2, c, [&](const glm::ivec3& b, int bit) {
    if (!(hidden >> bit & 1u)) col_.see_brick(s_.pyr.index(1, b));
  });
}

}  // namespace

void traverse_cells(const Scene::Impl& s, Scratch::Impl& w, const WorldFrustum& wf, FrameStats& st,
                    const FrameGeometry& g) {
  Collector col(s, w, wf, st, g);
  CellTraversal(s, w, wf, st, col).run();
}

}  // namespace voxvis::detail
