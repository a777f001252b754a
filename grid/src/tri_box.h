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
#include <cstdint>

#include <glm/geometric.hpp>

#include "voxvis/types.h"

namespace voxvis::detail {

/// Whether triangle (a, b, c) meets the box of centre `center` and half size
/// `half` (all closed), each separating test taken with a margin of 1e-12 of
/// the magnitudes involved, towards "meets".
inline bool triangle_meets_box(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& center, const Vec3& half) {
  // The inputs are finite: plain comparisons (maxsd) give what std::fmax
  // does, without its NaN handling's call (this test runs once per voxel a
  // mesh's triangle may touch).
  const auto max2 = [](double x, double y) { return x > y ? x : y; };
  const auto min2 = [](double x, double y) { return x < y ? x : y; };
  const Vec3 v[3] = {a - center, b - center, c - center};
  double vmax = 0.0;
  for (const Vec3& p : v) vmax = max2(vmax, max2(std::fabs(p.x), max2(std::fabs(p.y), std::fabs(p.z))));
  const double reach = vmax + max2(half.x, max2(half.y, half.z));
  // Separated along axis n when the triangle's projection [lo, hi] misses
  // the box's [-r, r].
  auto separated = [&](const Vec3& n) {
    const double p0 = glm::dot(v[0], n), p1 = glm::dot(v[1], n), p2 = glm::dot(v[2], n);
    const double r = half.x * std::fabs(n.x) + half.y * std::fabs(n.y) + half.z * std::fabs(n.z);
    const double lo = min2(p0, min2(p1, p2)), hi = max2(p0, max2(p1, p2));
    const double mag = std::fabs(n.x) + std::fabs(n.y) + std::fabs(n.z);
    const double eps = 1e-12 * mag * reach;
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

/// Calls mark(x, y, z) for every voxel of [lo, hi] (voxel i spans [i, i+1]
/// along each axis) that triangle (a, b, c) meets, each voxel grown by
/// `grow` (triangle_meets_box). A box of more than 64 voxels is tried a
/// block of 4^3 voxels at a time first, each block grown a little more than
/// its voxels, so that a voxel the voxel test keeps is never in a block the
/// block test drops: a large triangle costs the blocks it crosses, not the
/// voxels of its box. Returns the tests made.
template <class Mark>
std::uint64_t triangle_voxels(const Vec3& a, const Vec3& b, const Vec3& c, const glm::ivec3& lo, const glm::ivec3& hi,
                              const Vec3& grow, Mark&& mark) {
  std::uint64_t tests = 0;
  const auto voxels = [&](const glm::ivec3& v0, const glm::ivec3& v1) {
    for (int z = v0.z; z <= v1.z; ++z)
      for (int y = v0.y; y <= v1.y; ++y)
        for (int x = v0.x; x <= v1.x; ++x) {
          ++tests;
          if (triangle_meets_box(a, b, c, Vec3(x + 0.5, y + 0.5, z + 0.5), 0.5 + grow)) mark(x, y, z);
        }
  };
  const glm::ivec3 n = hi - lo + 1;
  if (static_cast<std::int64_t>(n.x) * n.y * n.z <= 64) {
    voxels(lo, hi);
    return tests;
  }
  // The block test's margin: far above the roundings of either test at
  // these magnitudes, far below a voxel.
  const auto size = [](const Vec3& p) { return std::fabs(p.x) + std::fabs(p.y) + std::fabs(p.z); };
  const double margin = 1e-9 * (size(a) + size(b) + size(c) + 4.0);
  const glm::ivec3 b0 = lo >> 2, b1 = hi >> 2;
  for (int bz = b0.z; bz <= b1.z; ++bz)
    for (int by = b0.y; by <= b1.y; ++by)
      for (int bx = b0.x; bx <= b1.x; ++bx) {
        const glm::ivec3 v0 = glm::max(glm::ivec3(bx, by, bz) << 2, lo);
        const glm::ivec3 v1 = glm::min((glm::ivec3(bx, by, bz) << 2) + 3, hi);
        const Vec3 centre = 0.5 * (Vec3(v0) + Vec3(v1 + 1));
        const Vec3 half = 0.5 * Vec3(v1 + 1 - v0) + grow + margin;
        ++tests;
        if (triangle_meets_box(a, b, c, centre, half)) voxels(v0, v1);
      }
  return tests;
}

}  // namespace voxvis::detail
