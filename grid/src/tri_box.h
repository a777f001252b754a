// tri_box.h — whether a triangle meets an axis-aligned box (closed sets), by
// the separating axis theorem (Akenine-Möller, "Fast 3D Triangle-Box
// Overlap Testing", 2001): two convex sets are disjoint exactly when some
// axis separates them, and for a triangle and a box the candidates are the
// box's three face normals, the triangle's normal and the nine cross
// products of their edges. The arithmetic is rounded, so callers grow the
// box by their rounding allowance (which is then much larger than this
// test's own few ulps): it answers "may meet", never "disjoint" wrongly.
#pragma once

#include <cmath>

#include <glm/geometric.hpp>

#include "voxvis/types.h"

namespace voxvis::detail {

/// Whether triangle (a, b, c) meets the box of centre `center` and half size
/// `half` (all closed), each separating test taken with a margin of 1e-12 of
/// the magnitudes involved, towards "meets".
inline bool triangle_meets_box(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& center, const Vec3& half) {
  const Vec3 v[3] = {a - center, b - center, c - center};
  // Separated along axis n when the triangle's projection [lo, hi] misses
  // the box's [-r, r].
  auto separated = [&](const Vec3& n) {
    const double p0 = glm::dot(v[0], n), p1 = glm::dot(v[1], n), p2 = glm::dot(v[2], n);
    const double r = half.x * std::fabs(n.x) + half.y * std::fabs(n.y) + half.z * std::fabs(n.z);
    const double lo = std::fmin(p0, std::fmin(p1, p2)), hi = std::fmax(p0, std::fmax(p1, p2));
    const double mag = std::fabs(n.x) + std::fabs(n.y) + std::fabs(n.z);
    double vmax = 0.0;
    for (const Vec3& p : v) vmax = std::fmax(vmax, std::fmax(std::fabs(p.x), std::fmax(std::fabs(p.y), std::fabs(p.z))));
    const double eps = 1e-12 * mag * (vmax + std::fmax(half.x, std::fmax(half.y, half.z)));
    return lo > r + eps || hi < -r - eps;
  };
  // The box's faces: the triangle's own box against the box.
  for (int k = 0; k < 3; ++k) {
    Vec3 n(0.0);
    n[k] = 1.0;
    if (separated(n)) return false;
  }
  const Vec3 e[3] = {v[1] - v[0], v[2] - v[1], v[0] - v[2]};
  if (separated(glm::cross(e[0], e[1]))) return false;  // The triangle's plane.
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) {
      Vec3 axis(0.0);
      axis[k] = 1.0;
      const Vec3 n = glm::cross(e[i], axis);
      if (n != Vec3(0.0) && separated(n)) return false;
    }
  return true;
}

}  // namespace voxvis::detail
