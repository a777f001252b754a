// mesh_interior.cpp — see mesh_interior.h.
#include "mesh_interior.h"

#include <cstdint>
#include <mutex>
#include <unordered_map>

#include <openvdb/openvdb.h>
#include <openvdb/tools/MeshToVolume.h>

namespace voxvis::detail {

namespace {

/// The mesh in OpenVDB's index space: OpenVDB's voxel (i, j, k) is centred
/// on the integer point, the grid's voxel (i, j, k) on (i + 1/2, ...), so
/// points move by a half voxel.
struct IndexSpaceMesh {
  const std::vector<Vec3>& g;
  const Mesh& mesh;
  std::size_t polygonCount() const { return mesh.triangles.size(); }
  std::size_t pointCount() const { return g.size(); }
  std::size_t vertexCount(std::size_t) const { return 3; }
  void getIndexSpacePoint(std::size_t n, std::size_t v, openvdb::Vec3d& pos) const {
    const Vec3& p = g[mesh.triangles[n][v]];
    pos = openvdb::Vec3d(p.x - 0.5, p.y - 0.5, p.z - 0.5);
  }
};

}  // namespace

bool mesh_closed(const Mesh& mesh) {
  // Per directed side, how often it is run; a closed mesh runs each side
  // once each way.
  std::unordered_map<std::uint64_t, std::uint32_t> runs;
  runs.reserve(mesh.triangles.size() * 3);
  for (const auto& t : mesh.triangles)
    for (int k = 0; k < 3; ++k) ++runs[std::uint64_t{t[k]} << 32 | t[(k + 1) % 3]];
  for (const auto& [side, n] : runs) {
    if (n != 1) return false;
    const auto it = runs.find((side << 32) | (side >> 32));
    if (it == runs.end() || it->second != 1) return false;
  }
  return true;
}

void inside_voxel_centres(const std::vector<Vec3>& g, const Mesh& mesh, const VoxBox& range,
                          const std::function<void(int, int, int)>& emit) {
  if (range.empty()) return;
  static std::once_flag init;
  std::call_once(init, [] { openvdb::initialize(); });
  const IndexSpaceMesh adapter{g, mesh};
  const openvdb::math::Transform::Ptr xform = openvdb::math::Transform::createLinearTransform(1.0);
  // A narrow band of three voxels each side (the default): the sign of
  // every value, inside the band or not, is the region's.
  const openvdb::FloatGrid::Ptr sdf = openvdb::tools::meshToVolume<openvdb::FloatGrid>(adapter, *xform, 3.0f, 3.0f);
  const openvdb::FloatGrid::ConstAccessor acc = sdf->getConstAccessor();
  for (int z = range.lo.z; z <= range.hi.z; ++z)
    for (int y = range.lo.y; y <= range.hi.y; ++y)
      for (int x = range.lo.x; x <= range.hi.x; ++x)
        if (acc.getValue(openvdb::Coord(x, y, z)) < 0.0f) emit(x, y, z);
}

}  // namespace voxvis::detail
