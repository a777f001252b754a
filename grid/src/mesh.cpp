// mesh.cpp — the rules of meshes and their placement (voxvis/mesh.h).
#include "voxvis/mesh.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>

namespace voxvis {
namespace {

bool finite3(const Vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

double max_abs3(const Vec3& v) { return std::fmax(std::fabs(v.x), std::fmax(std::fabs(v.y), std::fabs(v.z))); }

std::string vec_text(const Vec3& v) {
  std::string out(1, '[');
  for (int a = 0; a < 3; ++a) {
    if (a > 0) out += ", ";
    out += number_text(v[a]);
  }
  out += ']';
  return out;
}

}  // namespace

Status validate_mesh(const Mesh& mesh, const std::string& field) {
  const std::size_t nv = mesh.vertices.size();
  if (mesh.triangles.empty()) return Status::Error(field + ".triangles", "a mesh needs at least one triangle");
  if (nv > kMaxMeshVertices)
    return Status::Error(field + ".vertices", "at most " + std::to_string(kMaxMeshVertices) + " vertices, got " +
                                                  std::to_string(nv));
  if (mesh.triangles.size() > kMaxMeshTriangles)
    return Status::Error(field + ".triangles", "at most " + std::to_string(kMaxMeshTriangles) +
                                                   " triangles, got " + std::to_string(mesh.triangles.size()));
  for (std::size_t i = 0; i < nv; ++i) {
    const Vec3& v = mesh.vertices[i];
    if (!finite3(v) || max_abs3(v) > kMaxCoordinate)
      return Status::Error(field + ".vertices[" + std::to_string(i) + "]",
                           "must be finite and at most " + number_text(kMaxCoordinate) + " on every axis, got " +
                               vec_text(v));
  }
  // The field's text is made only for an error: this loop runs once per
  // triangle of every mesh a description holds.
  auto at = [&](std::size_t t) { return field + ".triangles[" + std::to_string(t) + "]"; };
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    for (int k = 0; k < 3; ++k)
      if (tri[static_cast<std::size_t>(k)] >= nv)
        return Status::Error(at(t), "vertex index " + std::to_string(tri[static_cast<std::size_t>(k)]) +
                                        " is out of range (the mesh has " + std::to_string(nv) + " vertices)");
    const Vec3& a = mesh.vertices[tri[0]];
    const Vec3 n = glm::cross(mesh.vertices[tri[1]] - a, mesh.vertices[tri[2]] - a);
    if (!(max_abs3(n) > 0.0))
      return Status::Error(at(t), "is degenerate (its vertices " + std::to_string(tri[0]) + ", " +
                                      std::to_string(tri[1]) + ", " + std::to_string(tri[2]) +
                                      " span no area); remove it");
  }
  return Status::Ok();
}

Status validate_rotation(const Quat& q, const std::string& field) {
  const double n = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
  if (!std::isfinite(n) || !(std::fabs(n - 1.0) <= kQuatTolerance))
    return Status::Error(field, "must be a unit quaternion [w, x, y, z] (norm within " +
                                    number_text(kQuatTolerance) + " of 1), got norm " + number_text(n));
  return Status::Ok();
}

Status validate_mesh_object(const ObjectDesc& o, const std::string& field) {
  MeshPlacementCheck check;
  return check.check(o, field);
}

Status MeshPlacementCheck::check(const ObjectDesc& o, const std::string& field) {
  if (!o.mesh) return Status::Error(field + ".mesh", "a mesh object needs its triangles");
  auto it = measured_.find(o.mesh.get());
  if (it == measured_.end()) {
    if (Status s = validate_mesh(*o.mesh, field + ".mesh"); !s) return s;
    ModelBox box{Vec3(std::numeric_limits<double>::infinity()), Vec3(-std::numeric_limits<double>::infinity())};
    for (const Vec3& v : o.mesh->vertices) box.lo = glm::min(box.lo, v), box.hi = glm::max(box.hi, v);
    it = measured_.emplace(o.mesh.get(), box).first;
  }
  if (!std::isfinite(o.scale) || !(o.scale > 0.0))
    return Status::Error(field + ".scale", "must be finite and > 0, got " + number_text(o.scale));
  if (Status s = validate_rotation(o.rotation, field + ".rotation"); !s) return s;
  if (!finite3(o.center) || max_abs3(o.center) > kMaxCoordinate)
    return Status::Error(field + ".center", "must be finite and at most " + number_text(kMaxCoordinate) +
                                                " on every axis, got " + vec_text(o.center));
  // The model box placed: its centre placed, and per axis the reach of its
  // rotated half extents (|R| h), grown by one part in 2^40 for roundings,
  // so that it holds every vertex as place() computes it.
  const Quat q = unit_rotation(o.rotation);
  const Vec3 mid = 0.5 * (it->second.lo + it->second.hi), half = 0.5 * (it->second.hi - it->second.lo);
  const glm::dmat3 r = glm::mat3_cast(q);
  Vec3 reach(0.0);
  for (int a = 0; a < 3; ++a)
    for (int k = 0; k < 3; ++k) reach[a] += std::fabs(r[k][a]) * half[k];
  const Vec3 around = o.scale * (q * mid), spread = o.scale * reach;
  const Vec3 lo = o.center + around - spread, hi = o.center + around + spread;
  constexpr double kRounding = 1.0 + 0x1p-40;
  if (!(max_abs3(glm::abs(o.center + around) + spread) * kRounding <= kMaxCoordinate)) {
    // At the origin the box would fit: the centre takes it beyond.
    const bool by_center = max_abs3(glm::abs(around) + spread) * kRounding <= kMaxCoordinate;
    return Status::Error(field + (by_center ? ".center" : ".scale"),
                         "places the mesh beyond " + number_text(kMaxCoordinate) + " (its box " + vec_text(lo) +
                             " to " + vec_text(hi) + ")");
  }
  return Status::Ok();
}

Quat unit_rotation(const Quat& q) {
  const double n = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
  return Quat(q.w / n, q.x / n, q.y / n, q.z / n);
}

Vec3 place(const ObjectDesc& o, const Vec3& p) { return o.center + o.scale * (unit_rotation(o.rotation) * p); }

void mesh_bounds(const ObjectDesc& o, Vec3* lo, Vec3* hi) {
  constexpr double inf = std::numeric_limits<double>::infinity();
  Vec3 l(inf), h(-inf);
  if (o.mesh) {
    const Quat q = unit_rotation(o.rotation);
    for (const Vec3& v : o.mesh->vertices) {
      const Vec3 w = o.center + o.scale * (q * v);
      l = glm::min(l, w);
      h = glm::max(h, w);
    }
  }
  *lo = l;
  *hi = h;
}

void object_bounds(const ObjectDesc& o, Vec3* lo, Vec3* hi) {
  switch (o.shape) {
    case Shape::Sphere:
      *lo = o.center - Vec3(o.radius);
      *hi = o.center + Vec3(o.radius);
      return;
    case Shape::Box:
      *lo = o.center - o.half_extent;
      *hi = o.center + o.half_extent;
      return;
    case Shape::Mesh:
      mesh_bounds(o, lo, hi);
      return;
  }
}

Vec3 mesh_centroid(const Mesh& mesh) {
  Vec3 sum(0.0);
  for (const Vec3& v : mesh.vertices) sum += v;
  return mesh.vertices.empty() ? sum : sum / static_cast<double>(mesh.vertices.size());
}

double mesh_reach(const Mesh& mesh, const Vec3& centroid) {
  double r = 0.0;
  for (const Vec3& v : mesh.vertices) r = std::fmax(r, glm::length(v - centroid));
  // A few roundings of the length: one part in 2^40 more covers them.
  return r * (1.0 + 0x1p-40) + std::numeric_limits<double>::denorm_min();
}

}  // namespace voxvis
