// mesh_pairs.cpp — see mesh_pairs.h.
#include "mesh_pairs.h"

#include <cmath>
#include <unordered_map>

#include <glm/geometric.hpp>

namespace voxvis::detail {

namespace {

/// Normals closer than this (cosine of the angle between them) pair.
constexpr double kCoplanarCos = 1.0 - 5e-7;

std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) {
  return a < b ? (std::uint64_t{a} << 32 | b) : (std::uint64_t{b} << 32 | a);
}

}  // namespace

MeshQuads pair_triangles(const Mesh& mesh) {
  const std::size_t n = mesh.triangles.size();
  MeshQuads out;
  out.partner.assign(n, MeshQuads::kNone);
  out.quad.assign(n, {0, 0, 0, 0});
  // Per side, the triangles holding it: the first, and the second (or kNone;
  // a third marks the side as not shared by exactly two).
  struct Side {
    std::uint32_t first, second;
    bool many;
  };
  std::unordered_map<std::uint64_t, Side> sides;
  sides.reserve(n * 2);
  for (std::uint32_t t = 0; t < n; ++t) {
    const auto& tri = mesh.triangles[t];
    for (int k = 0; k < 3; ++k) {
      auto [it, fresh] = sides.try_emplace(edge_key(tri[k], tri[(k + 1) % 3]), Side{t, MeshQuads::kNone, false});
      if (fresh) continue;
      if (it->second.second == MeshQuads::kNone) {
        it->second.second = t;
      } else {
        it->second.many = true;
      }
    }
  }
  std::vector<Vec3> normal(n);
  for (std::size_t t = 0; t < n; ++t) {
    const auto& tri = mesh.triangles[t];
    const Vec3 &a = mesh.vertices[tri[0]], &b = mesh.vertices[tri[1]], &c = mesh.vertices[tri[2]];
    const Vec3 c3 = glm::cross(b - a, c - a);
    const double len = glm::length(c3);
    normal[t] = len > 0.0 && std::isfinite(len) ? c3 / len : Vec3(0.0);
  }
  for (std::uint32_t t = 0; t < n; ++t) {
    if (out.partner[t] != MeshQuads::kNone) continue;
    const auto& tri = mesh.triangles[t];
    for (int k = 0; k < 3; ++k) {
      const Side& side = sides.at(edge_key(tri[k], tri[(k + 1) % 3]));
      if (side.many || side.second == MeshQuads::kNone) continue;
      const std::uint32_t u = side.first == t ? side.second : side.first;
      if (out.partner[u] != MeshQuads::kNone) continue;
      // Nearly coplanar, either orientation (a mesh may wind them either way).
      if (!(std::fabs(glm::dot(normal[t], normal[u])) >= kCoplanarCos)) continue;
      // The quad B, A, D, C around the shared side A C.
      const std::uint32_t A = tri[k], C = tri[(k + 1) % 3], B = tri[(k + 2) % 3];
      const auto& ut = mesh.triangles[u];
      std::uint32_t D = ut[0];
      for (std::uint32_t v : ut)
        if (v != A && v != C) D = v;
      const std::array<std::uint32_t, 4> q{B, A, D, C};
      // Convex in its plane: every corner turns the same way.
      bool convex = true;
      double first = 0.0;
      for (int j = 0; j < 4 && convex; ++j) {
        const Vec3 &p0 = mesh.vertices[q[j]], &p1 = mesh.vertices[q[(j + 1) % 4]], &p2 = mesh.vertices[q[(j + 2) % 4]];
        const double turn = glm::dot(glm::cross(p1 - p0, p2 - p1), normal[t]);
        if (j == 0) first = turn;
        convex = turn != 0.0 && (turn > 0.0) == (first > 0.0);
      }
      if (!convex) continue;
      out.partner[t] = u;
      out.partner[u] = t;
      out.quad[t] = q;
      out.quad[u] = q;
      break;
    }
  }
  return out;
}

}  // namespace voxvis::detail
