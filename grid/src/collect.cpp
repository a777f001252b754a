// collect.cpp — see collect.h.
#include "collect.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "numeric.h"
#include "opaque_boxes.h"

namespace voxvis::detail {

namespace {

/// Adds the ticks of its scope to a counter (Scratch::Impl::render_ticks).
/// No clock read per occluder: a clock can be a system call (a CPU-time
/// clock is), and the frame's own two reads are what timing tools replace.
class ScopedTicks {
 public:
  explicit ScopedTicks(std::uint64_t& sum) : sum_(sum), t0_(ticks()) {}
  ~ScopedTicks() { sum_ += ticks() - t0_; }
  ScopedTicks(const ScopedTicks&) = delete;
  ScopedTicks& operator=(const ScopedTicks&) = delete;

 private:
  std::uint64_t& sum_;
  std::uint64_t t0_;
};
}  // namespace

bool eye_too_far(const Vec3& eye_grid) { return max_abs(eye_grid) > 0x1p40; }

bool ob_hides_object(const OcclusionBuffer& ob, const Obj& o, bool fine) {
  return o.shape == Shape::Sphere ? ob.hides_sphere(o.center, o.radius, fine)
                                  : ob.hides_world(o.box_lo(), o.box_hi(), fine);
}

bool ob_hides_tbv(const OcclusionBuffer& ob, const Obj& o) { return ob.hides_world_split(o.tbv_lo, o.tbv_hi, 3); }

bool make_frame_geometry(const Scene::Impl& s, const WorldFrustum& wf, FrameGeometry* out) {
  FrameGeometry& g = *out;
  const GridSpec& spec = s.spec;
  g.eg = s.to_grid(wf.eye);
  for (int a = 0; a < 3; ++a) {
    g.E[a] = static_cast<std::int64_t>(std::floor(g.eg[a]));
    g.glo[a] = -g.E[a];
    g.ghi[a] = s.res[a] - 1 - g.E[a];
  }
  g.stride[0] = 1;
  g.stride[1] = s.res.x;
  g.stride[2] = std::int64_t{s.res.x} * s.res.y;
  const Vec3 e = g.eg - Vec3(static_cast<double>(g.E[0]), static_cast<double>(g.E[1]), static_cast<double>(g.E[2]));
  // Depth of the farthest grid corner bounds the pyramid we need.
  double dmax = -std::numeric_limits<double>::infinity();
  for (int c = 0; c < 8; ++c) {
    const Vec3 p{(c & 1) ? spec.bounds_max.x : spec.bounds_min.x, (c & 2) ? spec.bounds_max.y : spec.bounds_min.y,
                 (c & 4) ? spec.bounds_max.z : spec.bounds_min.z};
    dmax = std::fmax(dmax, glm::dot(p - wf.eye, wf.f));
  }
  const double world_scale = max_abs(wf.eye) + s.slop_bounds + 1.0;
  const double far_eff = std::fmin(wf.far, dmax + 1e-9 * world_scale + 1e-9);
  if (!(far_eff >= wf.near - 1e-9 * world_scale)) return false;  // The grid is wholly before near or behind.
  const double vmin = std::fmin(spec.voxel_size.x, std::fmin(spec.voxel_size.y, spec.voxel_size.z));
  const double vmax = std::fmax(spec.voxel_size.x, std::fmax(spec.voxel_size.y, spec.voxel_size.z));
  // Rounding allowance, local grid units: the eye's mapping, then the size of
  // the numbers the shells reach.
  g.tol = 1e-9 + 64.0 * kUlp * (world_scale / vmin + max_abs(g.eg) + double(std::max({s.res.x, s.res.y, s.res.z})));
  g.lf = make_local_frustum(wf, e, spec.voxel_size, far_eff, g.tol);
  g.depth_tol = 4.0 * g.tol * vmax + 1e-9 * world_scale;
  g.vs = spec.voxel_size;
  g.outside_meshes = s.any_closed_mesh && mesh_tip_clear(s, wf);
  g.mesh_interiors = g.outside_meshes && !s.brick_mesh_boxes.ids.empty();
  return true;
}

void Collector::add(std::uint32_t slot) {
  std::uint32_t& seen = w_.obj_seen[slot];
  if (seen == w_.frame) return;
  seen = w_.frame;
  const Obj& o = s_.objs[slot];
  if (!wf_.may_intersect_box(o.box_lo(), o.box_hi())) return;
  if (!o.dynamic && own_voxels_hidden(o)) {
    ++st_.front_objects_culled;
    return;
  }
  OcclusionBuffer& ob = w_.ob;
  if (ob.on()) {
    if (ob_hides_object(ob, o)) {
      ++st_.ob_objects_culled;
      return;
    }
    // Every object the frame finds is an occluder, at the position the
    // scene has for it (the one it is visible at): a mesh by its triangles
    // (a static one's are drawn brick by brick as the traversal reaches
    // them, render_brick_triangles; its box is not solid).
    if (o.shape == Shape::Mesh) {
      if (o.dynamic) render_mesh(o);
    } else {
      const ScopedTicks timed(w_.render_ticks);
      const bool wrote =
          o.shape == Shape::Sphere ? ob.render_sphere(o.center, o.radius) : ob.render_box(o.box_lo(), o.box_hi());
      if (wrote) ++st_.ob_occluders;
    }
  }
  w_.obj_mark[slot] = w_.frame;
  w_.pvs.push_back(slot);
}

void Collector::reveal(std::uint32_t slot) {
  // A TBV reached as not occluded may hold the object anywhere in view, but
  // the object itself is where it was last reported: it goes into the PVS
  // whenever its box meets the frustum, with no occlusion test, and the TBV
  // is dropped after the traversal. Both only add to the PVS (the object's own
  // voxels do not occlude in this frame), so deferring keeps the frame
  // conservative while the traversal stays read-only.
  if (w_.obj_seen[slot] == w_.frame) return;  // Already handled this frame.
  const Obj& o = s_.objs[slot];
  if (w_.ob.on() && ob_hides_tbv(w_.ob, o)) {
    // Every position the object can reach before the TBV expires is hidden
    // now: nothing to reveal, and the object (inside the TBV) is hidden too.
    w_.obj_seen[slot] = w_.frame;
    ++st_.ob_objects_culled;
    return;
  }
  w_.deferred.push_back(slot);
  add(slot);
}

void Collector::reveal_part(std::uint32_t slot, const Vec3& lo, const Vec3& hi) {
  if (w_.obj_seen[slot] == w_.frame) return;
  const Obj& o = s_.objs[slot];
  const Vec3 plo = glm::max(o.tbv_lo, lo), phi = glm::min(o.tbv_hi, hi);
  // Hidden here says nothing of its other parts: not marked handled.
  if (w_.ob.on() && glm::all(glm::lessThanEqual(plo, phi)) && w_.ob.hides_world_split(plo, phi, 3)) return;
  reveal(slot);
}

void Collector::render_opaque_box_at(std::uint32_t b) {
  if (b == kNoBox || w_.box_seen[b] == w_.frame) return;
  w_.box_seen[b] = w_.frame;
  const VoxBox& vb = s_.opaque_boxes[b];
  const GridSpec& spec = s_.spec;
  const Vec3 lo = spec.bounds_min + Vec3(vb.lo) * spec.voxel_size;
  const Vec3 hi = spec.bounds_min + Vec3(vb.hi + 1) * spec.voxel_size;
  const ScopedTicks timed(w_.render_ticks);
  if (w_.ob.render_box(lo, hi)) ++st_.ob_occluders;
}

bool mesh_tip_clear(const Scene::Impl& s, const WorldFrustum& wf) {
  Vec3 lo = wf.eye, hi = wf.eye;
  for (const Vec3& c : wf.tip()) {
    lo = glm::min(lo, c);
    hi = glm::max(hi, c);
  }
  if (!std::isfinite(lo.x + lo.y + lo.z + hi.x + hi.y + hi.z)) return false;
  const double mag = max_abs(lo) + max_abs(hi);
  // Grown by more than the rounding of the corners (a few ulps of mag).
  const double grow = 1e-9 * mag + s.slop(mag);
  if (s.closed_mesh_beyond_grid && !s.box_inside_grid(lo - grow, hi + grow)) return false;
  const VoxBox vb = s.touch_range(lo - grow, hi + grow, s.slop(mag));
  if (vb.empty()) return true;  // Wholly beyond the grid, and no closed mesh is.
  const glm::ivec3 n = vb.hi - vb.lo + 1;
  if (std::int64_t{n.x} * n.y * n.z > 4096) return false;
  for (int z = vb.lo.z; z <= vb.hi.z; ++z)
    for (int y = vb.lo.y; y <= vb.hi.y; ++y)
      for (int x = vb.lo.x; x <= vb.hi.x; ++x)
        if (s.vflags[static_cast<std::size_t>(s.index(x, y, z))] & (Scene::Impl::kMeshInside | Scene::Impl::kMeshTouched))
          return false;
  return true;
}

void Collector::render_brick_triangles(std::size_t bi) {
  if (g_.mesh_interiors)
    for (const std::uint32_t* p = s_.brick_mesh_boxes.begin(bi); p != s_.brick_mesh_boxes.end(bi); ++p)
      render_opaque_box_at(*p);
  if (s_.brick_tri_offsets.empty()) return;
  const std::uint32_t first = s_.brick_tri_offsets[bi], last = s_.brick_tri_offsets[bi + 1];
  if (first == last) return;
  const ScopedTicks timed(w_.render_ticks);
  for (std::uint32_t k = first; k < last; ++k) {
    const TriRef& t = s_.brick_tris[k];
    const Obj& o = s_.objs[t.slot];
    std::uint32_t& seen = w_.tri_seen[o.tri_base + t.tri];
    if (seen == w_.frame) continue;
    seen = w_.frame;
    const std::uint32_t partner = o.quads->partner[t.tri];
    if (partner != MeshQuads::kNone) w_.tri_seen[o.tri_base + partner] = w_.frame;
    render_triangle_of(o, o.placed.data(), t.tri);
  }
}

void Collector::render_mesh(const Obj& o) {
  const ScopedTicks timed(w_.render_ticks);
  const ObjectDesc d = o.mesh_desc();
  const Mesh& mesh = *o.mesh;
  // A mesh whose every triangle would be dropped as under a pixel (its
  // ball, radius and allowance, is) places no vertex.
  const bool triangles = !w_.ob.ball_below_a_pixel(o.center, o.half.x);
  std::vector<Vec3>& p = w_.placed;
  if (triangles) {
    p.resize(mesh.vertices.size());
    for (std::size_t i = 0; i < p.size(); ++i) p[i] = place(d, mesh.vertices[i]);
  }
  if (o.interior && model_tip_clear(o)) {
    // Its interior, as oriented boxes where it is (docs/design.md, "Meshes").
    const Quat q = o.mesh_rotation;
    const Vec3 axes[3] = {q * Vec3(1, 0, 0), q * Vec3(0, 1, 0), q * Vec3(0, 0, 1)};
    const double err = 2.0 * o.mesh_allowance();
    for (const ModelInterior::Box& b : o.interior->boxes)
      if (w_.ob.render_oriented_box(place(d, b.center), axes, o.mesh_scale * b.half, err)) ++st_.ob_occluders;
  }
  const std::uint32_t n = triangles ? static_cast<std::uint32_t>(mesh.triangles.size()) : 0;
  for (std::uint32_t t = 0; t < n; ++t) {
    const std::uint32_t partner = o.quads->partner[t];
    if (partner == MeshQuads::kNone || partner > t) render_triangle_of(o, p.data(), t);
  }
}

bool Collector::model_tip_clear(const Obj& o) const {
  // The frustum's tip (the eye and the near rectangle) in the mesh's frame:
  // model = rotate(q^-1, world - origin) / scale, its cubes grown by one for
  // the rounding of that map.
  const ModelInterior& in = *o.interior;
  const Quat qi = glm::conjugate(o.mesh_rotation);
  Vec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
  for (const Vec3& w : wf_.tip()) {
    const Vec3 m = (qi * (w - o.mesh_origin)) / o.mesh_scale;
    lo = glm::min(lo, m);
    hi = glm::max(hi, m);
  }
  const Vec3 glo = (lo - in.lo) / in.h - 1.0, ghi = (hi - in.lo) / in.h + 1.0;
  if (!std::isfinite(glo.x + glo.y + glo.z + ghi.x + ghi.y + ghi.z)) return false;
  glm::ivec3 a, b;
  for (int k = 0; k < 3; ++k) {
    // Beyond the cubes is beyond the mesh's box: outside it.
    if (ghi[k] < 0.0 || glo[k] > in.n[k]) return true;
    a[k] = static_cast<int>(std::fmax(std::floor(glo[k]), 0.0));
    b[k] = static_cast<int>(std::fmin(std::floor(ghi[k]), in.n[k] - 1.0));
  }
  if (std::int64_t{b.x - a.x + 1} * (b.y - a.y + 1) * (b.z - a.z + 1) > 4096) return false;
  for (int z = a.z; z <= b.z; ++z)
    for (int y = a.y; y <= b.y; ++y)
      for (int x = a.x; x <= b.x; ++x)
        if (in.at(x, y, z) != 0) return false;
  return true;
}

void Collector::render_triangle_of(const Obj& o, const Vec3* p, std::uint32_t t) {
  const double err = o.mesh_allowance();
  const std::uint32_t partner = o.quads->partner[t];
  if (o.outward != 0 && g_.outside_meshes) {
    // A closed mesh seen from outside: a ray meeting a triangle from behind
    // (its outer side facing away) has met the mesh before. Leaving an
    // occluder out is conservative whatever the eye.
    const Vec3& eye = w_.ob.eye();
    auto facing_away = [&](std::uint32_t k) {
      const auto& a = o.mesh->triangles[k];
      return o.outward * glm::dot(glm::cross(p[a[1]] - p[a[0]], p[a[2]] - p[a[0]]), p[a[0]] - eye) > 0.0;
    };
    if (facing_away(t) && (partner == MeshQuads::kNone || facing_away(partner))) return;
  }
  bool raised = false;
  if (partner != MeshQuads::kNone) {
    const auto& q = o.quads->quad[t];
    const Vec3 corners[4] = {p[q[0]], p[q[1]], p[q[2]], p[q[3]]};
    if (!w_.ob.render_quad(corners, err, &raised)) {
      // Not drawable as one quad here (crossing the near plane, or its
      // image not convex): its two triangles.
      const auto& a = o.mesh->triangles[t];
      const auto& b = o.mesh->triangles[partner];
      raised = w_.ob.render_triangle(p[a[0]], p[a[1]], p[a[2]], err);
      raised = w_.ob.render_triangle(p[b[0]], p[b[1]], p[b[2]], err) || raised;
    }
  } else {
    const auto& a = o.mesh->triangles[t];
    raised = w_.ob.render_triangle(p[a[0]], p[a[1]], p[a[2]], err);
  }
  if (raised) ++st_.ob_occluders;
}

bool Collector::front_blocked(const std::int64_t v[3], std::int64_t idx) const {
  // Every ray from the eye first meets the closed voxel at a point q; but
  // for a set of rays of measure zero (those meeting it first on an edge or
  // a corner), q lies inside a face towards the eye, across an axis a where
  // the eye lies outside v's slab, and the ray's points just before q lie in
  // the face neighbour v + step_a. When those neighbours are all static
  // opaque and wholly beyond the near plane, every such ray is inside an
  // object strictly before q, so no point of v is the first hit on a set of
  // rays of positive measure. This reaches what the shells' exit rule
  // cannot: a voxel just under a surface seen at a grazing angle, whose rays
  // come through neighbours of its own shell.
  int step[3];
  for (int a = 0; a < 3; ++a) {
    if (v[a] != 0) {
      // Towards the eye. A rounding that puts the true eye in v's slab
      // only asks for more neighbours than needed.
      step[a] = v[a] > 0 ? -1 : 1;
    } else if (g_.lf.e[a] >= g_.tol && g_.lf.e[a] <= 1.0 - g_.tol) {
      step[a] = 0;  // The eye lies in v's slab along a.
    } else {
      return false;  // Too near a face of its voxel to tell.
    }
  }
  if (step[0] == 0 && step[1] == 0 && step[2] == 0) return false;  // The eye's voxel.
  const std::uint8_t* flags = s_.vflags.data();
  for (int a = 0; a < 3; ++a) {
    if (step[a] == 0) continue;
    std::int64_t u[3] = {v[0], v[1], v[2]};
    u[a] += step[a];
    const std::int64_t ui = idx + step[a] * g_.stride[a];
    if (!g_.in_grid(u) || !(flags[static_cast<std::size_t>(ui)] & Scene::Impl::kStaticOpaque)) return false;
    const Vec3 lo{static_cast<double>(u[0]), static_cast<double>(u[1]), static_cast<double>(u[2])};
    if (!(g_.lf.depth_min(lo) >= g_.lf.near + g_.depth_tol)) return false;
  }
  return true;
}

bool Collector::own_voxels_hidden(const Obj& o) const {
  VoxBox vb;
  if (!s_.own_voxels(o, &vb)) return false;
  const glm::ivec3 n = vb.hi - vb.lo + 1;
  if (n.x * n.y * n.z > 8) return false;  // Small objects only: the test is per voxel.
  std::int64_t v[3];
  for (int z = vb.lo.z; z <= vb.hi.z; ++z)
    for (int y = vb.lo.y; y <= vb.hi.y; ++y)
      for (int x = vb.lo.x; x <= vb.hi.x; ++x) {
        v[0] = x - g_.E[0];
        v[1] = y - g_.E[1];
        v[2] = z - g_.E[2];
        if (!front_blocked(v, g_.gindex(v))) return false;
      }
  return true;
}

void Collector::see_voxel(int x, int y, int z) {
  static_assert(kBrickShift == 2, "a brick's voxels are the 64 bits of a mask");
  const std::size_t b = s_.pyr.index(1, glm::ivec3(x >> kBrickShift, y >> kBrickShift, z >> kBrickShift));
  std::uint64_t& seen = w_.seen_vox[b];
  if (seen == 0) w_.seen_list.push_back(static_cast<std::uint32_t>(b));
  seen |= std::uint64_t{1} << ((x & 3) | (y & 3) << 2 | (z & 3) << 4);
}

void Collector::see_brick(std::size_t b, std::uint64_t mask) {
  if (mask == 0) return;
  std::uint64_t& seen = w_.seen_vox[b];
  if (seen == 0) w_.seen_list.push_back(static_cast<std::uint32_t>(b));
  seen |= mask;
}

}  // namespace voxvis::detail
