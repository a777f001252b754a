// region_occlusion.cpp — see region_occlusion.h.
#include "region_occlusion.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "numeric.h"
#include "voxvis/assert.h"

namespace voxvis::detail {

namespace {

/// Relative margin by which occluders are shrunk: far above the rounding of
/// a segment's parameter (a few ulps of the coordinates' magnitude).
constexpr double kRegionMargin = 1e-9;

/// The bucket coordinate of a world coordinate along axis a.
int bucket_of(const RegionOccluders& r, double v, int a) {
  return clamp_floor((v - r.origin[a]) / r.side, 0, r.res[a] - 1);
}

std::size_t bucket_index(const RegionOccluders& r, int x, int y, int z) {
  return static_cast<std::size_t>(x) +
         static_cast<std::size_t>(r.res.x) * (static_cast<std::size_t>(y) + static_cast<std::size_t>(r.res.y) * z);
}

/// Clips the segment [a, b] to the box [lo, hi]; false when it misses it.
bool clip_segment(Vec3* a, Vec3* b, const Vec3& lo, const Vec3& hi) {
  double t0 = 0.0, t1 = 1.0;
  const Vec3 d = *b - *a;
  for (int k = 0; k < 3; ++k) {
    if (d[k] == 0.0) {
      if ((*a)[k] < lo[k] || (*a)[k] > hi[k]) return false;
      continue;
    }
    double ta = (lo[k] - (*a)[k]) / d[k], tb = (hi[k] - (*a)[k]) / d[k];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::fmax(t0, ta);
    t1 = std::fmin(t1, tb);
    if (t0 > t1) return false;
  }
  const Vec3 a0 = *a;
  *a = a0 + t0 * d;
  *b = a0 + t1 * d;
  return true;
}

}  // namespace

namespace {

/// Calls visit(bucket) for every bucket occluder k's box meets.
template <class Visit>
void for_buckets(const RegionOccluders& r, const RegionOccluder& k, Visit visit) {
  const glm::ivec3 b0(bucket_of(r, k.lo.x, 0), bucket_of(r, k.lo.y, 1), bucket_of(r, k.lo.z, 2));
  const glm::ivec3 b1(bucket_of(r, k.hi.x, 0), bucket_of(r, k.hi.y, 1), bucket_of(r, k.hi.z, 2));
  for (int z = b0.z; z <= b1.z; ++z)
    for (int y = b0.y; y <= b1.y; ++y)
      for (int x = b0.x; x <= b1.x; ++x) visit(bucket_index(r, x, y, z));
}

}  // namespace

std::uint64_t place_region_occluders(std::vector<RegionOccluder> occ, RegionOccluders* out) {
  *out = RegionOccluders{};
  out->occ = std::move(occ);
  if (out->occ.empty()) return 0;
  Vec3 lo = out->occ[0].lo, hi = out->occ[0].hi;
  for (const RegionOccluder& k : out->occ) {
    lo = glm::min(lo, k.lo);
    hi = glm::max(hi, k.hi);
  }
  const Vec3 extent = hi - lo;
  const double longest = std::max(extent.x, std::max(extent.y, extent.z));
  out->origin = lo;
  for (int n = kRegionBuckets;; n /= 2) {
    out->side = longest > 0.0 && std::isfinite(longest) ? longest / n : 1.0;
    for (int a = 0; a < 3; ++a) out->res[a] = std::clamp(static_cast<int>(std::ceil(extent[a] / out->side)), 1, n);
    const auto buckets = static_cast<std::size_t>(out->res.x) * out->res.y * out->res.z;
    if (n > 1 && buckets > kRegionBucketsPerOccluder * out->occ.size()) continue;  // Too many: coarser.
    out->offsets.assign(buckets + 1, 0);
    for (const RegionOccluder& k : out->occ) for_buckets(*out, k, [&](std::size_t b) { ++out->offsets[b + 1]; });
    for (std::size_t b = 0; b < buckets; ++b) out->offsets[b + 1] += out->offsets[b];
    const std::uint64_t occluders = out->occ.size();
    if (n == 1 || (buckets <= kRegionBucketsPerOccluder * occluders &&
                   out->offsets[buckets] <= (kRegionEntriesPerOccluder - kRegionBucketsPerOccluder) * occluders))
      return out->offsets[buckets];
  }
}

bool RegionOccluders::inside_one(const Vec3& lo, const Vec3& hi) const {
  if (offsets.empty()) return false;
  const Vec3 c = 0.5 * (lo + hi);
  const std::size_t b = bucket_index(*this, bucket_of(*this, c.x, 0), bucket_of(*this, c.y, 1), bucket_of(*this, c.z, 2));
  for (std::uint32_t i = offsets[b]; i < offsets[b + 1]; ++i) {
    const RegionOccluder& k = occ[ids[i]];
    if (k.radius == 0.0 && glm::all(glm::lessThanEqual(k.lo, lo)) && glm::all(glm::lessThanEqual(hi, k.hi)))
      return true;
  }
  return false;
}

void fill_region_buckets(RegionOccluders* out) {
  if (out->offsets.empty()) return;
  out->ids.resize(out->offsets.back());
  std::vector<std::uint32_t> next(out->offsets.begin(), out->offsets.end() - 1);
  for (std::uint32_t i = 0; i < out->occ.size(); ++i)
    for_buckets(*out, out->occ[i], [&](std::size_t b) { out->ids[next[b]++] = i; });
}

RegionOcclusion::RegionOcclusion(const RegionOccluders& occ, const RegionEyes& eyes, std::vector<std::uint32_t>& mark,
                                 std::uint32_t& stamp)
    : occ_(occ), eyes_(eyes), mark_(mark), stamp_(stamp) {
  // Every occluder has its mark (the frame sizes the marks to the scene's).
  VOXVIS_ASSERT(mark_.size() >= occ_.occ.size());
  eye_mag_ = std::max(max_abs(eyes.lo), max_abs(eyes.hi));
  const Vec3 centre = 0.5 * (eyes.lo + eyes.hi), half = 0.5 * (eyes.hi - eyes.lo);
  near_plane_ = glm::dot(eyes.f, centre) + glm::dot(glm::abs(eyes.f), half) + eyes.near;
}

namespace {

/// Splits the box [lo, hi] in two along its longest side.
void halve(const Vec3& lo, const Vec3& hi, Vec3* h, Vec3* l) {
  const Vec3 extent = hi - lo;
  const int a = extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
  *h = hi;
  *l = lo;
  (*h)[a] = (*l)[a] = lo[a] + 0.5 * extent[a];
}

}  // namespace

bool RegionOcclusion::hides(const Vec3& lo, const Vec3& hi, int levels) const {
  if (occ_.occ.empty() || !finite3(lo) || !finite3(hi)) return false;
  return hides_from(eyes_.lo, eyes_.hi, lo, hi, levels);
}

bool RegionOcclusion::hides_from(const Vec3& elo, const Vec3& ehi, const Vec3& lo, const Vec3& hi, int levels) const {
  bool centre_met = false;
  if (hides_whole(elo, ehi, lo, hi, &centre_met)) return true;
  // No occluder even meets the segment between the centres: the middle of
  // the object shows from the middle of the eyes, and no halving hides it.
  if (levels <= 0 || !centre_met) return false;
  // Halve whichever box is the larger: the object's, or the eyes' (a wall
  // corner hides from each half of the eyes by another wall).
  const Vec3 ex = hi - lo, ee = ehi - elo;
  Vec3 h, l;
  if (std::max(ee.x, std::max(ee.y, ee.z)) > std::max(ex.x, std::max(ex.y, ex.z))) {
    halve(elo, ehi, &h, &l);
    return hides_from(elo, h, lo, hi, levels - 1) && hides_from(l, ehi, lo, hi, levels - 1);
  }
  halve(lo, hi, &h, &l);
  return hides_from(elo, ehi, lo, h, levels - 1) && hides_from(elo, ehi, l, hi, levels - 1);
}

bool RegionOcclusion::hides_whole(const Vec3& elo, const Vec3& ehi, const Vec3& lo, const Vec3& hi,
                                   bool* centre_met) const {
  Vec3 x[8], e[8];
  for (int c = 0; c < 8; ++c) {
    x[c] = Vec3((c & 1) ? hi.x : lo.x, (c & 2) ? hi.y : lo.y, (c & 4) ? hi.z : lo.z);
    e[c] = Vec3((c & 1) ? ehi.x : elo.x, (c & 2) ? ehi.y : elo.y, (c & 4) ? ehi.z : elo.z);
  }
  const double mag = eye_mag_ + std::max(max_abs(lo), max_abs(hi));
  // Every occluder that hides the box meets the segment between the two
  // boxes' centres: the buckets along it, the part within the occluders'.
  const Vec3 ce = 0.5 * (elo + ehi), cx = 0.5 * (lo + hi);
  hull_lo_ = glm::min(elo, lo);
  hull_hi_ = glm::max(ehi, hi);
  Vec3 a = ce, b = cx;
  const Vec3 bound_hi = occ_.origin + Vec3(occ_.res) * occ_.side;
  if (!clip_segment(&a, &b, occ_.origin, bound_hi)) return false;
  if (++stamp_ == 0) {
    std::fill(mark_.begin(), mark_.end(), 0u);
    stamp_ = 1;
  }
  // The occluder that hid the last box first: neighbours share walls.
  if (hint_ < occ_.occ.size()) {
    mark_[hint_] = stamp_;
    if (blocks(occ_.occ[hint_], ce, cx, e, x, mag, centre_met)) return true;
  }
  const double step = 0.5 * occ_.side;
  const int n = std::min(1 + static_cast<int>(std::ceil(glm::length(b - a) / step)), 8 * kRegionBuckets);
  std::size_t last = ~std::size_t{0};
  for (int s = 0; s <= n; ++s) {
    const Vec3 p = a + (static_cast<double>(s) / n) * (b - a);
    const std::size_t bucket =
        bucket_index(occ_, bucket_of(occ_, p.x, 0), bucket_of(occ_, p.y, 1), bucket_of(occ_, p.z, 2));
    if (bucket == last) continue;
    last = bucket;
    for (std::uint32_t i = occ_.offsets[bucket]; i < occ_.offsets[bucket + 1]; ++i) {
      const std::uint32_t id = occ_.ids[i];
      VOXVIS_ASSERT(id < occ_.occ.size());
      if (mark_[id] == stamp_) continue;
      mark_[id] = stamp_;
      if (blocks(occ_.occ[id], ce, cx, e, x, mag, centre_met)) {
        hint_ = id;
        return true;
      }
    }
  }
  return false;
}

bool RegionOcclusion::blocks(const RegionOccluder& k, const Vec3& ce, const Vec3& cx, const Vec3 (&e8)[8],
                             const Vec3 (&x)[8], double mag, bool* centre_met) const {
  // Within the boxes' hull, or it meets no segment between them.
  if (k.lo.x > hull_hi_.x || k.lo.y > hull_hi_.y || k.lo.z > hull_hi_.z || k.hi.x < hull_lo_.x ||
      k.hi.y < hull_lo_.y || k.hi.z < hull_lo_.z)
    return false;
  const double margin = kRegionMargin * (1.0 + mag + std::max(max_abs(k.lo), max_abs(k.hi)));
  if (eyes_.omnidirectional) {
    // At least near from the eye box along some axis (region_occlusion.h).
    bool apart = false;
    for (int a = 0; a < 3; ++a)
      apart = apart || k.lo[a] - eyes_.hi[a] >= eyes_.near + margin || eyes_.lo[a] - k.hi[a] >= eyes_.near + margin;
    if (!apart) return false;
  }
  // The segments from the centre, then from each eye corner to each corner:
  // first those joining corners of the same side (the beam's edges, which
  // pass an occluder too small first), then the rest.
  auto all_meet = [&](auto meets) {
    if (!meets(ce, cx)) return false;
    *centre_met = true;
    for (int c = 0; c < 8; ++c)
      if (!meets(e8[c], x[c])) return false;
    for (int c = 0; c < 8; ++c)
      for (int d = 0; d < 8; ++d)
        if (c != d && !meets(e8[c], x[d])) return false;
    return true;
  };
  if (k.radius > 0.0) {
    const Vec3 c = 0.5 * (k.lo + k.hi);
    const double r = k.radius - margin;
    if (!(r > 0.0)) return false;
    if (!eyes_.omnidirectional && glm::dot(eyes_.f, c) - r < near_plane_ + margin) return false;
    return all_meet([&](const Vec3& e, const Vec3& p) {
      const Vec3 d = p - e;
      const double dd = glm::dot(d, d);
      const double t = dd > 0.0 ? std::clamp(glm::dot(c - e, d) / dd, 0.0, 1.0) : 0.0;
      const Vec3 q = e + t * d - c;
      return glm::dot(q, q) <= r * r;
    });
  }
  const Vec3 lo = k.lo + Vec3(margin), hi = k.hi - Vec3(margin);
  if (lo.x > hi.x || lo.y > hi.y || lo.z > hi.z) return false;
  return all_meet([&](const Vec3& e, const Vec3& p) { return segment_meets_box(e, p, lo, hi); });
}

bool RegionOcclusion::segment_meets_box(const Vec3& e, const Vec3& x, const Vec3& lo, const Vec3& hi) const {
  double t0 = 0.0, t1 = 1.0;
  const Vec3 d = x - e;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0) {
      if (e[a] < lo[a] || e[a] > hi[a]) return false;
      continue;
    }
    double ta = (lo[a] - e[a]) / d[a], tb = (hi[a] - e[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = ta > t0 ? ta : t0;
    t1 = tb < t1 ? tb : t1;
    if (t0 > t1) return false;
  }
  if (eyes_.omnidirectional) return true;
  // Frustum regions: only where f·p >= near_plane_ (plus the margin).
  const double plane = near_plane_ + kRegionMargin * (1.0 + max_abs(e) + max_abs(x));
  const double fe = glm::dot(eyes_.f, e), fd = glm::dot(eyes_.f, d);
  if (fd == 0.0) return fe >= plane;
  const double t = (plane - fe) / fd;
  if (fd > 0.0) t0 = t > t0 ? t : t0;
  else t1 = t < t1 ? t : t1;
  return t0 <= t1;
}

}  // namespace voxvis::detail
