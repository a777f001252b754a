// mesh_level_set.h — the one place the engine calls OpenVDB: the sign of a
// closed mesh's level set at voxel centres (`openvdb::tools::meshToVolume`,
// a narrow-band level set whose inactive values carry the sign of the region
// they lie in, by flood fill). mesh_interior.h says what the engine makes of
// it.
//
// A file of its own because OpenVDB's templates are most of the engine's
// compile time (about 90 s of one core optimized, eight minutes under the
// sanitizers): the sanitizer and fuzz builds compile this file without
// instrumentation (grid/CMakeLists.txt), so it holds nothing but the call.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "voxbox.h"
#include "voxvis/types.h"

namespace voxvis::detail {

/// For a closed mesh whose vertices, placed and mapped, are `g` (grid
/// coordinates: voxel i spans [i, i+1] along each axis), calls emit(x, y, z)
/// for every voxel of `range` whose centre OpenVDB's level set of the mesh
/// (voxel size 1, centres at the grid's voxel centres) puts inside. The
/// level set is made on the calling thread alone; `cancelled` (may be empty)
/// is polled from it. False, having emitted nothing, when it said to stop.
bool level_set_inside(const std::vector<Vec3>& g, const Mesh& mesh, const VoxBox& range,
                      const std::function<bool()>& cancelled, const std::function<void(int, int, int)>& emit);

}  // namespace voxvis::detail
