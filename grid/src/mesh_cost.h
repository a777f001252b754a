// mesh_cost.h — what a mesh's triangles can cost a build, bounded in O(1)
// per triangle without touching a voxel: the cells each can touch (its
// voxels' id-list entries, its bricks' triangle entries) and the narrow band
// of the level set that finds a closed mesh's interior (mesh_interior.h),
// counted a leaf of its tree at a time.
// Scene::estimate counts with these bounds, so that refusing a scene too
// large for the memory budget costs no more than reading it.
//
// The bound is a volume. The cells a triangle T touches, each grown by g on
// every side, have their centres in T grown by a cube of half side 1/2 + g
// (cell units); their unit cells, disjoint, lie in T grown by a cube of
// side w = 2 (1 + g), whose volume is exactly (the mixed volumes of a flat
// convex set and a cube)
//     w |N|_1 / 2 + (w^2 / 2) (|e0|_1 + |e1|_1 + |e2|_1) + w^3,
// N the cross product of two edges (twice the area along the normal), e_i
// the edges: the faces' slab, the edges' prisms, the corners' cube. Callers
// take the least of it and the cells of the triangle's own box, which is
// exact for small triangles.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "voxvis/types.h"

namespace voxvis::detail {

/// At most how many cells of side `side` (voxels; grid coordinates in
/// voxels) triangle (a, b, c) touches when each cell is grown by `grow`
/// voxels on every side. Not clipped to the grid.
double cells_touched_bound(const Vec3& a, const Vec3& b, const Vec3& c, double side, double grow);

/// The nodes of the trees of a level set (OpenVDB's: leaves of 8^3 voxels
/// under internal nodes of 128^3 and 4096^3) whose narrow band reaches
/// `distance` voxels (along each axis) from a mesh's triangles.
struct LevelSetNodes {
  std::uint64_t leaves = 0, internal = 0, top = 0;
  /// Bytes while the level set is made: the distance grid and the
  /// closest-triangle grid OpenVDB builds beside it, with room for the
  /// conversion's own copies (about 8 KiB a leaf, 128 KiB an internal
  /// node, 1 MiB a top node; measured: docs/design.md, "What a mesh costs").
  std::uint64_t bytes() const { return 8192 * leaves + 131072 * internal + 1048576 * top; }
};

/// Counts the leaves (and their parents) that triangles of `mesh`, at grid
/// coordinates `g` (voxel i spans [i, i+1]; OpenVDB's voxel i is centred on
/// i + 1/2 there), reach within `distance` voxels, each triangle descending
/// from a cube over its box to the leaves it meets (O(the leaves it meets)
/// tests, however large it is). False, with the count so far, once the
/// leaves pass `max_leaves` or `tick` (steps of work done) says stop.
bool level_set_nodes(const std::vector<Vec3>& g, const Mesh& mesh, double distance, std::uint64_t max_leaves,
                     const std::function<bool(std::uint64_t)>& tick, LevelSetNodes* out);

/// Voxels (or any unit cells) of the box [lo, hi] of cell indices, 0 when
/// it is empty.
double cells_of(const glm::ivec3& lo, const glm::ivec3& hi);

}  // namespace voxvis::detail
