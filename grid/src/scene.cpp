// scene.cpp — a scene's conservative discretization, moves and temporal
// bounding volumes. Building a scene (validation, the grid, the cost
// estimate) is in build.cpp; the frame is in frame.cpp.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <limits>
#include <string>

#include <glm/geometric.hpp>

#include "numeric.h"
#include "opaque_boxes.h"
#include "scene_impl.h"

namespace voxvis {

using detail::Obj;
using detail::VoxBox;
using detail::finite3;
using detail::clamp_floor;
using detail::kUlp;
using detail::max_abs;

namespace {

/// now + period, but always later than now: the frame's expiry loop takes
/// every TBV expiring at or before its time, so a renewal that rounded back to
/// `now` would expire again at once, for ever. Scene times are bounded
/// (kMaxSceneTime) so that this only guards; it never shortens a period that
/// rounding keeps.
double expiry_after(double now, double period) {
  return std::fmax(now + period, std::nextafter(now, std::numeric_limits<double>::infinity()));
}

}  // namespace

// ---------------------------------------------------------------------------
// Scratch

Scratch::Scratch() : impl_(std::make_unique<Impl>()) {}
Scratch::~Scratch() = default;

void Scratch::Impl::begin(std::size_t objects, std::size_t boxes, std::size_t bricks, std::size_t cells,
                          std::size_t triangles) {
  pvs.clear();
  deferred.clear();
  // A frame that ended early (an error) may have left its seen record.
  for (std::uint32_t b : seen_list) seen_vox[b] = 0;
  seen_list.clear();
  seen_cells.clear();
  if (seen_vox.size() < bricks) seen_vox.resize(bricks, 0);
  if (obj_mark.size() < objects) obj_mark.resize(objects, 0);
  if (obj_seen.size() < objects) obj_seen.resize(objects, 0);
  if (box_seen.size() < boxes) box_seen.resize(boxes, 0);
  if (cell_seen.size() < cells) cell_seen.resize(cells, 0);
  if (tri_seen.size() < triangles) tri_seen.resize(triangles, 0);
  // Start the frame counter over before it wraps, so that no stale object
  // mark can ever match (stamp tags cycle separately, below).
  if (++frame == std::numeric_limits<std::uint32_t>::max()) {
    std::fill(obj_mark.begin(), obj_mark.end(), 0u);
    std::fill(obj_seen.begin(), obj_seen.end(), 0u);
    std::fill(box_seen.begin(), box_seen.end(), 0u);
    std::fill(cell_seen.begin(), cell_seen.end(), 0u);
    std::fill(tri_seen.begin(), tri_seen.end(), 0u);
    frame = 1;
  }
  pvs.clear();
  reveals.clear();
}

void Scratch::Impl::begin_voxels(std::size_t voxels) {
  if (stamp.size() < voxels) stamp.resize(voxels, 0);
  if (++stamp_tag == 64) {
    std::fill(stamp.begin(), stamp.end(), std::uint8_t{0});
    stamp_tag = 1;
  }
}

// ---------------------------------------------------------------------------
// Geometry

double Scene::Impl::slop(double mag) const {
  // Generous allowance for the rounding of (p - bounds_min) / voxel_size and
  // of the distance arithmetic; errs towards "touches" and "not opaque".
  return 64.0 * kUlp * (mag + slop_bounds) + 1e-300;
}

VoxBox Scene::Impl::touch_range(const Vec3& lo, const Vec3& hi, double slop_w) const {
  const Vec3 glo = to_grid(lo) - slop_w * inv_vs;
  const Vec3 ghi = to_grid(hi) + slop_w * inv_vs;
  VoxBox vb;
  for (int a = 0; a < 3; ++a) {
    // Voxel i spans [i, i+1]; it touches [glo, ghi] iff ceil(glo)-1 <= i <= floor(ghi).
    vb.lo[a] = clamp_floor(std::ceil(glo[a]) - 1.0, 0, res[a] - 1);
    vb.hi[a] = clamp_floor(ghi[a], -1, res[a] - 1);
    if (ghi[a] < 0.0 || glo[a] > res[a]) {
      vb.hi = glm::ivec3(-1);
      vb.lo = glm::ivec3(0);
      return vb;
    }
  }
  return vb;
}

bool Scene::Impl::touches(const Obj& o, const Vec3& c, int x, int y, int z) const {
  const double s = slop(max_abs(c) + o.radius + max_abs(o.half));
  const Vec3 v{static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)};
  if (o.shape == Shape::Sphere) {
    const Vec3 cg = to_grid(c);
    const Vec3 q = glm::clamp(cg, v, v + 1.0);
    const Vec3 dw = (q - cg) * spec.voxel_size;
    const double rr = o.radius + s;
    return glm::dot(dw, dw) <= rr * rr;
  }
  const Vec3 sg = s * inv_vs;
  const Vec3 lo = to_grid(c - o.half) - sg;
  const Vec3 hi = to_grid(c + o.half) + sg;
  return v.x <= hi.x && v.x + 1.0 >= lo.x && v.y <= hi.y && v.y + 1.0 >= lo.y &&
         v.z <= hi.z && v.z + 1.0 >= lo.z;
}

bool Scene::Impl::contains_voxel(const Obj& o, const Vec3& c, int x, int y, int z) const {
  const double s = slop(max_abs(c) + o.radius + max_abs(o.half));
  const Vec3 v{static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)};
  if (o.shape == Shape::Sphere) {
    const Vec3 cg = to_grid(c);
    const Vec3 far_d = glm::max(glm::abs(v - cg), glm::abs(v + 1.0 - cg)) * spec.voxel_size;
    const double rr = o.radius - s;
    return rr > 0.0 && glm::dot(far_d, far_d) <= rr * rr;
  }
  Vec3 lo, hi;
  inner_box(o, c, &lo, &hi);
  return v.x >= lo.x && v.x + 1.0 <= hi.x && v.y >= lo.y && v.y + 1.0 <= hi.y &&
         v.z >= lo.z && v.z + 1.0 <= hi.z;
}

namespace {

/// s = a + b rounded; true when the sum is exact (Knuth's TwoSum: the
/// rounding error is computed exactly and is zero).
bool exact_sum(double a, double b, double* s) {
  *s = a + b;
  const double bb = *s - a;
  const double err = (a - (*s - bb)) + (b - bb);
  return err == 0.0;
}

/// Whether w - b0 equals g * h exactly, as real numbers. Both sides are
/// written as an unevaluated sum hi + lo with hi the rounded value and lo its
/// exact error (TwoSum, TwoProduct by fma); that pair is unique for a real
/// number, so comparing the pairs compares the reals.
bool on_boundary(double w, double b0, double g, double h) {
  const double d = w - b0;
  const double dd = d - w;
  const double derr = (w - (d - dd)) + (-b0 - dd);
  const double p = g * h;
  const double perr = std::fma(g, h, -p);
  return d == p && derr == perr;
}

constexpr int kMaxUnion = 16;  ///< Inner boxes the exact union test takes per voxel.

}  // namespace

