// scene.cpp — a scene's conservative discretization (which voxels an object
// touches, which it fills, the union of objects' opacity), its viewers and
// its moves. The dynamic layer and the TBVs' life are in scene_tbv.cpp;
// building a scene (validation, the grid, the cost estimate) in build.cpp;
// the frame in frame.cpp.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include <glm/geometric.hpp>

#include "numeric.h"
#include "scene_impl.h"

namespace voxvis {

using detail::Obj;
using detail::VoxBox;
using detail::finite3;
using detail::clamp_floor;
using detail::kUlp;
using detail::max_abs;

// ---------------------------------------------------------------------------
// Scratch

Scratch::Scratch() : impl_(std::make_unique<Impl>()) {}
Scratch::~Scratch() = default;

void Scratch::Impl::begin(std::size_t objects, std::size_t boxes, std::size_t bricks, std::size_t cells,
                          std::size_t triangles) {
  pvs.clear();
  deferred.clear();
  // A frame that ended early (an error) may have left its seen record.
  for (std::uint32_t b : seen_list) seen_vox[b] = 0;
  seen_list.clear();
  seen_cells.clear();
  if (seen_vox.size() < bricks) seen_vox.resize(bricks, 0);
  if (obj_mark.size() < objects) obj_mark.resize(objects, 0);
  if (obj_seen.size() < objects) obj_seen.resize(objects, 0);
  if (box_seen.size() < boxes) box_seen.resize(boxes, 0);
  if (cell_seen.size() < cells) cell_seen.resize(cells, 0);
  if (tri_seen.size() < triangles) tri_seen.resize(triangles, 0);
  // Start the frame counter over before it wraps, so that no stale object
  // mark can ever match (stamp tags cycle separately, below).
  if (++frame == std::numeric_limits<std::uint32_t>::max()) {
    std::fill(obj_mark.begin(), obj_mark.end(), 0u);
    std::fill(obj_seen.begin(), obj_seen.end(), 0u);
    std::fill(box_seen.begin(), box_seen.end(), 0u);
    std::fill(cell_seen.begin(), cell_seen.end(), 0u);
    std::fill(tri_seen.begin(), tri_seen.end(), 0u);
    frame = 1;
  }
  pvs.clear();
  reveals.clear();
}

void Scratch::Impl::begin_voxels(std::size_t voxels) {
  if (stamp.size() < voxels) stamp.resize(voxels, 0);
  if (++stamp_tag == 64) {
    std::fill(stamp.begin(), stamp.end(), std::uint8_t{0});
    stamp_tag = 1;
  }
}

// ---------------------------------------------------------------------------
// Geometry

double Scene::Impl::slop(double mag) const {
  // Generous allowance for the rounding of (p - bounds_min) / voxel_size and
  // of the distance arithmetic; errs towards "touches" and "not opaque".
  return 64.0 * kUlp * (mag + slop_bounds) + 1e-300;
}

VoxBox Scene::Impl::touch_range(const Vec3& lo, const Vec3& hi, double slop_w) const {
  const Vec3 glo = to_grid(lo) - slop_w * inv_vs;
  const Vec3 ghi = to_grid(hi) + slop_w * inv_vs;
  VoxBox vb;
  for (int a = 0; a < 3; ++a) {
    // Voxel i spans [i, i+1]; it touches [glo, ghi] iff ceil(glo)-1 <= i <= floor(ghi).
    vb.lo[a] = clamp_floor(std::ceil(glo[a]) - 1.0, 0, res[a] - 1);
    vb.hi[a] = clamp_floor(ghi[a], -1, res[a] - 1);
    if (ghi[a] < 0.0 || glo[a] > res[a]) {
      vb.hi = glm::ivec3(-1);
      vb.lo = glm::ivec3(0);
      return vb;
    }
  }
  return vb;
}

bool Scene::Impl::touches(const Obj& o, const Vec3& c, int x, int y, int z) const {
  const double s = slop(max_abs(c) + o.radius + max_abs(o.half));
  const Vec3 v{static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)};
  if (o.shape == Shape::Sphere) {
    const Vec3 cg = to_grid(c);
    const Vec3 q = glm::clamp(cg, v, v + 1.0);
    const Vec3 dw = (q - cg) * spec.voxel_size;
    const double rr = o.radius + s;
    return glm::dot(dw, dw) <= rr * rr;
  }
  const Vec3 sg = s * inv_vs;
  const Vec3 lo = to_grid(c - o.half) - sg;
  const Vec3 hi = to_grid(c + o.half) + sg;
  return v.x <= hi.x && v.x + 1.0 >= lo.x && v.y <= hi.y && v.y + 1.0 >= lo.y &&
         v.z <= hi.z && v.z + 1.0 >= lo.z;
}

