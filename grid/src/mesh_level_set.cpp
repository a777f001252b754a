// mesh_level_set.cpp — see mesh_level_set.h.
#include "mesh_level_set.h"

#include <atomic>
#include <mutex>

#include <openvdb/openvdb.h>
#include <openvdb/tools/MeshToVolume.h>
#include <openvdb/util/NullInterrupter.h>
#include <tbb/task_arena.h>

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

/// Asks the build's control whether to stop, from OpenVDB's threads.
struct Interrupter final : openvdb::util::NullInterrupter {
  const std::function<bool()>& stop;
  std::atomic<bool> stopped{false};
  explicit Interrupter(const std::function<bool()>& s) : stop(s) {}
  bool wasInterrupted(int = -1) override {
    if (!stopped.load(std::memory_order_relaxed) && stop && stop()) stopped.store(true, std::memory_order_relaxed);
    return stopped.load(std::memory_order_relaxed);
  }
};

/// The level set, or null when `stop` said to stop (the conversion's
/// partial grid is not used). On the calling thread alone: a build runs
/// beside the frames of the scenes already served, at a lower priority,
/// and OpenVDB's worker threads would take every core at the normal one.
openvdb::FloatGrid::Ptr level_set(const std::vector<Vec3>& g, const Mesh& mesh, const std::function<bool()>& stop) {
  static std::once_flag init;
  std::call_once(init, [] { openvdb::initialize(); });
  const IndexSpaceMesh adapter{g, mesh};
  const openvdb::math::Transform::Ptr xform = openvdb::math::Transform::createLinearTransform(1.0);
  Interrupter interrupter(stop);
  openvdb::FloatGrid::Ptr sdf;
  tbb::task_arena one(1);
  // A narrow band of three voxels each side (the default): the sign of
  // every value, inside the band or not, is the region's.
  one.execute([&] { sdf = openvdb::tools::meshToVolume<openvdb::FloatGrid>(interrupter, adapter, *xform, 3.0f, 3.0f); });
  return interrupter.stopped.load() ? nullptr : sdf;
}

}  // namespace

bool level_set_inside(const std::vector<Vec3>& g, const Mesh& mesh, const VoxBox& range,
                      const std::function<bool()>& cancelled, const std::function<void(int, int, int)>& emit) {
  if (range.empty()) return true;
  const openvdb::FloatGrid::Ptr sdf = level_set(g, mesh, cancelled);
  if (!sdf) return false;
  const openvdb::FloatGrid::ConstAccessor acc = sdf->getConstAccessor();
  for (int z = range.lo.z; z <= range.hi.z; ++z)
    for (int y = range.lo.y; y <= range.hi.y; ++y)
      for (int x = range.lo.x; x <= range.hi.x; ++x)
        if (acc.getValue(openvdb::Coord(x, y, z)) < 0.0f) emit(x, y, z);
  return true;
}

}  // namespace voxvis::detail