double detail::Obj::mesh_allowance() const { return 64.0 * kUlp * (max_abs(mesh_origin) + mesh_extent) + 1e-300; }

void Scene::Impl::place_mesh(Obj& o) const {
  // The placed points' rounding and the box's own are allowed for.
  const double m = o.mesh_allowance();
  if (o.dynamic) {
    o.center = o.mesh_origin + o.mesh_scale * (o.mesh_rotation * o.mesh_centroid);
    o.half = Vec3(o.radius + m);
    return;
  }
  Vec3 lo, hi;
  mesh_bounds(o.mesh_desc(), &lo, &hi);
  o.center = (lo + hi) * 0.5;
  o.half = glm::max(hi - o.center, o.center - lo) + m;
}

void Scene::Impl::inner_box(const Obj& o, const Vec3& c, Vec3* lo, Vec3* hi) const {
  if (o.shape == Shape::Mesh) {  // No volume is known to be inside a mesh: empty.
    *lo = Vec3(std::numeric_limits<double>::infinity());
    *hi = Vec3(-std::numeric_limits<double>::infinity());
    return;
  }
  const double s = slop(max_abs(c) + o.radius + max_abs(o.half));
  const Vec3 sg = s * inv_vs;
  if (o.shape == Shape::Sphere) {
    // Inscribed cube, half side r / sqrt(3), rounded down generously; its
    // mapping is rounded, so it is shrunk by the allowance too.
    const double h = o.radius * (1.0 / std::sqrt(3.0)) * (1.0 - 16.0 * kUlp);
    *lo = to_grid(c - h) + sg;
    *hi = to_grid(c + h) - sg;
    return;
  }
  for (int a = 0; a < 3; ++a) {
    // A face whose world coordinate is exactly bounds_min + n * voxel_size
    // maps to n with no rounding at all: compare exactly there (this is
    // what lets voxel-aligned walls and unit blocks cover their voxels).
    for (int side = 0; side < 2; ++side) {
      double w = 0.0;
      const bool exact = exact_sum(c[a], side ? o.half[a] : -o.half[a], &w);
      const double g = (w - spec.bounds_min[a]) * inv_vs[a];
      // g is the face's exact grid coordinate when g * voxel_size equals
      // w - bounds_min as real numbers; any rounding shows as a difference.
      const bool exact_g = exact && on_boundary(w, spec.bounds_min[a], g, spec.voxel_size[a]);
      const double v = exact_g ? g : (side ? g - sg[a] : g + sg[a]);
      (side ? (*hi)[a] : (*lo)[a]) = v;
    }
  }
}

bool Scene::Impl::own_voxels(const Obj& o, VoxBox* out) const {
  const Vec3 c = o.center;
  const Vec3 half = o.shape == Shape::Sphere ? Vec3(o.radius) : o.half;
  const Vec3 sg = slop(max_abs(c) + o.radius + max_abs(o.half)) * inv_vs;
  for (int a = 0; a < 3; ++a) {
    double g[2];
    for (int side = 0; side < 2; ++side) {
      double w = 0.0;
      const bool exact = exact_sum(c[a], side ? half[a] : -half[a], &w);
      const double q = (w - spec.bounds_min[a]) * inv_vs[a];
      const bool exact_g = exact && on_boundary(w, spec.bounds_min[a], q, spec.voxel_size[a]);
      g[side] = exact_g ? q : (side ? q + sg[a] : q - sg[a]);
    }
    // Voxel i is [i, i+1]; the closed range [g0, g1] lies in voxels
    // floor(g0) .. ceil(g1) - 1 (one voxel when it is a single point).
    const double i0 = std::floor(g[0]), i1 = std::fmax(i0, std::ceil(g[1]) - 1.0);
    if (!(i0 >= 0.0) || !(i1 <= res[a] - 1.0)) return false;
    out->lo[a] = static_cast<int>(i0);
    out->hi[a] = static_cast<int>(i1);
  }
  return true;
}

bool Scene::Impl::union_covers(const std::uint32_t* slots, std::size_t n, int x, int y, int z) const {
  const Vec3 v0{static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)};
  const Vec3 v1 = v0 + 1.0;
  Vec3 blo[kMaxUnion], bhi[kMaxUnion];
  int nb = 0;
  bool too_many = false;
  for (std::size_t i = 0; i < n; ++i) {
    const Obj& o = objs[slots[i]];
    const Vec3& c = o.dynamic ? o.disc_center : o.center;
    if (o.shape == Shape::Sphere && contains_voxel(o, c, x, y, z)) return true;
    Vec3 lo, hi;
    inner_box(o, c, &lo, &hi);
    lo = glm::max(lo, v0);
    hi = glm::min(hi, v1);
    // Boxes meeting the voxel in less than a volume add nothing to the cover
    // of its open cells (see below).
    if (!(lo.x < hi.x && lo.y < hi.y && lo.z < hi.z)) continue;
    if (lo == v0 && hi == v1) return true;  // One object covers it.
    if (nb == kMaxUnion) {
      too_many = true;  // Keep looking for a single cover; the union is not tested.
      continue;
    }
    blo[nb] = lo;
    bhi[nb] = hi;
    ++nb;
  }
  if (too_many || nb < 2) return false;
  // The faces of the boxes cut the voxel into cells; no face passes through
  // a cell's interior, so a box holding a cell's centre holds the whole
  // closed cell. The voxel is covered iff every cell's centre is.
  double cut[3][2 * kMaxUnion + 2];
  int nc[3];
  for (int a = 0; a < 3; ++a) {
    int k = 0;
    cut[a][k++] = v0[a];
    cut[a][k++] = v1[a];
    for (int i = 0; i < nb; ++i) {
      cut[a][k++] = blo[i][a];
      cut[a][k++] = bhi[i][a];
    }
    std::sort(cut[a], cut[a] + k);
    nc[a] = static_cast<int>(std::unique(cut[a], cut[a] + k) - cut[a]);
  }
  for (int k = 0; k + 1 < nc[2]; ++k) {
    const double cz = 0.5 * (cut[2][k] + cut[2][k + 1]);
    for (int j = 0; j + 1 < nc[1]; ++j) {
      const double cy = 0.5 * (cut[1][j] + cut[1][j + 1]);
      for (int i = 0; i + 1 < nc[0]; ++i) {
        const double cx = 0.5 * (cut[0][i] + cut[0][i + 1]);
        bool in = false;
        for (int b = 0; b < nb && !in; ++b)
          in = cx > blo[b].x && cx < bhi[b].x && cy > blo[b].y && cy < bhi[b].y &&
               cz > blo[b].z && cz < bhi[b].z;
        if (!in) return false;
      }
    }
  }
  return true;
}

