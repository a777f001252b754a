// raycast.cpp — see raycast.h. Brute-force in spirit, with two exact
// accelerations that never change the answer: objects are binned into
// screen-space tiles by the projection of their bounding box, and the
// candidates of a tile are visited in order of their least possible depth so
// that a ray stops once no remaining candidate can be entered earlier.
#include "raycast.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <iterator>
#include <numbers>

#include <glm/geometric.hpp>

namespace voxvis::test {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

bool finite3(const Vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

/// Axis-aligned bounding box of an object (exact for boxes).
void object_aabb(const ObjectDesc& obj, Vec3* lo, Vec3* hi) {
  const Vec3 h = obj.shape == Shape::Sphere ? Vec3(obj.radius) : obj.half_extent;
  *lo = obj.center - h;
  *hi = obj.center + h;
}

/// Minimum and maximum of n·(p - origin) over the box [lo, hi].
void box_extent_along(const Vec3& n, const Vec3& origin, const Vec3& lo, const Vec3& hi,
                      double* mn, double* mx, double* magnitude) {
  double a = 0.0;
  double b = 0.0;
  double m = 0.0;
  for (int i = 0; i < 3; ++i) {
    const double p = n[i] * (lo[i] - origin[i]);
    const double q = n[i] * (hi[i] - origin[i]);
    a += std::min(p, q);
    b += std::max(p, q);
    m += std::max(std::abs(p), std::abs(q));
  }
  *mn = a;
  *mx = b;
  *magnitude = m;
}

/// splitmix64: order-independent per-cell jitter.
std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

double unit_from_bits(std::uint64_t bits) {
  return static_cast<double>(bits >> 11) * 0x1.0p-53;
}

struct Candidate {
  std::size_t index;  ///< Into the objects vector.
  double zmin;        ///< Least depth any of its points can have, clipped to near.
};

struct Ray {
  double x;
  double y;
};

/// Casts one ray against `cands` (sorted by zmin) and appends the first hits'
/// indices to `hits` (cleared first).
void cast(const std::vector<ObjectDesc>& objects, const std::vector<Candidate>& cands,
          const ViewBasis& basis, const Vec3& d, std::vector<std::size_t>* hits) {
  hits->clear();
  double best = kInf;
  for (const Candidate& c : cands) {
    if (c.zmin - 1e-9 * (1.0 + std::abs(best)) > best) break;
    double t0 = 0.0;
    double t1 = 0.0;
    if (!intersect(objects[c.index], basis.eye, d, &t0, &t1)) continue;
    const double entry = std::max(t0, basis.near);
    const double exit = std::min(t1, basis.far);
    if (!(entry <= exit)) continue;
    if (entry < best) {
      best = entry;
      hits->clear();
      hits->push_back(c.index);
    } else if (entry == best) {
      hits->push_back(c.index);
    }
  }
}

}  // namespace

bool make_basis(const Camera& cam, ViewBasis* out) {
  if (!finite3(cam.eye) || !finite3(cam.dir) || !finite3(cam.up)) return false;
  if (!std::isfinite(cam.fov_y_deg) || !std::isfinite(cam.aspect) || !std::isfinite(cam.near) ||
      !std::isfinite(cam.far)) {
    return false;
  }
  if (!(cam.fov_y_deg > 0.0 && cam.fov_y_deg < 180.0)) return false;
  if (!(cam.aspect > 0.0) || !(cam.near > 0.0) || !(cam.far > cam.near)) return false;
  const double dl = glm::length(cam.dir);
  if (!(dl > 0.0) || !std::isfinite(dl)) return false;
  ViewBasis b;
  b.eye = cam.eye;
  b.f = cam.dir / dl;
  const Vec3 r = glm::cross(b.f, cam.up);
  const double rl = glm::length(r);
  if (!(rl > 1e-12 * glm::length(cam.up)) || !std::isfinite(rl)) return false;
  b.right = r / rl;
  b.up = glm::cross(b.right, b.f);
  b.tany = std::tan(cam.fov_y_deg * (std::numbers::pi / 360.0));
  b.tanx = cam.aspect * b.tany;
  b.near = cam.near;
  b.far = cam.far;
  *out = b;
  return true;
}

bool intersect(const ObjectDesc& obj, const Vec3& eye, const Vec3& d, double* t0, double* t1) {
  if (obj.shape == Shape::Sphere) {
    // Closest approach first (stable for grazing rays), then the chord.
    const double a = glm::dot(d, d);
    if (!(a > 0.0)) return false;
    const Vec3 oc = eye - obj.center;
    const double tm = -glm::dot(oc, d) / a;
    const Vec3 closest = oc + tm * d;
    const double h2 = obj.radius * obj.radius - glm::dot(closest, closest);
    if (h2 < 0.0) return false;
    const double half = std::sqrt(h2 / a);
    *t0 = tm - half;
    *t1 = tm + half;
    return true;
  }
  double lo_t = -kInf;
  double hi_t = kInf;
  for (int i = 0; i < 3; ++i) {
    const double lo = obj.center[i] - obj.half_extent[i];
    const double hi = obj.center[i] + obj.half_extent[i];
    if (d[i] == 0.0) {
      if (eye[i] < lo || eye[i] > hi) return false;
      continue;
    }
    double ta = (lo - eye[i]) / d[i];
    double tb = (hi - eye[i]) / d[i];
    if (ta > tb) std::swap(ta, tb);
    lo_t = std::max(lo_t, ta);
    hi_t = std::min(hi_t, tb);
    if (lo_t > hi_t) return false;
  }
  *t0 = lo_t;
  *t1 = hi_t;
  return true;
}

std::vector<ObjectId> visible_objects(const std::vector<ObjectDesc>& objects, const Camera& cam,
                                      const RaySampling& sampling) {
  ViewBasis basis;
  if (!make_basis(cam, &basis)) return {};
  const int cols = std::max(1, sampling.cols);
  const int rows = std::max(1, sampling.rows);
  constexpr int kTile = 8;
  const int tcols = (cols + kTile - 1) / kTile;
  const int trows = (rows + kTile - 1) / kTile;
  std::vector<std::vector<Candidate>> tiles(static_cast<std::size_t>(tcols) * trows);

  // Bin every object that can be hit within [near, far] into the tiles its
  // bounding box's projection overlaps (the whole image when the box reaches
  // the eye's plane).
  for (std::size_t i = 0; i < objects.size(); ++i) {
    Vec3 lo;
    Vec3 hi;
    object_aabb(objects[i], &lo, &hi);
    double zmin = 0.0;
    double zmax = 0.0;
    double zmag = 0.0;
    box_extent_along(basis.f, basis.eye, lo, hi, &zmin, &zmax, &zmag);
    const double ztol = 1e-9 * (zmag + basis.far);
    if (zmax < basis.near - ztol || zmin > basis.far + ztol) continue;
    double x0 = -1.0;
    double x1 = 1.0;
    double y0 = -1.0;
    double y1 = 1.0;
    if (zmin > 1e-6 * (zmag + basis.near)) {
      x0 = y0 = kInf;
      x1 = y1 = -kInf;
      for (int c = 0; c < 8; ++c) {
        const Vec3 p((c & 1) ? hi.x : lo.x, (c & 2) ? hi.y : lo.y, (c & 4) ? hi.z : lo.z);
        const Vec3 v = p - basis.eye;
        const double z = glm::dot(v, basis.f);
        const double px = glm::dot(v, basis.right) / (z * basis.tanx);
        const double py = glm::dot(v, basis.up) / (z * basis.tany);
        x0 = std::min(x0, px);
        x1 = std::max(x1, px);
        y0 = std::min(y0, py);
        y1 = std::max(y1, py);
      }
      const double tol = 1e-7;
      x0 -= tol * (1.0 + std::abs(x0));
      y0 -= tol * (1.0 + std::abs(y0));
      x1 += tol * (1.0 + std::abs(x1));
      y1 += tol * (1.0 + std::abs(y1));
      if (x1 < -1.0 || x0 > 1.0 || y1 < -1.0 || y0 > 1.0) continue;
    }
    auto tile_of = [](double s, int cells, int tiles_n) {
      const double c = (std::clamp(s, -1.0, 1.0) + 1.0) * 0.5 * cells / kTile;
      return std::clamp(static_cast<int>(std::floor(c)), 0, tiles_n - 1);
    };
    const int i0 = tile_of(x0, cols, tcols);
    const int i1 = tile_of(x1, cols, tcols);
    const int j0 = tile_of(y0, rows, trows);
    const int j1 = tile_of(y1, rows, trows);
    const Candidate cand{i, std::max(zmin, basis.near)};
    for (int tj = j0; tj <= j1; ++tj) {
      for (int ti = i0; ti <= i1; ++ti) {
        tiles[static_cast<std::size_t>(tj) * tcols + ti].push_back(cand);
      }
    }
  }

  std::vector<char> seen(objects.size(), 0);
  std::vector<std::size_t> hits;
  std::vector<Ray> rays;
  for (int tj = 0; tj < trows; ++tj) {
    for (int ti = 0; ti < tcols; ++ti) {
      std::vector<Candidate>& cands = tiles[static_cast<std::size_t>(tj) * tcols + ti];
      if (cands.empty()) continue;
      std::stable_sort(cands.begin(), cands.end(),
                       [](const Candidate& a, const Candidate& b) { return a.zmin < b.zmin; });
      rays.clear();
      const int cx0 = ti * kTile;
      const int cx1 = std::min(cols, cx0 + kTile);
      const int cy0 = tj * kTile;
      const int cy1 = std::min(rows, cy0 + kTile);
      for (int cy = cy0; cy < cy1; ++cy) {
        for (int cx = cx0; cx < cx1; ++cx) {
          double jx = 0.5;
          double jy = 0.5;
          if (sampling.jitter) {
            const std::uint64_t cell = static_cast<std::uint64_t>(cy) * static_cast<std::uint64_t>(cols) +
                                       static_cast<std::uint64_t>(cx);
            const std::uint64_t h = splitmix64(sampling.seed ^ splitmix64(cell));
            jx = unit_from_bits(h);
            jy = unit_from_bits(splitmix64(h));
          }
          rays.push_back({-1.0 + 2.0 * (cx + jx) / cols, -1.0 + 2.0 * (cy + jy) / rows});
        }
      }
      if (sampling.corners) {
        // Corner (cx, cy) belongs to tile floor(c / kTile) (the last tile for
        // the far image edge); it lies on that tile's closed boundary.
        const int kx1 = ti == tcols - 1 ? cols : cx1 - 1;
        const int ky1 = tj == trows - 1 ? rows : cy1 - 1;
        for (int cy = cy0; cy <= ky1; ++cy) {
          for (int cx = cx0; cx <= kx1; ++cx) {
            const double x = cx == cols ? 1.0 : -1.0 + 2.0 * cx / cols;
            const double y = cy == rows ? 1.0 : -1.0 + 2.0 * cy / rows;
            rays.push_back({x, y});
          }
        }
      }
      for (const Ray& r : rays) {
        cast(objects, cands, basis, basis.ray_dir(r.x, r.y), &hits);
        for (std::size_t h : hits) seen[h] = 1;
      }
    }
  }
  std::vector<ObjectId> ids;
  for (std::size_t i = 0; i < objects.size(); ++i) {
    if (seen[i]) ids.push_back(objects[i].id);
  }
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  return ids;
}

std::vector<ObjectId> first_hit(const std::vector<ObjectDesc>& objects, const Camera& cam, double x,
                                double y) {
  ViewBasis basis;
  if (!make_basis(cam, &basis)) return {};
  std::vector<Candidate> cands;
  cands.reserve(objects.size());
  for (std::size_t i = 0; i < objects.size(); ++i) cands.push_back({i, -kInf});
  std::vector<std::size_t> hits;
  cast(objects, cands, basis, basis.ray_dir(x, y), &hits);
  std::vector<ObjectId> ids;
  for (std::size_t h : hits) ids.push_back(objects[h].id);
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  return ids;
}

std::size_t voxels_in_view(const std::vector<ObjectDesc>& objects, const Camera& cam, const Vec3& bmin,
                           const Vec3& bmax, const glm::ivec3& res, const RaySampling& sampling) {
  ViewBasis basis;
  if (!make_basis(cam, &basis) || res.x < 1 || res.y < 1 || res.z < 1) return 0;
  // Only objects that may meet the frustum can be hit.
  const std::vector<ObjectId> in = frustum_objects(objects, cam);
  // Nearest first, each with the least depth its box can have, so that a
  // ray stops looking once nothing left can come nearer than its hit.
  std::vector<Candidate> cands;
  for (std::size_t i = 0; i < objects.size(); ++i) {
    if (!std::binary_search(in.begin(), in.end(), objects[i].id)) continue;
    const ObjectDesc& o = objects[i];
    const Vec3 h = o.shape == Shape::Sphere ? Vec3(o.radius) : o.half_extent;
    const Vec3& f = basis.f;
    const double zmin = glm::dot(f, o.center - basis.eye) -
                        (std::abs(f.x) * h.x + std::abs(f.y) * h.y + std::abs(f.z) * h.z);
    cands.push_back({i, zmin});
  }
  std::sort(cands.begin(), cands.end(), [](const Candidate& a, const Candidate& b) { return a.zmin < b.zmin; });
  const Vec3 vs = (bmax - bmin) / Vec3(res);
  std::vector<char> seen(static_cast<std::size_t>(res.x) * static_cast<std::size_t>(res.y) *
                             static_cast<std::size_t>(res.z),
                         0);
  std::size_t count = 0;
  std::vector<std::size_t> hits;
  for (int row = 0; row < sampling.rows; ++row)
    for (int col = 0; col < sampling.cols; ++col) {
      const double x = -1.0 + (2.0 * col + 1.0) / sampling.cols;
      const double y = -1.0 + (2.0 * row + 1.0) / sampling.rows;
      const Vec3 d = basis.ray_dir(x, y);
      cast(objects, cands, basis, d, &hits);
      double t_end = basis.far;
      for (std::size_t h : hits) {
        double t0 = 0.0, t1 = 0.0;
        if (intersect(objects[h], basis.eye, d, &t0, &t1)) t_end = std::min(t_end, std::max(t0, basis.near));
      }
      // The segment [near, t_end] in grid units, clipped to the grid box.
      const Vec3 o = (basis.eye - bmin) / vs;
      const Vec3 g = d / vs;
      double ta = basis.near, tb = t_end;
      for (int a = 0; a < 3; ++a) {
        if (g[a] == 0.0) {
          if (o[a] < 0.0 || o[a] > res[a]) ta = kInf;
          continue;
        }
        const double u = (0.0 - o[a]) / g[a], v = (res[a] - o[a]) / g[a];
        ta = std::max(ta, std::min(u, v));
        tb = std::min(tb, std::max(u, v));
      }
      if (!(ta <= tb)) continue;
      // Amanatides-Woo through the voxels the segment meets.
      glm::ivec3 cell, step;
      Vec3 next, delta;
      const Vec3 p = o + g * ta;
      for (int a = 0; a < 3; ++a) {
        cell[a] = std::clamp(static_cast<int>(std::floor(p[a])), 0, res[a] - 1);
        step[a] = g[a] > 0.0 ? 1 : -1;
        delta[a] = g[a] != 0.0 ? 1.0 / std::abs(g[a]) : kInf;
        const double bound = g[a] > 0.0 ? cell[a] + 1.0 : cell[a];
        next[a] = g[a] != 0.0 ? (bound - o[a]) / g[a] : kInf;
      }
      for (;;) {
        const std::size_t idx = static_cast<std::size_t>(cell.x) +
                                static_cast<std::size_t>(res.x) *
                                    (static_cast<std::size_t>(cell.y) + static_cast<std::size_t>(res.y) * static_cast<std::size_t>(cell.z));
        if (!seen[idx]) {
          seen[idx] = 1;
          ++count;
        }
        const int a = next.x < next.y ? (next.x < next.z ? 0 : 2) : (next.y < next.z ? 1 : 2);
        if (next[a] > tb) break;
        cell[a] += step[a];
        if (cell[a] < 0 || cell[a] >= res[a]) break;
        next[a] += delta[a];
      }
    }
  return count;
}

bool project(const Camera& cam, const Vec3& p, double* x, double* y) {
  ViewBasis b;
  if (!make_basis(cam, &b)) return false;
  const Vec3 v = p - b.eye;
  const double z = glm::dot(v, b.f);
  if (!(z > 0.0)) return false;
  *x = glm::dot(v, b.right) / (z * b.tanx);
  *y = glm::dot(v, b.up) / (z * b.tany);
  return true;
}

std::vector<ObjectId> frustum_objects(const std::vector<ObjectDesc>& objects, const Camera& cam) {
  ViewBasis b;
  if (!make_basis(cam, &b)) return {};
  struct Plane {
    Vec3 n;
    double w;  // inside: n·(p - eye) <= w
  };
  const Plane planes[6] = {
      {b.right - b.tanx * b.f, 0.0}, {-b.right - b.tanx * b.f, 0.0},
      {b.up - b.tany * b.f, 0.0},    {-b.up - b.tany * b.f, 0.0},
      {-b.f, -b.near},               {b.f, b.far},
  };
  std::vector<ObjectId> ids;
  for (const ObjectDesc& obj : objects) {
    Vec3 lo;
    Vec3 hi;
    object_aabb(obj, &lo, &hi);
    bool outside = false;
    for (const Plane& p : planes) {
      double mn = 0.0;
      double mx = 0.0;
      double mag = 0.0;
      box_extent_along(p.n, b.eye, lo, hi, &mn, &mx, &mag);
      if (mn > p.w + 1e-9 * (mag + std::abs(p.w)) + 1e-300) {
        outside = true;
        break;
      }
    }
    if (!outside) ids.push_back(obj.id);
  }
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  return ids;
}

std::vector<ObjectId> missing_ids(const std::vector<ObjectId>& pvs,
                                  const std::vector<ObjectId>& visible) {
  std::vector<ObjectId> out;
  std::set_difference(visible.begin(), visible.end(), pvs.begin(), pvs.end(),
                      std::back_inserter(out));
  return out;
}

namespace {
std::string vec_str(const Vec3& v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "{%.17g, %.17g, %.17g}", v.x, v.y, v.z);
  return buf;
}
}  // namespace

