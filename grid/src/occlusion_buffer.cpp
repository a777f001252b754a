// occlusion_buffer.cpp — see occlusion_buffer.h for the rules and why they
// are conservative.
#include "occlusion_buffer.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "numeric.h"

namespace voxvis::detail {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kEps = std::numeric_limits<double>::epsilon();
/// Relative allowance added to every written bound: far above the rounding
/// of the entry depths (a near-tangent ray loses about sqrt(eps) of relative
/// precision in the sphere's quadratic), far below any distance that matters.
constexpr double kDepthSlack = 1e-7;

/// The smallest float not below d.
float round_up(double d) {
  if (!(d < static_cast<double>(std::numeric_limits<float>::max()))) return std::numeric_limits<float>::infinity();
  float f = static_cast<float>(d);
  if (static_cast<double>(f) < d) {
    if (f > 0.0f) {
      // The next float up: one more in the bits of a positive finite float.
      f = std::bit_cast<float>(std::bit_cast<std::uint32_t>(f) + 1u);
    } else {
      f = std::nextafter(f, std::numeric_limits<float>::infinity());
    }
  }
  return f;
}

}  // namespace

void OcclusionBuffer::begin(const WorldFrustum& wf, int width) {
  if (width <= 0) {
    w_ = 0;
    return;
  }
  eye_ = wf.eye;
  f_ = wf.f;
  r_ = wf.r;
  u_ = wf.u;
  tan_x_ = wf.tan_x;
  tan_y_ = wf.tan_y;
  near_ = wf.near;
  const int w = std::clamp(width, 1, kMaxSide);
  // Square pixels: W / aspect rows (the tangents' ratio, but computed from
  // the aspect, which validation bounds, so no tangent can make it NaN).
  const double hh = std::round(static_cast<double>(w) / wf.aspect);
  const int h = hh >= static_cast<double>(kMaxSide) ? kMaxSide : (hh >= 1.0 ? static_cast<int>(hh) : 1);
  if (w != w_ || h != h_ || px_.empty()) {
    w_ = w;
    h_ = h;
    tw_ = (w + kTile - 1) / kTile;
    th_ = (h + kTile - 1) / kTile;
    const auto tiles = static_cast<std::size_t>(tw_) * static_cast<std::size_t>(th_);
    px_.assign(tiles * kTile * kTile, 0.0f);
    tile_frame_.assign(tiles, 0u);
    tile_max_.assign(tiles, std::numeric_limits<float>::infinity());
    tile_dirty_.assign(tiles, 0);
  }
  w_ = w;
  h_ = h;
  if (++frame_ == 0) {
    std::fill(tile_frame_.begin(), tile_frame_.end(), 0u);
    frame_ = 1;
  }
  written_ = 0;
}

void OcclusionBuffer::write(int i, int j, double d) {
  const auto t = static_cast<std::size_t>((j / kTile) * tw_ + i / kTile);
  float* tile = px_.data() + t * kTile * kTile;
  if (tile_frame_[t] != frame_) {
    // First write this frame: empty pixels are +inf; pixels beyond the
    // image's edge are -inf, so that they never raise the tile's maximum.
    const int bi = (i / kTile) * kTile, bj = (j / kTile) * kTile;
    for (int y = 0; y < kTile; ++y)
      for (int x = 0; x < kTile; ++x)
        tile[y * kTile + x] = (bi + x < w_ && bj + y < h_) ? std::numeric_limits<float>::infinity()
                                                           : -std::numeric_limits<float>::infinity();
    tile_frame_[t] = frame_;
    tile_max_[t] = std::numeric_limits<float>::infinity();
    tile_dirty_[t] = 0;
  }
  float& p = tile[(j % kTile) * kTile + i % kTile];
  const float v = round_up(d);
  if (v < p) {
    p = v;
    tile_dirty_[t] = 1;
    ++written_;
  }
}

float OcclusionBuffer::pixel(int i, int j) const {
  const auto t = static_cast<std::size_t>((j / kTile) * tw_ + i / kTile);
  if (tile_frame_[t] != frame_) return std::numeric_limits<float>::infinity();
  return px_[t * kTile * kTile + static_cast<std::size_t>((j % kTile) * kTile + i % kTile)];
}

