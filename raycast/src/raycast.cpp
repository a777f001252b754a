// raycast.cpp — see voxvis/raycast.h.
//
// visible_objects finds, for every sampled ray, exactly the first hits that
// testing every object would find (CastOptions::brute_force does that), only
// faster: the objects that may meet the frustum go into a bounding volume
// hierarchy (binned surface-area heuristic, a few objects a leaf), and each
// ray walks it nearest box first, skipping a box only when it cannot hold an
// object entered at or before the ray's nearest hit so far. The skip never
// changes the answer:
// - a box's interval along a ray is computed with the same operations as a
//   box object's (intersect(): (bound - eye) / d per axis), and rounding is
//   monotone, so a node's computed interval contains every box inside it;
// - a sphere's leaf box is its bounding box grown by a margin far above the
//   rounding error of intersect()'s sphere formula (whose grazing hits may
//   lie outside the exact ball by about sqrt(2^-53 * r * distance));
// - a mesh's leaf box is its placed model box grown by 1e-10 of the
//   magnitudes involved, far above the rounding of taking rays into its
//   frame (PlacedMesh::world_box); its triangles are found through its own
//   hierarchy in model space, built once per mesh (mesh_bvh.h says how that
//   one handles rounding, and where it may differ from testing every
//   triangle: rays grazing a triangle's plane);
// - a box is skipped only when its entry is strictly beyond the nearest hit,
//   so every object entered at exactly that depth is still tested: ties make
//   all tied objects visible, as brute force does.
// The culling before the build uses the same grown boxes and a tolerance far
// above rounding. tests/raycast checks the fast path against brute force on
// random scenes with their hard cases.
//
// Written here rather than taken from a library. Debian packages two that
// could hold the objects: Embree (libembree-dev) traverses in single
// precision and keeps one nearest hit per ray, with spheres and boxes as
// user geometry through callbacks; CGAL's AABB tree (libcgal-dev) answers a
// ray's first intersection as one primitive, for kernel primitives
// (triangles, segments), not closed balls and boxes clipped to [near, far].
// Neither gives every object entered at the same least depth, nor the
// bit-for-bit agreement with the brute-force definition the tests rely on;
// on top of either, the tie rule, the near/far clipping and the margins
// above would still be ours, so the library would add a dependency without
// taking the hard part. A binned-SAH hierarchy is about 200 lines
// (bvh_build.cpp), shared with the meshes' hierarchies. For triangles too
// Embree is single precision; CGAL's exact predicates would decide each ray
// and triangle exactly, but the watertight test in double (mesh_bvh.h) gives
// the conservative edge rule the caster needs in about 30 lines, in the
// mesh's frame, with no second hierarchy to place per object.
#include "voxvis/raycast.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <thread>
#include <unordered_map>

#include <glm/geometric.hpp>

#include "bvh_build.h"
#include "mesh_bvh.h"
#include "voxvis/mesh.h"

