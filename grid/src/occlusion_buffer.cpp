// occlusion_buffer.cpp — see occlusion_buffer.h for the rules and why they
// are conservative.
#include "occlusion_buffer.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "numeric.h"
#include "occludee_corners.h"
#include "occlusion_tile.h"
#include "voxvis/assert.h"

namespace voxvis::detail {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr double kPi = 3.14159265358979323846;
/// Pixels across a disc's image (at its nearest depth, an overestimate)
/// under which it cannot cover a whole pixel: not drawn.
constexpr double kLeastDiscPixels = 1.4;

/// The vertices of the regular n-gon on the unit circle, angle 2 pi k / n:
/// the inscribed polygons of render_disc, computed once.
struct UnitCircle {
  double cos[24], sin[24];
};
const UnitCircle& unit_circle(int n) {
  static const auto make = [](int sides) {
    UnitCircle c{};
    for (int k = 0; k < sides; ++k) {
      const double th = 2.0 * kPi * k / sides;
      c.cos[k] = std::cos(th);
      c.sin[k] = std::sin(th);
    }
    return c;
  };
  static const UnitCircle c8 = make(8), c12 = make(12), c16 = make(16), c24 = make(24);
  return n == 8 ? c8 : n == 12 ? c12 : n == 16 ? c16 : c24;
}

/// The polygon inscribed in a disc `px_across` pixels wide: an orthonormal
/// pair in the plane of unit normal `normal`, and the sides — more for a
/// larger image, where a side's sagitta rho (1 - cos(pi / n)) would
/// otherwise cost pixels.
struct DiscFrame {
  Vec3 e1, e2;
  int sides;
  const UnitCircle* circle;
};
// Inlined: it runs for every disc drawn, and a call costs 1% of a frame.
[[gnu::always_inline]] inline DiscFrame disc_frame(const Vec3& normal, double px_across) {
  const Vec3 a = std::fabs(normal.x) < 0.6 ? Vec3(1, 0, 0) : Vec3(0, 1, 0);
  DiscFrame d;
  d.e1 = glm::normalize(glm::cross(normal, a));
  d.e2 = glm::cross(normal, d.e1);
  d.sides = px_across < 3.0 ? 8 : px_across < 6.0 ? 12 : px_across < 24.0 ? 16 : 24;
  d.circle = &unit_circle(d.sides);
  return d;
}

/// The smallest float not below d (d >= 0).
float round_up(double d) {
  if (!(d < static_cast<double>(std::numeric_limits<float>::max()))) return std::numeric_limits<float>::infinity();
  float f = static_cast<float>(d);
  if (static_cast<double>(f) < d) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

/// The largest of a tile's 32 bounds.
float tile_largest(const float* tile) {
  float lo, hi;
  least_and_largest(tile, kTilePixels, &lo, &hi);
  return hi;
}

}  // namespace

void OcclusionBuffer::begin(const WorldFrustum& wf, int width) {
  on_ = false;
  if (width <= 0) return;
  on_ = true;
  view_ = wf;
  eye_ = wf.eye;
  f_ = wf.f;
  r_ = wf.r;
  u_ = wf.u;
  tan_x_ = wf.tan_x;
  tan_y_ = wf.tan_y;
  inv_tan_x_ = 1.0 / tan_x_;
  inv_tan_y_ = 1.0 / tan_y_;
  near_ = wf.near;
  const int w = std::clamp(width, 1, kMaxSide);
  // Square pixels: W / aspect rows (the tangents' ratio, but computed from
  // the aspect, which validation bounds, so no tangent can make it NaN).
  const double hh = std::round(static_cast<double>(w) / wf.aspect);
  const int h = hh >= static_cast<double>(kMaxSide) ? kMaxSide : (hh >= 1.0 ? static_cast<int>(hh) : 1);
  if (w != w_ || h != h_ || px_.empty()) {
    w_ = w;
    h_ = h;
    tw_ = (w + kTileW - 1) / kTileW;
    th_ = (h + kTileH - 1) / kTileH;
    const std::size_t tiles = static_cast<std::size_t>(tw_) * static_cast<std::size_t>(th_);
    // Pixels past the image hold +inf: never written, they never lower a
    // tile's least bound (and make its largest +inf, which decides nothing).
    px_.assign(tiles * kTilePixels, std::numeric_limits<float>::infinity());
    for (int j = 0; j < h_; ++j)
      for (int i = 0; i < w_; ++i) px_[at(i, j)] = 0.0f;
    tile_min_.assign(tiles, 0.0f);
    tile_max_.resize(tiles);
    for (std::size_t t = 0; t < tiles; ++t) tile_max_[t] = tile_largest(px_.data() + t * kTilePixels);
    tile_written_.assign(tiles, 0);
    written_tiles_.clear();
    covered_tiles_ = 0;
  } else {
    clear_written();
  }
  // d(X, Y) = f + (2X/W - 1) tan_x r + (2Y/H - 1) tan_y u.
  d0_ = f_ - tan_x_ * r_ - tan_y_ * u_;
  dx_ = (2.0 * tan_x_ / w_) * r_;
  dy_ = (2.0 * tan_y_ / h_) * u_;
  written_ = 0;
}

PixelAffine OcclusionBuffer::linear(const Vec3& n) const {
  return PixelAffine{glm::dot(n, d0_), glm::dot(n, dx_), glm::dot(n, dy_)};
}

std::size_t OcclusionBuffer::at(int i, int j) const {
  VOXVIS_ASSERT(i >= 0 && i < w_ && j >= 0 && j < h_);
  const auto t = static_cast<std::size_t>(j / kTileH) * static_cast<std::size_t>(tw_) + static_cast<std::size_t>(i / kTileW);
  return t * kTilePixels + static_cast<std::size_t>((j % kTileH) * kTileW + i % kTileW);
}

void OcclusionBuffer::clear_written() {
  // Only pixels within the image are ever written; the others keep +inf.
  for (const std::uint32_t t : written_tiles_) {
    float* tile = px_.data() + static_cast<std::size_t>(t) * kTilePixels;
    const int I0 = static_cast<int>(t % static_cast<std::uint32_t>(tw_)) * kTileW;
    const int J0 = static_cast<int>(t / static_cast<std::uint32_t>(tw_)) * kTileH;
    tile_min_[t] = 0.0f;
    tile_written_[t] = 0;
    if (I0 + kTileW <= w_ && J0 + kTileH <= h_) {
      std::fill(tile, tile + kTilePixels, 0.0f);
      tile_max_[t] = 0.0f;
      continue;
    }
    const int ni = std::min(kTileW, w_ - I0), nj = std::min(kTileH, h_ - J0);
    for (int dj = 0; dj < nj; ++dj) std::fill(tile + dj * kTileW, tile + dj * kTileW + ni, 0.0f);
    tile_max_[t] = tile_largest(tile);
  }
  written_tiles_.clear();
  covered_tiles_ = 0;
}

float OcclusionBuffer::pixel(int i, int j) const {
  const float w = px_[at(i, j)];
  return w > 0.0f ? round_up(near_ / static_cast<double>(w)) : std::numeric_limits<float>::infinity();
}

bool OcclusionBuffer::rect(double x0, double x1, double y0, double y1, int* i0, int* i1, int* j0,
                           int* j1) const {
  // Image coordinate x maps to pixel column (x + 1) * W / 2; the pixel of
  // a column a is floor(a). Checked first (a NaN fails), then clamped to
  // the image, where a conversion to int is the floor (without a library
  // call for std::floor at -O3 on the baseline).
  const double sw = 0.5 * w_, sh = 0.5 * h_;
  const double a0 = (x0 + 1.0) * sw, a1 = (x1 + 1.0) * sw;
  const double b0 = (y0 + 1.0) * sh, b1 = (y1 + 1.0) * sh;
  if (!(a1 >= 0.0) || !(a0 < w_) || !(b1 >= 0.0) || !(b0 < h_)) return false;
  *i0 = a0 > 0.0 ? static_cast<int>(a0) : 0;
  *i1 = a1 < w_ - 1.0 ? static_cast<int>(a1) : w_ - 1;
  *j0 = b0 > 0.0 ? static_cast<int>(b0) : 0;
  *j1 = b1 < h_ - 1.0 ? static_cast<int>(b1) : h_ - 1;
  return true;
}

bool OcclusionBuffer::polygon_edges(const Vec3* v, int n, ConvexOccluder* occ) const {
  if (occ->edges + n > ConvexOccluder::kMaxEdges) return false;
  // Scaled to unit size first: the products of coordinates of a world
  // shrunk to 1e-90 would underflow.
  double m = 0.0;
  for (int k = 0; k < n; ++k) m = std::fmax(m, max_abs(v[k]));
  if (!(m > 0.0) || !std::isfinite(m)) return false;
  Vec3 s[24];
  Vec3 centre(0.0);
  for (int k = 0; k < n; ++k) {
    s[k] = v[k] / m;
    centre += s[k];
  }
  for (int k = 0; k < n; ++k) {
    // The plane through the eye and side (v_k, v_k+1); the polygon's rays
    // lie on its centre's side.
    Vec3 nrm = glm::cross(s[k], s[(k + 1) % n]);
    if (glm::dot(nrm, centre) < 0.0) nrm = -nrm;
    const double len = glm::length(nrm);
    // A side that defines no plane would leave the polygon unbounded there:
    // then nothing is written.
    if (!(len > 0.0) || !std::isfinite(len)) return false;
    occ->edge[occ->edges++] = linear(nrm / len);
  }
  return true;
}

double OcclusionBuffer::farthest_bound() const {
  if (!on()) return kInf;
  while (covered_tiles_ < tile_min_.size() && tile_min_[covered_tiles_] > 0.0f) ++covered_tiles_;
  if (covered_tiles_ < tile_min_.size()) return kInf;  // A tile without a bound yet.
  float m = std::numeric_limits<float>::max();
  for (std::size_t t = 0; t < tile_min_.size() && m > 0.0f; ++t) m = std::min(m, tile_min_[t]);
  return m > 0.0f ? near_ / static_cast<double>(m) * (1.0 + 4.0 * kEps) : kInf;
}

bool OcclusionBuffer::sphere_range(const Vec3& w, double radius, double* x0, double* x1, double* y0,
                                   double* y1) const {
  // Tangent slopes of the ball in the planes of x and y: the exact image
  // range of its outline.
  const double zc = glm::dot(f_, w);
  const double den = zc * zc - radius * radius;
  if (!(zc > radius) || !(den > 0.0)) return false;
  const double xc = glm::dot(r_, w), yc = glm::dot(u_, w);
  const double sx = radius * std::sqrt(std::fmax(0.0, xc * xc + den));
  const double sy = radius * std::sqrt(std::fmax(0.0, yc * yc + den));
  *x0 = (xc * zc - sx) / den / tan_x_;
  *x1 = (xc * zc + sx) / den / tan_x_;
  *y0 = (yc * zc - sy) / den / tan_y_;
  *y1 = (yc * zc + sy) / den / tan_y_;
  return std::isfinite(*x0) && std::isfinite(*x1) && std::isfinite(*y0) && std::isfinite(*y1);
}

bool OcclusionBuffer::render_disc(const Vec3& centre, const Vec3& normal, double rho, double w_max, double slack) {
  const double den = glm::dot(normal, centre);
  const double px_across = disc_pixels(centre, rho);
  if (!(px_across > kLeastDiscPixels) || !(den > 0.0)) return false;
  const DiscFrame d = disc_frame(normal, px_across);
  const Vec3 e1 = d.e1, e2 = d.e2;
  const int n = d.sides;
  const UnitCircle& circle = *d.circle;
  Vec3 v[24];
  double x0 = kInf, x1 = -kInf, y0 = kInf, y1 = -kInf;
  for (int k = 0; k < n; ++k) {
    v[k] = centre + rho * (circle.cos[k] * e1 + circle.sin[k] * e2);
    const double z = glm::dot(f_, v[k]);
    if (!(z > 0.0)) return false;
    // The range only limits the pixels visited (the edges decide): a
    // reciprocal's rounding is harmless here.
    const double iz = 1.0 / z;
    const double x = glm::dot(r_, v[k]) * iz * inv_tan_x_, y = glm::dot(u_, v[k]) * iz * inv_tan_y_;
    x0 = least(x0, x), x1 = greatest(x1, x), y0 = least(y0, y), y1 = greatest(y1, y);
  }
  ConvexOccluder occ;
  if (!std::isfinite(x0 + x1 + y0 + y1)) return false;
  if (!rect(x0, x1, y0, y1, &occ.i0, &occ.i1, &occ.j0, &occ.j1)) return false;
  if (!polygon_edges(v, n, &occ)) return false;
  return fill_disc(&occ, normal / den, w_max, slack);
}

double OcclusionBuffer::disc_pixels(const Vec3& centre, double rho) const {
  const double z_near = std::max(glm::dot(f_, centre) - rho, near_);
  return 2.0 * rho / z_near * (0.5 * w_ / tan_x_);
}

bool OcclusionBuffer::fill_disc(ConvexOccluder* occ, const Vec3& plane, double w_max, double slack) {
  // Reciprocal depth on the disc's plane {n·p = den}: (n / den)·d.
  occ->plane[0] = linear(plane);
  occ->planes = 1;
  occ->w_max = w_max;
  occ->slack = slack;
  return fill(*occ);
}

bool OcclusionBuffer::render_facing_disc(const Vec3& centre, double rho, double w_max, double slack, double x0,
                                         double x1, double y0, double y1) {
  const double len = glm::length(centre);
  const double px_across = disc_pixels(centre, rho);
  if (!(px_across > kLeastDiscPixels) || !(len > 0.0) || !std::isfinite(len)) return false;
  ConvexOccluder occ;
  if (!rect(x0, x1, y0, y1, &occ.i0, &occ.i1, &occ.j0, &occ.j1)) return false;
  const Vec3 normal = centre / len;
  const DiscFrame d = disc_frame(normal, px_across);
  const Vec3 e1 = d.e1, e2 = d.e2;
  const int n = d.sides;
  const UnitCircle& circle = *d.circle;
  // Vertex k is c + p u_k, u_k = cos_k e1 + sin_k e2 (scaled to unit size,
  // so that no product underflows). The plane through the eye and side
  // (k, k+1) has the normal c x (c + p u_k+1) ... = p c x (u_k+1 - u_k) +
  // p^2 u_k x u_k+1 = p (dcos A + dsin B) + p^2 sin(2 pi / n) N, with
  // A = c x e1, B = c x e2, N = e1 x e2 the disc's normal: positive at the
  // centre's ray (c . N > 0), so every edge is >= 0 inside. A and B are
  // perpendicular to c, as are the sides: each normal is good to a few eps
  // of its own length, and the edge functions, linear in it, are sums of
  // three functions taken once.
  const double m = max_abs(centre) + rho;
  const Vec3 c = centre / m;
  const double p = rho / m;
  const double s = std::sin(2.0 * kPi / n);
  const PixelAffine la = linear(p * glm::cross(c, e1)), lb = linear(p * glm::cross(c, e2));
  const PixelAffine ln = linear((p * p * s) * normal);
  for (int k = 0; k < n; ++k) {
    const int k1 = k + 1 == n ? 0 : k + 1;
    const double dc = circle.cos[k1] - circle.cos[k], ds = circle.sin[k1] - circle.sin[k];
    const PixelAffine e{dc * la.c + ds * lb.c + ln.c, dc * la.gx + ds * lb.gx + ln.gx, dc * la.gy + ds * lb.gy + ln.gy};
    // A side that defines no plane would leave the polygon unbounded there.
    const double mag = std::fabs(e.c) + std::fabs(e.gx) + std::fabs(e.gy);
    if (!(mag > 0.0) || !std::isfinite(mag)) return false;
    occ.edge[occ.edges++] = e;
  }
  return fill_disc(&occ, normal / len, w_max, slack);
}

bool OcclusionBuffer::render_sphere(const Vec3& c, double radius) {
  if (!on()) return false;
  const Vec3 w = c - eye_;
  const double mag = max_abs(eye_) + max_abs(c) + radius;
  const double zc = glm::dot(f_, w);
  const double ww = glm::dot(w, w);
  // Only the part beyond the near plane occludes (the ray caster clips
  // objects there); a ball around the eye writes nothing.
  if (!(zc + radius > near_) || !(ww > radius * radius)) return false;
  // Shrunk, so that a rounding can only drop a pixel.
  const double delta = 1e-9 * mag + 16.0 * kEps * ww / radius;
  const double rs = radius - delta;
  if (!(rs > 0.5 * radius)) return false;
  const double w_max = 1.0 / std::fmax(zc - rs, near_);
  const double slack = 1.0 - kDepthSlack - 1e-9 * mag * w_max;
  // The occluders are polygons inscribed in discs inside the ball.
  if (zc - rs < near_ * (1.0 + kDepthSlack) + 1e-9 * mag) {
    // The near plane cuts the ball: the disc it cuts, at depth `near` (every
    // ray through it is inside the ball there).
    const double s = zc - near_;
    const double q2 = rs * rs - s * s;
    return q2 > 0.0 && render_disc(w - s * f_, f_, std::sqrt(q2), w_max, slack);
  }
  // The disc bounded by the ball's outline (its rim, the circle of tangent
  // points from the eye), covering all the outline; then, for a ball a few
  // pixels wide, a disc across it nearer the eye (a plane 1/sqrt(2) of the
  // radius before the centre: radius r/sqrt(2), about half the outline), so
  // that what lies just behind the ball's front is hidden too.
  // Both discs lie in the shrunk ball: its image range bounds the pixels
  // they may cover (the inner disc's own, when that ball is beyond the eye's
  // plane, bounds its pixels more closely).
  double x0, x1, y0, y1;
  if (!sphere_range(w, rs, &x0, &x1, &y0, &y1)) return false;
  const double k = rs * rs / ww;
  const double len = std::sqrt(ww);
  const Vec3 axis = w / len;
  bool any = render_facing_disc(w * (1.0 - k), rs * std::sqrt(1.0 - k), w_max, slack, x0, x1, y0, y1);
  const double inner = rs * 0.70710678118654752;
  if (rs / (zc - rs) * (0.5 * w_ / tan_x_) >= 4.0) {
    const Vec3 ci = w - inner * axis;
    double a0, a1, b0, b1;
    if (sphere_range(ci, inner, &a0, &a1, &b0, &b1)) x0 = a0, x1 = a1, y0 = b0, y1 = b1;
    any |= render_facing_disc(ci, inner, w_max, slack, x0, x1, y0, y1);
  }
  return any;
}

bool OcclusionBuffer::render_box(const Vec3& lo, const Vec3& hi) {
  if (!on()) return false;
  static const Vec3 kAxes[3] = {Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
  const double mag = max_abs(eye_) + max_abs(lo) + max_abs(hi);
  const double delta = 1e-9 * mag;
  const Vec3 L = lo + delta - eye_, H = hi - delta - eye_;
  const Vec3 gl = lo - delta - eye_, gh = hi + delta - eye_;
  return render_box_frame(kAxes, L, H, gl, gh, mag);
}

bool OcclusionBuffer::render_oriented_box(const Vec3& center, const Vec3 axes[3], const Vec3& half, double err) {
  if (!on()) return false;
  const Vec3 c = center - eye_;
  const double mag = max_abs(eye_) + max_abs(center) + std::fmax(half.x, std::fmax(half.y, half.z));
  // The box's coordinates relative to the eye along its axes, each good to
  // a few eps of mag (and the axes' own rounding, far below the shrink).
  const double delta = 1e-9 * mag + err;
  Vec3 L, H, gl, gh;
  for (int a = 0; a < 3; ++a) {
    const double m = glm::dot(axes[a], c);
    L[a] = m - half[a] + delta, H[a] = m + half[a] - delta;
    gl[a] = m - half[a] - delta, gh[a] = m + half[a] + delta;
  }
  return render_box_frame(axes, L, H, gl, gh, mag);
}

bool OcclusionBuffer::render_box_frame(const Vec3 axes[3], const Vec3& L, const Vec3& H, const Vec3& gl, const Vec3& gh,
                                       double mag) {
  if (!(L.x < H.x && L.y < H.y && L.z < H.z)) return false;  // Too thin to trust.
  // The view's directions in the box's frame (exact for the world's axes).
  const Vec3 f(glm::dot(f_, axes[0]), glm::dot(f_, axes[1]), glm::dot(f_, axes[2]));
  const Vec3 rr(glm::dot(r_, axes[0]), glm::dot(r_, axes[1]), glm::dot(r_, axes[2]));
  const Vec3 uu(glm::dot(u_, axes[0]), glm::dot(u_, axes[1]), glm::dot(u_, axes[2]));
  const Vec3 size = H - L;
  double zmin = glm::dot(f, L);
  for (int a = 0; a < 3; ++a) zmin += least(0.0, f[a] * size[a]);
  double zmax = glm::dot(f, L);
  for (int a = 0; a < 3; ++a) zmax += greatest(0.0, f[a] * size[a]);
  // Only the part beyond the near plane occludes (the ray caster clips
  // objects there); a box around the eye writes nothing.
  if (!(zmax > near_)) return false;
  if (gl.x <= 0.0 && gh.x >= 0.0 && gl.y <= 0.0 && gh.y >= 0.0 && gl.z <= 0.0 && gh.z >= 0.0) return false;
  const bool clip = zmin < near_ + 1e-9 * mag;
  // Image range of the part beyond the near plane: its corners there and
  // where its edges cross the plane.
  double x0 = kInf, x1 = -kInf, y0 = kInf, y1 = -kInf;
  auto take = [&](const Vec3& p) {
    const double z = glm::dot(f, p);
    const double iz = 1.0 / z;  // The range only limits the pixels visited.
    const double x = glm::dot(rr, p) * iz * inv_tan_x_, y = glm::dot(uu, p) * iz * inv_tan_y_;
    x0 = least(x0, x), x1 = greatest(x1, x);
    y0 = least(y0, y), y1 = greatest(y1, y);
  };
  for (int k = 0; k < 8; ++k) {
    const Vec3 p{(k & 1) ? H.x : L.x, (k & 2) ? H.y : L.y, (k & 4) ? H.z : L.z};
    const double z = glm::dot(f, p);
    if (z >= near_) {
      take(p);
    } else {
      for (int bit = 1; bit < 8; bit <<= 1) {
        const int k2 = k ^ bit;
        const Vec3 q{(k2 & 1) ? H.x : L.x, (k2 & 2) ? H.y : L.y, (k2 & 4) ? H.z : L.z};
        const double zq = glm::dot(f, q);
        if (zq > near_) take(p + (q - p) * ((near_ - z) / (zq - z)));
      }
    }
  }
  if (clip) {
    // A crossing point rounded to just before the plane: widen a little
    // (the range only limits the pixels visited; the edges decide).
    const double wx = 1e-9 * (1.0 + std::fmax(std::fabs(x0), std::fabs(x1)));
    const double wy = 1e-9 * (1.0 + std::fmax(std::fabs(y0), std::fabs(y1)));
    x0 -= wx, x1 += wx, y0 -= wy, y1 += wy;
  }
  ConvexOccluder occ;
  if (!(x0 <= x1) || !(y0 <= y1) || !std::isfinite(x0 + x1 + y0 + y1)) return false;
  if (!rect(x0, x1, y0, y1, &occ.i0, &occ.i1, &occ.j0, &occ.j1)) return false;
  // The slab test in reciprocal depths. Along an axis where the eye lies
  // below the slab the ray enters at the plane L (reciprocal depth d_a/L_a,
  // positive for a ray heading in) and leaves at H; above it, the reverse;
  // within it, the ray only leaves, at H (d_a > 0) or L (d_a < 0). The ray
  // meets the box when every entry is ahead of it and the last entry comes
  // no later than the first exit: every entry's reciprocal is at least
  // every exit's. Each is linear in d, so each condition is an edge
  // function; the entry depth is the largest entry, so its reciprocal is
  // the least entry reciprocal: the planes.
  PixelAffine entry[3], exits[6];
  int own_exit[3];  // The exit of each entry's own axis.
  int n_in = 0, n_out = 0;
  double least_face = kInf;
  const double exit_cap = 1.0 / (near_ * (1.0 + kDepthSlack) + 1e-9 * mag);
  for (int a = 0; a < 3; ++a) {
    const Vec3& e = axes[a];  // Its coordinate along the axis is e·(p - eye).
    if (L[a] > 0.0 || H[a] < 0.0) {
      const double P = L[a] > 0.0 ? L[a] : H[a], Q = L[a] > 0.0 ? H[a] : L[a];
      own_exit[n_in] = n_out;
      entry[n_in++] = linear(e / P);
      exits[n_out++] = linear(e / Q);
      least_face = least(least_face, std::fabs(P));
    } else {
      // With the eye on a face's plane a ray heading out through it leaves
      // at once: it must not head out (d_a <= 0 at H = 0, d_a >= 0 at L = 0).
      if (H[a] > 0.0) {
        exits[n_out++] = linear(e / H[a]);
      } else {
        occ.edge[occ.edges++] = linear(-e);
      }
      if (L[a] < 0.0) {
        exits[n_out++] = linear(e / L[a]);
      } else {
        occ.edge[occ.edges++] = linear(e);
      }
    }
  }
  if (n_in == 0) return false;  // The eye is in the box (the test above, with rounding).
  for (int k = 0; k < n_in; ++k) {
    occ.edge[occ.edges++] = entry[k];  // Ahead of the eye.
    for (int x = 0; x < n_out; ++x) {
      // The pair of one axis holds whenever the entry is ahead.
      if (x == own_exit[k]) continue;
      occ.edge[occ.edges++] = PixelAffine{entry[k].c - exits[x].c, entry[k].gx - exits[x].gx, entry[k].gy - exits[x].gy};
    }
    occ.plane[occ.planes++] = entry[k];
  }
  if (clip) {
    // The part beyond the near plane: the ray must leave the box beyond it,
    // and is first inside the box at max(entry, near).
    for (int x = 0; x < n_out; ++x)
      occ.edge[occ.edges++] = PixelAffine{exit_cap - exits[x].c, -exits[x].gx, -exits[x].gy};
    occ.w_cap = 1.0 / near_;
  }
  occ.w_max = 1.0 / std::fmax(zmin, near_);
  // A face's coordinate is good to eps * mag: its plane's depth along a ray
  // to eps * mag / |face| of it.
  occ.slack = 1.0 - kDepthSlack - 4.0 * kEps * mag / least_face - 1e-9 * mag * occ.w_max;
  return fill(occ);
}

bool OcclusionBuffer::rect_hidden(int i0, int i1, int j0, int j1, double w, OccludeeDepth* depth) const {
  // A tile whose least bound is above w hides the rectangle's part in it
  // and is passed over: most tiles of an occludee hidden behind a wall. For
  // a float m, (double) m > w exactly when m > w_down, the largest float not
  // above w, so the scan compares floats; the tiles it stops at are
  // decided by tile_hides.
  const float w_down = float_at_or_below(w);
  const int tx0 = i0 / kTileW, tx1 = i1 / kTileW;
  for (int ty = j0 / kTileH; ty <= j1 / kTileH; ++ty) {
    const std::size_t row = static_cast<std::size_t>(ty) * static_cast<std::size_t>(tw_);
    const float* mins = tile_min_.data() + row;
    for (int tx = tx0; tx <= tx1; ++tx) {
      if (mins[tx] > w_down) continue;
      if (!tile_hides(row + static_cast<std::size_t>(tx), tx * kTileW, ty * kTileH, i0, i1, j0, j1, w, depth))
        return false;
    }
  }
  return true;
}

bool OcclusionBuffer::tile_hides(std::size_t t, int I0, int J0, int i0, int i1, int j0, int j1, double w,
                                 OccludeeDepth* depth) const {
  const int pi0 = std::max(i0, I0), pi1 = std::min(i1, I0 + kTileW - 1);
  const int pj0 = std::max(j0, J0), pj1 = std::min(j1, J0 + kTileH - 1);
  const float* tile = px_.data() + t * kTilePixels;
  if (!depth) {
    // Every pixel of the tile at or below the occludee's bound: one of
    // them lies in the rectangle, and does not hide it.
    if (!(static_cast<double>(tile_max_[t]) > w)) return false;
    // Pixels are compared in float against w rounded up: a pixel above that
    // is above w.
    const float wf = round_up(w);
    const int c0 = pi0 - I0, c1 = pi1 - I0, r0 = pj0 - J0, r1 = pj1 - J0;
    const bool avx2 = kernel == BufferKernel::Auto && cpu_has_avx2();
    return avx2 ? tile_above_avx2(tile, c0, c1, r0, r1, wf) : tile_above_scalar(tile, c0, c1, r0, r1, wf);
  }
  // With the occludee's planes: its largest reciprocal depth over the
  // tile's part of the rectangle, then over each pixel that cannot decide.
  entry_planes(depth);
  const double wt = depth->bound(w, pi0, pi1, pj0, pj1);
  if (static_cast<double>(tile_min_[t]) > wt) return true;
  for (int j = pj0; j <= pj1; ++j) {
    for (int i = pi0; i <= pi1; ++i) {
      const double v = static_cast<double>(tile[(j - J0) * kTileW + (i - I0)]);
      if (!(v > wt) && !(v > depth->bound(wt, i, i, j, j))) return false;
    }
  }
  return true;
}

void OcclusionBuffer::entry_planes(OccludeeDepth* depth) const {
  if (depth->planes >= 0) return;
  depth->planes = 0;
  // Along an axis where the eye lies outside the box's slab, a ray meeting
  // the box does so at or beyond the slab's near plane {p_a = P}: at depth
  // >= P / d_a, so at reciprocal depth <= near d_a / P, an affine function
  // of the pixel coordinates. Each plane is moved towards the eye by twice
  // the positions' allowance; a plane that would reach the eye is left out.
  const Vec3& rel = depth->rel;
  const Vec3& size = depth->size;
  const double tol = depth->tol;
  for (int a = 0; a < 3; ++a) {
    double P;
    if (rel[a] - 2.0 * tol > 0.0) {
      P = rel[a] - 2.0 * tol;
    } else if (rel[a] + size[a] + 2.0 * tol < 0.0) {
      P = rel[a] + size[a] + 2.0 * tol;
    } else {
      continue;
    }
    const double k = near_ / P;  // linear(k e_a), written out.
    depth->add(PixelAffine{k * d0_[a], k * dx_[a], k * dy_[a]}, w_, h_);
  }
}

bool OcclusionBuffer::hides(const Vec3& rel, const Vec3& size, double tol, bool fine) const {
  if (!on() || written_ == 0) return false;
  tol += 4.0 * kEps * (max_abs(rel) + max_abs(size));
  double zmin = glm::dot(f_, rel);
  for (int a = 0; a < 3; ++a) zmin += std::min(0.0, f_[a] * size[a]);
  zmin -= 2.0 * tol;
  if (!(zmin > near_)) return false;  // Crossing the near plane or behind the eye.
  const double wmin = near_ / zmin;
  OccludeeDepth depth{rel, size, tol};
  OccludeeDepth* planes = fine ? &depth : nullptr;
  const double X0 = glm::dot(r_, rel), Y0 = glm::dot(u_, rel), Z0 = glm::dot(f_, rel);
  {
    // Quick rejection: the pixel of the box's centre must hold a larger
    // bound than the box's over that pixel (a necessary condition only, so
    // any rounding is harmless).
    const Vec3 ch = 0.5 * size;
    const double izc = 1.0 / (Z0 + glm::dot(f_, ch));
    const double xi = ((X0 + glm::dot(r_, ch)) * izc * inv_tan_x_ + 1.0) * 0.5 * w_;
    const double yi = ((Y0 + glm::dot(u_, ch)) * izc * inv_tan_y_ + 1.0) * 0.5 * h_;
    if (xi >= 0.0 && xi < w_ && yi >= 0.0 && yi < h_) {
      const int i = static_cast<int>(xi), j = static_cast<int>(yi);
      const double v = static_cast<double>(px_[at(i, j)]);
      if (!(v > wmin)) {
        if (!planes) return false;
        entry_planes(planes);
        if (!(v > planes->bound(wmin, i, i, j, j))) return false;
      }
    }
  }
  // The box's X, Y and Z ranges bound its corners' slopes X/Z and Y/Z:
  // with Z in [zlo, zhi], zlo > 0, X/Z lies in [Xlo / (Xlo < 0 ? zlo : zhi),
  // Xhi / (Xhi > 0 ? zlo : zhi)] (a superset of the corners' hull).
  BoxCorners box;
  box.X0 = X0, box.Y0 = Y0, box.Z0 = Z0;
  double xlo = X0, xhi = X0, ylo = Y0, yhi = Y0, zlo = Z0, zhi = Z0;
  for (int a = 0; a < 3; ++a) {
    const double ex = box.ex[a] = r_[a] * size[a], ey = box.ey[a] = u_[a] * size[a], ez = box.ez[a] = f_[a] * size[a];
    (ex < 0.0 ? xlo : xhi) += ex;
    (ey < 0.0 ? ylo : yhi) += ey;
    (ez < 0.0 ? zlo : zhi) += ez;
  }
  const double izlo = 1.0 / zlo, izhi = 1.0 / zhi;
  double x0 = xlo * (xlo < 0.0 ? izlo : izhi), x1 = xhi * (xhi > 0.0 ? izlo : izhi);
  double y0 = ylo * (ylo < 0.0 ? izlo : izhi), y1 = yhi * (yhi > 0.0 ? izlo : izhi);
  if (fine) {
    // The corners' own slopes (all beyond the near plane): the hull of the
    // box's projection, where the superset above can reach far beyond it (a
    // long box seen at a slant: its far top corner's height over its
    // nearest depth). Four corners to an instruction where the CPU can.
    if (kernel == BufferKernel::Auto && cpu_has_avx2()) {
      corner_slopes_avx2(box, &x0, &x1, &y0, &y1);
    } else {
      corner_slopes_scalar(box, &x0, &x1, &y0, &y1);
    }
  }
  // A corner's position is good to tol (world units) in X, Y and Z: its
  // slope X/Z moves by at most tol (1 + |X/Z|) / Z. Plus a millionth of a
  // pixel, so that a point on a pixel boundary counts for both pixels.
  // Multiplications by reciprocals below: each adds a rounding or two to a
  // slope, a billionth of the millionth of a pixel allowed for where the
  // slope lies in the image (and nothing that matters beyond it).
  const double izmin = 1.0 / zmin;
  const double ms = 2.0 * tol * (1.0 + std::max(std::fabs(x0), std::fabs(x1))) * izmin;
  const double mt = 2.0 * tol * (1.0 + std::max(std::fabs(y0), std::fabs(y1))) * izmin;
  const double mx = ms * inv_tan_x_ + 2e-6 / w_, my = mt * inv_tan_y_ + 2e-6 / h_;
  int i0, i1, j0, j1;
  if (!rect(x0 * inv_tan_x_ - mx, x1 * inv_tan_x_ + mx, y0 * inv_tan_y_ - my, y1 * inv_tan_y_ + my, &i0, &i1, &j0,
            &j1))
    return false;
  return rect_hidden(i0, i1, j0, j1, wmin, planes);
}

bool OcclusionBuffer::hides_world(const Vec3& lo, const Vec3& hi, bool fine) const {
  if (!on() || written_ == 0) return false;
  const double tol = 1e-12 * (max_abs(lo) + max_abs(hi) + max_abs(eye_) + 1.0);
  return hides(lo - eye_, hi - lo, tol, fine);
}

bool OcclusionBuffer::hides_world_split(const Vec3& lo, const Vec3& hi, int levels) const {
  // Off (view_ is then another frame's, or none), or empty: nothing hidden.
  if (!on() || written_ == 0) return false;
  // A piece wholly outside the frustum is seen by no ray of the frame.
  if (!view_.may_intersect_box(lo, hi) || hides_world(lo, hi, true)) return true;
  if (levels <= 0) return false;
  // One depth over the box's whole rectangle is loose when the box spans a
  // range of depths (a box under a floor seen at a slant: the far part of
  // its rectangle shows floor beyond the box's nearest point). Each half
  // has a narrower rectangle and a nearer-to-true least depth; the box is
  // hidden when both halves are. The nearer half first: it is the likelier
  // to be visible, which ends the test.
  const Vec3 size = hi - lo;
  int a = 0;
  for (int k = 1; k < 3; ++k)
    if (size[k] > size[a]) a = k;
  const double mid = lo[a] + 0.5 * size[a];
  if (!(mid > lo[a] && mid < hi[a])) return false;
  Vec3 near_hi = hi, far_lo = lo;
  near_hi[a] = mid;
  far_lo[a] = mid;
  const bool low_nearer = f_[a] >= 0.0;
  const Vec3 l1 = low_nearer ? lo : far_lo, h1 = low_nearer ? near_hi : hi;
  const Vec3 l2 = low_nearer ? far_lo : lo, h2 = low_nearer ? hi : near_hi;
  return hides_world_split(l1, h1, levels - 1) && hides_world_split(l2, h2, levels - 1);
}

bool OcclusionBuffer::hides_sphere(const Vec3& center, double radius, bool fine) const {
  if (!on() || written_ == 0) return false;
  const double mag = max_abs(eye_) + max_abs(center) + radius;
  // The ball grown by the rounding of center - eye; its nearest depth is
  // at least zc - r.
  const Vec3 w = center - eye_;
  const double r = radius * (1.0 + 1e-9) + 4.0 * kEps * mag;
  const double zc = glm::dot(f_, w);
  const double zmin = zc - r - 4.0 * kEps * mag;
  // Nearly touching the eye's plane, the outline's slopes lose precision:
  // the bounding box answers instead.
  if (!(zmin > near_) || !(zc - r > 1e-3 * r)) return hides_world(center - radius, center + radius, fine);
  double x0, x1, y0, y1;
  if (!sphere_range(w, r, &x0, &x1, &y0, &y1)) return false;
  // Rounding of the slopes: a few eps of (|w| + r)^2 / (zc^2 - r^2), times
  // (1 + |slope|); plus a millionth of a pixel, so that a point on a pixel
  // boundary counts for both pixels.
  const double den = zc * zc - r * r;
  const double e = 64.0 * kEps * (glm::dot(w, w) + r * r) / den;
  const double sxm = std::max(std::fabs(x0), std::fabs(x1)) * tan_x_;
  const double sym = std::max(std::fabs(y0), std::fabs(y1)) * tan_y_;
  const double mx = e * (1.0 + sxm) / tan_x_ + 2e-6 / w_, my = e * (1.0 + sym) / tan_y_ + 2e-6 / h_;
  int i0, i1, j0, j1;
  if (!rect(x0 - mx, x1 + mx, y0 - my, y1 + my, &i0, &i1, &j0, &j1)) return false;
  // Over each pixel, no nearer than the ball's bounding box there.
  OccludeeDepth depth{w - r, Vec3(2.0 * r), 4.0 * kEps * mag};
  return rect_hidden(i0, i1, j0, j1, near_ / zmin, fine ? &depth : nullptr);
}

}  // namespace voxvis::detail
