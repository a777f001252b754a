// mesh_interior.h — the voxels wholly inside a closed mesh, from OpenVDB's
// level set of it (docs/design.md, "Meshes": "Opaque interiors").
//
// A mesh is closed when every side is shared by exactly two triangles that
// run it in opposite directions: its surface then divides space into an
// unbounded outside and bounded insides. OpenVDB's mesh-to-volume
// conversion (`openvdb::tools::meshToVolume`, a narrow-band level set whose
// inactive values carry the sign of the region they lie in, by flood fill)
// gives the sign at voxel centres; the engine takes as interior only the
// voxels whose centre it puts inside AND that no triangle touches (the
// engine's own exact triangle-box test, grown by the rounding allowance),
// so a voxel lies wholly in one region, the one its centre is in. This is
// the engine's only use of OpenVDB.
#pragma once

#include <functional>
#include <vector>

#include "voxbox.h"
#include "voxvis/types.h"

namespace voxvis::detail {

/// Whether `mesh` is closed: every side (pair of vertex indices) is shared
/// by exactly two triangles, which run it in opposite directions.
bool mesh_closed(const Mesh& mesh);

/// For a closed mesh whose vertices, placed and mapped, are `g` (grid
/// coordinates: voxel i spans [i, i+1] along each axis), calls emit(x, y, z)
/// for every voxel of `range` whose centre OpenVDB's level set of the mesh
/// (voxel size 1, centres at the grid's voxel centres) puts inside.
void inside_voxel_centres(const std::vector<Vec3>& g, const Mesh& mesh, const VoxBox& range,
                          const std::function<void(int, int, int)>& emit);

}  // namespace voxvis::detail