bool OcclusionBuffer::rect(double x0, double x1, double y0, double y1, int* i0, int* i1, int* j0,
                           int* j1) const {
  // Image coordinate x maps to pixel column (x + 1) * W / 2.
  const double sw = 0.5 * w_, sh = 0.5 * h_;
  const double a0 = std::floor((x0 + 1.0) * sw), a1 = std::floor((x1 + 1.0) * sw);
  const double b0 = std::floor((y0 + 1.0) * sh), b1 = std::floor((y1 + 1.0) * sh);
  if (!(a1 >= 0.0) || !(a0 <= w_ - 1.0) || !(b1 >= 0.0) || !(b0 <= h_ - 1.0)) return false;
  *i0 = static_cast<int>(std::max(a0, 0.0));
  *i1 = static_cast<int>(std::min(a1, w_ - 1.0));
  *j0 = static_cast<int>(std::max(b0, 0.0));
  *j1 = static_cast<int>(std::min(b1, h_ - 1.0));
  return true;
}

template <class Entry, class Least>
bool OcclusionBuffer::fill(int i0, int i1, int j0, int j1, double nearest, Entry&& entry, Least&& least) {
  bool any = false;
  // Tile by tile, so that a tile whose every pixel already holds a bound no
  // farther than the occluder's nearest depth there costs a few operations:
  // the occluder cannot lower any of them.
  for (int tj = j0 / kTile; tj <= j1 / kTile; ++tj)
    for (int ti = i0 / kTile; ti <= i1 / kTile; ++ti) {
      const auto t = static_cast<std::size_t>(tj * tw_ + ti);
      if (tile_frame_[t] == frame_) {
        const double m = static_cast<double>(tile_max(t));
        if (m <= nearest) continue;
        // The rays through the corners of the tile's part of the rectangle.
        Vec3 d[4];
        for (int c = 0; c < 4; ++c) {
          const int ci = std::clamp((ti + (c & 1)) * kTile, i0, i1 + 1);
          const int cj = std::clamp((tj + (c >> 1)) * kTile, j0, j1 + 1);
          d[c] = f_ + ((2.0 * ci / w_ - 1.0) * tan_x_) * r_ + ((2.0 * cj / h_ - 1.0) * tan_y_) * u_;
        }
        // Writing is optional (the buffer stays conservative), so these
        // skips may be guesses that only cost pixels the occluder could have
        // lowered: the occluder's least depth over the tile, when the shape
        // can bound it; and the rays through the corners all entering it
        // beyond the tile's largest bound.
        if (m <= least(d)) continue;
        bool behind = true;
        for (int c = 0; c < 4 && behind; ++c) {
          double te = -1.0;
          behind = entry(d[c], &te) && te > m;
        }
        if (behind) continue;
      }
      any |= fill_tile(std::max(i0, ti * kTile), std::min(i1, ti * kTile + kTile - 1), std::max(j0, tj * kTile),
                       std::min(j1, tj * kTile + kTile - 1), nearest, entry);
    }
  return any;
}

template <class Entry>
bool OcclusionBuffer::fill_tile(int i0, int i1, int j0, int j1, double nearest, Entry& entry) {
  const int nc = i1 - i0 + 2, nr = j1 - j0 + 2;
  double corner_t[(kTile + 1) * (kTile + 1)];
  // Corner (i, j) is the image point (2i/W - 1, 2j/H - 1); neighbours share
  // the very same corner rays (computed the same way in every tile), so the
  // pixels' squares tile the image.
  for (int jj = 0; jj < nr; ++jj) {
    const double yc = 2.0 * (j0 + jj) / h_ - 1.0;
    const Vec3 fy = f_ + (yc * tan_y_) * u_;
    for (int ii = 0; ii < nc; ++ii) {
      const double xc = 2.0 * (i0 + ii) / w_ - 1.0;
      const Vec3 d = fy + (xc * tan_x_) * r_;
      double t = -1.0;
      if (!entry(d, &t)) t = -1.0;
      corner_t[jj * nc + ii] = t;
    }
  }
  bool any = false, lowered = false;
  float* tile = nullptr;
  std::size_t t_index = 0;
  for (int j = j0; j <= j1; ++j) {
    const double* c0 = corner_t + (j - j0) * nc;
    const double* c1 = c0 + nc;
    for (int i = i0; i <= i1; ++i) {
      const int k = i - i0;
      const double t[4] = {c0[k], c0[k + 1], c1[k], c1[k + 1]};
      int hits = 0;
      double tmax = 0.0;
      for (double v : t) {
        if (v > 0.0) {
          ++hits;
          tmax = std::max(tmax, v);
        }
      }
      double d;
      if (fault == BufferFault::OuterCoverage) {
        if (hits == 0) continue;
        d = tmax;
      } else {
        if (hits < 4) continue;  // Inner coverage: all four corner rays hit.
        d = fault == BufferFault::NearDepth ? nearest : tmax;
      }
      if (tile == nullptr) {
        // The first write prepares the tile (all these pixels lie in one).
        write(i, j, d);
        t_index = static_cast<std::size_t>((j / kTile) * tw_ + i / kTile);
        tile = px_.data() + t_index * kTile * kTile;
        any = true;
        continue;
      }
      float& p = tile[(j % kTile) * kTile + i % kTile];
      const float v = round_up(d);
      if (v < p) {
        p = v;
        lowered = true;
        ++written_;
      }
    }
  }
  if (lowered) tile_dirty_[t_index] = 1;
  return any;
}