bool Scene::Impl::in_one_ball(const std::uint32_t* slots, std::size_t n, int x, int y, int z) const {
  for (std::size_t i = 0; i < n; ++i) {
    const Obj& o = objs[slots[i]];
    if (o.shape == Shape::Sphere && !o.dynamic && contains_voxel(o, o.center, x, y, z)) return true;
  }
  return false;
}

void Scene::Impl::coarse_static(int x, int y, int z, std::uint32_t* out, std::size_t* n, std::size_t cap) const {
  for (int l = 1; l < pyr.levels && *n < cap; ++l) {
    const detail::IdLists& lists = static_lists[static_cast<std::size_t>(l)];
    if (!lists.any()) continue;
    const int sh = detail::kCellShift * l;
    const std::size_t c = pyr.index(l, glm::ivec3(x >> sh, y >> sh, z >> sh));
    for (const std::uint32_t* p = lists.begin(c); p != lists.end(c) && *n < cap; ++p) out[(*n)++] = *p;
  }
}

bool Scene::Impl::covered_now(int x, int y, int z) const {
  std::uint32_t slots[detail::kCoverCandidates];
  std::size_t n = 0;
  const auto i = static_cast<std::size_t>(index(x, y, z));
  const detail::IdLists& own = static_lists[0];
  for (const std::uint32_t* p = own.begin(i); p != own.end(i) && n < std::size(slots); ++p) slots[n++] = *p;
  if (vflags[i] & kCoarseIds) coarse_static(x, y, z, slots, &n, std::size(slots));
  if (!bricks.empty()) {
    const int levels = coarse_dyn_live > 0 ? pyr.levels : 2;
    for (int l = 1; l < levels; ++l) {
      const int sh = detail::kCellShift * l;
      const glm::ivec3 c(x >> sh, y >> sh, z >> sh);
      const detail::Brick& br = l == 1 ? bricks[pyr.index(1, c)]
                                       : coarse_dyn[static_cast<std::size_t>(l)][pyr.index(l, c)];
      if (br.live == 0) continue;
      for (const detail::BrickEntry& e : br.entries) {
        if ((e.key & 1u) || !current(e) || objs[e.key >> 1].no_opacity) continue;
        if (n == std::size(slots)) return false;  // Too crowded to test: not covered (tightness only).
        slots[n++] = e.key >> 1;
      }
    }
  }
  return union_covers(slots, n, x, y, z);
}

bool Scene::Impl::box_inside_grid(const Vec3& lo, const Vec3& hi) const {
  const double s = slop(std::fmax(max_abs(lo), max_abs(hi)));
  for (int a = 0; a < 3; ++a)
    if (!(lo[a] >= spec.bounds_min[a] + s) || !(hi[a] <= spec.bounds_max[a] - s)) return false;
  return true;
}

// ---------------------------------------------------------------------------
// Dynamic layer

namespace {

/// The bricks (bricks_res coordinates) holding the voxels of vb; empty for
/// an empty vb.
VoxBox bricks_of(const VoxBox& vb) {
  return vb.empty() ? vb : VoxBox{vb.lo >> detail::kBrickShift, vb.hi >> detail::kBrickShift};
}

/// The cells of levels >= 1 that hold the entries of voxel box vb: its range
/// of bricks split into the coarsest cells wholly inside it (cells.h).
template <class Emit>
void dyn_cells_of(const detail::Pyramid& pyr, const VoxBox& vb, Emit&& emit) {
  if (vb.empty()) return;
  detail::decompose(
      pyr, 1, bricks_of(vb), [](const VoxBox&) { return true; }, [](const VoxBox&) { return false; }, true, emit,
      [](std::uint64_t) { return true; });
}

/// The level-2 cells over a range of bricks, when at most 3 a side (a
/// range that size holds no cell of level 3 whole); else an empty box.
VoxBox cells2_over(const VoxBox& bricks) {
  const VoxBox c{bricks.lo >> detail::kCellShift, bricks.hi >> detail::kCellShift};
  return glm::all(glm::lessThan(c.hi - c.lo, glm::ivec3(3))) ? c : VoxBox{};
}

/// Calls fn(k, cell, bricks of the range inside it) for each level-2 cell of
/// `cells` (cells2_over's), k counting x fastest.
template <class Fn>
void for_cells2(const detail::Pyramid& pyr, const VoxBox& cells, const VoxBox& bricks, Fn&& fn) {
  int k = 0;
  for (int z = cells.lo.z; z <= cells.hi.z; ++z)
    for (int y = cells.lo.y; y <= cells.hi.y; ++y)
      for (int x = cells.lo.x; x <= cells.hi.x; ++x, ++k) {
        const glm::ivec3 c(x, y, z);
        const VoxBox span = pyr.span(2, c, 1);
        fn(k, c, span, VoxBox{glm::max(span.lo, bricks.lo), glm::min(span.hi, bricks.hi)});
      }
}

/// The cells holding the entries of a TBV over voxels vb (Obj::tbv_coarse):
/// dyn_cells_of's, but the level-2 cells of `coarse` whole. Over at most 3
/// level-2 cells a side, dyn_cells_of's are, cell by cell, the cell when
/// the range covers it and the range's bricks in it otherwise.
template <class Emit>
void tbv_cells_of(const detail::Pyramid& pyr, const VoxBox& vb, std::uint32_t coarse, Emit&& emit) {
  if (coarse == 0 || vb.empty()) {
    dyn_cells_of(pyr, vb, emit);
    return;
  }
  const VoxBox bricks = bricks_of(vb);
  for_cells2(pyr, cells2_over(bricks), bricks, [&](int k, const glm::ivec3& c, const VoxBox& span, const VoxBox& in) {
    if ((coarse >> k & 1u) || in == span) {
      emit(2, c);
      return;
    }
    for (int z = in.lo.z; z <= in.hi.z; ++z)
      for (int y = in.lo.y; y <= in.hi.y; ++y)
        for (int x = in.lo.x; x <= in.hi.x; ++x) emit(1, glm::ivec3(x, y, z));
  });
}

/// Whether tbv_cells_of writes the same cells for (vb, coarse) as for
/// (old_vb, old_coarse): then a TBV grown within the cells holding it whole
/// keeps its entries.
bool same_tbv_cells(const detail::Pyramid& pyr, const VoxBox& old_vb, std::uint32_t old_coarse, const VoxBox& vb,
                    std::uint32_t coarse) {
  if (old_coarse == 0 || coarse == 0 || old_vb.empty() || vb.empty()) return false;
  const VoxBox ob = bricks_of(old_vb), nb = bricks_of(vb);
  const VoxBox cells = cells2_over(nb);
  if (cells != cells2_over(ob)) return false;
  bool same = true;
  for_cells2(pyr, cells, nb, [&](int k, const glm::ivec3&, const VoxBox& span, const VoxBox& in) {
    const VoxBox old_in{glm::max(span.lo, ob.lo), glm::min(span.hi, ob.hi)};
    const bool whole = (coarse >> k & 1u) || in == span;
    const bool old_whole = (old_coarse >> k & 1u) || old_in == span;
    if (whole != old_whole || (!whole && in != old_in)) same = false;
  });
  return same;
}

}  // namespace

