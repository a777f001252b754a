#include "frustum.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <glm/geometric.hpp>

#include "numeric.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define VOXVIS_FRUSTUM_AVX2 1
#include <immintrin.h>
#endif

namespace voxvis {

using detail::finite3;
using detail::max_abs;

namespace {

/// v scaled to unit length without overflow or underflow: any finite
/// non-zero vector, 1e308 or 5e-324 components included, has a direction.
/// Zero for the zero vector.
Vec3 unit(const Vec3& v) {
  const double m = max_abs(v);
  if (!(m > 0.0)) return Vec3(0.0);
  const Vec3 s = v / m;  // Largest component +-1: the length is in [1, sqrt(3)].
  return s / glm::length(s);
}

}  // namespace

Status validate_camera(const Camera& c) {
  if (!finite3(c.eye)) return Status::Error("eye", "must be three finite numbers");
  if (max_abs(c.eye) > kMaxCoordinate)
    return Status::Error("eye", "magnitude exceeds " + number_text(kMaxCoordinate));
  if (!finite3(c.dir)) return Status::Error("dir", "must be three finite numbers");
  if (!finite3(c.up)) return Status::Error("up", "must be three finite numbers");
  if (!(max_abs(c.dir) > 0.0)) return Status::Error("dir", "must not be the zero vector");
  if (!(max_abs(c.up) > 0.0)) return Status::Error("up", "must not be the zero vector");
  const double s = glm::length(glm::cross(unit(c.dir), unit(c.up)));
  if (!(s > 1e-9)) return Status::Error("up", "must not be parallel to dir");
  if (!std::isfinite(c.fov_y_deg) || !(c.fov_y_deg >= kMinFovDeg) || !(c.fov_y_deg < 180.0))
    return Status::Error("fov_y_deg", "must be in [" + number_text(kMinFovDeg) + ", 180) degrees, got " + number_text(c.fov_y_deg));
  if (!std::isfinite(c.aspect) || !(c.aspect >= 1.0 / kMaxAspect) || !(c.aspect <= kMaxAspect))
    return Status::Error("aspect", "must be in [0.001, 1000], got " + number_text(c.aspect));
  if (!std::isfinite(c.near) || !(c.near > 0.0))
    return Status::Error("near", "must be > 0, got " + number_text(c.near));
  if (!std::isfinite(c.far) || !(c.far > c.near))
    return Status::Error("far", "must be finite and > near, got " + number_text(c.far));
  if (!finite3(c.eye_extent)) return Status::Error("eye_extent", "must be three finite numbers");
  for (int a = 0; a < 3; ++a) {
    const double h = c.eye_extent[a];
    if (!(h >= 0.0)) return Status::Error("eye_extent", "half extents must be >= 0, got " + number_text(h));
    if (h > kMaxCoordinate) return Status::Error("eye_extent", "half extent exceeds " + number_text(kMaxCoordinate));
  }
  if (!std::isfinite(c.horizon_s) || !(c.horizon_s >= 0.0) || !(c.horizon_s <= kMaxHorizon))
    return Status::Error("horizon_s", "must be in [0, " + number_text(kMaxHorizon) + "] seconds, got " +
                                          number_text(c.horizon_s));
  return Status::Ok();
}

namespace detail {

WorldFrustum make_world_frustum(const Camera& c) {
  WorldFrustum w;
  w.eye = c.eye;
  w.f = unit(c.dir);
  w.r = unit(glm::cross(w.f, unit(c.up)));
  w.u = glm::cross(w.r, w.f);
  constexpr double kPi = 3.14159265358979323846;
  w.tan_y = std::tan(c.fov_y_deg * kPi / 360.0);
  w.tan_x = w.tan_y * c.aspect;
  w.aspect = c.aspect;
  w.near = c.near;
  w.far = c.far;
  // Planes relative to the eye: n·(p - eye) + d >= 0 inside.
  auto side = [](const Vec3& n) { return Plane{glm::normalize(n), 0.0}; };
  w.planes[0] = side(w.tan_x * w.f + w.r);
  w.planes[1] = side(w.tan_x * w.f - w.r);
  w.planes[2] = side(w.tan_y * w.f + w.u);
  w.planes[3] = side(w.tan_y * w.f - w.u);
  w.planes[4] = Plane{w.f, -c.near};
  w.planes[5] = Plane{-w.f, c.far};
  for (std::size_t k = 0; k < w.planes.size(); ++k) {
    w.plane_nx[k] = w.planes[k].n.x, w.plane_ny[k] = w.planes[k].n.y, w.plane_nz[k] = w.planes[k].n.z;
    w.plane_d[k] = w.planes[k].d;
  }
  return w;
}

bool box_outside_scalar(const WorldFrustum& f, const Vec3& rlo, const Vec3& rhi, double neg_margin) {
  for (const Plane& p : f.planes)
    if (p.box_max(rlo, rhi) < neg_margin) return true;
  return false;
}

#if VOXVIS_FRUSTUM_AVX2
namespace {
/// The largest value over the box of four planes' n·p + d, summed as
/// Plane::box_max sums it: ((d + x) + y) + z, each term n times the box's
/// side that n points to (hi where n > 0, else lo).
__attribute__((target("avx2"))) inline __m256d box_max4(const WorldFrustum& f, std::size_t k, const Vec3& rlo,
                                                        const Vec3& rhi) {
  const __m256d zero = _mm256_setzero_pd();
  const __m256d nx = _mm256_loadu_pd(f.plane_nx.data() + k), ny = _mm256_loadu_pd(f.plane_ny.data() + k);
  const __m256d nz = _mm256_loadu_pd(f.plane_nz.data() + k);
  const __m256d px = _mm256_blendv_pd(_mm256_set1_pd(rlo.x), _mm256_set1_pd(rhi.x), _mm256_cmp_pd(nx, zero, _CMP_GT_OQ));
  const __m256d py = _mm256_blendv_pd(_mm256_set1_pd(rlo.y), _mm256_set1_pd(rhi.y), _mm256_cmp_pd(ny, zero, _CMP_GT_OQ));
  const __m256d pz = _mm256_blendv_pd(_mm256_set1_pd(rlo.z), _mm256_set1_pd(rhi.z), _mm256_cmp_pd(nz, zero, _CMP_GT_OQ));
  __m256d v = _mm256_add_pd(_mm256_loadu_pd(f.plane_d.data() + k), _mm256_mul_pd(nx, px));
  v = _mm256_add_pd(v, _mm256_mul_pd(ny, py));
  return _mm256_add_pd(v, _mm256_mul_pd(nz, pz));
}
}  // namespace

__attribute__((target("avx2"))) bool box_outside_avx2(const WorldFrustum& f, const Vec3& rlo, const Vec3& rhi,
                                                      double neg_margin) {
  const __m256d m = _mm256_set1_pd(neg_margin);
  const __m256d below = _mm256_or_pd(_mm256_cmp_pd(box_max4(f, 0, rlo, rhi), m, _CMP_LT_OQ),
                                     _mm256_cmp_pd(box_max4(f, 4, rlo, rhi), m, _CMP_LT_OQ));
  return _mm256_movemask_pd(below) != 0;
}
#else
bool box_outside_avx2(const WorldFrustum& f, const Vec3& rlo, const Vec3& rhi, double neg_margin) {
  return box_outside_scalar(f, rlo, rhi, neg_margin);
}
#endif

bool WorldFrustum::sane() const {
  auto unit_len = [](const Vec3& v) {
    const double l = glm::dot(v, v);
    return finite3(v) && l > 0.99 && l < 1.01;
  };
  if (!unit_len(f) || !unit_len(r) || !unit_len(u)) return false;
  if (!(std::fabs(glm::dot(f, r)) < 1e-6) || !(std::fabs(glm::dot(f, u)) < 1e-6)) return false;
  if (!std::isfinite(tan_x) || !std::isfinite(tan_y) || !(tan_x > 0.0) || !(tan_y > 0.0)) return false;
  for (const Plane& p : planes)
    if (!finite3(p.n) || !std::isfinite(p.d)) return false;
  return true;
}

bool WorldFrustum::may_intersect_box(const Vec3& lo, const Vec3& hi) const {
  const Vec3 rlo = lo - eye;
  const Vec3 rhi = hi - eye;
  // Margin grows with the magnitudes involved so rounding never culls.
  const double scale = 1.0 + max_abs(rlo) + max_abs(rhi) + max_abs(eye);
  const double margin = 1e-9 * scale;
  return !(cpu_has_avx2() ? box_outside_avx2(*this, rlo, rhi, -margin) : box_outside_scalar(*this, rlo, rhi, -margin));
}

LocalFrustum make_local_frustum(const WorldFrustum& wf, const Vec3& e, const Vec3& vs,
                                double far_eff, double tol) {
  LocalFrustum lf;
  lf.e = e;
  lf.near = wf.near;
  lf.tol = tol;
  // A world plane through the eye, n·(p - eye) >= 0, becomes (n∘vs)·(x - e) >= 0
  // in grid units: the grid is an axis scaling of the world.
  auto through_eye = [&](const Vec3& nw) {
    Vec3 n = glm::normalize(nw * vs);
    return Plane{n, -glm::dot(n, e)};
  };
  for (int i = 0; i < 4; ++i) lf.side[static_cast<std::size_t>(i)] = through_eye(wf.planes[static_cast<std::size_t>(i)].n);
  lf.depth_n = wf.f * vs;
  {
    const double len = glm::length(lf.depth_n);
    const Vec3 n = -lf.depth_n / len;
    lf.side[4] = Plane{n, -glm::dot(n, e) + far_eff / len};
  }
  lf.verts[0] = e;
  int k = 1;
  for (double sx : {-1.0, 1.0}) {
    for (double sy : {-1.0, 1.0}) {
      const Vec3 w = far_eff * (wf.f + sx * wf.tan_x * wf.r + sy * wf.tan_y * wf.u);
      lf.verts[static_cast<std::size_t>(k++)] = e + w / vs;
    }
  }
  return lf;
}

}  // namespace detail
}  // namespace voxvis