bool Scene::Impl::contains_voxel(const Obj& o, const Vec3& c, int x, int y, int z) const {
  const double s = slop(max_abs(c) + o.radius + max_abs(o.half));
  const Vec3 v{static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)};
  if (o.shape == Shape::Sphere) {
    const Vec3 cg = to_grid(c);
    const Vec3 far_d = glm::max(glm::abs(v - cg), glm::abs(v + 1.0 - cg)) * spec.voxel_size;
    const double rr = o.radius - s;
    return rr > 0.0 && glm::dot(far_d, far_d) <= rr * rr;
  }
  Vec3 lo, hi;
  inner_box(o, c, &lo, &hi);
  return v.x >= lo.x && v.x + 1.0 <= hi.x && v.y >= lo.y && v.y + 1.0 <= hi.y &&
         v.z >= lo.z && v.z + 1.0 <= hi.z;
}

namespace {

/// s = a + b rounded; true when the sum is exact (Knuth's TwoSum: the
/// rounding error is computed exactly and is zero).
bool exact_sum(double a, double b, double* s) {
  *s = a + b;
  const double bb = *s - a;
  const double err = (a - (*s - bb)) + (b - bb);
  return err == 0.0;
}

/// Whether w - b0 equals g * h exactly, as real numbers. Both sides are
/// written as an unevaluated sum hi + lo with hi the rounded value and lo its
/// exact error (TwoSum, TwoProduct by fma); that pair is unique for a real
/// number, so comparing the pairs compares the reals.
bool on_boundary(double w, double b0, double g, double h) {
  const double d = w - b0;
  const double dd = d - w;
  const double derr = (w - (d - dd)) + (-b0 - dd);
  const double p = g * h;
  const double perr = std::fma(g, h, -p);
  return d == p && derr == perr;
}

constexpr int kMaxUnion = 16;  ///< Inner boxes the exact union test takes per voxel.

}  // namespace

double detail::Obj::mesh_allowance() const { return 64.0 * kUlp * (max_abs(mesh_origin) + mesh_extent) + 1e-300; }

void Scene::Impl::place_mesh(Obj& o) const {
  // The placed points' rounding and the box's own are allowed for.
  const double m = o.mesh_allowance();
  if (o.dynamic) {
    o.center = o.mesh_origin + o.mesh_scale * (o.mesh_rotation * o.mesh_centroid);
    o.half = Vec3(o.radius + m);
    return;
  }
  Vec3 lo, hi;
  mesh_bounds(o.mesh_desc(), &lo, &hi);
  o.center = (lo + hi) * 0.5;
  o.half = glm::max(hi - o.center, o.center - lo) + m;
}

