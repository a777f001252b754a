// mesh_interior.h — the voxels wholly inside a closed mesh, from OpenVDB's
// level set of it (docs/design.md, "Meshes": "Opaque interiors").
//
// A mesh is closed when every side is shared by exactly two triangles that
// run it in opposite directions: its surface then divides space into an
// unbounded outside and bounded insides. OpenVDB's mesh-to-volume
// conversion (mesh_level_set.h) gives the sign at voxel centres; the engine
// takes as interior only the voxels whose centre it puts inside AND that no
// triangle touches (the engine's own exact triangle-box test, grown by the
// rounding allowance), so a voxel lies wholly in one region, the one its
// centre is in.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include <glm/vec3.hpp>

#include "voxbox.h"
#include "voxvis/types.h"

namespace voxvis::detail {

/// Whether `mesh` is closed: every side (pair of vertex indices) is shared
/// by exactly two triangles, which run it in opposite directions.
bool mesh_closed(const Mesh& mesh);

/// How a build stops these conversions early: `cancelled` (polled by
/// OpenVDB, from its threads too) and `tick` (steps of work done; false:
/// stop). Either may be empty.
struct BuildStop {
  std::function<bool()> cancelled;
  std::function<bool(std::uint64_t)> tick;
};

/// A dynamic closed mesh's interior in its own frame (model units), built
/// once: a grid of cubes of side `h` over the mesh's box grown by a cube,
/// each flagged kTouched (a triangle meets it, grown by `grow`) or kInside
/// (not touched, its centre enclosed by OpenVDB's level set), and the
/// inside cubes covered by boxes (opaque_boxes.h), drawn into the buffer at
/// the mesh's placement as oriented boxes.
struct ModelInterior {
  static constexpr std::uint8_t kTouched = 1, kInside = 2;
  struct Box {
    Vec3 center, half;  ///< Model units.
  };
  Vec3 lo{0.0};              ///< Least corner of cube (0, 0, 0), model units.
  double h = 1.0;            ///< Side of a cube, model units.
  glm::ivec3 n{0};           ///< Cubes along each axis.
  std::vector<std::uint8_t> flags;  ///< x fastest.
  std::vector<Box> boxes;
  std::uint8_t at(int x, int y, int z) const {
    return flags[static_cast<std::size_t>(x + n.x * (y + static_cast<std::size_t>(n.y) * z))];
  }
};

/// The cubes model_interior(mesh, h, ...) lays out along each axis.
glm::ivec3 model_interior_cubes(const Mesh& mesh, double h);

/// The interior of closed mesh `mesh` at cubes of side about `h` (coarser
/// when the mesh would need more than 128 along an axis), triangles tested
/// against cubes grown by `grow` (model units), into `*out`. False when
/// `stop` stopped it (`*out` is then not to be used).
bool model_interior(const Mesh& mesh, double h, double grow, const BuildStop& stop, ModelInterior* out);

}  // namespace voxvis::detail
