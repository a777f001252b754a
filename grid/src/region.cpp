// region.cpp — see region.h.
#include "region.h"

#include <cmath>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "numeric.h"

namespace voxvis::detail {

RegionReach make_region_reach(const Camera& camera) {
  RegionReach r;
  r.on = is_region(camera);
  r.eye = camera.eye;
  r.half = camera.eye_extent;
  r.omnidirectional = camera.omnidirectional;
  r.horizon = camera.horizon_s;
  r.near = camera.near;
  r.far = camera.far;
  return r;
}

bool RegionReach::may_reach(const WorldFrustum& wf, const Vec3& lo, const Vec3& hi, double speed) const {
  // Up to 1e12 (coordinates and half extents) plus kMaxHorizon times a
  // speed: finite, and their squares too, for any finite speed below 1e140.
  const Vec3 grow = half + Vec3(speed * horizon);
  if (!finite3(grow)) return true;  // A reach beyond doubles reaches everything.
  const Vec3 glo = lo - grow, ghi = hi + grow;
  if (!omnidirectional) return wf.may_intersect_box(glo, ghi);
  // The distances from the eye to the grown box, nearest and farthest,
  // against [near, far], with a margin that grows with the magnitudes.
  const Vec3 a = glo - eye, b = ghi - eye;
  const double margin = 1e-9 * (1.0 + max_abs(a) + max_abs(b) + max_abs(eye));
  const Vec3 nearest = glm::max(glm::max(a, -b), Vec3(0.0));
  const Vec3 farthest = glm::max(glm::abs(a), glm::abs(b));
  return glm::length(nearest) <= far + margin && glm::length(farthest) >= near - margin;
}

}  // namespace voxvis::detail
