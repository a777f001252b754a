// meshes.cpp — see meshes.h.
#include "meshes.h"

#include <cmath>
#include <map>
#include <utility>
#include <vector>

#include <glm/geometric.hpp>

#include "voxvis/mesh.h"
#include "voxvis/rng.h"

namespace voxvis::test {

std::shared_ptr<const Mesh> cube_mesh(const Vec3& half) {
  auto m = std::make_shared<Mesh>();
  for (int c = 0; c < 8; ++c)
    m->vertices.push_back(Vec3(c & 1 ? half.x : -half.x, c & 2 ? half.y : -half.y, c & 4 ? half.z : -half.z));
  m->triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                  {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  return m;
}

std::shared_ptr<const Mesh> icosphere(int levels) {
  auto m = std::make_shared<Mesh>();
  const double p = (1.0 + std::sqrt(5.0)) / 2.0;
  const Vec3 corners[12] = {{-1, p, 0}, {1, p, 0}, {-1, -p, 0}, {1, -p, 0}, {0, -1, p}, {0, 1, p},
                            {0, -1, -p}, {0, 1, -p}, {p, 0, -1}, {p, 0, 1}, {-p, 0, -1}, {-p, 0, 1}};
  for (const Vec3& c : corners) m->vertices.push_back(glm::normalize(c));
  std::vector<std::array<std::uint32_t, 3>> tris = {
      {0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
      {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
      {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (int level = 0; level < levels; ++level) {
    // Each edge's midpoint once, pushed out to the sphere.
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> mid;
    auto midpoint = [&](std::uint32_t a, std::uint32_t b) {
      const auto key = a < b ? std::make_pair(a, b) : std::make_pair(b, a);
      const auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      const auto k = static_cast<std::uint32_t>(m->vertices.size());
      m->vertices.push_back(glm::normalize(m->vertices[a] + m->vertices[b]));
      mid.emplace(key, k);
      return k;
    };
    std::vector<std::array<std::uint32_t, 3>> next;
    next.reserve(4 * tris.size());
    for (const auto& t : tris) {
      const std::uint32_t ab = midpoint(t[0], t[1]), bc = midpoint(t[1], t[2]), ca = midpoint(t[2], t[0]);
      next.push_back({t[0], ab, ca});
      next.push_back({t[1], bc, ab});
      next.push_back({t[2], ca, bc});
      next.push_back({ab, bc, ca});
    }
    tris.swap(next);
  }
  m->triangles = std::move(tris);
  return m;
}

SceneDesc copied_triangle_scene(int copies, double leg) {
  SceneDesc d;
  d.bounds_min = Vec3(0.0);
  d.bounds_max = Vec3(100.0);
  d.grid = glm::ivec3(64);
  auto m = std::make_shared<Mesh>();
  m->vertices.reserve(3 * static_cast<std::size_t>(copies));
  m->triangles.reserve(static_cast<std::size_t>(copies));
  for (int i = 0; i < copies; ++i) {
    const auto k = static_cast<std::uint32_t>(m->vertices.size());
    m->vertices.push_back(Vec3(5.0));
    m->vertices.push_back(Vec3(5.0 + leg, 5.0, 5.0 + 0.3 * leg));
    m->vertices.push_back(Vec3(5.0, 5.0 + leg, 5.0 + 0.6 * leg));
    m->triangles.push_back({k, k + 1, k + 2});
  }
  d.objects.push_back(mesh_object(1, m, Vec3(0.0)));
  return d;
}

std::shared_ptr<const Mesh> triangle_soup(int count, std::uint64_t seed) {
  auto m = std::make_shared<Mesh>();
  Rng rng(seed);
  while (static_cast<int>(m->triangles.size()) < count) {
    Vec3 v[3];
    for (Vec3& p : v) p = rng.in_box(Vec3(-1.0), Vec3(1.0));
    if (!(glm::length(glm::cross(v[1] - v[0], v[2] - v[0])) > 1e-3)) continue;
    const auto k = static_cast<std::uint32_t>(m->vertices.size());
    for (const Vec3& p : v) m->vertices.push_back(p);
    m->triangles.push_back({k, k + 1, k + 2});
  }
  return m;
}

ObjectDesc mesh_object(ObjectId id, std::shared_ptr<const Mesh> mesh, const Vec3& center, const Quat& rotation,
                       double scale) {
  ObjectDesc o;
  o.id = id;
  o.shape = Shape::Mesh;
  o.mesh = std::move(mesh);
  o.center = center;
  o.rotation = rotation;
  o.scale = scale;
  return o;
}

ObjectDesc placed_by_hand(const ObjectDesc& o) {
  auto m = std::make_shared<Mesh>(*o.mesh);
  for (Vec3& v : m->vertices) v = place(o, v);
  return mesh_object(o.id, std::move(m), Vec3(0.0));
}

Quat rotation_about(const Vec3& axis, double angle) {
  const Vec3 a = glm::normalize(axis) * std::sin(0.5 * angle);
  return Quat(std::cos(0.5 * angle), a.x, a.y, a.z);
}

}  // namespace voxvis::test