float OcclusionBuffer::tile_max(std::size_t t) const {
  if (tile_dirty_[t]) {
    const float* tile = px_.data() + t * kTile * kTile;
    float m = -std::numeric_limits<float>::infinity();
    for (int k = 0; k < kTile * kTile; ++k) m = std::max(m, tile[k]);
    tile_max_[t] = m;
    tile_dirty_[t] = 0;
  }
  return tile_max_[t];
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

bool OcclusionBuffer::render_sphere(const Vec3& c, double radius) {
  if (!on()) return false;
  const Vec3 w = c - eye_;
  const double mag = max_abs(eye_) + max_abs(c) + radius;
  const double zc = glm::dot(f_, w);
  const double ww = glm::dot(w, w);
  // Only the part beyond the near plane occludes (the ray caster clips
  // objects there); a ball around the eye writes nothing.
  if (!(zc + radius > near_) || !(ww > radius * radius)) return false;
  // Shrink so that a rounding error in the hit test can only drop a pixel:
  // the discriminant's error is a few eps * |d|^2 |w|^2, the shrink moves it
  // by about 2 |d|^2 r delta.
  const double delta = 1e-9 * mag + 16.0 * kEps * ww / radius;
  const double rs = radius - delta;
  if (!(rs > 0.5 * radius)) return false;
  const double cc = ww - rs * rs;
  // Image range: the outline's when the ball lies wholly in front of the
  // eye's plane, else the whole image.
  double x0 = -1.0, x1 = 1.0, y0 = -1.0, y1 = 1.0;
  if (zc - radius > 1e-3 * radius && !sphere_range(w, radius, &x0, &x1, &y0, &y1)) return false;
  int i0, i1, j0, j1;
  if (!rect(x0, x1, y0, y1, &i0, &i1, &j0, &j1)) return false;
  const double abs_slack = 1e-9 * mag;
  const bool clip = zc - radius < near_ + 1e-9 * mag;
  return fill(i0, i1, j0, j1, std::fmax(zc - radius, near_), [&](const Vec3& d, double* t) {
    const double a = glm::dot(d, d);
    const double b = glm::dot(d, w);
    if (!(b > 0.0)) return false;
    const double disc = b * b - a * cc;
    if (!(disc >= 0.0)) return false;
    const double q = b + std::sqrt(disc);
    double te = cc / q;  // Entry parameter = depth (d·f = 1).
    if (clip) {
      // The part beyond the near plane: the ray must leave the shrunk ball
      // beyond it, and is first inside the ball at max(entry, near).
      if (!(q / a >= near_ * (1.0 + kDepthSlack) + abs_slack)) return false;
      if (te < near_) te = near_;
    }
    *t = te * (1.0 + kDepthSlack) + abs_slack;
    return true;
  }, [](const Vec3 (&)[4]) { return 0.0; });
}

bool OcclusionBuffer::render_box(const Vec3& lo, const Vec3& hi) {
  if (!on()) return false;
  const double mag = max_abs(eye_) + max_abs(lo) + max_abs(hi);
  const double delta = 1e-9 * mag;
  const Vec3 L = lo + delta - eye_, H = hi - delta - eye_;
  if (!(L.x < H.x && L.y < H.y && L.z < H.z)) return false;  // Too thin to trust.
  const Vec3 size = H - L;
  double zmin = glm::dot(f_, L);
  for (int a = 0; a < 3; ++a) zmin += std::fmin(0.0, f_[a] * size[a]);
  double zmax = glm::dot(f_, L);
  for (int a = 0; a < 3; ++a) zmax += std::fmax(0.0, f_[a] * size[a]);
  // Only the part beyond the near plane occludes (the ray caster clips
  // objects there); a box around the eye writes nothing.
  if (!(zmax > near_)) return false;
  {
    const Vec3 gl = lo - delta - eye_, gh = hi + delta - eye_;
    if (gl.x <= 0.0 && gh.x >= 0.0 && gl.y <= 0.0 && gh.y >= 0.0 && gl.z <= 0.0 && gh.z >= 0.0) return false;
  }
  const bool clip = zmin < near_ + 1e-9 * mag;
  // Image range of the part beyond the near plane: its corners there and
  // where its edges cross the plane.
  double x0 = kInf, x1 = -kInf, y0 = kInf, y1 = -kInf;
  auto take = [&](const Vec3& p) {
    const double z = glm::dot(f_, p);
    const double x = glm::dot(r_, p) / (z * tan_x_), y = glm::dot(u_, p) / (z * tan_y_);
    x0 = std::fmin(x0, x), x1 = std::fmax(x1, x);
    y0 = std::fmin(y0, y), y1 = std::fmax(y1, y);
  };
  for (int k = 0; k < 8; ++k) {
    const Vec3 p{(k & 1) ? H.x : L.x, (k & 2) ? H.y : L.y, (k & 4) ? H.z : L.z};
    const double z = glm::dot(f_, p);
    if (z >= near_) {
      take(p);
    } else {
      // The edges from this corner to corners beyond the plane.
      for (int bit = 1; bit < 8; bit <<= 1) {
        const int k2 = k ^ bit;
        const Vec3 q{(k2 & 1) ? H.x : L.x, (k2 & 2) ? H.y : L.y, (k2 & 4) ? H.z : L.z};
        const double zq = glm::dot(f_, q);
        if (zq > near_) take(p + (q - p) * ((near_ - z) / (zq - z)));
      }
    }
  }
  // A crossing point rounded to just before the plane: widen a little (the
  // range only limits the pixels visited; the hit test decides coverage).
  if (clip) {
    const double wx = 1e-9 * (1.0 + std::fmax(std::fabs(x0), std::fabs(x1)));
    const double wy = 1e-9 * (1.0 + std::fmax(std::fabs(y0), std::fabs(y1)));
    x0 -= wx, x1 += wx, y0 -= wy, y1 += wy;
  }
  if (!(x0 <= x1) || !(y0 <= y1) || !std::isfinite(x0 + x1 + y0 + y1)) return false;
  int i0, i1, j0, j1;
  if (!rect(x0, x1, y0, y1, &i0, &i1, &j0, &j1)) return false;
  const double abs_slack = 1e-9 * mag;
  const double near_exit = near_ * (1.0 + kDepthSlack) + abs_slack;
  // The slab test of the ray eye + t d against [L, H], in reciprocals of
  // the face planes so that a ray costs one division (for its depth), not
  // three. Along an axis where the eye lies below the slab, the ray enters
  // at t = L/d and leaves at H/d, so it needs d > 0 and meets the planes at
  // 1/t = d/L and d/H; above the slab the same with L and H swapped; within
  // it the ray only leaves, at 1/t = d/H (d > 0) or d/L (d < 0). The ray
  // hits the box when every entry reciprocal is positive and the least of
  // them (the last entry) is no smaller than the largest exit reciprocal.
  // Reciprocals are good to a few eps, far below kDepthSlack.
  double in_r[3], out_r[3], out_r2[3], face[3];
  int outside[3], n_out = 0, inside[3], n_in = 0;
  for (int a = 0; a < 3; ++a) {
    if (L[a] > 0.0) {
      in_r[a] = 1.0 / L[a], out_r[a] = 1.0 / H[a], face[a] = L[a];
      outside[n_out++] = a;
    } else if (H[a] < 0.0) {
      in_r[a] = 1.0 / H[a], out_r[a] = 1.0 / L[a], face[a] = -H[a];
      outside[n_out++] = a;
    } else {
      // With the eye on a face's plane (H or L exactly 0) a ray heading out
      // through it leaves at once: +inf and -inf (1 / 0.0 would be +inf
      // for both, and a ray out through L would seem never to leave).
      out_r[a] = H[a] > 0.0 ? 1.0 / H[a] : kInf;
      out_r2[a] = L[a] < 0.0 ? 1.0 / L[a] : -kInf;
      inside[n_in++] = a;
    }
  }
  if (n_out == 0) return false;  // The eye is in the box (the test above, with rounding).
  const double exit_cap = 1.0 / near_exit;  // Leaving beyond the near plane.
  return fill(i0, i1, j0, j1, std::fmax(zmin, near_), [&](const Vec3& d, double* t) {
    double least_in = kInf, most_out = 0.0, entry_face = 1.0;
    for (int k = 0; k < n_out; ++k) {
      const int a = outside[k];
      const double e = d[a] * in_r[a];
      if (!(e > 0.0)) return false;  // Heading away from the slab, or along it.
      if (e < least_in) least_in = e, entry_face = face[a];
      const double x = d[a] * out_r[a];
      if (x > most_out) most_out = x;
    }
    for (int k = 0; k < n_in; ++k) {
      const int a = inside[k];
      const double x = std::max(d[a] * out_r[a], d[a] * out_r2[a]);  // NaN (d = 0 on a face) never wins.
      if (x > most_out) most_out = x;
    }
    if (!(least_in >= most_out)) return false;
    double tin = 1.0 / least_in;
    // The face's coordinate is good to eps * mag: its plane's depth along
    // this ray to eps * mag / |d| = eps * mag * tin / |face|.
    double err = 4.0 * kEps * mag * tin / entry_face;
    if (clip) {
      // The part beyond the near plane: the ray must leave the shrunk box
      // beyond it, and is first inside the box at max(entry, near).
      if (!(most_out <= exit_cap)) return false;
      if (tin < near_) tin = near_, err = 0.0;
    }
    *t = tin * (1.0 + kDepthSlack) + abs_slack + err;
    return true;
  }, [&](const Vec3 (&d)[4]) {
    // Over the tile every hitting ray enters at or beyond each front
    // face's plane, and a plane's depth P/d_a over the tile is least where
    // |d_a| is largest, at a corner (d is affine in the image point).
    double lb = 0.0;
    for (int k = 0; k < n_out; ++k) {
      const int a = outside[k];
      double dlo = d[0][a], dhi = d[0][a];
      for (int c = 1; c < 4; ++c) dlo = std::min(dlo, d[c][a]), dhi = std::max(dhi, d[c][a]);
      if (L[a] > 0.0 && dlo > 0.0) lb = std::max(lb, L[a] / dhi);
      if (H[a] < 0.0 && dhi < 0.0) lb = std::max(lb, H[a] / dlo);
    }
    return lb;
  });
}

bool OcclusionBuffer::rect_hidden(int i0, int i1, int j0, int j1, double zmin) const {
  for (int tj = j0 / kTile; tj <= j1 / kTile; ++tj) {
    for (int ti = i0 / kTile; ti <= i1 / kTile; ++ti) {
      const auto t = static_cast<std::size_t>(tj * tw_ + ti);
      if (tile_frame_[t] != frame_) return false;  // Empty tile.
      const float* tile = px_.data() + t * kTile * kTile;
      if (static_cast<double>(tile_max(t)) < zmin) continue;
      const int pi0 = std::max(i0, ti * kTile), pi1 = std::min(i1, ti * kTile + kTile - 1);
      const int pj0 = std::max(j0, tj * kTile), pj1 = std::min(j1, tj * kTile + kTile - 1);
      for (int j = pj0; j <= pj1; ++j)
        for (int i = pi0; i <= pi1; ++i)
          if (!(static_cast<double>(tile[(j % kTile) * kTile + i % kTile]) < zmin)) return false;
    }
  }
  return true;
}

bool OcclusionBuffer::hides(const Vec3& rel, const Vec3& size, double tol) const {
  if (!on() || written_ == 0) return false;
  tol += 4.0 * kEps * (max_abs(rel) + max_abs(size));
  double zmin = glm::dot(f_, rel);
  for (int a = 0; a < 3; ++a) zmin += std::min(0.0, f_[a] * size[a]);
  zmin -= 2.0 * tol;
  if (!(zmin > near_)) return false;  // Crossing the near plane or behind the eye.
  const double X0 = glm::dot(r_, rel), Y0 = glm::dot(u_, rel), Z0 = glm::dot(f_, rel);
  {
    // Quick rejection: the pixel of the box's centre must hold a nearer
    // bound (a necessary condition only, so any rounding is harmless).
    const Vec3 ch = 0.5 * size;
    const double zc = Z0 + glm::dot(f_, ch);
    const double xi = ((X0 + glm::dot(r_, ch)) / (zc * tan_x_) + 1.0) * 0.5 * w_;
    const double yi = ((Y0 + glm::dot(u_, ch)) / (zc * tan_y_) + 1.0) * 0.5 * h_;
    if (xi >= 0.0 && xi < w_ && yi >= 0.0 && yi < h_) {
      const int i = static_cast<int>(xi), j = static_cast<int>(yi);
      const auto t = static_cast<std::size_t>((j / kTile) * tw_ + i / kTile);
      if (tile_frame_[t] != frame_) return false;
      if (!(static_cast<double>(px_[t * kTile * kTile + static_cast<std::size_t>((j % kTile) * kTile + i % kTile)]) < zmin))
        return false;
    }
  }
  // The box's X, Y and Z ranges bound its corners' slopes X/Z and Y/Z:
  // with Z in [zlo, zhi], zlo > 0, X/Z lies in [Xlo / (Xlo < 0 ? zlo : zhi),
  // Xhi / (Xhi > 0 ? zlo : zhi)] (a superset of the corners' hull).
  double xlo = X0, xhi = X0, ylo = Y0, yhi = Y0, zlo = Z0, zhi = Z0;
  for (int a = 0; a < 3; ++a) {
    const double ex = r_[a] * size[a], ey = u_[a] * size[a], ez = f_[a] * size[a];
    (ex < 0.0 ? xlo : xhi) += ex;
    (ey < 0.0 ? ylo : yhi) += ey;
    (ez < 0.0 ? zlo : zhi) += ez;
  }
  const double izlo = 1.0 / zlo, izhi = 1.0 / zhi;
  const double x0 = xlo * (xlo < 0.0 ? izlo : izhi), x1 = xhi * (xhi > 0.0 ? izlo : izhi);
  const double y0 = ylo * (ylo < 0.0 ? izlo : izhi), y1 = yhi * (yhi > 0.0 ? izlo : izhi);
  // A corner's position is good to tol (world units) in X, Y and Z: its
  // slope X/Z moves by at most tol (1 + |X/Z|) / Z. Plus a millionth of a
  // pixel, so that a point on a pixel boundary counts for both pixels.
  const double ms = 2.0 * tol * (1.0 + std::max(std::fabs(x0), std::fabs(x1))) / zmin;
  const double mt = 2.0 * tol * (1.0 + std::max(std::fabs(y0), std::fabs(y1))) / zmin;
  const double mx = ms / tan_x_ + 2e-6 / w_, my = mt / tan_y_ + 2e-6 / h_;
  int i0, i1, j0, j1;
  if (!rect(x0 / tan_x_ - mx, x1 / tan_x_ + mx, y0 / tan_y_ - my, y1 / tan_y_ + my, &i0, &i1, &j0, &j1))
    return false;
  return rect_hidden(i0, i1, j0, j1, zmin);
}

bool OcclusionBuffer::hides_world(const Vec3& lo, const Vec3& hi) const {
  if (!on() || written_ == 0) return false;
  const double tol = 1e-12 * (max_abs(lo) + max_abs(hi) + max_abs(eye_) + 1.0);
  return hides(lo - eye_, hi - lo, tol);
}

bool OcclusionBuffer::hides_sphere(const Vec3& center, double radius) const {
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
  if (!(zmin > near_) || !(zc - r > 1e-3 * r)) return hides_world(center - radius, center + radius);
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
  return rect_hidden(i0, i1, j0, j1, zmin);
}

}  // namespace voxvis::detail