bool Scene::Impl::unseen_around(const VoxBox& vb) const {
  if (vb.empty() || cell_any_seen_at.empty()) return false;
  const VoxBox cells{vb.lo >> (detail::kBrickShift + detail::kCellShift), vb.hi >> (detail::kBrickShift + detail::kCellShift)};
  return unseen_range(VoxBox{cells.lo << detail::kCellShift,
                             glm::min(((cells.hi + 1) << detail::kCellShift) - 1, pyr.res[1] - 1)});
}

std::uint32_t Scene::Impl::tbv_coarse_cells(const VoxBox& vb, bool quiet) const {
  // Only the cell traversal tests a TBV's own box for every entry it reads
  // (the shell traversal tests entries voxel by voxel), and only a memory
  // of seen space tells where a cell is not in view.
  if (vb.empty() || dyn_count[1].empty() || cell_any_seen_at.empty() || !(options.tbv_seen_memory > 0.0)) return 0;
  const VoxBox range = bricks_of(vb);
  const VoxBox cells = cells2_over(range);
  if (cells.empty()) return 0;
  // Behind a wall, the usual case, nothing around the range was seen: one
  // question for all of its cells.
  const bool none_seen = quiet || unseen_around(vb);
  std::uint32_t coarse = 0;
  for_cells2(pyr, cells, range, [&](int k, const glm::ivec3&, const VoxBox& span, const VoxBox& in) {
    if (in != span && (none_seen || unseen_range(span))) coarse |= std::uint32_t{1} << k;
  });
  return coarse;
}

void Scene::Impl::brick_add(const VoxBox& vb, std::uint32_t key, std::uint32_t gen, std::uint32_t coarse) {
  tbv_cells_of(pyr, vb, coarse, [&](int level, const glm::ivec3& c) {
    detail::Brick& br = dyn_cell(level, c);
    if (br.entries.size() >= 2 * std::size_t{br.live} + 16) {
      std::erase_if(br.entries, [&](const detail::BrickEntry& e) { return !current(e); });
    }
    br.entries.push_back({key, gen});
    ++br.live;
    if (level > 1) ++coarse_dyn_live;
    dyn_count_add(level, c, 1);
  });
}

void Scene::Impl::brick_remove(const VoxBox& vb, std::uint32_t coarse) {
  tbv_cells_of(pyr, vb, coarse, [&](int level, const glm::ivec3& c) {
    // The same cells brick_add wrote (the choice of cells is stored with
    // the entry's owner): each still counts its entry.
    VOXVIS_ASSERT(dyn_cell(level, c).live > 0 && (level == 1 || coarse_dyn_live > 0));
    --dyn_cell(level, c).live;
    if (level > 1) --coarse_dyn_live;
    dyn_count_add(level, c, -1);
  });
}

void Scene::Impl::dyn_count_add(int level, glm::ivec3 c, int delta) {
  if (dyn_count[1].empty()) return;  // Buffer off: no cell traversal to summarize for.
  // A cell's count is its own live entries and its children that are not
  // empty, so only a change between empty and not climbs: adding to a cell
  // that already holds something touches that one cell.
  for (int l = level; l < pyr.levels; ++l, c >>= detail::kCellShift) {
    std::uint32_t& n = dyn_count[static_cast<std::size_t>(l)][pyr.index(l, c)];
    VOXVIS_ASSERT(delta >= 0 || std::int64_t{n} + delta >= 0);
    const bool was = n > 0;
    n = static_cast<std::uint32_t>(static_cast<std::int64_t>(n) + delta);
    if (was == (n > 0)) return;
    if (l + 1 < pyr.levels) {
      const std::uint64_t bit = std::uint64_t{1} << ((c.x & 3) | (c.y & 3) << 2 | (c.z & 3) << 4);
      dyn_mask[static_cast<std::size_t>(l) + 1][pyr.index(l + 1, c >> detail::kCellShift)] ^= bit;
    }
  }
}

void Scene::Impl::list_add(std::vector<std::uint32_t>& list, std::int32_t& pos, std::uint32_t slot) {
  if (pos >= 0) return;
  pos = static_cast<std::int32_t>(list.size());
  list.push_back(slot);
}

void Scene::Impl::list_remove(std::vector<std::uint32_t>& list, std::int32_t& pos, bool tbv) {
  if (pos < 0) return;
  const std::uint32_t moved = list.back();
  list[static_cast<std::size_t>(pos)] = moved;
  (tbv ? objs[moved].tbv_outside_pos : objs[moved].outside_pos) = pos;
  list.pop_back();
  pos = -1;
}

void Scene::Impl::discretize(std::uint32_t slot) {
  Obj& o = objs[slot];
  o.disc_center = o.center;
  const double s = slop(max_abs(o.center) + o.radius + max_abs(o.half));
  const VoxBox vb = touch_range(o.box_lo(), o.box_hi(), s);
  brick_add(vb, slot << 1, o.disc_gen);
  if (!box_inside_grid(o.box_lo(), o.box_hi())) list_add(outside_objs, o.outside_pos, slot);
  ++pending.objects_discretized;
  if (o.no_opacity) return;  // No dynamic opacity (Obj::no_opacity).
  // Adding an object only adds to the cover: a voxel changes only where the
  // object alone contains it, or where its inner box meets the voxel in a
  // volume and joins the union.
  Vec3 ilo, ihi;
  inner_box(o, o.center, &ilo, &ihi);
  for (int z = vb.lo.z; z <= vb.hi.z; ++z)
    for (int y = vb.lo.y; y <= vb.hi.y; ++y)
      for (int x = vb.lo.x; x <= vb.hi.x; ++x) {
        const auto i = static_cast<std::size_t>(index(x, y, z));
        if (vflags[i] & (kStaticOpaque | kDynOpaque)) continue;
        const Vec3 v{static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)};
        bool cov = contains_voxel(o, o.center, x, y, z);
        if (!cov && glm::all(glm::lessThan(glm::max(ilo, v), glm::min(ihi, v + 1.0))))
          cov = covered_now(x, y, z);
        if (cov) vflags[i] |= kDynOpaque;
      }
}

