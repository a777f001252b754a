// occlusion_triangle.cpp — triangles as occluders of the occlusion buffer
// (OcclusionBuffer::render_triangle; the buffer's rules are in
// occlusion_buffer.h, the argument in docs/design.md, "Meshes").
//
// A triangle is planar and convex, so the buffer's two rules carry over as
// they do for a disc: the rays meeting the triangle beyond the near plane are
// those inside the three planes through the eye and its sides (clipped by the
// near plane first: then a fourth side), and the depth at which a ray meets
// it is the depth of its plane along the ray, whose reciprocal is affine in
// the pixel coordinates. A pixel is written only when all four of its corner
// rays meet the polygon (inner coverage), with the least reciprocal depth of
// those corners (the farthest first hit over the pixel).
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "numeric.h"
#include "occlusion_buffer.h"

namespace voxvis::detail {

namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

/// The least distance from point c to the lines of the sides of polygon
/// q[0..n), and the shortest side.
void side_distances(const Vec3* q, int n, const Vec3& c, double* h_min, double* side_min) {
  double h = std::numeric_limits<double>::infinity(), l = h;
  for (int k = 0; k < n; ++k) {
    const Vec3 e = q[(k + 1) % n] - q[k];
    const double len = glm::length(e);
    l = std::fmin(l, len);
    h = std::fmin(h, len > 0.0 ? glm::length(glm::cross(e, c - q[k])) / len : 0.0);
  }
  *h_min = h;
  *side_min = l;
}

/// The plane of triangle (s0, s1, s2) (vertices relative to the eye, scaled
/// to unit size): unit normal n facing away from the eye, the eye at distance
/// p from it, and how far (`err`) the computed plane may lie from the true
/// one near the triangle: its normal's direction is good to a few eps of
/// |e1| |e2| / |e1 x e2| (the sine of the triangle's angle at s0), over the
/// triangle's extent; its points to the vertices' own error (`vertex_err`).
bool triangle_plane(const Vec3& s0, const Vec3& s1, const Vec3& s2, double vertex_err, Vec3* n_out, double* p_out,
                    double* err_out) {
  const Vec3 e1 = s1 - s0, e2 = s2 - s0;
  Vec3 n = glm::cross(e1, e2);
  const double nl = glm::length(n);
  if (!(nl > 0.0) || !std::isfinite(nl)) return false;
  n /= nl;
  double p = glm::dot(n, s0);
  if (p < 0.0) n = -n, p = -p;
  const double extent = std::fmax(glm::length(e1), std::fmax(glm::length(e2), glm::length(e2 - e1)));
  const double err = 8.0 * kEps * (glm::length(e1) * glm::length(e2) / nl) * extent + vertex_err;
  // Seen edge-on (or the eye near its plane): the depths cannot be trusted,
  // and the triangle covers no pixel.
  if (!(p > 64.0 * err)) return false;
  *n_out = n;
  *p_out = p;
  *err_out = err;
  return true;
}

}  // namespace

bool OcclusionBuffer::render_triangle(const Vec3& a, const Vec3& b, const Vec3& c, double err) {
  if (!on()) return false;
  const double mag = max_abs(eye_) + std::fmax(max_abs(a), std::fmax(max_abs(b), max_abs(c)));
  // Relative to the eye: each coordinate good to an ulp of `mag`.
  const Vec3 v[3] = {a - eye_, b - eye_, c - eye_};
  const double m = std::fmax(max_abs(v[0]), std::fmax(max_abs(v[1]), max_abs(v[2])));
  if (!(m > 0.0) || !std::isfinite(m) || !std::isfinite(mag) || !(err >= 0.0)) return false;
  if (below_a_pixel(v, 3)) return false;
  // The plane, from the vertices scaled to unit size (no product of a world
  // of 1e-90 underflows).
  Vec3 n;
  double p = 0.0, plane_err = 0.0;
  if (!triangle_plane(v[0] / m, v[1] / m, v[2] / m, (4.0 * kEps * mag + 2.0 * err) / m, &n, &p, &plane_err))
    return false;

  // The part beyond the near plane (slightly beyond, so that a crossing
  // point rounded towards the eye still lies beyond it): at most four
  // vertices.
  const double zc = near_ * (1.0 + kDepthSlack) + 1e-9 * mag;
  Vec3 q[4];
  int nq = 0;
  auto push = [&](const Vec3& x) {
    if (nq == 0 || x != q[nq - 1]) q[nq++] = x;
  };
  for (int k = 0; k < 3; ++k) {
    const Vec3 &x = v[k], &y = v[(k + 1) % 3];
    const double zx = glm::dot(f_, x), zy = glm::dot(f_, y);
    if (zx >= zc) push(x);
    if ((zx >= zc) != (zy >= zc)) push(x + (y - x) * ((zc - zx) / (zy - zx)));
  }
  if (nq >= 2 && q[nq - 1] == q[0]) --nq;
  if (nq < 3) return false;
  // Reciprocal depth on the plane {n·x = p m}: (n / (p m))·d. Its relative
  // error is the plane's over the eye's distance from it.
  const PixelAffine plane = linear(n / (p * m));
  return fill_polygon(q, nq, &plane, 1, plane_err / p, mag, err);
}

