// mesh_interior.cpp — see mesh_interior.h.
#include "mesh_interior.h"

#include "opaque_boxes.h"
#include "tri_box.h"

#include <atomic>
#include <cstdint>
#include <mutex>
#include <limits>
#include <unordered_map>

#include <algorithm>
#include <cmath>

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

namespace {

/// Asks the build's control whether to stop, from OpenVDB's threads.
struct Interrupter final : openvdb::util::NullInterrupter {
  const std::function<bool()>* stop;
  std::atomic<bool> stopped{false};
  explicit Interrupter(const std::function<bool()>* s) : stop(s) {}
  bool wasInterrupted(int = -1) override {
    if (!stopped.load(std::memory_order_relaxed) && stop != nullptr && *stop && (*stop)())
      stopped.store(true, std::memory_order_relaxed);
    return stopped.load(std::memory_order_relaxed);
  }
};

/// The level set, or null when `stop` said to stop (the conversion's
/// partial grid is not used). On the calling thread alone: a build runs
/// beside the frames of the scenes already served, at a lower priority,
/// and OpenVDB's worker threads would take every core at the normal one.
openvdb::FloatGrid::Ptr level_set(const std::vector<Vec3>& g, const Mesh& mesh, const std::function<bool()>* stop) {
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

/// The layout of model_interior: false when the mesh or h cannot have one.
bool layout(const Mesh& mesh, double* h, Vec3* lo_out, glm::ivec3* n) {
  Vec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
  for (const Vec3& v : mesh.vertices) lo = glm::min(lo, v), hi = glm::max(hi, v);
  const double extent = std::fmax(hi.x - lo.x, std::fmax(hi.y - lo.y, hi.z - lo.z));
  if (!(extent > 0.0) || !(*h > 0.0) || !std::isfinite(extent / *h)) return false;
  *h = std::fmax(*h, extent / 126.0);
  *lo_out = lo - *h;
  for (int a = 0; a < 3; ++a) (*n)[a] = static_cast<int>(std::ceil((hi[a] - lo[a]) / *h)) + 2;
  return true;
}

}  // namespace

glm::ivec3 model_interior_cubes(const Mesh& mesh, double h) {
  Vec3 lo;
  glm::ivec3 n(0);
  return layout(mesh, &h, &lo, &n) ? n : glm::ivec3(0);
}

bool model_interior(const Mesh& mesh, double h, double grow, const BuildStop& stop, ModelInterior* result) {
  ModelInterior& out = *result;
  out = ModelInterior{};
  if (!layout(mesh, &h, &out.lo, &out.n)) return true;
  out.h = h;
  out.flags.assign(static_cast<std::size_t>(out.n.x) * out.n.y * out.n.z, 0);
  // The mesh in cube units (cube i spans [i, i+1]).
  std::vector<Vec3> g(mesh.vertices.size());
  for (std::size_t i = 0; i < g.size(); ++i) g[i] = (mesh.vertices[i] - out.lo) / h;
  const Vec3 half(0.5 + grow / h + 1e-9);
  for (const auto& t : mesh.triangles) {
    const Vec3 &a = g[t[0]], &b = g[t[1]], &c = g[t[2]];
    const Vec3 tlo = glm::min(a, glm::min(b, c)) - (half - 0.5), thi = glm::max(a, glm::max(b, c)) + (half - 0.5);
    glm::ivec3 v0, v1;
    for (int k = 0; k < 3; ++k) {
      v0[k] = std::clamp(static_cast<int>(std::ceil(tlo[k])) - 1, 0, out.n[k] - 1);
      v1[k] = std::clamp(static_cast<int>(std::floor(thi[k])), 0, out.n[k] - 1);
    }
    const std::uint64_t tests = triangle_voxels(a, b, c, v0, v1, half - 0.5, [&](int x, int y, int z) {
      out.flags[static_cast<std::size_t>(x + out.n.x * (y + static_cast<std::size_t>(out.n.y) * z))] |=
          ModelInterior::kTouched;
    });
    if (stop.tick && !stop.tick(tests + 1)) return false;
  }
  const openvdb::FloatGrid::Ptr sdf = level_set(g, mesh, &stop.cancelled);
  if (!sdf) return false;
  const openvdb::FloatGrid::ConstAccessor acc = sdf->getConstAccessor();
  for (int z = 0; z < out.n.z; ++z)
    for (int y = 0; y < out.n.y; ++y)
      for (int x = 0; x < out.n.x; ++x) {
        std::uint8_t& f = out.flags[static_cast<std::size_t>(x + out.n.x * (y + static_cast<std::size_t>(out.n.y) * z))];
        if (!(f & ModelInterior::kTouched) && acc.getValue(openvdb::Coord(x, y, z)) < 0.0f) f |= ModelInterior::kInside;
      }
  std::vector<VoxBox> boxes;
  std::vector<std::uint32_t> owner;
  cover_with_boxes(out.n, out.flags, ModelInterior::kInside, 16, &boxes, &owner);
  for (const VoxBox& b : boxes) {
    const Vec3 blo = out.lo + Vec3(b.lo) * h, bhi = out.lo + Vec3(b.hi + 1) * h;
    out.boxes.push_back({0.5 * (blo + bhi), 0.5 * (bhi - blo)});
  }
  return true;
}

bool inside_voxel_centres(const std::vector<Vec3>& g, const Mesh& mesh, const VoxBox& range, const BuildStop& stop,
                          const std::function<void(int, int, int)>& emit) {
  if (range.empty()) return true;
  const openvdb::FloatGrid::Ptr sdf = level_set(g, mesh, &stop.cancelled);
  if (!sdf) return false;
  const openvdb::FloatGrid::ConstAccessor acc = sdf->getConstAccessor();
  for (int z = range.lo.z; z <= range.hi.z; ++z)
    for (int y = range.lo.y; y <= range.hi.y; ++y)
      for (int x = range.lo.x; x <= range.hi.x; ++x)
        if (acc.getValue(openvdb::Coord(x, y, z)) < 0.0f) emit(x, y, z);
  return true;
}

}  // namespace voxvis::detail
