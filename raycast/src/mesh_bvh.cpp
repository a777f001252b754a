// mesh_bvh.cpp — see mesh_bvh.h.
#include "mesh_bvh.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <mutex>
#include <utility>

#include <glm/gtc/quaternion.hpp>

#include "voxvis/mesh.h"

namespace voxvis::raycast::detail {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

double max_abs3(const Vec3& v) { return std::max({std::fabs(v.x), std::fabs(v.y), std::fabs(v.z)}); }

/// A ray in a mesh's model frame, set up for the watertight test: kz the
/// axis of the direction's largest magnitude, kx and ky the others (swapped
/// when dir[kz] < 0, as the paper does to keep the triangles' winding; both
/// windings are hits here), and the shear sx, sy, sz.
struct ModelRay {
  Vec3 org;
  Vec3 dir;
  int kx = 0, ky = 1, kz = 2;
  double sx = 0.0, sy = 0.0, sz = 1.0;
  double pad = 0.0;  ///< How much the boxes grow, model units (mesh_bvh.h).
};

bool make_ray(const Vec3& org, const Vec3& dir, double pad, ModelRay* r) {
  const Vec3 a(std::fabs(dir.x), std::fabs(dir.y), std::fabs(dir.z));
  const int kz = a.x >= a.y ? (a.x >= a.z ? 0 : 2) : (a.y >= a.z ? 1 : 2);
  if (!(a[kz] > 0.0) || !std::isfinite(a[kz])) return false;
  r->org = org;
  r->dir = dir;
  r->kz = kz;
  r->kx = (kz + 1) % 3;
  r->ky = (r->kx + 1) % 3;
  if (dir[kz] < 0.0) std::swap(r->kx, r->ky);
  r->sx = dir[r->kx] / dir[kz];
  r->sy = dir[r->ky] / dir[kz];
  r->sz = 1.0 / dir[kz];
  r->pad = pad;
  return true;
}

/// The watertight test (mesh_bvh.h): whether the ray meets triangle
/// (p0, p1, p2), on either face, and where (t, into `*t`).
bool hit_triangle(const ModelRay& r, const Vec3& p0, const Vec3& p1, const Vec3& p2, double* t) {
  const Vec3 a = p0 - r.org;
  const Vec3 b = p1 - r.org;
  const Vec3 c = p2 - r.org;
  const double ax = a[r.kx] - r.sx * a[r.kz];
  const double ay = a[r.ky] - r.sy * a[r.kz];
  const double bx = b[r.kx] - r.sx * b[r.kz];
  const double by = b[r.ky] - r.sy * b[r.kz];
  const double cx = c[r.kx] - r.sx * c[r.kz];
  const double cy = c[r.ky] - r.sy * c[r.kz];
  const double u = cx * by - cy * bx;
  const double v = ax * cy - ay * cx;
  const double w = bx * ay - by * ax;
  if ((u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0)) return false;
  const double det = u + v + w;
  // Zero: the ray lies in the triangle's plane (or U, V, W all rounded to
  // 0), a grazing ray, of measure zero; no depth to give.
  if (det == 0.0) return false;
  const double az = r.sz * a[r.kz];
  const double bz = r.sz * b[r.kz];
  const double cz = r.sz * c[r.kz];
  *t = (u * az + v * bz + w * cz) / det;
  return std::isfinite(*t);
}

/// The parameter interval [t0, t1] of the ray within the node's box grown by
/// r.pad, cut to [lo, hi]; false when empty.
bool enter(const BvhNode& n, const ModelRay& r, double lo, double hi, double* t0, double* t1) {
  double a = lo;
  double b = hi;
  for (int i = 0; i < 3; ++i) {
    const double blo = n.lo[i] - r.pad;
    const double bhi = n.hi[i] + r.pad;
    if (r.dir[i] == 0.0) {
      if (r.org[i] < blo || r.org[i] > bhi) return false;
      continue;
    }
    double ta = (blo - r.org[i]) / r.dir[i];
    double tb = (bhi - r.org[i]) / r.dir[i];
    if (ta > tb) std::swap(ta, tb);
    a = std::max(a, ta);
    b = std::min(b, tb);
  }
  if (!(a <= b)) return false;
  *t0 = a;
  *t1 = b;
  return true;
}

/// The triangle `k` of `mesh` against the ray: its t when it is hit within
/// [lo, hi].
bool triangle_within(const Mesh& mesh, std::uint32_t k, const ModelRay& r, double lo, double hi, double* t) {
  const auto& tri = mesh.triangles[k];
  double th = 0.0;
  if (!hit_triangle(r, mesh.vertices[tri[0]], mesh.vertices[tri[1]], mesh.vertices[tri[2]], &th)) return false;
  if (!(th >= lo && th <= hi)) return false;
  *t = th;
  return true;
}

}  // namespace

