// voxvis/inspect.h — read-only views of what the engine holds and does,
// voxel by voxel, for tools that show it (`voxvis export --vdb`) and for
// tests: the grid's static opacity and the objects each voxel holds
// (inspect_grid), and the record of one frame's traversal (FrameTrace).
// Not for the serving path: inspect_grid reads every voxel of the grid.
//
// Voxels are named by grid indices: voxel (i, j, k) is the unit cube
// [i,i+1]x[j,j+1]x[k,k+1] of grid space (voxvis/types.h), in world units
// bounds_min + (i, j, k) * voxel_size to bounds_min + (i+1, j+1, k+1) *
// voxel_size (Scene::grid()).
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "voxvis/scene.h"

namespace voxvis {

/// An inclusive box of voxels, grid indices; empty when hi < lo on an axis.
struct VoxelBox {
  glm::ivec3 lo{0}, hi{-1};
  bool empty() const { return hi.x < lo.x || hi.y < lo.y || hi.z < lo.z; }
  /// Voxels in the box (0 when empty).
  std::int64_t count() const {
    return empty() ? 0 : std::int64_t{hi.x - lo.x + 1} * (hi.y - lo.y + 1) * (hi.z - lo.z + 1);
  }
  bool contains(const glm::ivec3& v) const {
    return v.x >= lo.x && v.x <= hi.x && v.y >= lo.y && v.y <= hi.y && v.z >= lo.z && v.z <= hi.z;
  }
  bool operator==(const VoxelBox&) const = default;
};

/// What one frame's traversal did with the grid's voxels, recorded by the
/// frames of a Scratch that carries it (Scratch::set_trace). Both lists are
/// boxes of voxels within the grid, and no two boxes overlap (in one list or
/// across the two), so a voxel is visited, occluded, or neither. What the two words mean for
/// each traversal (docs/formats.md, "voxvis export"):
///  * Cells (the occlusion buffer on): a cell of the pyramid (a brick of
///    4^3 voxels or coarser, cut at the grid's far faces) is recorded
///    whole. `occluded`: the cells the traversal skipped as hidden by the
///    buffer, or lying beyond its farthest bound once every pixel holds one
///    (the early end). `visited`: the bricks it entered, the cells of bricks
///    it took whole (less their bricks proven hidden), and the empty cells it
///    tested and found in view and not hidden (only scenes with dynamic
///    objects test empty cells). Neither: cells outside the frustum, and empty
///    cells the traversal did not test (their parent's mask says they hold
///    nothing).
///  * Voxels (the buffer off): runs of voxels along x. `visited`: the voxels
///    whose status the traversal computed and found not hidden (open space
///    and the opaque voxels that occlude); `occluded`: those it proved
///    hidden, by the shells before them or by their front neighbours.
///    Neither: voxels it never reached (outside the view pyramid, beyond the
///    early exit, or far from every live voxel of the shell before).
struct FrameTrace {
  enum class Traversal : std::uint8_t {
    None,    ///< No traversal: the grid was out of view, or the frame fell back to frustum culling.
    Cells,   ///< The cell pyramid (SceneOptions::occlusion_buffer > 0).
    Voxels,  ///< The voxel shells (occlusion_buffer == 0).
  };
  Traversal traversal = Traversal::None;
  std::vector<VoxelBox> visited;
  std::vector<VoxelBox> occluded;

  void clear() {
    traversal = Traversal::None;
    visited.clear();
    occluded.clear();
  }
};

/// One row of voxels along x (y and z fixed), as inspect_grid reads it.
/// The spans hold Scene::grid().res.x entries and live during the call only.
struct GridRow {
  int y = 0, z = 0;
  /// Per voxel x, bits: kCovered when static objects cover it (static
  /// opacity, docs/design.md "Opacity"), kInsideMesh when it lies wholly
  /// inside a closed static mesh (built with the occlusion buffer on:
  /// docs/design.md "Meshes"); 0 when neither. Dynamic objects' opacity is
  /// not included.
  std::span<const std::uint8_t> opaque;
  static constexpr std::uint8_t kCovered = 1, kInsideMesh = 2;
  /// Per voxel x: the objects the grid holds for the voxel, the ones that
  /// touch its closed cube (with the engine's rounding allowance, which only
  /// adds a voxel an object touches within a few ulps): static objects as
  /// stored in the voxel and the cells above it, dynamic objects by the
  /// engine's test at their current centres (under a TBV or not).
  std::span<const std::uint32_t> objects;
};

/// Calls `row` for every row of the grid, z outermost, then y. With `only`
/// given, `objects` counts only the objects whose ids it lists (any order;
/// unknown ids are ignored). Reads the scene under its shared lock: frames
/// may run meanwhile, moves wait until it returns, and `row` must not call
/// the scene's apply_moves.
void inspect_grid(const Scene& scene, const std::function<void(const GridRow&)>& row,
                  const std::vector<ObjectId>* only = nullptr);

}  // namespace voxvis