bool OcclusionBuffer::render_quad(const Vec3 corners[4], double err, bool* raised) {
  *raised = false;
  if (!on()) return true;
  double mag = max_abs(eye_);
  Vec3 q[4];
  double m = 0.0;
  for (int k = 0; k < 4; ++k) {
    mag = std::fmax(mag, max_abs(eye_) + max_abs(corners[k]));
    q[k] = corners[k] - eye_;
    m = std::fmax(m, max_abs(q[k]));
  }
  if (!(m > 0.0) || !std::isfinite(m) || !std::isfinite(mag) || !(err >= 0.0)) return false;
  // Wholly beyond the near plane (a quad crossing it is drawn as its two
  // triangles: clipping a quad that is not quite planar as one polygon would
  // cut a chord across the bend).
  const double zc = near_ * (1.0 + kDepthSlack) + 1e-9 * mag;
  for (const Vec3& x : q)
    if (!(glm::dot(f_, x) >= zc)) return false;
  if (below_a_pixel(q, 4)) return true;  // Drawn: as nothing.
  // Its image convex, every turn the same way by more than the rounding of
  // the triple products (with the diagonal q1 q3, the two triangles' images
  // then make up the quad's): then every ray within the four sides' planes
  // through the eye meets one of the triangles.
  Vec3 s[4];
  for (int k = 0; k < 4; ++k) s[k] = q[k] / m;
  double turn[4];
  for (int k = 0; k < 4; ++k) turn[k] = glm::dot(s[k], glm::cross(s[(k + 1) % 4], s[(k + 2) % 4]));
  const double tiny = 64.0 * kEps + 4.0 * (4.0 * kEps * mag + 2.0 * err) / m;
  const bool ccw = turn[0] > tiny && turn[1] > tiny && turn[2] > tiny && turn[3] > tiny;
  const bool cw = turn[0] < -tiny && turn[1] < -tiny && turn[2] < -tiny && turn[3] < -tiny;
  if (!ccw && !cw) return false;
  // The depth of either triangle's plane bounds the ray's hit on the quad
  // from beyond when it is the farther of the two along that ray: the least
  // reciprocal of the two planes.
  const double vertex_err = (4.0 * kEps * mag + 2.0 * err) / m;
  Vec3 n0, n1;
  double p0 = 0.0, p1 = 0.0, e0 = 0.0, e1 = 0.0;
  if (!triangle_plane(s[0], s[1], s[3], vertex_err, &n0, &p0, &e0)) return false;
  if (!triangle_plane(s[1], s[2], s[3], vertex_err, &n1, &p1, &e1)) return false;
  const PixelAffine planes[2] = {linear(n0 / (p0 * m)), linear(n1 / (p1 * m))};
  *raised = fill_polygon(q, 4, planes, 2, std::fmax(e0 / p0, e1 / p1), mag, err);
  return true;
}