void Scene::Impl::inner_box(const Obj& o, const Vec3& c, Vec3* lo, Vec3* hi) const {
  if (o.shape == Shape::Mesh) {  // No volume is known to be inside a mesh: empty.
    *lo = Vec3(std::numeric_limits<double>::infinity());
    *hi = Vec3(-std::numeric_limits<double>::infinity());
    return;
  }
  const double s = slop(max_abs(c) + o.radius + max_abs(o.half));
  const Vec3 sg = s * inv_vs;
  if (o.shape == Shape::Sphere) {
    // Inscribed cube, half side r / sqrt(3), rounded down generously; its
    // mapping is rounded, so it is shrunk by the allowance too.
    const double h = o.radius * (1.0 / std::sqrt(3.0)) * (1.0 - 16.0 * kUlp);
    *lo = to_grid(c - h) + sg;
    *hi = to_grid(c + h) - sg;
    return;
  }
  for (int a = 0; a < 3; ++a) {
    // A face whose world coordinate is exactly bounds_min + n * voxel_size
    // maps to n with no rounding at all: compare exactly there (this is
    // what lets voxel-aligned walls and unit blocks cover their voxels).
    for (int side = 0; side < 2; ++side) {
      double w = 0.0;
      const bool exact = exact_sum(c[a], side ? o.half[a] : -o.half[a], &w);
      const double g = (w - spec.bounds_min[a]) * inv_vs[a];
      // g is the face's exact grid coordinate when g * voxel_size equals
      // w - bounds_min as real numbers; any rounding shows as a difference.
      const bool exact_g = exact && on_boundary(w, spec.bounds_min[a], g, spec.voxel_size[a]);
      const double v = exact_g ? g : (side ? g - sg[a] : g + sg[a]);
      (side ? (*hi)[a] : (*lo)[a]) = v;
    }
  }
}

bool Scene::Impl::own_voxels(const Obj& o, VoxBox* out) const {
  const Vec3 c = o.center;
  const Vec3 half = o.shape == Shape::Sphere ? Vec3(o.radius) : o.half;
  const Vec3 sg = slop(max_abs(c) + o.radius + max_abs(o.half)) * inv_vs;
  for (int a = 0; a < 3; ++a) {
    double g[2];
    for (int side = 0; side < 2; ++side) {
      double w = 0.0;
      const bool exact = exact_sum(c[a], side ? half[a] : -half[a], &w);
      const double q = (w - spec.bounds_min[a]) * inv_vs[a];
      const bool exact_g = exact && on_boundary(w, spec.bounds_min[a], q, spec.voxel_size[a]);
      g[side] = exact_g ? q : (side ? q + sg[a] : q - sg[a]);
    }
    // Voxel i is [i, i+1]; the closed range [g0, g1] lies in voxels
    // floor(g0) .. ceil(g1) - 1 (one voxel when it is a single point).
    const double i0 = std::floor(g[0]), i1 = std::fmax(i0, std::ceil(g[1]) - 1.0);
    if (!(i0 >= 0.0) || !(i1 <= res[a] - 1.0)) return false;
    out->lo[a] = static_cast<int>(i0);
    out->hi[a] = static_cast<int>(i1);
  }
  return true;
}

bool Scene::Impl::union_covers(const std::uint32_t* slots, std::size_t n, int x, int y, int z) const {
  const Vec3 v0{static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)};
  const Vec3 v1 = v0 + 1.0;
  Vec3 blo[kMaxUnion], bhi[kMaxUnion];
  int nb = 0;
  bool too_many = false;
  for (std::size_t i = 0; i < n; ++i) {
    const Obj& o = objs[slots[i]];
    const Vec3& c = o.dynamic ? o.disc_center : o.center;
    if (o.shape == Shape::Sphere && contains_voxel(o, c, x, y, z)) return true;
    Vec3 lo, hi;
    inner_box(o, c, &lo, &hi);
    lo = glm::max(lo, v0);
    hi = glm::min(hi, v1);
    // Boxes meeting the voxel in less than a volume add nothing to the cover
    // of its open cells (see below).
    if (!(lo.x < hi.x && lo.y < hi.y && lo.z < hi.z)) continue;
    if (lo == v0 && hi == v1) return true;  // One object covers it.
    if (nb == kMaxUnion) {
      too_many = true;  // Keep looking for a single cover; the union is not tested.
      continue;
    }
    blo[nb] = lo;
    bhi[nb] = hi;
    ++nb;
  }
  if (too_many || nb < 2) return false;
  // The faces of the boxes cut the voxel into cells; no face passes through
  // a cell's interior, so a box holding a cell's centre holds the whole
  // closed cell. The voxel is covered iff every cell's centre is.
  double cut[3][2 * kMaxUnion + 2];
  int nc[3];
  for (int a = 0; a < 3; ++a) {
    int k = 0;
    cut[a][k++] = v0[a];
    cut[a][k++] = v1[a];
    for (int i = 0; i < nb; ++i) {
      cut[a][k++] = blo[i][a];
      cut[a][k++] = bhi[i][a];
    }
    std::sort(cut[a], cut[a] + k);
    nc[a] = static_cast<int>(std::unique(cut[a], cut[a] + k) - cut[a]);
  }
  for (int k = 0; k + 1 < nc[2]; ++k) {
    const double cz = 0.5 * (cut[2][k] + cut[2][k + 1]);
    for (int j = 0; j + 1 < nc[1]; ++j) {
      const double cy = 0.5 * (cut[1][j] + cut[1][j + 1]);
      for (int i = 0; i + 1 < nc[0]; ++i) {
        const double cx = 0.5 * (cut[0][i] + cut[0][i + 1]);
        bool in = false;
        for (int b = 0; b < nb && !in; ++b)
          in = cx > blo[b].x && cx < bhi[b].x && cy > blo[b].y && cy < bhi[b].y &&
               cz > blo[b].z && cz < bhi[b].z;
        if (!in) return false;
      }
    }
  }
  return true;
}