MeshBvh::MeshBvh(const Mesh& mesh) {
  for (const Vec3& v : mesh.vertices) max_abs_ = std::max(max_abs_, max_abs3(v));
  const std::size_t n = mesh.triangles.size();
  if (n == 0) return;
  std::vector<BvhItem> items(n);
  for (std::size_t k = 0; k < n; ++k) {
    const auto& tri = mesh.triangles[k];
    const Vec3& p0 = mesh.vertices[tri[0]];
    const Vec3& p1 = mesh.vertices[tri[1]];
    const Vec3& p2 = mesh.vertices[tri[2]];
    BvhItem& it = items[k];
    for (int a = 0; a < 3; ++a) {
      it.lo[a] = std::min({p0[a], p1[a], p2[a]});
      it.hi[a] = std::max({p0[a], p1[a], p2[a]});
      it.c[a] = 0.5 * it.lo[a] + 0.5 * it.hi[a];
    }
    it.index = static_cast<std::uint32_t>(k);
  }
  build_bvh(items, &nodes_);
  order_.reserve(n);
  for (const BvhItem& it : items) order_.push_back(it.index);
}

std::shared_ptr<const MeshBvh> mesh_bvh(const std::shared_ptr<const Mesh>& mesh, bool* built) {
  struct Entry {
    std::weak_ptr<const Mesh> mesh;
    std::shared_ptr<const MeshBvh> bvh;
  };
  static std::mutex mu;
  static std::unordered_map<const Mesh*, Entry> cache;  // Guarded by mu.
  if (built) *built = false;
  {
    const std::lock_guard<std::mutex> lock(mu);
    // An entry whose mesh still lives is this mesh: no other object can
    // have its address while it lives.
    if (const auto it = cache.find(mesh.get()); it != cache.end() && !it->second.mesh.expired()) return it->second.bvh;
  }
  // Built outside the lock: other meshes' look-ups need not wait for it.
  auto bvh = std::make_shared<const MeshBvh>(*mesh);
  const std::lock_guard<std::mutex> lock(mu);
  std::erase_if(cache, [](const auto& e) { return e.second.mesh.expired(); });
  const auto [it, added] = cache.try_emplace(mesh.get(), Entry{mesh, bvh});
  if (!added) return it->second.bvh;  // Another thread built it meanwhile.
  if (built) *built = true;
  return bvh;
}

PlacedMesh::PlacedMesh(const ObjectDesc& o, const Vec3& eye, std::shared_ptr<const MeshBvh> bvh)
    : mesh_(o.mesh.get()), bvh_(std::move(bvh)) {
  const Quat q = unit_rotation(o.rotation);
  to_model_ = glm::mat3_cast(glm::conjugate(q)) / o.scale;
  org_ = to_model_ * (eye - o.center);
  double max_abs = 0.0;
  Vec3 mlo(kInf), mhi(-kInf);
  if (bvh_ && !bvh_->nodes().empty()) {
    max_abs = bvh_->max_abs();
    const BvhNode& root = bvh_->nodes()[0];
    mlo = Vec3(root.lo[0], root.lo[1], root.lo[2]);
    mhi = Vec3(root.hi[0], root.hi[1], root.hi[2]);
  } else {
    for (const auto& tri : mesh_->triangles)
      for (std::uint32_t k : tri) {
        const Vec3& v = mesh_->vertices[k];
        mlo = glm::min(mlo, v);
        mhi = glm::max(mhi, v);
        max_abs = std::max(max_abs, max_abs3(v));
      }
  }
  pad_ = 1e-12 * (max_abs3(org_) + max_abs);
  // The world box: the model box's corners placed (voxvis/mesh.h, place()),
  // grown.
  box_lo_ = Vec3(kInf);
  box_hi_ = Vec3(-kInf);
  if (mesh_->triangles.empty()) return;
  for (int c = 0; c < 8; ++c) {
    const Vec3 corner(c & 1 ? mhi.x : mlo.x, c & 2 ? mhi.y : mlo.y, c & 4 ? mhi.z : mlo.z);
    const Vec3 w = place(o, corner);
    box_lo_ = glm::min(box_lo_, w);
    box_hi_ = glm::max(box_hi_, w);
  }
  const double margin = 1e-10 * (max_abs3(o.center) + max_abs3(eye - o.center) + o.scale * max_abs);
  box_lo_ -= Vec3(margin);
  box_hi_ += Vec3(margin);
}

