// mesh_pairs.h — a mesh's triangles paired into quads for the occlusion
// buffer: two triangles sharing a side, nearly coplanar, whose union is a
// convex quad, are drawn as one convex occluder. A pixel straddling the
// shared side belongs wholly to neither triangle, so drawn apart they would
// leave a seam of unwritten pixels along the diagonal of every quad a level
// is made of (docs/design.md, "Meshes").
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "voxvis/types.h"

namespace voxvis::detail {

struct MeshQuads {
  static constexpr std::uint32_t kNone = ~0u;
  /// Per triangle: the triangle it is paired with, or kNone.
  std::vector<std::uint32_t> partner;
  /// Per paired triangle: the quad's vertex indices q0..q3, its triangles
  /// (q0, q1, q3) and (q1, q2, q3) (OcclusionBuffer::render_quad).
  std::vector<std::array<std::uint32_t, 4>> quad;
};

/// Pairs the triangles of `mesh` (model space): greedily, each with the
/// first unpaired neighbour across a side shared by exactly two triangles
/// whose normal is within about 1/1000 of a radian of its own and with
/// which it makes a convex quad. Pairing only chooses what is drawn
/// together; the buffer checks the quad it is given as placed and seen.
MeshQuads pair_triangles(const Mesh& mesh);

}  // namespace voxvis::detail
