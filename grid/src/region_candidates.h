// region_candidates.h — the dynamic objects and TBVs a region frame must
// test, found through the cells instead of the whole list, so that movers
// hidden far from the eyes cost a region frame nothing (docs/design.md,
// "Regions").
//
// The argument. A dynamic object not under a TBV has entries in the cells
// (bricks and coarser, scene_impl.h) of every voxel its box touches, clipped
// to the grid; an object under a TBV lies in its TBV, which has entries where
// its box touches; what is wholly beyond the grid box is on the `outside`
// lists. A region frame keeps a box B of an object moving at up to v only if
// B grown by g = v * horizon (a) comes within `far` of an eye of the box and
// (b), when the eyes' free space is known (region_cavity.h), touches a voxel
// of the eyes' components. So B itself meets the eye box grown by
// far + g_max, and the components' voxel box grown by g_max (in voxels, one
// more for rounding), and for a frustum region the box around the frusta
// grown by the eye box and g: the cells of the voxels inside all hold an entry of
// every object and TBV the frame can keep whose box meets the grid. (A box
// only partly inside the grid loses nothing: clamping a point of it into the
// grid box keeps it in B and moves it no farther from anything inside.) A box
// wholly beyond the grid can be kept only when all the grown boxes reach out of
// the grid box; then the outside lists are tested too.
//
// The same range (its faces in open space shrunk to whole cells) is what the
// frame records as seen (see_region), so that hidden movers' TBVs do not grow
// into the room the eyes are in.
#pragma once

#include <cstdint>

#include "region.h"
#include "region_cavity.h"
#include "scene_impl.h"

namespace voxvis::detail {

/// Where a region frame looks for dynamic objects and TBVs (scenes with
/// dynamic objects; otherwise `all`, with nothing to test).
struct RegionVisit {
  bool all = true;       ///< Test every dynamic slot: the range would cost more to read.
  VoxBox range;          ///< Voxels (clipped to the grid) whose cells hold every candidate.
  bool outside = true;   ///< Those wholly beyond the grid box may be kept too.
  /// What the frame records as seen (see_region): `range` with its faces in
  /// open space shrunk to whole cells of 16 voxels.
  VoxBox seen;
};

/// The ranges for one frame (argued above). `all` when the range's bricks
/// outnumber kBricksPerMover times the dynamic objects.
RegionVisit region_visit(const Scene::Impl& s, const RegionReach& reach, const WorldFrustum& wf,
                         const RegionCavity& cavity);

/// Records the voxels of `range` (RegionVisit::seen) as seen by this
/// frame, as whole cells of levels >= 2 and bricks masked to it, so that
/// TBVs made after the frame keep clear of it (Scene::Impl::tbv_box), as
/// they keep clear of what a point frame saw: a TBV grown into it would be
/// revealed by the next frame. Scenes with dynamic objects only.
void see_region(const Scene::Impl& s, Scratch::Impl& w, const VoxBox& range);

/// Reading a brick costs a fraction of testing an object: a range is read
/// when it has at most this many bricks per dynamic object.
inline constexpr std::int64_t kBricksPerMover = 16;

/// Calls visit(slot) for each object with a current entry in the cells of
/// `range` (bricks and the coarser cells above them), possibly more than
/// once; returns the cells read.
template <class Visit>
std::uint64_t for_each_entry(const Scene::Impl& s, const VoxBox& range, Visit&& visit) {
  std::uint64_t cells = 0;
  if (range.empty() || s.bricks.empty()) return cells;
  for (int l = 1; l < s.pyr.levels; ++l) {
    if (l > 1 && s.coarse_dyn_live == 0) break;
    const int sh = kBrickShift + kCellShift * (l - 1);
    const glm::ivec3 lo = range.lo >> sh, hi = range.hi >> sh;
    for (int z = lo.z; z <= hi.z; ++z)
      for (int y = lo.y; y <= hi.y; ++y)
        for (int x = lo.x; x <= hi.x; ++x) {
          const std::size_t i = s.pyr.index(l, glm::ivec3(x, y, z));
          const Brick& cell = l == 1 ? s.bricks[i] : s.coarse_dyn[static_cast<std::size_t>(l)][i];
          ++cells;
          if (cell.live == 0) continue;
          for (const BrickEntry& e : cell.entries)
            if (s.current(e)) visit(e.key >> 1);
        }
  }
  return cells;
}

}  // namespace voxvis::detail
