// mesh_interior.cpp — see mesh_interior.h.
#include "mesh_interior.h"

#include "mesh_level_set.h"
#include "opaque_boxes.h"
#include "tri_box.h"

#include <cstdint>
#include <limits>
#include <unordered_map>

#include <algorithm>
#include <cmath>


namespace voxvis::detail {

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
  const VoxBox all{glm::ivec3(0), out.n - 1};
  const bool done = level_set_inside(g, mesh, all, stop.cancelled, [&](int x, int y, int z) {
    std::uint8_t& f = out.flags[static_cast<std::size_t>(x + out.n.x * (y + static_cast<std::size_t>(out.n.y) * z))];
    if (!(f & ModelInterior::kTouched)) f |= ModelInterior::kInside;
  });
  if (!done) return false;
  std::vector<VoxBox> boxes;
  std::vector<std::uint32_t> owner;
  cover_with_boxes(out.n, out.flags, ModelInterior::kInside, 16, &boxes, &owner);
  for (const VoxBox& b : boxes) {
    const Vec3 blo = out.lo + Vec3(b.lo) * h, bhi = out.lo + Vec3(b.hi + 1) * h;
    out.boxes.push_back({0.5 * (blo + bhi), 0.5 * (bhi - blo)});
  }
  return true;
}

}  // namespace voxvis::detail
