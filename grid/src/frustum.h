// frustum.h — the view pyramid in world space and in eye-voxel-local grid
// space, with the conservative tests the traversal needs.
//
// "Local" coordinates are grid coordinates minus the integer coordinates of
// the eye's voxel E, so voxel (i,j,k) of the local frame is the unit cube
// [i,i+1]x[j,j+1]x[k,k+1] and the eye lies in [0,1)^3. Keeping the numbers
// small there is what keeps far-away or offset worlds precise.
#pragma once

#include <array>
#include <cstdint>

#include "voxvis/scene.h"

namespace voxvis::detail {

/// Plane n·x + d, inside where >= 0. `n` is unit length.
struct Plane {
  Vec3 n{0.0};
  double d = 0.0;
  /// Largest value over the box [lo, hi].
  double box_max(const Vec3& lo, const Vec3& hi) const {
    return d + (n.x > 0 ? n.x * hi.x : n.x * lo.x) + (n.y > 0 ? n.y * hi.y : n.y * lo.y) +
           (n.z > 0 ? n.z * hi.z : n.z * lo.z);
  }
};

/// Camera basis and pyramid in world space.
struct WorldFrustum {
  Vec3 eye{0.0};
  Vec3 f{0.0}, r{0.0}, u{0.0};  ///< Unit forward, right, up.
  double tan_x = 0.0, tan_y = 0.0;
  double aspect = 1.0;            ///< Width / height of the image.
  double near = 0.0, far = 0.0;
  std::array<Plane, 6> planes{};  ///< left, right, bottom, top, near, far.
  /// The planes again, by field, for the AVX2 box test (four planes to an
  /// instruction); lanes 6 and 7 hold n = 0, d = 0, which cull nothing.
  /// make_world_frustum writes both forms.
  std::array<double, 8> plane_nx{}, plane_ny{}, plane_nz{}, plane_d{};

  /// Whether every number the occlusion tests derive from the camera is
  /// usable: a unit orthogonal basis, finite positive tangents and planes.
  /// A validated camera always gives one; a frame answers by frustum
  /// culling alone otherwise (FrameStats::frustum_fallback).
  bool sane() const;

  /// True unless the box [lo, hi] is certainly outside the frustum
  /// (separating plane test with a small margin: errs towards "inside").
  bool may_intersect_box(const Vec3& lo, const Vec3& hi) const;

  /// The frustum's tip: the four corners of the near rectangle, then the
  /// eye (every ray starts in their hull).
  std::array<Vec3, 5> tip() const {
    std::array<Vec3, 5> p;
    for (int k = 0; k < 4; ++k)
      p[static_cast<std::size_t>(k)] = eye + near * (f + ((k & 1) ? 1.0 : -1.0) * tan_x * r + ((k & 2) ? 1.0 : -1.0) * tan_y * u);
    p[4] = eye;
    return p;
  }
};

WorldFrustum make_world_frustum(const Camera& camera);

/// may_intersect_box's test, for the box [rlo, rhi] relative to the eye:
/// whether some plane's largest value over it is below `neg_margin`
/// (Plane::box_max, the same sums in the same order). The scalar reference,
/// and the AVX2 kernel (call only where cpu_has_avx2()); the tests compare
/// the two.
bool box_outside_scalar(const WorldFrustum& f, const Vec3& rlo, const Vec3& rhi, double neg_margin);
bool box_outside_avx2(const WorldFrustum& f, const Vec3& rlo, const Vec3& rhi, double neg_margin);

/// The pyramid (eye apex, cut at depth `far_eff`) in local grid coordinates.
struct LocalFrustum {
  Vec3 e{0.0};                 ///< Eye, local grid units, in [0,1)^3.
  std::array<Plane, 5> side{};  ///< Four sides through the eye, then the far cut.
  Vec3 depth_n{0.0};           ///< depth(x) = depth_n·(x - e), world units.
  std::array<Vec3, 5> verts{};  ///< Apex, then the four far corners.
  double near = 0.0;           ///< World units.
  double tol = 0.0;            ///< Margin for inside tests, local grid units.

  /// Conservative: false only if unit voxel [lo, lo+1] misses the pyramid.
  bool may_contain_voxel(const Vec3& lo) const {
    const Vec3 hi = lo + 1.0;
    for (const Plane& p : side) {
      if (p.box_max(lo, hi) < -tol) return false;
    }
    return true;
  }
  /// Smallest and largest depth (world units) over unit voxel [lo, lo+1].
  double depth_min(const Vec3& lo) const {
    const Vec3 a = lo - e;
    const Vec3& n = depth_n;
    return (n.x > 0 ? n.x * a.x : n.x * (a.x + 1.0)) + (n.y > 0 ? n.y * a.y : n.y * (a.y + 1.0)) +
           (n.z > 0 ? n.z * a.z : n.z * (a.z + 1.0));
  }
  double depth_max(const Vec3& lo) const {
    const Vec3 a = lo - e;
    const Vec3& n = depth_n;
    return (n.x > 0 ? n.x * (a.x + 1.0) : n.x * a.x) + (n.y > 0 ? n.y * (a.y + 1.0) : n.y * a.y) +
           (n.z > 0 ? n.z * (a.z + 1.0) : n.z * a.z);
  }
};

/// Builds the local pyramid. `eye_grid_frac` is the eye in local grid units,
/// `voxel_size` world units per voxel, `far_eff` the depth beyond which no
/// voxel of the grid lies (world units).
LocalFrustum make_local_frustum(const WorldFrustum& wf, const Vec3& eye_local,
                                const Vec3& voxel_size, double far_eff, double tol);

}  // namespace voxvis::detail