void Scene::Impl::undiscretize(std::uint32_t slot) {
  Obj& o = objs[slot];
  const Vec3 c = o.disc_center;
  const double s = slop(max_abs(c) + o.radius + max_abs(o.half));
  const VoxBox vb = touch_range(c - o.half, c + o.half, s);
  brick_remove(vb);
  ++o.disc_gen;  // Its brick entries are stale from now on.
  list_remove(outside_objs, o.outside_pos, false);
  if (o.no_opacity) return;  // It never took part in any cover.
  // The object no longer counts (its entries are stale): a covered voxel it
  // touched may have needed it, so its cover is computed again from the
  // objects that remain. Per-object counts would not do: a voxel covered by
  // a union loses its cover when any one member leaves.
  for (int z = vb.lo.z; z <= vb.hi.z; ++z)
    for (int y = vb.lo.y; y <= vb.hi.y; ++y)
      for (int x = vb.lo.x; x <= vb.hi.x; ++x) {
        const auto i = static_cast<std::size_t>(index(x, y, z));
        if ((vflags[i] & kDynOpaque) && !covered_now(x, y, z))
          vflags[i] &= static_cast<std::uint8_t>(~kDynOpaque);
      }
}

double Scene::Impl::initial_period(const Obj& o) const {
  if (options.tbv_period > 0.0) return options.tbv_period;
  if (!(o.max_speed > 0.0)) return options.tbv_max_period;
  const double vmin = std::fmin(spec.voxel_size.x, std::fmin(spec.voxel_size.y, spec.voxel_size.z));
  return std::clamp(options.tbv_voxels * vmin / o.max_speed, kMinTbvPeriod, max_period(o));
}

double Scene::Impl::max_period(const Obj& o) const {
  if (options.tbv_period > 0.0) return options.tbv_period;
  if (!(o.max_speed > 0.0)) return options.tbv_max_period;
  // A TBV's bricks cost grows with the cube of its size while its renewals
  // fall only linearly with its period: beyond a few voxels of growth,
  // longer periods cost more than they save.
  const double vmin = std::fmin(spec.voxel_size.x, std::fmin(spec.voxel_size.y, spec.voxel_size.z));
  return std::clamp(options.tbv_max_voxels * vmin / o.max_speed, kMinTbvPeriod, options.tbv_max_period);
}

double Scene::Impl::tbv_box(std::uint32_t slot, Vec3* lo_out, Vec3* hi_out, bool* cut) const {
  const double period = full_tbv_box(slot, lo_out, hi_out);
  return cut_tbv_box(slot, period, lo_out, hi_out, cut);
}

double Scene::Impl::full_tbv_box(std::uint32_t slot, Vec3* lo_out, Vec3* hi_out) const {
  const Obj& o = objs[slot];
  // Every centre reachable before expiry is within max_speed * period of the
  // current one, so the object's box grown by that much bounds it (Sudarsky &
  // Gotsman's TBV, as a box since our objects are boxes and spheres).
  //
  // The period is scaled by a factor in [0.5, 1.5), different for each object
  // and renewal, so that TBVs created together (say, 100,000 objects hidden
  // in the first frame) do not all expire in the same later frame.
  std::uint64_t h = (std::uint64_t{slot} << 32) ^ o.tbv_epoch ^ 0x9e3779b97f4a7c15ull;
  h = (h ^ (h >> 30)) * 0xbf58476d1ce4e5b9ull;
  h = (h ^ (h >> 27)) * 0x94d049bb133111ebull;
  h ^= h >> 31;
  const double period = o.tbv_period * (0.5 + static_cast<double>(h >> 11) * 0x1p-53);
  const double grow = o.max_speed * period;
  // Growth stops at the grid's bounds (the object's own box never shrinks):
  // beyond them the object can only get by a move, and a move that leaves
  // the TBV reveals it (apply_moves). So a hidden object near the boundary
  // costs nothing per frame instead of a frustum test beyond the grid.
  const Vec3 lo = o.box_lo(), hi = o.box_hi();
  *lo_out = glm::min(lo, glm::max(lo - grow, spec.bounds_min));
  *hi_out = glm::max(hi, glm::min(hi + grow, spec.bounds_max));
  return period;
}

double Scene::Impl::cut_tbv_box(std::uint32_t slot, double period, Vec3* lo_out, Vec3* hi_out, bool* cut) const {
  if (cut) *cut = false;
  const Obj& o = objs[slot];
  const double grow = o.max_speed * period;
  const Vec3 lo = o.box_lo(), hi = o.box_hi();
  // Nor into space a viewer saw recently: a TBV there would be revealed at
  // once, waking an object that cannot be seen where it is. The growth (and
  // with it the period) is cut to what keeps clear of the seen voxels, so the
  // TBV still holds every position the object can reach before it expires.
  // When that leaves less than a quarter of the first TBV's growth (the
  // object is next to seen space anyway) or a period under the engine's
  // shortest, the TBV is left as it was.
  const double vmin = std::fmin(spec.voxel_size.x, std::fmin(spec.voxel_size.y, spec.voxel_size.z));
  double room_brick = 0.0;
  const double floor = 0.25 * options.tbv_voxels * vmin;
  double room = unseen_growth(o, *lo_out, *hi_out, &room_brick);
  if (room_brick >= floor) room = room_brick;
  const double cut_period = grow > 0.0 ? period * (room / grow) : 0.0;
  if (room < grow && room >= floor && cut_period >= kMinTbvPeriod) {
    if (cut) *cut = true;
    *lo_out = glm::min(lo, glm::max(lo - room, spec.bounds_min));
    *hi_out = glm::max(hi, glm::min(hi + room, spec.bounds_max));
    return cut_period;
  }
  return period;
}