namespace voxvis::raycast {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
/// The radius of visible_near_pixel's cone, in pixels (raycast.h).
constexpr double kPixelCone = 1e-3;

bool finite3(const Vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

using detail::BvhItem;
using detail::BvhNode;
using detail::MeshSet;
using detail::PlacedMesh;

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
  const PlacedMesh* mesh = nullptr;  ///< A mesh object's triangles, placed; else null.
};

struct Ray {
  double x;
  double y;
};

/// The directions of a cone's four rays around a point of the image, in
/// units of its radius (RaySampling::cone, visible_near_pixel): 0.4 + k*pi/2
/// radians, no image axis or diagonal, so that a cone around a ray through a
/// voxel edge or corner has no ray along a voxel face, and one ray in each
/// quadrant, so that any line through the point has rays on both sides.
constexpr double kConeDir[4][2] = {{0.9210609940028851, 0.3894183423086505},
                                   {-0.3894183423086505, 0.9210609940028851},
                                   {-0.9210609940028851, -0.3894183423086505},
                                   {0.3894183423086505, -0.9210609940028851}};

/// The depth at which the ray eye + t*d is first in `obj` within [near,
/// far] (raycast.h): a sphere's or box's interval clipped, a mesh's least
/// hit there (`mesh`: its triangles placed for the eye; a mesh object
/// without it is never hit). False when the ray does not meet it there.
/// Adds the ray–triangle tests made to `*tests`.
bool clipped_entry(const ObjectDesc& obj, const PlacedMesh* mesh, const ViewBasis& b, const Vec3& d, double* entry,
                   std::uint64_t* tests) {
  if (obj.shape == Shape::Mesh) return mesh && mesh->hit(d, b.near, b.far, false, entry, tests);
  double t0 = 0.0;
  double t1 = 0.0;
  if (!intersect(obj, b.eye, d, &t0, &t1)) return false;
  *entry = std::max(t0, b.near);
  return *entry <= std::min(t1, b.far);
}

/// Casts one ray against `cands` (sorted by zmin) and appends the first hits'
/// indices to `hits` (cleared first).
void cast(const std::vector<ObjectDesc>& objects, const std::vector<Candidate>& cands,
          const ViewBasis& basis, const Vec3& d, std::vector<std::size_t>* hits, std::uint64_t* tests) {
  hits->clear();
  double best = kInf;
  for (const Candidate& c : cands) {
    if (c.zmin - 1e-9 * (1.0 + std::abs(best)) > best) break;
    double entry = 0.0;
    if (!clipped_entry(objects[c.index], c.mesh, basis, d, &entry, tests)) continue;
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
  // Directions of any finite magnitude (1e308 or 5e-324 components): scaled
  // by their largest component first, so that no length overflows or
  // underflows.
  auto scaled = [](const Vec3& v) {
    const double m = std::max({std::fabs(v.x), std::fabs(v.y), std::fabs(v.z)});
    return m > 0.0 ? v / m : Vec3(0.0);
  };
  const Vec3 dir = scaled(cam.dir), up = scaled(cam.up);
  const double dl = glm::length(dir);
  if (!(dl > 0.0) || !std::isfinite(dl) || !(glm::length(up) > 0.0)) return false;
  ViewBasis b;
  b.eye = cam.eye;
  b.f = dir / dl;
  const Vec3 r = glm::cross(b.f, up);
  const double rl = glm::length(r);
  if (!(rl > 1e-12 * glm::length(up)) || !std::isfinite(rl)) return false;
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
  if (obj.shape == Shape::Mesh) {
    if (!obj.mesh) return false;
    const PlacedMesh placed(obj, eye, detail::mesh_bvh(obj.mesh));
    std::uint64_t tests = 0;
    return placed.hit(d, -kInf, kInf, false, t0, &tests) && placed.hit(d, -kInf, kInf, true, t1, &tests);
  }
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

// --- the hierarchy and visible_objects ---------------------------------------

namespace {

/// The leaf box of an object. A box's is its own bounds, with the very
/// operations intersect() uses. A sphere's is its bounding box grown by a
/// margin that covers intersect()'s rounding for an eye at distance
/// `dist` from the centre: grazing hits may lie outside the exact ball by
/// about sqrt(c * 2^-53 * r * (r + dist)) + c * 2^-53 * dist (c a small
/// constant); the margin is over 20 times that, plus the rounding of the
/// grown bounds themselves. A mesh's is the box of its placed model box,
/// grown (PlacedMesh::world_box, which says by how much), or an empty box
/// (lo > hi) for a mesh object without triangles (never hit).
void leaf_box(const ObjectDesc& obj, const PlacedMesh* mesh, const Vec3& eye, double* lo, double* hi) {
  if (obj.shape == Shape::Mesh) {
    Vec3 l(kInf), h(-kInf);
    if (mesh) mesh->world_box(&l, &h);
    for (int i = 0; i < 3; ++i) {
      lo[i] = l[i];
      hi[i] = h[i];
    }
    return;
  }
  if (obj.shape == Shape::Box) {
    for (int i = 0; i < 3; ++i) {
      lo[i] = obj.center[i] - obj.half_extent[i];
      hi[i] = obj.center[i] + obj.half_extent[i];
    }
    return;
  }
  const double r = obj.radius;
  const double dist = glm::length(eye - obj.center);
  const double cmax = std::max({std::abs(obj.center.x), std::abs(obj.center.y), std::abs(obj.center.z)});
  const double margin = 1e-6 * std::sqrt(r * (r + dist)) + 1e-12 * (dist + r + cmax);
  for (int i = 0; i < 3; ++i) {
    lo[i] = obj.center[i] - r - margin;
    hi[i] = obj.center[i] + r + margin;
  }
}

/// A plane of the frustum: inside is n·(p - eye) <= w.
struct Plane {
  Vec3 n;
  double w;
};

/// The frustum's six planes: right, left, top, bottom, near, far.
std::array<Plane, 6> frustum_planes(const ViewBasis& b) {
  return {{{b.right - b.tanx * b.f, 0.0},
           {-b.right - b.tanx * b.f, 0.0},
           {b.up - b.tany * b.f, 0.0},
           {-b.up - b.tany * b.f, 0.0},
           {-b.f, -b.near},
           {b.f, b.far}}};
}

/// Whether the box [lo, hi] lies wholly outside the frustum of `b`, by far
/// more than any rounding of the rays (whose directions stray from the
/// frustum's planes by about 2^-53 * (1 + tanx + tany)^2 relative).
bool outside_frustum(const ViewBasis& b, const Vec3& lo, const Vec3& hi) {
  const std::array<Plane, 6> planes = frustum_planes(b);
  const double lens = (1.0 + b.tanx + b.tany) * (1.0 + b.tanx + b.tany);
  for (const Plane& p : planes) {
    double mn = 0.0;
    double mx = 0.0;
    double mag = 0.0;
    box_extent_along(p.n, b.eye, lo, hi, &mn, &mx, &mag);
    if (mn > p.w + 1e-9 * lens * (mag + std::abs(p.w)) + 1e-300) return true;
  }
  return false;
}

/// The hierarchy over the objects that may be hit under one camera.
class Bvh {
 public:
  Bvh(const std::vector<ObjectDesc>& objects, const ViewBasis& basis, MeshSet* meshes) {
    std::vector<BvhItem> items;
    items.reserve(objects.size());
    for (std::size_t i = 0; i < objects.size(); ++i) {
      BvhItem it;
      // A mesh's box comes from its hierarchy's root (no pass over its
      // vertices): the hierarchy is built on the mesh's first call, kept.
      leaf_box(objects[i], meshes->get(i), basis.eye, it.lo, it.hi);
      if (!(it.lo[0] <= it.hi[0]) ||
          outside_frustum(basis, Vec3(it.lo[0], it.lo[1], it.lo[2]), Vec3(it.hi[0], it.hi[1], it.hi[2])))
        continue;
      for (int a = 0; a < 3; ++a) it.c[a] = 0.5 * it.lo[a] + 0.5 * it.hi[a];
      it.index = static_cast<std::uint32_t>(i);
      items.push_back(it);
    }
    if (items.empty()) return;
    detail::build_bvh(items, &nodes_);
    objects_.reserve(items.size());
    index_.reserve(items.size());
    meshes_.reserve(items.size());
    for (const BvhItem& it : items) {
      objects_.push_back(objects[it.index]);
      index_.push_back(it.index);
      meshes_.push_back(meshes->get(it.index));
    }
  }

  /// Objects in leaf order, and their indices in the caller's vector.
  const std::vector<ObjectDesc>& objects() const { return objects_; }
  const std::vector<std::uint32_t>& index() const { return index_; }

  /// The first hits of the ray eye + t*d (positions in objects()), like
  /// cast() over every object; adds the ray–triangle tests to `*tests`.
  void cast(const ViewBasis& b, const Vec3& d, std::vector<std::uint32_t>* hits, std::uint64_t* tests) const {
    hits->clear();
    if (nodes_.empty()) return;
    const bool axis_zero[3] = {d.x == 0.0, d.y == 0.0, d.z == 0.0};
    struct Entry {
      std::uint32_t node;
      double t;
    };
    std::array<Entry, detail::kBvhStackSize> stack;
    int top = 0;
    double best = kInf;
    double t_root = 0.0;
    if (!enter(nodes_[0], b, d, axis_zero, &t_root)) return;
    stack[top++] = {0, t_root};
    while (top > 0) {
      const Entry e = stack[--top];
      // Strictly beyond: an object entered at exactly `best` ties.
      if (e.t > best) continue;
      const BvhNode& n = nodes_[e.node];
      if (n.count > 0) {
        for (std::uint32_t k = n.first; k < n.first + n.count; ++k) {
          double entry = 0.0;
          if (!clipped_entry(objects_[k], meshes_[k], b, d, &entry, tests)) continue;
          if (entry < best) {
            best = entry;
            hits->clear();
            hits->push_back(k);
          } else if (entry == best) {
            hits->push_back(k);
          }
        }
        continue;
      }
      double ta = 0.0;
      double tb = 0.0;
      const bool ha = enter(nodes_[n.first], b, d, axis_zero, &ta) && ta <= best;
      const bool hb = enter(nodes_[n.first + 1], b, d, axis_zero, &tb) && tb <= best;
      if (ha && hb) {
        // The nearer one on top.
        if (ta <= tb) {
          stack[top++] = {n.first + 1, tb};
          stack[top++] = {n.first, ta};
        } else {
          stack[top++] = {n.first, ta};
          stack[top++] = {n.first + 1, tb};
        }
      } else if (ha) {
        stack[top++] = {n.first, ta};
      } else if (hb) {
        stack[top++] = {n.first + 1, tb};
      }
    }
  }

 private:
  /// The node's box met by the ray within [near, far], and its entry clipped
  /// to near; the operations of intersect() for a box, so that the interval
  /// contains that of every box object inside.
  static bool enter(const BvhNode& n, const ViewBasis& b, const Vec3& d, const bool* axis_zero, double* t) {
    double lo_t = -kInf;
    double hi_t = kInf;
    for (int i = 0; i < 3; ++i) {
      if (axis_zero[i]) {
        if (b.eye[i] < n.lo[i] || b.eye[i] > n.hi[i]) return false;
        continue;
      }
      double ta = (n.lo[i] - b.eye[i]) / d[i];
      double tb = (n.hi[i] - b.eye[i]) / d[i];
      if (ta > tb) std::swap(ta, tb);
      lo_t = std::max(lo_t, ta);
      hi_t = std::min(hi_t, tb);
    }
    const double entry = std::max(lo_t, b.near);
    if (!(entry <= std::min(hi_t, b.far))) return false;
    *t = entry;
    return true;
  }

  std::vector<BvhNode> nodes_;
  std::vector<ObjectDesc> objects_;
  std::vector<std::uint32_t> index_;
  std::vector<const PlacedMesh*> meshes_;  ///< Per object: its triangles placed, or null.
};

/// The image points of `sampling`: the cells row by row, one ray each (at
/// its centre or jittered), then with `corners` the cones around the cell
/// corners, a row of corners at a time.
class Samples {
 public:
  explicit Samples(const RaySampling& s)
      : s_(s), cols_(std::max(1, s.cols)), rows_(std::max(1, s.rows)) {
    if (s_.corners) {
      std::vector<Ray> rays;
      for (int cy = 0; cy <= rows_; ++cy) {
        corner_row(cy, &rays);
        corner_rays_ += rays.size();
      }
    }
  }
  /// Rows of samples: the cell rows, then the corner rows.
  int rows() const { return rows_ + (s_.corners ? rows_ + 1 : 0); }
  std::size_t count() const { return static_cast<std::size_t>(cols_) * static_cast<std::size_t>(rows_) + corner_rays_; }
  /// The points of sample row `row`.
  void row(int row, std::vector<Ray>* out) const {
    out->clear();
    if (row < rows_) {
      const int cy = row;
      for (int cx = 0; cx < cols_; ++cx) {
        double jx = 0.5;
        double jy = 0.5;
        if (s_.jitter) {
          const std::uint64_t cell = static_cast<std::uint64_t>(cy) * static_cast<std::uint64_t>(cols_) +
                                     static_cast<std::uint64_t>(cx);
          const std::uint64_t h = splitmix64(s_.seed ^ splitmix64(cell));
          jx = unit_from_bits(h);
          jy = unit_from_bits(splitmix64(h));
        }
        out->push_back({-1.0 + 2.0 * (cx + jx) / cols_, -1.0 + 2.0 * (cy + jy) / rows_});
      }
      return;
    }
    corner_row(row - rows_, out);
  }

 private:
  /// The cones around the corners of row `cy` (raycast.h, RaySampling):
  /// four rays around each corner, at a radius of `cone` cells in the
  /// directions kConeDir, those strictly inside the image only.
  void corner_row(int cy, std::vector<Ray>* out) const {
    out->clear();
    const double y = cy == rows_ ? 1.0 : -1.0 + 2.0 * cy / rows_;
    const double rx = s_.cone * 2.0 / cols_;
    const double ry = s_.cone * 2.0 / rows_;
    for (int cx = 0; cx <= cols_; ++cx) {
      const double x = cx == cols_ ? 1.0 : -1.0 + 2.0 * cx / cols_;
      for (const auto& d : kConeDir) {
        const Ray r{x + rx * d[0], y + ry * d[1]};
        if (std::fabs(r.x) < 1.0 && std::fabs(r.y) < 1.0) out->push_back(r);
      }
    }
  }

  RaySampling s_;
  int cols_;
  int rows_;
  std::size_t corner_rays_ = 0;
};

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

/// visible_near_pixel's test, set up once for many pixels and objects: the
/// cone's rays cast by brute force (cast(), as first_hit) over the objects
/// whose projected bounding boxes overlap the target's (aim()), a superset
/// of those that may be entered before it on a ray that meets it; a ray is
/// cast only when it meets the target at all.
class NearPixel {
 public:
  NearPixel(const std::vector<ObjectDesc>& objects, const ViewBasis& basis, int width, int height)
      : objects_(objects), basis_(basis), width_(width), height_(height),
        rx_(kPixelCone * 2.0 / width), ry_(kPixelCone * 2.0 / height), meshes_(objects, basis.eye, false) {
    rects_.reserve(objects.size());
    for (std::size_t k = 0; k < objects.size(); ++k) rects_.push_back(project_box(k));
  }
  /// Takes objects[target] as the object to test from now on: its pixels
  /// and the objects that may hide it.
  void aim(std::size_t target) {
    target_ = target;
    // Two pixels of margin: far above the rounding of the projections, and
    // the cones reach 1e-3 pixel beyond the pixel centres.
    const double mx = 4.0 / width_;
    const double my = 4.0 / height_;
    const Rect& t = rects_[target];
    const Rect window{std::max(t.x0, -1.0) - mx, std::min(t.x1, 1.0) + mx, std::max(t.y0, -1.0) - my,
                      std::min(t.y1, 1.0) + my};
    cands_.clear();
    for (std::size_t k = 0; k < objects_.size(); ++k) {
      const Rect& r = rects_[k];
      if (k == target || (r.x0 <= window.x1 && r.x1 >= window.x0 && r.y0 <= window.y1 && r.y1 >= window.y0))
        cands_.push_back({k, -kInf, meshes_.get(k)});
    }
    // Pixel i's centre is at x = -1 + (2i+1)/width; a pixel more each side.
    auto pixel = [](double x, int n) { return std::clamp((x + 1.0) * 0.5 * n - 0.5, -2.0, n + 1.0); };
    i0_ = std::max(0, static_cast<int>(std::floor(pixel(t.x0, width_))) - 1);
    i1_ = std::min(width_ - 1, static_cast<int>(std::ceil(pixel(t.x1, width_))) + 1);
    j0_ = std::max(0, static_cast<int>(std::floor(pixel(t.y0, height_))) - 1);
    j1_ = std::min(height_ - 1, static_cast<int>(std::ceil(pixel(t.y1, height_))) + 1);
  }
  /// The pixels [i0, i1] x [j0, j1] whose cones may meet the target.
  int i0() const { return i0_; }
  int i1() const { return i1_; }
  int j0() const { return j0_; }
  int j1() const { return j1_; }
  /// Whether the target is first on some ray of the cone around the centre
  /// of pixel (i, j).
  bool visible(int i, int j) {
    const ObjectDesc& o = objects_[target_];
    const double x = -1.0 + 2.0 * (i + 0.5) / width_;
    const double y = -1.0 + 2.0 * (j + 0.5) / height_;
    for (const auto& c : kConeDir) {
      const Vec3 d = basis_.ray_dir(x + rx_ * c[0], y + ry_ * c[1]);
      double entry = 0.0;
      if (!clipped_entry(o, meshes_.get(target_), basis_, d, &entry, &tests_)) continue;
      cast(objects_, cands_, basis_, d, &hits_, &tests_);
      if (std::find(hits_.begin(), hits_.end(), target_) != hits_.end()) return true;
    }
    return false;
  }

 private:
  /// A rectangle of the image plane (x, y as in ViewBasis::ray_dir).
  struct Rect {
    double x0, x1, y0, y1;
  };
  /// Where the bounding box of objects[k] projects (a mesh's: the box of
  /// its hits, PlacedMesh::world_box); the whole plane when a corner is not
  /// in front of the eye (every ray that meets the object meets the box in
  /// front of the eye, so passes through the rectangle); nothing for a mesh
  /// object that cannot be hit.
  Rect project_box(std::size_t k) {
    const Rect whole{-kInf, kInf, -kInf, kInf};
    Rect r{kInf, -kInf, kInf, -kInf};
    Vec3 lo;
    Vec3 hi;
    if (objects_[k].shape == Shape::Mesh) {
      const PlacedMesh* mesh = meshes_.get(k);
      if (!mesh) return r;
      mesh->world_box(&lo, &hi);
    } else {
      object_bounds(objects_[k], &lo, &hi);
    }
    for (int c = 0; c < 8; ++c) {
      const Vec3 v = Vec3(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z) - basis_.eye;
      const double z = glm::dot(v, basis_.f);
      if (!(z > 0.0)) return whole;
      const double x = glm::dot(v, basis_.right) / (z * basis_.tanx);
      const double y = glm::dot(v, basis_.up) / (z * basis_.tany);
      if (!std::isfinite(x) || !std::isfinite(y)) return whole;
      r = {std::min(r.x0, x), std::max(r.x1, x), std::min(r.y0, y), std::max(r.y1, y)};
    }
    return r;
  }

  const std::vector<ObjectDesc>& objects_;
  ViewBasis basis_;
  int width_;
  int height_;
  double rx_;
  double ry_;
  MeshSet meshes_;
  std::vector<Rect> rects_;
  std::size_t target_ = 0;
  std::vector<Candidate> cands_;
  std::vector<std::size_t> hits_;
  std::uint64_t tests_ = 0;  ///< Ray–triangle tests (not reported).
  int i0_ = 0, i1_ = 0, j0_ = 0, j1_ = 0;
};

/// The index of the object `id` in `objects`, objects.size() when none.
std::size_t index_of(const std::vector<ObjectDesc>& objects, ObjectId id) {
  const auto it = std::find_if(objects.begin(), objects.end(), [id](const ObjectDesc& o) { return o.id == id; });
  return static_cast<std::size_t>(it - objects.begin());
}

}  // namespace

std::vector<ObjectId> visible_objects(const std::vector<ObjectDesc>& objects, const Camera& cam,
                                      const RaySampling& sampling, const CastOptions& options,
                                      CastStats* stats) {
  ViewBasis basis;
  CastStats local;
  CastStats& st = stats ? *stats : local;
  st = CastStats{};
  if (!make_basis(cam, &basis)) return {};
  const auto t_build = std::chrono::steady_clock::now();
  const Samples samples(sampling);
  st.rays = samples.count();
  MeshSet meshes(objects, basis.eye, options.brute_force);
  std::optional<Bvh> bvh;
  // Brute force: every object (a mesh with every triangle), in order.
  std::vector<Candidate> all;
  if (options.brute_force) {
    all.reserve(objects.size());
    for (std::size_t i = 0; i < objects.size(); ++i) all.push_back({i, -kInf, meshes.get(i)});
  } else {
    bvh.emplace(objects, basis, &meshes);
  }
  const std::size_t candidates = bvh ? bvh->objects().size() : objects.size();
  st.in_frustum = candidates;
  st.meshes_built = meshes.built();
  st.build_ms = ms_since(t_build);

  // Rows of samples to threads; each marks what it hits in its own flags.
  int threads = options.threads;
  if (threads <= 0) {
    threads = st.rays < 16384 || candidates == 0 ? 1 : static_cast<int>(std::thread::hardware_concurrency());
  }
  threads = std::clamp(threads, 1, std::max(1, samples.rows()));
  st.threads = threads;
  const auto t_cast = std::chrono::steady_clock::now();
  const auto nthreads = static_cast<std::size_t>(threads);
  std::vector<std::vector<char>> seen(nthreads, std::vector<char>(candidates, 0));
  std::vector<std::uint64_t> tests(nthreads, 0);
  std::atomic<int> next_row{0};
  auto work = [&](std::size_t k) {
    std::vector<char>& flags = seen[k];
    std::uint64_t count = 0;
    std::vector<Ray> rays;
    std::vector<std::uint32_t> hits;
    std::vector<std::size_t> brute_hits;
    for (int row = next_row++; row < samples.rows(); row = next_row++) {
      samples.row(row, &rays);
      for (const Ray& r : rays) {
        const Vec3 d = basis.ray_dir(r.x, r.y);
        if (bvh) {
          bvh->cast(basis, d, &hits, &count);
          for (std::uint32_t h : hits) flags[h] = 1;
        } else {
          cast(objects, all, basis, d, &brute_hits, &count);
          for (std::size_t h : brute_hits) flags[h] = 1;
        }
      }
    }
    tests[k] = count;
  };
  if (candidates > 0) {
    std::vector<std::thread> pool;
    for (std::size_t k = 1; k < nthreads; ++k) pool.emplace_back(work, k);
    work(0);
    for (std::thread& t : pool) t.join();
  }
  for (std::uint64_t n : tests) st.triangle_tests += n;
  std::vector<ObjectId> ids;
  for (std::size_t i = 0; i < candidates; ++i) {
    bool hit = false;
    for (const std::vector<char>& f : seen) hit = hit || f[i] != 0;
    if (hit) ids.push_back(objects[bvh ? bvh->index()[i] : i].id);
  }
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  st.cast_ms = ms_since(t_cast);
  return ids;
}

std::vector<ObjectId> first_hit(const std::vector<ObjectDesc>& objects, const Camera& cam, double x,
                                double y) {
  ViewBasis basis;
  if (!make_basis(cam, &basis)) return {};
  MeshSet meshes(objects, basis.eye, false);
  std::vector<Candidate> cands;
  cands.reserve(objects.size());
  for (std::size_t i = 0; i < objects.size(); ++i) cands.push_back({i, -kInf, meshes.get(i)});
  std::vector<std::size_t> hits;
  std::uint64_t tests = 0;
  cast(objects, cands, basis, basis.ray_dir(x, y), &hits, &tests);
  std::vector<ObjectId> ids;
  for (std::size_t h : hits) ids.push_back(objects[h].id);
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  return ids;
}

bool visible_near_pixel(const std::vector<ObjectDesc>& objects, const Camera& cam, int width, int height, int i,
                        int j, ObjectId id) {
  ViewBasis basis;
  if (!make_basis(cam, &basis) || width < 1 || height < 1) return false;
  const std::size_t target = index_of(objects, id);
  if (target == objects.size()) return false;
  NearPixel near(objects, basis, width, height);
  near.aim(target);
  return near.visible(i, j);
}

void confirm_near_pixels(const std::vector<ObjectDesc>& objects, const Camera& cam, int width, int height,
                         const std::vector<ObjectId>& pixel_ids, const std::vector<ObjectId>& seen,
                         std::vector<ObjectId>* confirmed, std::vector<ObjectId>* dismissed) {
  confirmed->clear();
  dismissed->clear();
  std::vector<ObjectId> ids = seen;
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  ViewBasis basis;
  if (ids.empty() || !make_basis(cam, &basis) || width < 1 || height < 1) {
    *dismissed = ids;
    return;
  }
  std::unordered_map<ObjectId, std::size_t> index;
  for (std::size_t k = 0; k < objects.size(); ++k) index.emplace(objects[k].id, k);
  // ids[k]'s object, objects.size() for an id the scene lacks (never confirmed).
  std::vector<std::size_t> target(ids.size(), objects.size());
  for (std::size_t k = 0; k < ids.size(); ++k)
    if (const auto at = index.find(ids[k]); at != index.end()) target[k] = at->second;
  NearPixel near(objects, basis, width, height);
  std::vector<char> ok(ids.size(), 0);
  const auto w = static_cast<std::size_t>(width);
  const bool by_image = pixel_ids.size() == w * static_cast<std::size_t>(height);
  for (std::size_t k = 0; k < ids.size(); ++k) {
    if (target[k] == objects.size()) continue;
    near.aim(target[k]);
    // Among the pixels whose cones may meet it (no other can confirm it),
    // those showing it (a pixel showing nothing, 0, is tried for object 0
    // too: a superset of its pixels), or all of them.
    for (int j = near.j0(); j <= near.j1() && !ok[k]; ++j)
      for (int i = near.i0(); i <= near.i1() && !ok[k]; ++i) {
        const std::size_t p = static_cast<std::size_t>(j) * w + static_cast<std::size_t>(i);
        if (!by_image || pixel_ids[p] == ids[k]) ok[k] = near.visible(i, j) ? 1 : 0;
      }
  }
  for (std::size_t k = 0; k < ids.size(); ++k) (ok[k] ? confirmed : dismissed)->push_back(ids[k]);
}

std::size_t voxels_in_view(const std::vector<ObjectDesc>& objects, const Camera& cam, const Vec3& bmin,
                           const Vec3& bmax, const glm::ivec3& res, const RaySampling& sampling) {
  ViewBasis basis;
  if (!make_basis(cam, &basis) || res.x < 1 || res.y < 1 || res.z < 1) return 0;
  // Only objects that may meet the frustum can be hit.
  const std::vector<ObjectId> in = frustum_objects(objects, cam);
  // Nearest first, each with the least depth its box can have, so that a
  // ray stops looking once nothing left can come nearer than its hit.
  MeshSet meshes(objects, basis.eye, false);
  std::vector<Candidate> cands;
  for (std::size_t i = 0; i < objects.size(); ++i) {
    if (!std::binary_search(in.begin(), in.end(), objects[i].id)) continue;
    const ObjectDesc& o = objects[i];
    Vec3 c = o.center;
    Vec3 h = o.shape == Shape::Sphere ? Vec3(o.radius) : o.half_extent;
    const PlacedMesh* mesh = meshes.get(i);
    if (o.shape == Shape::Mesh) {
      // The box of every hit the caster computes on it.
      if (!mesh) continue;
      Vec3 lo, hi;
      mesh->world_box(&lo, &hi);
      c = 0.5 * lo + 0.5 * hi;
      h = hi - c;
    }
    const Vec3& f = basis.f;
    const double zmin = glm::dot(f, c - basis.eye) -
                        (std::abs(f.x) * h.x + std::abs(f.y) * h.y + std::abs(f.z) * h.z);
    cands.push_back({i, zmin, mesh});
  }
  std::sort(cands.begin(), cands.end(), [](const Candidate& a, const Candidate& b) { return a.zmin < b.zmin; });
  const Vec3 vs = (bmax - bmin) / Vec3(res);
  std::vector<char> seen(static_cast<std::size_t>(res.x) * static_cast<std::size_t>(res.y) *
                             static_cast<std::size_t>(res.z),
                         0);
  std::size_t count = 0;
  std::vector<std::size_t> hits;
  std::uint64_t tests = 0;
  for (int row = 0; row < sampling.rows; ++row)
    for (int col = 0; col < sampling.cols; ++col) {
      const double x = -1.0 + (2.0 * col + 1.0) / sampling.cols;
      const double y = -1.0 + (2.0 * row + 1.0) / sampling.rows;
      const Vec3 d = basis.ray_dir(x, y);
      cast(objects, cands, basis, d, &hits, &tests);
      double t_end = basis.far;
      for (std::size_t h : hits) {
        double entry = 0.0;
        if (clipped_entry(objects[h], meshes.get(h), basis, d, &entry, &tests)) t_end = std::min(t_end, entry);
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
  const std::array<Plane, 6> planes = frustum_planes(b);
  std::vector<ObjectId> ids;
  for (const ObjectDesc& obj : objects) {
    Vec3 lo;
    Vec3 hi;
    object_bounds(obj, &lo, &hi);
    if (!(lo.x <= hi.x)) continue;  // A mesh object without triangles.
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

}  // namespace voxvis::raycast