bool Scene::Impl::in_one_ball(const std::uint32_t* slots, std::size_t n, int x, int y, int z) const {
  for (std::size_t i = 0; i < n; ++i) {
    const Obj& o = objs[slots[i]];
    if (o.shape == Shape::Sphere && !o.dynamic && contains_voxel(o, o.center, x, y, z)) return true;
  }
  return false;
}

void Scene::Impl::coarse_static(int x, int y, int z, std::uint32_t* out, std::size_t* n, std::size_t cap) const {
  for (int l = 1; l < pyr.levels && *n < cap; ++l) {
    const detail::IdLists& lists = static_lists[static_cast<std::size_t>(l)];
    if (!lists.any()) continue;
    const int sh = detail::kCellShift * l;
    const std::size_t c = pyr.index(l, glm::ivec3(x >> sh, y >> sh, z >> sh));
    for (const std::uint32_t* p = lists.begin(c); p != lists.end(c) && *n < cap; ++p) out[(*n)++] = *p;
  }
}

bool Scene::Impl::covered_now(int x, int y, int z) const {
  std::uint32_t slots[detail::kCoverCandidates];
  std::size_t n = 0;
  const auto i = static_cast<std::size_t>(index(x, y, z));
  const detail::IdLists& own = static_lists[0];
  for (const std::uint32_t* p = own.begin(i); p != own.end(i) && n < std::size(slots); ++p) slots[n++] = *p;
  if (vflags[i] & kCoarseIds) coarse_static(x, y, z, slots, &n, std::size(slots));
  if (!bricks.empty()) {
    const int levels = coarse_dyn_live > 0 ? pyr.levels : 2;
    for (int l = 1; l < levels; ++l) {
      const int sh = detail::kCellShift * l;
      const glm::ivec3 c(x >> sh, y >> sh, z >> sh);
      const detail::Brick& br = l == 1 ? bricks[pyr.index(1, c)]
                                       : coarse_dyn[static_cast<std::size_t>(l)][pyr.index(l, c)];
      if (br.live == 0) continue;
      for (const detail::BrickEntry& e : br.entries) {
        if ((e.key & 1u) || !current(e) || objs[e.key >> 1].no_opacity) continue;
        if (n == std::size(slots)) return false;  // Too crowded to test: not covered (tightness only).
        slots[n++] = e.key >> 1;
      }
    }
  }
  return union_covers(slots, n, x, y, z);
}

bool Scene::Impl::box_inside_grid(const Vec3& lo, const Vec3& hi) const {
  const double s = slop(std::fmax(max_abs(lo), max_abs(hi)));
  for (int a = 0; a < 3; ++a)
    if (!(lo[a] >= spec.bounds_min[a] + s) || !(hi[a] <= spec.bounds_max[a] - s)) return false;
  return true;
}

// ---------------------------------------------------------------------------
// Scene