double Scene::Impl::unseen_growth(const Obj& o, const Vec3& lo, const Vec3& hi, double* room_brick) const {
  const double inf = std::numeric_limits<double>::infinity();
  *room_brick = inf;
  if (!(time - last_seen_at <= options.tbv_seen_memory)) return inf;
  const double s = slop(std::fmax(max_abs(lo), max_abs(hi)));
  const VoxBox own = touch_range(o.box_lo(), o.box_hi(), s);
  const VoxBox want = touch_range(lo, hi, s);
  if (own.empty() || want.empty()) return inf;  // Beyond the grid: no bricks to keep clear of.
  // Grow a brick range from the object's own bricks towards the wanted ones,
  // every side one layer a round (the uniform growth a TBV has), until a
  // round meets a layer holding a voxel seen recently. Such a side stops
  // half a voxel short of the nearest seen voxel in the layer, so that the
  // rounding allowance of touch_range cannot reach it; `room_brick` stops it
  // short of the whole layer instead, since a TBV that reaches into a brick
  // with seen voxels costs every visit of that brick's voxels.
  const int bs = 1 << detail::kBrickShift;
  VoxBox r = bricks_of(own);
  const VoxBox t = bricks_of(want);
  // Nothing seen anywhere it may grow (a TBV behind a wall): every round
  // below would find its layer unseen.
  if (unseen_range(t)) return inf;
  // Voxels of a brick (bit x + 4y + 16z) whose coordinate on axis a is k.
  auto plane = [](int a, int k) {
    static constexpr std::uint64_t kPlane0[3] = {0x1111111111111111ull, 0x000F000F000F000Full, 0xFFFFull};
    return kPlane0[a] << (k << (2 * a));
  };
  double room = inf;
  for (bool grew = true; grew && room == inf;) {
    grew = false;
    for (int a = 0; a < 3; ++a)
      for (int side = 0; side < 2; ++side) {
        const int c = side ? r.hi[a] + 1 : r.lo[a] - 1;
        if (side ? c > t.hi[a] : c < t.lo[a]) continue;  // Grown as far as wanted.
        // The layer's recently seen voxels, OR-ed over its bricks.
        VoxBox l = r;
        l.lo[a] = l.hi[a] = c;
        const std::uint64_t m = layer_seen(l);
        if (m == 0) {
          (side ? r.hi[a] : r.lo[a]) = c;
          grew = true;
          continue;
        }
        int k = side ? 0 : bs - 1;
        while ((m & plane(a, k)) == 0) k += side ? 1 : -1;
        // Grid coordinates of the side's stop, and of the layer's near face.
        const double stop = side ? c * bs + k - 0.5 : c * bs + k + 1.5;
        const double layer = side ? c * bs - 0.5 : (c + 1) * bs + 0.5;
        const double v = spec.voxel_size[a];
        const double ob = (side ? o.box_hi()[a] : o.box_lo()[a]) - spec.bounds_min[a];
        room = std::fmin(room, side ? stop * v - ob : ob - stop * v);
        *room_brick = std::fmin(*room_brick, side ? layer * v - ob : ob - layer * v);
      }
  }
  return room;
}

bool Scene::Impl::recent_cell(const std::vector<double>& at, int l, const VoxBox& range) const {
  const int sh = detail::kCellShift * (l - 1);
  const glm::ivec3 lo = range.lo >> sh, hi = range.hi >> sh;
  for (int z = lo.z; z <= hi.z; ++z)
    for (int y = lo.y; y <= hi.y; ++y)
      for (int x = lo.x; x <= hi.x; ++x)
        if (!(time - at[pyr.index(l, glm::ivec3(x, y, z))] > options.tbv_seen_memory)) return true;
  return false;
}

bool Scene::Impl::unseen_range(const VoxBox& range) const {
  if (cell_any_seen_at.empty()) return false;
  for (int l = 3; l < pyr.levels; ++l)
    if (recent_cell(cell_seen_at[static_cast<std::size_t>(l)], l, range)) return false;
  // Level 2 holds its cells' own whole records and their bricks' records.
  return !recent_cell(cell_any_seen_at, 2, range);
}

std::uint64_t Scene::Impl::layer_seen(const VoxBox& range) const {
  // A brick counts as wholly seen while a cell above it was seen (recorded
  // whole, mark_seen): the cells above the layer are few, so they are asked
  // once each rather than once per brick and level.
  for (int l = 2; l < pyr.levels; ++l)
    if (recent_cell(cell_seen_at[static_cast<std::size_t>(l)], l, range)) return ~std::uint64_t{0};
  std::uint64_t m = 0;
  for (int z = range.lo.z; z <= range.hi.z; ++z)
    for (int y = range.lo.y; y <= range.hi.y; ++y)
      for (int x = range.lo.x; x <= range.hi.x; ++x) {
        const std::size_t i = pyr.index(1, glm::ivec3(x, y, z));
        if (seen_recently(i)) m |= seen_mask[i];
      }
  return m;
}

void Scene::Impl::mark_seen(Scratch::Impl& w, double t) {
  // The level-2 summary keeps the latest time (never lowered: a record of
  // an older frame only makes unseen_range say less).
  const auto touch2 = [&](std::size_t cell2) {
    double& at = cell_any_seen_at[cell2];
    if (!(at >= t)) at = t;
  };
  for (const auto& [level, cell] : w.seen_cells) {
    cell_seen_at[level][cell] = t;
    if (level == 2 && !cell_any_seen_at.empty()) touch2(cell);
    last_seen_at = t;
  }
  w.seen_cells.clear();
  const glm::ivec3 rb = pyr.res[1];
  for (std::uint32_t b : w.seen_list) {
    // A brick not seen within the memory forgets its old voxels.
    seen_mask[b] = seen_recently(b) ? seen_mask[b] | w.seen_vox[b] : w.seen_vox[b];
    seen_at[b] = t;
    w.seen_vox[b] = 0;
    last_seen_at = t;
    if (!cell_any_seen_at.empty()) {
      const glm::ivec3 c(static_cast<int>(b % static_cast<std::uint32_t>(rb.x)),
                         static_cast<int>(b / static_cast<std::uint32_t>(rb.x) % static_cast<std::uint32_t>(rb.y)),
                         static_cast<int>(b / (static_cast<std::uint32_t>(rb.x) * static_cast<std::uint32_t>(rb.y))));
      touch2(pyr.index(2, c >> detail::kCellShift));
    }
  }
  w.seen_list.clear();
}

void Scene::Impl::make_tbv(std::uint32_t slot, double now, const TbvBox* box) {
  Obj& o = objs[slot];
  double period;
  if (box) {
    o.tbv_lo = box->lo;
    o.tbv_hi = box->hi;
    period = box->period;
  } else {
    period = tbv_box(slot, &o.tbv_lo, &o.tbv_hi);
  }
  o.tbv_center = o.center;
  o.tbv_expiry = o.max_speed > 0.0 ? expiry_after(now, period) : std::numeric_limits<double>::infinity();
  o.under_tbv = true;
  ++wake_epoch;
  ++o.tbv_gen;
  ++o.tbv_epoch;
  if (std::isfinite(o.tbv_expiry)) expiry.push({o.tbv_expiry, slot, o.tbv_epoch});
  const double s = slop(std::fmax(max_abs(o.tbv_lo), max_abs(o.tbv_hi)));
  o.tbv_voxels = touch_range(o.tbv_lo, o.tbv_hi, s);
  o.tbv_coarse = tbv_coarse_cells(o.tbv_voxels);
  brick_add(o.tbv_voxels, (slot << 1) | 1u, o.tbv_gen, o.tbv_coarse);
  // Clamped growth ends on the bounds, so only an object that itself reaches
  // beyond them has a TBV with a part outside the grid.
  if (!box_inside_grid(o.box_lo(), o.box_hi())) list_add(outside_tbvs, o.tbv_outside_pos, slot);
  ++tbv_count;
}

