// region_occlusion.h — occlusion for a region of eyes (docs/design.md,
// "Occlusion for regions"): what a static convex occluder hides from every
// eye of a box at once.
//
// The umbra. For a convex occluder K and a point x, the eyes e whose
// segment [e, x] meets K form a convex set (if [e1, x] meets K at y1 and
// [e2, x] at y2, the segment from a mix of e1 and e2 to x meets K at the
// matching mix of y1 and y2); for an eye e, the points x whose segment
// meets K form a convex set too (the cone beyond K). So every segment from
// an eye of the box E to a point of the box X meets K exactly when the 64
// segments between their corners do: X lies in K's umbra from E, and is
// hidden from every eye of E by K alone. That is exact for one occluder;
// occluders fuse by splitting X (its pieces may be hidden by different
// occluders, and X is hidden when each piece is).
//
// Strictness and the near plane. Segments are tested against K shrunk by a
// margin far above the arithmetic's rounding, so a segment found to meet it
// meets K's interior, strictly before its end: the point of X at the end is
// then never a first hit, ties included. Only the part of K no eye of E
// sees nearer than `near` counts (the reference clips at near): for a
// frustum region, K cut by the plane `near` beyond the eye box along the
// view direction; for an omnidirectional one, an occluder is used only when
// it lies at least `near` from the eye box along some axis (so at least
// near from every eye in distance and in a cube face's depth). The eye box
// therefore never meets an occluder used.
//
// Occluders are the scene's static boxes and balls and, with the buffer on,
// its static opaque voxels as boxes (opaque_boxes.h; inside the union of
// static objects, so they fuse abutting objects); dynamic objects and mesh
// triangles are left out, which only loosens the answer. They are found
// through a coarse grid of buckets along the segment between the boxes'
// centres, which every occluder hiding X must meet; missing one there
// would only loosen the answer too.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "voxvis/types.h"

namespace voxvis::detail {

/// A static convex occluder: a box, or a ball (radius > 0) about the box's
/// centre.
struct RegionOccluder {
  Vec3 lo{0.0}, hi{0.0};
  double radius = 0.0;
};

/// The scene's region occluders and their buckets (made when the scene is
/// built; static occluders never change).
struct RegionOccluders {
  std::vector<RegionOccluder> occ;
  Vec3 origin{0.0};
  double side = 1.0;          ///< A bucket's side, world units.
  glm::ivec3 res{0};          ///< Buckets per axis (0: no occluders).
  std::vector<std::uint32_t> offsets;  ///< Bucket b holds ids[offsets[b] .. offsets[b+1]).
  std::vector<std::uint32_t> ids;
  /// Whether the box [lo, hi] lies inside one box occluder (filled).
  bool inside_one(const Vec3& lo, const Vec3& hi) const;
};

/// Buckets per axis along the occluders' longest extent, at most: fewer
/// when there would be more than kRegionBucketsPerOccluder buckets an
/// occluder, or when finer buckets would list the occluders more than
/// kRegionEntriesPerOccluder times each on average, so that the lists'
/// size is known before the scene is built (region_occluder_bytes).
inline constexpr int kRegionBuckets = 32;
inline constexpr std::uint64_t kRegionBucketsPerOccluder = 2;
inline constexpr std::uint64_t kRegionEntriesPerOccluder = 8;
/// The most bytes the region occluders of `n` occluders take, their
/// buckets' offsets and lists included.
inline std::uint64_t region_occluder_bytes(std::uint64_t n) {
  return n * (sizeof(RegionOccluder) + 4 * (kRegionEntriesPerOccluder + 2 * kRegionBucketsPerOccluder)) + 4 * 64;
}

/// The most opaque-voxel boxes a scene of `bricks` bricks uses as region
/// occluders (the largest): one for every 8 bricks.
inline std::size_t region_box_occluders(std::size_t bricks) { return bricks / 8 + 16; }

/// Puts `occ` in `out` and lays out their buckets; returns how many bucket
/// entries fill_region_buckets will make (for the build's memory budget).
std::uint64_t place_region_occluders(std::vector<RegionOccluder> occ, RegionOccluders* out);
/// Fills the buckets laid out by place_region_occluders.
void fill_region_buckets(RegionOccluders* out);

/// The region a frame asks for, as the occlusion test needs it.
struct RegionEyes {
  Vec3 lo{0.0}, hi{0.0};   ///< The eye box.
  bool omnidirectional = false;
  Vec3 f{0.0};             ///< Unit view direction (frustum regions).
  double near = 0.0;
};

/// One frame's region occlusion tests. `mark` is a scratch array (one
/// entry per occluder, any contents) and `stamp` its counter, both the
/// caller's, so that a frame allocates nothing.
class RegionOcclusion {
 public:
  RegionOcclusion(const RegionOccluders& occ, const RegionEyes& eyes, std::vector<std::uint32_t>& mark,
                  std::uint32_t& stamp);

  /// Whether every point of the box [lo, hi] is hidden from every eye of
  /// the region by static occluders: by one occluder whole, or else, to
  /// `levels` levels, the halves (along the longest side) of the larger of
  /// the two boxes, the object's or the eyes', each so.
  bool hides(const Vec3& lo, const Vec3& hi, int levels) const;

 private:
  bool hides_from(const Vec3& elo, const Vec3& ehi, const Vec3& lo, const Vec3& hi, int levels) const;
  /// Whether one occluder hides [lo, hi] from every eye of [elo, ehi];
  /// `centre_met`: set when one meets the segment between the centres.
  bool hides_whole(const Vec3& elo, const Vec3& ehi, const Vec3& lo, const Vec3& hi, bool* centre_met) const;
  /// Whether occluder k can hide anything from the region (the near rule)
  /// and, if so, whether the segment between the centres `ce` and `cx`
  /// (which sets `centre_met`) and all 64 between the eyes' corners `e`
  /// and the object's `x` meet it.
  bool blocks(const RegionOccluder& k, const Vec3& ce, const Vec3& cx, const Vec3 (&e)[8], const Vec3 (&x)[8],
              double mag, bool* centre_met) const;
  /// Whether the segment [e, x] meets the box [lo, hi] cut by the near
  /// half-space (frustum regions).
  bool segment_meets_box(const Vec3& e, const Vec3& x, const Vec3& lo, const Vec3& hi) const;

  const RegionOccluders& occ_;
  RegionEyes eyes_;
  double eye_mag_ = 0.0;
  double near_plane_ = 0.0;  ///< Frustum regions: f·p must be at least this.
  std::vector<std::uint32_t>& mark_;
  std::uint32_t& stamp_;
  mutable Vec3 hull_lo_{0.0}, hull_hi_{0.0};  ///< The box around both boxes of the current test.
  mutable std::uint32_t hint_ = ~0u;          ///< The occluder that last hid a box, tried first.
};

}  // namespace voxvis::detail
