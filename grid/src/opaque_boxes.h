// opaque_boxes.h — the static opaque voxels (those the union of static
// objects covers) as a few large boxes, for the occlusion buffer.
//
// Why. The buffer's occluders write a pixel only when one convex occluder
// covers all of it, so the seam between two abutting occluders (two unit
// blocks, two wall segments, a floor tile and the next) is never written:
// every seam is a line of open pixels through which whatever lies behind
// stays potentially visible. A box of opaque voxels is itself a convex
// occluder, wholly inside the union of the objects (every point of an
// opaque voxel lies in some static object), so rendering it fuses its
// objects with no seam inside it.
//
// The boxes overlap on purpose: each grows from a voxel no earlier box
// covered across every opaque voxel, covered or not, one layer at a time in
// each direction in turn. So a low box of terrain reaches under the higher
// ground beside it, and the concave edge where its top meets the higher
// ground's side is covered by one box rather than split between two.
//
// Each opaque voxel records the box grown from it or the first box covering
// it (its owner); the traversal renders a voxel's owner the first time it
// reaches the voxel as potentially visible.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "voxbox.h"

namespace voxvis::detail {

inline constexpr std::uint32_t kNoBox = 0xffffffffu;

/// Covers the voxels with `bit` set in `flags` (grid of `res`, x fastest)
/// with boxes; owner[i] is the owning box of voxel i or kNoBox. Boxes are at
/// most `max_side` voxels along each axis, so that one is never much larger
/// than the view it is seen in.
void cover_with_boxes(const glm::ivec3& res, const std::vector<std::uint8_t>& flags, std::uint8_t bit,
                      int max_side, std::vector<VoxBox>* boxes, std::vector<std::uint32_t>* owner);

}  // namespace voxvis::detail