bool PlacedMesh::hit(const Vec3& d, double lo, double hi, bool last, double* t, std::uint64_t* tests) const {
  ModelRay r;
  if (!(lo <= hi) || !make_ray(org_, to_model_ * d, pad_, &r)) return false;
  const Mesh& mesh = *mesh_;
  bool found = false;
  double best = last ? lo : hi;  // The nearer (farther) end of what is left.
  auto take = [&](std::uint32_t k) {
    ++*tests;
    double th = 0.0;
    if (!triangle_within(mesh, k, r, last ? best : lo, last ? hi : best, &th)) return;
    found = true;
    best = th;
  };
  if (!bvh_) {
    const auto n = static_cast<std::uint32_t>(mesh.triangles.size());
    for (std::uint32_t k = 0; k < n; ++k) take(k);
    if (found) *t = best;
    return found;
  }
  const std::vector<BvhNode>& nodes = bvh_->nodes();
  const std::vector<std::uint32_t>& order = bvh_->order();
  if (nodes.empty()) return false;
  struct Entry {
    std::uint32_t node;
    double t0, t1;
  };
  std::array<Entry, kBvhStackSize> stack;
  int top = 0;
  double t0 = 0.0, t1 = 0.0;
  if (!enter(nodes[0], r, lo, hi, &t0, &t1)) return false;
  stack[top++] = {0, t0, t1};
  while (top > 0) {
    const Entry e = stack[--top];
    // Nothing in the box can improve on the best hit so far.
    if (last ? e.t1 < best : e.t0 > best) continue;
    const BvhNode& n = nodes[e.node];
    if (n.count > 0) {
      for (std::uint32_t k = n.first; k < n.first + n.count; ++k) take(order[k]);
      continue;
    }
    Entry c[2];
    bool h[2];
    for (int s = 0; s < 2; ++s) {
      c[s].node = n.first + static_cast<std::uint32_t>(s);
      h[s] = enter(nodes[c[s].node], r, last ? best : lo, last ? hi : best, &c[s].t0, &c[s].t1);
    }
    // The more promising child on top: the nearer entry (the farther exit).
    const bool second_first = last ? c[1].t1 > c[0].t1 : c[1].t0 < c[0].t0;
    const int first = h[0] && h[1] ? (second_first ? 1 : 0) : (h[0] ? 0 : 1);
    if (h[0] && h[1]) stack[top++] = c[1 - first];
    if (h[first]) stack[top++] = c[first];
  }
  if (found) *t = best;
  return found;
}

MeshSet::MeshSet(const std::vector<ObjectDesc>& objects, const Vec3& eye, bool brute_force)
    : objects_(objects), eye_(eye), brute_force_(brute_force), slot_(objects.size(), -1) {}

const PlacedMesh* MeshSet::get(std::size_t i) {
  const ObjectDesc& o = objects_[i];
  if (o.shape != Shape::Mesh || !o.mesh) return nullptr;
  if (slot_[i] >= 0) return &placed_[static_cast<std::size_t>(slot_[i])];
  std::shared_ptr<const MeshBvh> bvh;
  if (!brute_force_) {
    auto& known = bvhs_[o.mesh.get()];
    if (!known) {
      bool built = false;
      known = mesh_bvh(o.mesh, &built);
      built_ += built ? 1 : 0;
    }
    bvh = known;
  }
  slot_[i] = static_cast<std::int32_t>(placed_.size());
  placed_.emplace_back(o, eye_, std::move(bvh));
  return &placed_.back();
}

}  // namespace voxvis::raycast::detail