void Scene::Impl::renew_tbv(std::uint32_t slot, double now) {
  Obj& o = objs[slot];
  if (o.center != o.tbv_center) {
    const std::uint64_t epoch = wake_epoch;  // Still under a TBV: no wake change.
    drop_tbv(slot);
    make_tbv(slot, now);
    wake_epoch = epoch;
    return;
  }
  // The object has not moved since its TBV was made (the common case for a
  // hidden object nobody simulates): the new box has the same centre, so the
  // union of old and new is a valid TBV, and only the bricks it adds need
  // writing. A renewal at the growth cap then costs no brick at all. But a
  // box cut short by seen space replaces the old one rather than joining
  // it: the old one may reach into space seen since it was made, which
  // would reveal it.
  Vec3 lo, hi;
  double period = full_tbv_box(slot, &lo, &hi);
  // Behind a wall, the usual case, nothing around the union of old and new
  // was seen within the memory: no cut to look for, and each cell around it
  // may hold it whole. One question of the seen record for both.
  const Vec3 ulo = glm::min(o.tbv_lo, lo), uhi = glm::max(o.tbv_hi, hi);
  const VoxBox uvb = touch_range(ulo, uhi, slop(std::fmax(max_abs(ulo), max_abs(uhi))));
  const bool quiet = unseen_around(uvb);
  bool cut = false;
  if (!quiet) period = cut_tbv_box(slot, period, &lo, &hi, &cut);
  // Entries are written per range of bricks (its coarsest cells), so a
  // range that did not change writes nothing, and one that changed is
  // written anew: the old entries go stale (a new generation), about the
  // TBV's surface in cells.
  const VoxBox old_vb = o.tbv_voxels;
  if (cut) {
    // The cut box replaces the old one. Over the same bricks (the usual
    // case for an object beside seen space that has not moved) the entries
    // stand as they are: both traversals test the TBV's own box or voxel
    // range, never a brick's, before revealing it, and the cells written
    // depend on the range of bricks alone.
    const double sc = slop(std::fmax(max_abs(lo), max_abs(hi)));
    const VoxBox vb = touch_range(lo, hi, sc);
    if (bricks_of(vb) != bricks_of(old_vb)) {
      const std::uint64_t epoch = wake_epoch;
      drop_tbv(slot);
      const TbvBox box{lo, hi, period};  // Not computed twice.
      make_tbv(slot, now, &box);
      wake_epoch = epoch;
      return;
    }
    o.tbv_lo = lo;
    o.tbv_hi = hi;
    o.tbv_voxels = vb;
    o.tbv_expiry = expiry_after(now, period);
    ++o.tbv_epoch;
    expiry.push({o.tbv_expiry, slot, o.tbv_epoch});
    return;
  }
  // Not cut: lo and hi are still the whole growth, and the union is uvb's.
  o.tbv_lo = ulo;
  o.tbv_hi = uhi;
  o.tbv_voxels = uvb;
  if (bricks_of(o.tbv_voxels) != bricks_of(old_vb)) {
    // Grown within the cells holding it whole (the usual case behind a
    // wall), it keeps its entries.
    const std::uint32_t coarse = tbv_coarse_cells(o.tbv_voxels, quiet);
    if (!same_tbv_cells(pyr, old_vb, o.tbv_coarse, o.tbv_voxels, coarse)) {
      brick_remove(old_vb, o.tbv_coarse);
      ++o.tbv_gen;
      brick_add(o.tbv_voxels, (slot << 1) | 1u, o.tbv_gen, coarse);
    }
    o.tbv_coarse = coarse;
  }
  o.tbv_expiry = expiry_after(now, period);
  ++o.tbv_epoch;
  expiry.push({o.tbv_expiry, slot, o.tbv_epoch});
}

void Scene::Impl::drop_tbv(std::uint32_t slot) {
  Obj& o = objs[slot];
  brick_remove(o.tbv_voxels, o.tbv_coarse);
  list_remove(outside_tbvs, o.tbv_outside_pos, true);
  o.under_tbv = false;
  ++wake_epoch;
  ++o.tbv_gen;    // Its brick entries are stale from now on,
  ++o.tbv_epoch;  // and so is its expiry entry.
  --tbv_count;
}

void Scene::Impl::reveal(std::uint32_t slot) {
  Obj& o = objs[slot];
  drop_tbv(slot);
  o.tbv_period = initial_period(o);
  discretize(slot);
  if (!o.pending_unclaimed) {
    o.pending_unclaimed = true;
    unclaimed.push_back(slot);
  }
}

void Scene::Impl::apply_queue(FrameStats& st, bool tbvs) {
  for (std::uint32_t slot : queued_reveals) {
    Obj& o = objs[slot];
    o.reveal_queued = false;
    if (o.under_tbv) reveal(slot);  // Not when a move revealed it meanwhile.
  }
  queued_reveals.clear();
  if (!tbvs) return;
  // A dynamic object no viewer's last PVS holds is hidden from all of them
  // and gets a TBV; claims may have come back since it was queued.
  for (std::uint32_t slot : unclaimed) {
    Obj& o = objs[slot];
    o.pending_unclaimed = false;
    if (o.claims == 0 && !o.under_tbv) {
      undiscretize(slot);
      make_tbv(slot, time);
      ++st.tbvs_created;
    }
  }
  unclaimed.clear();
}

// ---------------------------------------------------------------------------
// Scene

Status validate_time(const std::string& field, double t) {
  if (std::isfinite(t) && std::fabs(t) <= kMaxSceneTime) return Status::Ok();
  char range[64];
  std::snprintf(range, sizeof range, "[%g, %g]", -kMaxSceneTime, kMaxSceneTime);
  return Status::Error(field, std::string("must be a finite time in seconds within ") + range +
                                  ", got " + number_text(t) +
                                  " (milliseconds or microseconds since 1970 are out of range)");
}

