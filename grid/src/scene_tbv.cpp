// scene_tbv.cpp — the dynamic layer and the temporal bounding volumes' life:
// where dynamic objects and TBVs are stored (bricks, the 16-voxel cells that
// hold a TBV whole, the counts of dynamic entries per cell), the seen record
// that bounds a TBV's growth, and making, renewing, dropping and revealing
// TBVs (docs/design.md, *Where TBVs are stored*). The scene's static
// discretization and its moves are in scene.cpp; the frame's expiry loop that
// calls renew_tbv is in frame.cpp.
#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "numeric.h"
#include "scene_impl.h"

namespace voxvis {

using detail::Obj;
using detail::VoxBox;
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

double Scene::Impl::tbv_box(std::uint32_t slot, Vec3* lo_out, Vec3* hi_out, bool* cut) {
  const double period = full_tbv_box(slot, lo_out, hi_out);
  return cut_tbv_box(slot, period, lo_out, hi_out, cut);
}

double Scene::Impl::period_scale(std::uint32_t slot) const {
  std::uint64_t h = (std::uint64_t{slot} << 32) ^ objs[slot].tbv_epoch ^ 0x9e3779b97f4a7c15ull;
  h = (h ^ (h >> 30)) * 0xbf58476d1ce4e5b9ull;
  h = (h ^ (h >> 27)) * 0x94d049bb133111ebull;
  h ^= h >> 31;
  return kMaxPeriodScale - 1.0 + static_cast<double>(h >> 11) * 0x1p-53;
}

void Scene::Impl::grown_box(const Obj& o, double grow, Vec3* lo, Vec3* hi) const {
  // Growth stops at the grid's bounds (the object's own box never shrinks):
  // beyond them the object can only get by a move, and a move that leaves
  // the TBV reveals it (apply_moves). So a hidden object near the boundary
  // costs nothing per frame instead of a frustum test beyond the grid.
  const Vec3 blo = o.box_lo(), bhi = o.box_hi();
  *lo = glm::min(blo, glm::max(blo - grow, spec.bounds_min));
  *hi = glm::max(bhi, glm::min(bhi + grow, spec.bounds_max));
}

double Scene::Impl::longest_growth(const Obj& o) const { return o.max_speed * kMaxPeriodScale * max_period(o); }

double Scene::Impl::full_tbv_box(std::uint32_t slot, Vec3* lo_out, Vec3* hi_out) const {
  const Obj& o = objs[slot];
  // Every centre reachable before expiry is within max_speed * period of the
  // current one, so the object's box grown by that much bounds it (Sudarsky &
  // Gotsman's TBV, as a box since our objects are boxes and spheres).
  //
  // The period is scaled by a factor in [0.5, 1.5), different for each object
  // and renewal, so that TBVs created together (say, 100,000 objects hidden
  // in the first frame) do not all expire in the same later frame.
  const double period = o.tbv_period * period_scale(slot);
  grown_box(o, o.max_speed * period, lo_out, hi_out);
  return period;
}

double Scene::Impl::cut_tbv_box(std::uint32_t slot, double period, Vec3* lo_out, Vec3* hi_out, bool* cut) {
  if (cut) *cut = false;
  const Obj& o = objs[slot];
  const double grow = o.max_speed * period;
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
  double room = seen_room(slot, &room_brick);
  if (room_brick >= floor) room = room_brick;
  const double cut_period = grow > 0.0 ? period * (room / grow) : 0.0;
  if (room < grow && room >= floor && cut_period >= kMinTbvPeriod) {
    if (cut) *cut = true;
    grown_box(o, room, lo_out, hi_out);
    return cut_period;
  }
  return period;
}

double Scene::Impl::seen_room(std::uint32_t slot, double* room_brick) {
  Obj& o = objs[slot];
  if (o.room_epoch != seen_epoch || o.room_center != o.center || !(time - o.room_at <= options.tbv_seen_memory)) {
    Vec3 lo, hi;
    grown_box(o, longest_growth(o), &lo, &hi);
    o.room = unseen_growth(o, lo, hi, &o.room_brick);
    o.room_epoch = seen_epoch;
    o.room_center = o.center;
    o.room_at = time;
  }
  *room_brick = o.room_brick;
  return o.room;
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
  // Level 2 holds its cells' own whole records and their bricks' records:
  // asked first, since where anything was seen it is most likely there.
  if (recent_cell(cell_any_seen_at, 2, range)) return false;
  for (int l = 3; l < pyr.levels; ++l)
    if (recent_cell(cell_seen_at[static_cast<std::size_t>(l)], l, range)) return false;
  return true;
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
    if (!(t - cell_seen_at[level][cell] <= options.tbv_seen_memory)) ++seen_epoch;
    cell_seen_at[level][cell] = t;
    if (level == 2 && !cell_any_seen_at.empty()) touch2(cell);
    last_seen_at = t;
  }
  w.seen_cells.clear();
  const glm::ivec3 rb = pyr.res[1];
  for (std::uint32_t b : w.seen_list) {
    // A brick not seen within the memory forgets its old voxels.
    const bool recent = seen_recently(b);
    if ((recent ? w.seen_vox[b] & ~seen_mask[b] : w.seen_vox[b]) != 0) ++seen_epoch;
    seen_mask[b] = recent ? seen_mask[b] | w.seen_vox[b] : w.seen_vox[b];
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

double Scene::Impl::quiet_tbv_box(std::uint32_t slot, Vec3* lo, Vec3* hi, VoxBox* vb) {
  Obj& o = objs[slot];
  if (!(o.max_speed > 0.0) || options.tbv_period > 0.0 || cell_any_seen_at.empty() ||
      !(options.tbv_seen_memory > 0.0))
    return 0.0;
  // Its entries go to the cells of 16 voxels around it, three a side at
  // most for any box that touches 33 voxels or fewer a side (touch_range
  // adds a voxel each side of the box's own width): the growth those cells
  // hold whole, never more than the longest period allowed. Failing that
  // (seen space within those cells), the longest period's growth at its
  // largest scale, which holds every box full_tbv_box makes.
  const double longest = longest_growth(o);
  double widest = o.max_speed * options.tbv_max_period;
  for (int a = 0; a < 3; ++a)
    widest = std::fmin(widest, 0.5 * (31.0 * spec.voxel_size[a] - 2.0 * o.half[a]));
  // The last answer stands while nothing newly seen came (seen_epoch), the
  // object stayed and the memory has not passed: a box found unseen is
  // still unseen, and one found seen can only have been forgotten since
  // (then the answer is the more cautious one).
  const bool known =
      o.quiet_epoch == seen_epoch && o.quiet_center == o.center && time - o.quiet_at <= options.tbv_seen_memory;
  const int first = known ? o.quiet_tier : 1;
  if (!known) {
    o.quiet_epoch = seen_epoch;
    o.quiet_center = o.center;
    o.quiet_at = time;
  }
  o.quiet_tier = 0;
  // Tiers before `first` were found seen at the same count; none when 0.
  for (int tier = first; tier >= 1 && tier <= 2; ++tier) {
    if (tier == 2 && !(widest > longest)) break;  // The same box as tier 1.
    const double grow = tier == 1 ? std::fmax(widest, longest) : longest;
    Vec3 l, h;
    grown_box(o, grow, &l, &h);
    const VoxBox v = touch_range(l, h, slop(std::fmax(max_abs(l), max_abs(h))));
    if (!(known && tier == first) && !unseen_around(v)) continue;
    o.quiet_tier = tier;
    *lo = l;
    *hi = h;
    *vb = v;
    // The period the growth holds, scaled into [0.75, 1) so that TBVs made
    // together do not expire together.
    return grow / o.max_speed * (0.625 + 0.25 * period_scale(slot));
  }
  return 0.0;
}

void Scene::Impl::make_tbv(std::uint32_t slot, double now, const TbvBox* box) {
  Obj& o = objs[slot];
  double period = 0.0;
  VoxBox quiet_vb;
  bool quiet = false;
  if (box) {
    o.tbv_lo = box->lo;
    o.tbv_hi = box->hi;
    period = box->period;
  } else if ((period = quiet_tbv_box(slot, &o.tbv_lo, &o.tbv_hi, &quiet_vb)) > 0.0) {
    // The doubling of periods (frame.cpp, renew) starts short because an
    // object that just left the view may soon be back in it. One whose TBV
    // may grow as far as its cells hold it whole and stay in space no viewer
    // saw within the memory (behind a wall, the usual case for a crowd) is
    // not likely to be: it takes that box and the period it holds, so its
    // renewals, each a wake of the object, come a few times less often, and
    // every renewal that finds it as quiet keeps the box (renew_tbv): its
    // entries are written once.
    o.tbv_period = max_period(o);
    quiet = true;
  } else {
    period = tbv_box(slot, &o.tbv_lo, &o.tbv_hi);
  }
  o.tbv_center = o.center;
  o.tbv_expiry = o.max_speed > 0.0 ? expiry_after(now, period) : std::numeric_limits<double>::infinity();
  o.under_tbv = true;
  ++wake_epoch;
  ++o.tbv_gen;
  ++o.tbv_epoch;
  if (std::isfinite(o.tbv_expiry)) expiry.push({o.tbv_expiry, slot, o.tbv_epoch}, now);
  o.tbv_voxels = quiet ? quiet_vb : touch_range(o.tbv_lo, o.tbv_hi, slop(std::fmax(max_abs(o.tbv_lo), max_abs(o.tbv_hi))));
  o.tbv_coarse = tbv_coarse_cells(o.tbv_voxels, quiet);
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
  double period = 0.0;
  // At the longest period with nothing seen around its quiet box, the box
  // is that one (make_tbv), which holds the old one: the same box renewal
  // after renewal, and no entry written.
  VoxBox quiet_vb;
  const bool at_quiet = o.tbv_period >= max_period(o) && (period = quiet_tbv_box(slot, &lo, &hi, &quiet_vb)) > 0.0;
  if (!at_quiet) period = full_tbv_box(slot, &lo, &hi);
  // Behind a wall, the usual case, nothing around the union of old and new
  // was seen within the memory: no cut to look for, and each cell around it
  // may hold it whole. One question of the seen record for both.
  const Vec3 ulo = glm::min(o.tbv_lo, lo), uhi = glm::max(o.tbv_hi, hi);
  const VoxBox uvb = at_quiet && ulo == lo && uhi == hi
                         ? quiet_vb
                         : touch_range(ulo, uhi, slop(std::fmax(max_abs(ulo), max_abs(uhi))));
  const bool quiet = at_quiet || unseen_around(uvb);
  bool cut = false;
  if (at_quiet && (ulo != lo || uhi != hi)) {
    // The old box reaches beyond the quiet one (it was a wider quiet box,
    // and seen space has come into the cells around it since; or the object
    // has moved inside it): the quiet box, which holds every place the
    // object can reach before it expires, replaces it, as a cut one does.
    cut = true;
  } else if (!quiet) {
    period = cut_tbv_box(slot, period, &lo, &hi, &cut);
  }
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
    expiry.push({o.tbv_expiry, slot, o.tbv_epoch}, now);
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
  expiry.push({o.tbv_expiry, slot, o.tbv_epoch}, now);
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

}  // namespace voxvis