std::string describe(const Camera& cam) {
  char buf[128];
  std::snprintf(buf, sizeof buf, ", fov_y_deg=%.17g, aspect=%.17g, near=%.17g, far=%.17g}",
                cam.fov_y_deg, cam.aspect, cam.near, cam.far);
  return "Camera{eye=" + vec_str(cam.eye) + ", dir=" + vec_str(cam.dir) + ", up=" + vec_str(cam.up) +
         buf;
}

std::string describe(const ObjectDesc& obj) {
  std::string s = "Object{id=" + std::to_string(obj.id);
  if (obj.shape == Shape::Sphere) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "%.17g", obj.radius);
    s += ", sphere, center=" + vec_str(obj.center) + ", radius=" + buf;
  } else {
    s += ", box, center=" + vec_str(obj.center) + ", half_extent=" + vec_str(obj.half_extent);
  }
  if (obj.dynamic) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "%.17g", obj.max_speed);
    s += std::string(", dynamic, max_speed=") + buf;
  }
  return s + "}";
}

std::string describe_ids(const std::vector<ObjectId>& ids, std::size_t max_count) {
  std::string s = "[";
  for (std::size_t i = 0; i < ids.size() && i < max_count; ++i) {
    if (i) s += ", ";
    s += std::to_string(ids[i]);
  }
  if (ids.size() > max_count) s += ", ... (" + std::to_string(ids.size()) + " in all)";
  return s + "]";
}

}  // namespace voxvis::test