bool OcclusionBuffer::below_a_pixel(const Vec3* v, int n) const {
  // Its extent over its least depth, in pixels at the image's centre. Off
  // the centre an image is larger by up to 1 + tan^2, so a shape this test
  // drops may still cover a pixel there: dropping an occluder only costs
  // tightness. A triangle must hold a whole pixel's square to write it,
  // which one under 1.5 pixels across rarely does (a terrain of a million
  // triangles seen from above draws a third as many with this test).
  double zmin = std::numeric_limits<double>::infinity(), extent = 0.0;
  for (int k = 0; k < n; ++k) {
    zmin = least(zmin, glm::dot(f_, v[k]));
    for (int j = k + 1; j < n; ++j) extent = greatest(extent, max_abs(v[k] - v[j]));
  }
  if (!(zmin > near_)) return false;  // Crossing the near plane: left to the clipping.
  return 1.7320508075688772 * extent / zmin * (0.5 * w_ * inv_tan_x_) < 1.5;
}

bool OcclusionBuffer::ball_below_a_pixel(const Vec3& center, double radius) const {
  // below_a_pixel's test with the ball's extent and nearest depth, a part
  // in a billion short of its limit for the roundings of either.
  const double zmin = glm::dot(f_, center - eye_) - radius;
  if (!(zmin > near_)) return false;
  return 1.7320508075688772 * (2.0 * radius) / zmin * (0.5 * w_ * inv_tan_x_) < 1.5 * (1.0 - 1e-9);
}

bool OcclusionBuffer::fill_polygon(Vec3* q, int nq, const PixelAffine* planes, int np, double depth_err, double mag,
                                   double err) {
  // Shrunk towards its centroid by the rounding allowance: scaling by
  // (1 - t) moves side k inwards by t h_k (h_k: the centroid's distance to
  // it), so every side moves by at least delta. The allowance covers the
  // vertices' error and rounding, the clipping's and that of the planes
  // through the eye and a side (a few eps of R^2 / side for a side seen at
  // distance R). The shrunk vertices are convex combinations of the
  // polygon's, so they stay within the cone of rays meeting it.
  Vec3 centroid(0.0);
  double r = 0.0, zmin = std::numeric_limits<double>::infinity();
  for (int k = 0; k < nq; ++k) {
    centroid += q[k];
    r = greatest(r, glm::length(q[k]));
    zmin = least(zmin, glm::dot(f_, q[k]));
  }
  centroid /= static_cast<double>(nq);
  double h_min = 0.0, side_min = 0.0;
  side_distances(q, nq, centroid, &h_min, &side_min);
  if (!(side_min > 0.0)) return false;
  const double delta = 1e-9 * mag + 1e-9 * r + 2.0 * err + 8.0 * kEps * r * r / side_min;
  const double t = delta / h_min;
  if (!(t < 0.5)) return false;  // A sliver too thin to trust.
  double x0 = std::numeric_limits<double>::infinity(), x1 = -x0, y0 = x0, y1 = -x0;
  for (int k = 0; k < nq; ++k) {
    q[k] = centroid + (q[k] - centroid) * (1.0 - t);
    // The range only limits the pixels visited (the edges decide).
    const double iz = 1.0 / glm::dot(f_, q[k]);
    const double x = glm::dot(r_, q[k]) * iz * inv_tan_x_, y = glm::dot(u_, q[k]) * iz * inv_tan_y_;
    x0 = least(x0, x), x1 = greatest(x1, x), y0 = least(y0, y), y1 = greatest(y1, y);
  }
  ConvexOccluder occ;
  if (!std::isfinite(x0 + x1 + y0 + y1)) return false;
  if (!rect(x0, x1, y0, y1, &occ.i0, &occ.i1, &occ.j0, &occ.j1)) return false;
  if (!polygon_edges(q, nq, &occ)) return false;
  for (int k = 0; k < np; ++k) occ.plane[occ.planes++] = planes[k];
  occ.w_max = 1.0 / std::fmax(zmin, near_);
  occ.slack = 1.0 - kDepthSlack - 4.0 * depth_err - 1e-9 * mag * occ.w_max;
  if (!(occ.slack > 0.5)) return false;
  return fill(occ);
}

}  // namespace voxvis::detail
