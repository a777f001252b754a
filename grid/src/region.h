// region.h — what a region of eyes, directions and times can reach
// (Camera::eye_extent, omnidirectional, horizon_s; docs/design.md,
// "Regions").
//
// The frusta with apex in the eye box E = eye + [-h, h] are the point
// frustum F translated by every d in [-h, h], so a point x lies in one of
// them exactly when x - d lies in F for some d: a box B meets their union
// exactly when B grown by h on every side meets F. Omnidirectional, F is the
// shell of points between near and far from the eye, and the same holds. A
// dynamic object reaches, within the horizon H, no farther than
// max_speed * H from where it is (a TBV no farther than that from its
// bound, which holds until its expiry, at or after the frame's time): its
// box grows by that too.
#pragma once

#include "frustum.h"

namespace voxvis::detail {

struct RegionReach {
  bool on = false;        ///< The camera asks for a region.
  Vec3 eye{0.0};
  Vec3 half{0.0};         ///< The eye box's half extents.
  bool omnidirectional = false;
  double horizon = 0.0;   ///< Seconds.
  double near = 0.0, far = 0.0;

  /// False only when no eye of the box, in any direction the region
  /// allows (`wf`: the camera's frustum, unless omnidirectional), at any
  /// time of the horizon, can have any point of the box [lo, hi] (of an
  /// object moving at up to `speed`) within its view.
  bool may_reach(const WorldFrustum& wf, const Vec3& lo, const Vec3& hi, double speed) const;
};

RegionReach make_region_reach(const Camera& camera);

}  // namespace voxvis::detail
