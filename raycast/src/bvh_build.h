// bvh_build.h — the binned surface-area-heuristic builder shared by the
// caster's two hierarchies: over the objects of one call (raycast.cpp) and
// over the triangles of one mesh, in its model frame (mesh_bvh.cpp). Boxes
// are kept in double, exactly as given: each hierarchy states how its leaf
// boxes cover its rounding.
#pragma once

#include <cstdint>
#include <vector>

namespace voxvis::raycast::detail {

/// A node: its box; a leaf holds `count` items from `first` (in the order
/// build_bvh leaves them), an inner node (count 0) its two children at
/// `first` and `first + 1`.
struct BvhNode {
  double lo[3];
  double hi[3];
  std::uint32_t first = 0;
  std::uint32_t count = 0;
};

/// An item to build over: its box, the box's centre, and what it stands
/// for (an index into the caller's array).
struct BvhItem {
  double lo[3];
  double hi[3];
  double c[3];
  std::uint32_t index;
};

/// Deepest a traversal stack gets: the builder splits by the surface-area
/// heuristic down to kSahDepth (40) levels, then at the median (which
/// halves the items: at most 32 more levels for 2^32 items), and a
/// nearest-first traversal holds at most one entry per level plus one.
constexpr int kBvhStackSize = 128;

/// Builds the hierarchy over `items` (not empty) into `nodes` (node 0 the
/// root), reordering `items` into leaf order; a leaf holds at most 4 items
/// (more only when their centres coincide).
void build_bvh(std::vector<BvhItem>& items, std::vector<BvhNode>* nodes);

}  // namespace voxvis::raycast::detail
