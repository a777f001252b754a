// region_candidates.cpp — where a region frame looks for dynamic objects
// and TBVs (region_candidates.h).
#include "region_candidates.h"

#include <algorithm>
#include <cmath>

#include "numeric.h"

namespace voxvis::detail {

namespace {

/// The voxels of the world box [lo, hi] (clipped to the grid, with rounding
/// allowed for), or the whole grid when it is not finite; `beyond`: whether
/// it reaches out of the grid box.
VoxBox world_range(const Scene::Impl& s, const Vec3& lo, const Vec3& hi, bool* beyond) {
  const VoxBox all{glm::ivec3(0), s.res - 1};
  if (!finite3(lo) || !finite3(hi)) {
    *beyond = true;
    return all;
  }
  const double slop = s.slop(max_abs(lo) + max_abs(hi));
  const Vec3 glo = s.to_grid(lo) - slop * s.inv_vs, ghi = s.to_grid(hi) + slop * s.inv_vs;
  *beyond = !(glm::all(glm::greaterThan(glo, Vec3(0.0))) && glm::all(glm::lessThan(ghi, Vec3(s.res))));
  return s.touch_range(lo, hi, slop);
}

VoxBox meet(const VoxBox& a, const VoxBox& b) { return VoxBox{glm::max(a.lo, b.lo), glm::min(a.hi, b.hi)}; }

std::int64_t bricks_in(const VoxBox& r) {
  if (r.empty()) return 0;
  const glm::ivec3 n = (r.hi >> kBrickShift) - (r.lo >> kBrickShift) + 1;
  return std::int64_t{n.x} * n.y * n.z;
}

/// The voxels of brick b (bricks_res coordinates) inside `range`, as a
/// brick's mask (bit x + 4y + 16z).
std::uint64_t brick_mask(const glm::ivec3& b, const VoxBox& range) {
  const glm::ivec3 lo = glm::max(range.lo - (b << kBrickShift), glm::ivec3(0));
  const glm::ivec3 hi = glm::min(range.hi - (b << kBrickShift), glm::ivec3(3));
  std::uint64_t row = 0, m = 0;
  for (int x = lo.x; x <= hi.x; ++x) row |= std::uint64_t{1} << x;
  for (int z = lo.z; z <= hi.z; ++z)
    for (int y = lo.y; y <= hi.y; ++y) m |= row << (4 * y + 16 * z);
  return m;
}

/// The voxel box `c` grown by `g` world units and one voxel more (for
/// rounding), per axis; `beyond`: whether it reaches out of the grid.
VoxBox grown_voxels(const Scene::Impl& s, const VoxBox& c, double g, bool* beyond) {
  const Vec3 gv = glm::ceil(Vec3(g) * s.inv_vs) + 1.0;
  *beyond = true;
  if (!finite3(gv) || max_abs(gv) > 1e9) return VoxBox{glm::ivec3(0), s.res - 1};
  const glm::ivec3 n(gv);
  const VoxBox grown{c.lo - n, c.hi + n};
  *beyond = glm::any(glm::lessThan(grown.lo, glm::ivec3(0))) || glm::any(glm::greaterThanEqual(grown.hi, s.res));
  return grown;
}

/// The voxels (clipped to the grid) within reach of the eyes of a box
/// moving `g` within the horizon: the eye box grown by `far` + g (a frustum
/// region also: the box around the frusta, its eye and far corners grown by
/// the eye box and g); `beyond`: whether it reaches out of the grid box.
VoxBox distance_box(const Scene::Impl& s, const RegionReach& reach, const WorldFrustum& wf, double g, bool* beyond) {
  // (One voxel more: the reach tests' margins are relative, this is not.)
  const Vec3 grow = reach.half + Vec3(reach.far + g) + 1.0 / s.inv_vs;
  VoxBox range = world_range(s, reach.eye - grow, reach.eye + grow, beyond);
  Vec3 lo = reach.eye, hi = reach.eye;
  bool finite = !reach.omnidirectional && wf.sane();
  for (int k = 0; k < 4 && finite; ++k) {
    const Vec3 c = reach.eye + reach.far * (wf.f + ((k & 1) ? 1.0 : -1.0) * wf.tan_x * wf.r +
                                             ((k & 2) ? 1.0 : -1.0) * wf.tan_y * wf.u);
    finite = finite3(c);  // (An infinite far plane: no box but the grid's.)
    lo = glm::min(lo, c);
    hi = glm::max(hi, c);
  }
  if (finite) {
    const Vec3 gf = reach.half + Vec3(g) + 1.0 / s.inv_vs;
    bool out = true;
    range = meet(range, world_range(s, lo - gf, hi + gf, &out));
    *beyond = *beyond && out;
  }
  return meet(range, VoxBox{glm::ivec3(0), s.res - 1});
}

/// `r` shrunk to whole level-2 cells (16 voxels a side), except on the
/// grid's faces.
VoxBox whole_cells_in(const Scene::Impl& s, const VoxBox& r) {
  constexpr int sh = kBrickShift + kCellShift, n = 1 << sh;
  VoxBox in;
  for (int a = 0; a < 3; ++a) {
    in.lo[a] = r.lo[a] == 0 ? 0 : ((r.lo[a] + n - 1) >> sh) << sh;
    in.hi[a] = r.hi[a] == s.res[a] - 1 ? r.hi[a] : (((r.hi[a] + 1) >> sh) << sh) - 1;
  }
  return in;
}

}  // namespace

RegionVisit region_visit(const Scene::Impl& s, const RegionReach& reach, const WorldFrustum& wf,
                         const RegionCavity& cavity) {
  RegionVisit v;
  if (s.dynamic_count == 0 || s.bricks.empty()) return v;
  const double g = s.max_dynamic_speed * reach.horizon;
  bool beyond = true;
  const VoxBox distance = distance_box(s, reach, wf, g, &beyond);
  VoxBox range = distance;
  // The distance's faces lie in open space, wherever the eyes happen to be:
  // the seen record shrinks them to whole cells (recording less only lets
  // TBVs grow more), so that only the components' faces, at walls, are
  // recorded voxel by voxel, in bricks.
  v.seen = whole_cells_in(s, distance);
  if (cavity.on()) {
    bool out = true;
    const VoxBox space = grown_voxels(s, cavity.box(), g, &out);
    range = meet(range, space);
    v.seen = meet(v.seen, space);
    beyond = beyond && out;
  }
  v.range = range;
  v.outside = beyond;
  v.all = bricks_in(range) > kBricksPerMover * static_cast<std::int64_t>(s.dynamic_count);
  return v;
}

void see_region(const Scene::Impl& s, Scratch::Impl& w, const VoxBox& range) {
  if (s.bricks.empty() || w.seen_vox.size() < s.bricks.size() || range.empty()) return;
  const VoxBox bricks{range.lo >> kBrickShift, range.hi >> kBrickShift};
  // A cell is whole when all its voxels lie in the range (a convex test).
  auto whole = [&](const VoxBox& b) {
    return glm::all(glm::greaterThanEqual(b.lo << kBrickShift, range.lo)) &&
           glm::all(glm::lessThanEqual(glm::min((b.hi << kBrickShift) + 3, s.res - 1), range.hi));
  };
  auto emit = [&](int level, const glm::ivec3& c) {
    if (level >= 2) {
      w.seen_cells.emplace_back(static_cast<std::uint8_t>(level), static_cast<std::uint32_t>(s.pyr.index(level, c)));
      return;
    }
    const std::size_t b = s.pyr.index(1, c);
    std::uint64_t& seen = w.seen_vox[b];
    if (seen == 0) w.seen_list.push_back(static_cast<std::uint32_t>(b));
    seen |= brick_mask(c, range);
  };
  decompose(
      s.pyr, 1, bricks, whole, [](const VoxBox&) { return false; }, true, emit, [](std::uint64_t) { return true; });
}

}  // namespace voxvis::detail