Status validate_time(const std::string& field, double t) {
  if (std::isfinite(t) && std::fabs(t) <= kMaxSceneTime) return Status::Ok();
  char range[64];
  std::snprintf(range, sizeof range, "[%g, %g]", -kMaxSceneTime, kMaxSceneTime);
  return Status::Error(field, std::string("must be a finite time in seconds within ") + range +
                                  ", got " + number_text(t) +
                                  " (milliseconds or microseconds since 1970 are out of range)");
}

Scene::Scene(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Scene::~Scene() = default;

const GridSpec& Scene::grid() const { return impl_->spec; }
std::size_t Scene::object_count() const { return impl_->objs.size(); }
std::size_t Scene::dynamic_count() const { return impl_->dynamic_count; }
double Scene::time() const {
  std::lock_guard<std::mutex> book(impl_->book);
  return impl_->time;
}

ViewerId Scene::add_viewer() {
  std::lock_guard<std::mutex> book(impl_->book);
  const ViewerId id = impl_->next_viewer++;
  impl_->viewers.emplace(id, detail::ViewerState{});
  return id;
}

void Scene::remove_viewer(ViewerId viewer) {
  Impl& s = *impl_;
  std::lock_guard<std::mutex> book(s.book);  // Claims only: the grid is untouched.
  auto it = s.viewers.find(viewer);
  if (it == s.viewers.end()) return;
  for (std::uint32_t slot : it->second.last_pvs) {
    Obj& o = s.objs[slot];
    if (!o.dynamic) continue;
    if (--o.claims == 0 && !o.pending_unclaimed) {
      o.pending_unclaimed = true;
      s.unclaimed.push_back(slot);
    }
  }
  s.viewers.erase(it);
}

Status Scene::apply_moves(double t, std::span<const Move> moves, MoveReport* report,
                          Clock clock) {
  Impl& s = *impl_;
  std::unique_lock<detail::GridMutex> lock(s.mu);
  std::lock_guard<std::mutex> book(s.book);
  if (Status st = validate_time("t", t); !st) return st;
  if (clock == Clock::Latest && s.time_set) t = std::fmax(t, s.time);
  if (s.time_set && t < s.time)
    return Status::Error("t", "time goes backwards: " + number_text(t) + " < " + number_text(s.time));
  for (std::size_t i = 0; i < moves.size(); ++i) {
    const Move& m = moves[i];
    const std::string f = "moves[" + std::to_string(i) + "]";
    auto it = s.slot_of.find(m.id);
    if (it == s.slot_of.end()) return Status::Error(f + ".id", "unknown object id " + std::to_string(m.id));
    if (!s.objs[it->second].dynamic)
      return Status::Error(f + ".id", "object " + std::to_string(m.id) + " is static and cannot move");
    if (!finite3(m.center)) return Status::Error(f + ".center", "must be finite");
    if (max_abs(m.center) > kMaxCoordinate)
      return Status::Error(f + ".center", "magnitude exceeds " + number_text(kMaxCoordinate));
    const Obj& o = s.objs[it->second];
    if (m.has_rotation) {
      if (o.shape != Shape::Mesh)
        return Status::Error(f + ".rotation", "object " + std::to_string(m.id) + " is a " +
                                                  (o.shape == Shape::Sphere ? "sphere" : "box") +
                                                  "; only meshes rotate");
      if (Status st = validate_rotation(m.rotation, f + ".rotation"); !st) return st;
    }
    if (o.shape == Shape::Mesh) {
      const Quat q = m.has_rotation ? unit_rotation(m.rotation) : o.mesh_rotation;
      const Vec3 c = m.center + o.mesh_scale * (q * o.mesh_centroid);
      if (!(max_abs(c) + o.radius <= kMaxCoordinate))
        return Status::Error(f + ".center", "places the mesh beyond " + number_text(kMaxCoordinate));
    }
  }
  s.time = t;
  s.time_set = true;
  if (!moves.empty()) ++s.moves_epoch;
  s.apply_queue(s.pending, s.claims_made);  // Frames' queued reveals and TBVs first.
  if (report) {
    *report = MoveReport{};
    report->t = t;
  }
  for (const Move& m : moves) {
    const std::uint32_t slot = s.slot_of.find(m.id)->second;
    Obj& o = s.objs[slot];
    // The object's new centre and half: a mesh's are its centroid ball's
    // (place_mesh), whose centre lies in the mesh's hull and so moves no
    // faster than the mesh's fastest point.
    Vec3 center = m.center, half = o.half;
    Obj placed;
    if (o.shape == Shape::Mesh) {
      placed = o;
      placed.mesh_origin = m.center;
      if (m.has_rotation) {
        placed.mesh_rotation = unit_rotation(m.rotation);
        placed.mesh_rotation_given = m.rotation;
      }
      s.place_mesh(placed);
      center = placed.center;
      half = placed.half;
    }
    auto set_center = [&] {
      o.center = center;
      o.half = half;
      if (o.shape == Shape::Mesh) {
        o.mesh_origin = placed.mesh_origin;
        o.mesh_rotation = placed.mesh_rotation;
        o.mesh_rotation_given = placed.mesh_rotation_given;
      }
    };
    const double dist = glm::length(center - o.center);
    bool too_fast = false;
    // Before the first frame nothing has been observed, so nothing is checked.
    const double since = std::isfinite(o.last_move_t) ? o.last_move_t : s.first_frame_time;
    if (std::isfinite(since)) {
      const double allowed = o.max_speed * (t - since);
      too_fast = dist > allowed * (1.0 + 1e-9) + s.slop(max_abs(center));
    }
    o.last_move_t = t;
    if (too_fast) {
      ++s.pending.speed_violations;
      if (report) report->too_fast.push_back(m.id);
    }
    if (o.under_tbv) {
      const double sl = s.slop(max_abs(center));
      const bool inside = glm::all(glm::greaterThanEqual(center - half, o.tbv_lo + sl)) &&
                          glm::all(glm::lessThanEqual(center + half, o.tbv_hi - sl));
      set_center();
      // A move the TBV does not bound voids it: the object is revealed.
      if (too_fast || !inside) {
        s.reveal(slot);
        ++s.pending.tbvs_revealed;
        s.pending_wake.push_back(slot);
      }
    } else if (center != o.disc_center || half != o.half) {
      s.undiscretize(slot);
      set_center();
      s.discretize(slot);
    } else {
      set_center();
    }
    if (report) ++report->applied;
  }
  return Status::Ok();
}

std::uint64_t Scene::wake_epoch() const {
  std::lock_guard<std::mutex> book(impl_->book);
  return impl_->wake_epoch;
}

std::vector<Move> Scene::dynamic_centers(double* time, std::uint64_t* epoch) const {
  std::shared_lock<detail::GridMutex> lock(impl_->mu);
  std::lock_guard<std::mutex> book(impl_->book);
  if (time) *time = impl_->time;
  if (epoch) *epoch = impl_->moves_epoch;
  std::vector<Move> out;
  out.reserve(impl_->dynamic_count);
  for (const Obj& o : impl_->objs)
    if (o.dynamic)
      out.push_back(o.shape == Shape::Mesh ? Move{o.id, o.mesh_origin, true, o.mesh_rotation_given}
                                           : Move{o.id, o.center});
  std::sort(out.begin(), out.end(), [](const Move& a, const Move& b) { return a.id < b.id; });
  return out;
}

std::vector<ObjectId> Scene::wake_set() const {
  std::vector<ObjectId> ids;
  wake_set(&ids);
  return ids;
}

void Scene::wake_set(std::vector<ObjectId>* ids) const {
  std::shared_lock<detail::GridMutex> lock(impl_->mu);
  std::lock_guard<std::mutex> book(impl_->book);
  ids->clear();
  // A queued reveal is a wake already reported by its frame.
  for (const Obj& o : impl_->objs)
    if (o.dynamic && (!o.under_tbv || o.reveal_queued)) ids->push_back(o.id);
  std::sort(ids->begin(), ids->end());
}

}  // namespace voxvis