Scene::Scene(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Scene::~Scene() = default;

const GridSpec& Scene::grid() const { return impl_->spec; }
std::size_t Scene::object_count() const { return impl_->objs.size(); }
std::size_t Scene::dynamic_count() const { return impl_->dynamic_count; }
double Scene::time() const {
  std::lock_guard<std::mutex> book(impl_->book);
  return impl_->time;
}

ViewerId Scene::add_viewer() {
  std::lock_guard<std::mutex> book(impl_->book);
  const ViewerId id = impl_->next_viewer++;
  impl_->viewers.emplace(id, detail::ViewerState{});
  return id;
}

void Scene::remove_viewer(ViewerId viewer) {
  Impl& s = *impl_;
  std::lock_guard<std::mutex> book(s.book);  // Claims only: the grid is untouched.
  auto it = s.viewers.find(viewer);
  if (it == s.viewers.end()) return;
  for (std::uint32_t slot : it->second.last_pvs) {
    Obj& o = s.objs[slot];
    if (!o.dynamic) continue;
    if (--o.claims == 0 && !o.pending_unclaimed) {
      o.pending_unclaimed = true;
      s.unclaimed.push_back(slot);
    }
  }
  s.viewers.erase(it);
}

Status Scene::apply_moves(double t, std::span<const Move> moves, MoveReport* report,
                          Clock clock) {
  Impl& s = *impl_;
  std::unique_lock<detail::GridMutex> lock(s.mu);
  std::lock_guard<std::mutex> book(s.book);
  if (Status st = validate_time("t", t); !st) return st;
  if (clock == Clock::Latest && s.time_set) t = std::fmax(t, s.time);
  if (s.time_set && t < s.time)
    return Status::Error("t", "time goes backwards: " + number_text(t) + " < " + number_text(s.time));
  for (std::size_t i = 0; i < moves.size(); ++i) {
    const Move& m = moves[i];
    const std::string f = "moves[" + std::to_string(i) + "]";
    auto it = s.slot_of.find(m.id);
    if (it == s.slot_of.end()) return Status::Error(f + ".id", "unknown object id " + std::to_string(m.id));
    if (!s.objs[it->second].dynamic)
      return Status::Error(f + ".id", "object " + std::to_string(m.id) + " is static and cannot move");
    if (!finite3(m.center)) return Status::Error(f + ".center", "must be finite");
    if (max_abs(m.center) > kMaxCoordinate)
      return Status::Error(f + ".center", "magnitude exceeds " + number_text(kMaxCoordinate));
    const Obj& o = s.objs[it->second];
    if (m.has_rotation) {
      if (o.shape != Shape::Mesh)
        return Status::Error(f + ".rotation", "object " + std::to_string(m.id) + " is a " +
                                                  (o.shape == Shape::Sphere ? "sphere" : "box") +
                                                  "; only meshes rotate");
      if (Status st = validate_rotation(m.rotation, f + ".rotation"); !st) return st;
    }
    if (o.shape == Shape::Mesh) {
      const Quat q = m.has_rotation ? unit_rotation(m.rotation) : o.mesh_rotation;
      const Vec3 c = m.center + o.mesh_scale * (q * o.mesh_centroid);
      if (!(max_abs(c) + o.radius <= kMaxCoordinate))
        return Status::Error(f + ".center", "places the mesh beyond " + number_text(kMaxCoordinate));
    }
  }
  s.time = t;
  s.time_set = true;
  if (!moves.empty()) ++s.moves_epoch;
  s.apply_queue(s.pending, s.claims_made);  // Frames' queued reveals and TBVs first.
  if (report) {
    *report = MoveReport{};
    report->t = t;
  }
  for (const Move& m : moves) {
    const std::uint32_t slot = s.slot_of.find(m.id)->second;
    Obj& o = s.objs[slot];
    // The object's new centre and half: a mesh's are its centroid ball's
    // (place_mesh), whose centre lies in the mesh's hull and so moves no
    // faster than the mesh's fastest point.
    Vec3 center = m.center, half = o.half;
    Obj placed;
    if (o.shape == Shape::Mesh) {
      placed = o;
      placed.mesh_origin = m.center;
      if (m.has_rotation) {
        placed.mesh_rotation = unit_rotation(m.rotation);
        placed.mesh_rotation_given = m.rotation;
      }
      s.place_mesh(placed);
      center = placed.center;
      half = placed.half;
    }
    auto set_center = [&] {
      o.center = center;
      o.half = half;
      if (o.shape == Shape::Mesh) {
        o.mesh_origin = placed.mesh_origin;
        o.mesh_rotation = placed.mesh_rotation;
        o.mesh_rotation_given = placed.mesh_rotation_given;
      }
    };
    const double dist = glm::length(center - o.center);
    bool too_fast = false;
    // Before the first frame nothing has been observed, so nothing is checked.
    const double since = std::isfinite(o.last_move_t) ? o.last_move_t : s.first_frame_time;
    if (std::isfinite(since)) {
      const double allowed = o.max_speed * (t - since);
      too_fast = dist > allowed * (1.0 + 1e-9) + s.slop(max_abs(center));
    }
    o.last_move_t = t;
    if (too_fast) {
      ++s.pending.speed_violations;
      if (report) report->too_fast.push_back(m.id);
    }
    if (o.under_tbv) {
      const double sl = s.slop(max_abs(center));
      const bool inside = glm::all(glm::greaterThanEqual(center - half, o.tbv_lo + sl)) &&
                          glm::all(glm::lessThanEqual(center + half, o.tbv_hi - sl));
      set_center();
      // A move the TBV does not bound voids it: the object is revealed.
      if (too_fast || !inside) {
        s.reveal(slot);
        ++s.pending.tbvs_revealed;
        s.pending_wake.push_back(slot);
      }
    } else if (center != o.disc_center || half != o.half) {
      s.undiscretize(slot);
      set_center();
      s.discretize(slot);
    } else {
      set_center();
    }
    if (report) ++report->applied;
  }
  return Status::Ok();
}

std::uint64_t Scene::wake_epoch() const {
  std::lock_guard<std::mutex> book(impl_->book);
  return impl_->wake_epoch;
}

std::vector<Move> Scene::dynamic_centers(double* time, std::uint64_t* epoch) const {
  std::shared_lock<detail::GridMutex> lock(impl_->mu);
  std::lock_guard<std::mutex> book(impl_->book);
  if (time) *time = impl_->time;
  if (epoch) *epoch = impl_->moves_epoch;
  std::vector<Move> out;
  out.reserve(impl_->dynamic_count);
  for (const Obj& o : impl_->objs)
    if (o.dynamic)
      out.push_back(o.shape == Shape::Mesh ? Move{o.id, o.mesh_origin, true, o.mesh_rotation_given}
                                           : Move{o.id, o.center});
  std::sort(out.begin(), out.end(), [](const Move& a, const Move& b) { return a.id < b.id; });
  return out;
}

std::vector<ObjectId> Scene::wake_set() const {
  std::vector<ObjectId> ids;
  wake_set(&ids);
  return ids;
}

void Scene::wake_set(std::vector<ObjectId>* ids) const {
  std::shared_lock<detail::GridMutex> lock(impl_->mu);
  std::lock_guard<std::mutex> book(impl_->book);
  ids->clear();
  // A queued reveal is a wake already reported by its frame.
  for (const Obj& o : impl_->objs)
    if (o.dynamic && (!o.under_tbv || o.reveal_queued)) ids->push_back(o.id);
  std::sort(ids->begin(), ids->end());
}

}  // namespace voxvis
