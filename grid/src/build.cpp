// build.cpp — building a scene: validation of its description, the grid it
// gets, what it costs (Scene::estimate, counted from the objects' footprints
// without building) and Scene::create, which counts first and allocates
// nothing before the figure fits. The rest of a scene's life (moves, TBVs)
// is in scene.cpp.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include <glm/geometric.hpp>

#include "numeric.h"
#include "mesh_interior.h"
#include "opaque_boxes.h"
#include "scene_impl.h"
#include "tri_box.h"

#include <map>

namespace voxvis {

using detail::Obj;
using detail::VoxBox;
using detail::clamp_floor;
using detail::finite3;
using detail::kUlp;
using detail::max_abs;

namespace {

/// Longest side of an opaque box, voxels (opaque_boxes.h).
constexpr int kOpaqueBoxSide = 16;

std::string obj_field(std::size_t i, const char* name) {
  return "objects[" + std::to_string(i) + "]." + name;
}

Status validate_desc(const SceneDesc& d, const SceneOptions& opt) {
  if (!finite3(d.bounds_min) || !finite3(d.bounds_max))
    return Status::Error("bounds", "must be finite numbers");
  if (max_abs(d.bounds_min) > kMaxCoordinate || max_abs(d.bounds_max) > kMaxCoordinate)
    return Status::Error("bounds", "magnitude exceeds " + number_text(kMaxCoordinate));
  for (int a = 0; a < 3; ++a) {
    if (!(d.bounds_min[a] < d.bounds_max[a]))
      return Status::Error("bounds", std::string("min must be < max on every axis; axis ") +
                                         "xyz"[a] + " has " + number_text(d.bounds_min[a]) +
                                         " >= " + number_text(d.bounds_max[a]));
    const double extent = d.bounds_max[a] - d.bounds_min[a];
    if (!(extent >= kMinExtent))
      return Status::Error("bounds", std::string("extent on axis ") + "xyz"[a] + " is " + number_text(extent) +
                                         "; it must be at least " + number_text(kMinExtent) + " world units");
    if (!(extent > 64 * kUlp * std::fmax(std::fabs(d.bounds_min[a]), std::fabs(d.bounds_max[a]))))
      return Status::Error("bounds", std::string("extent on axis ") + "xyz"[a] +
                                         " is too small to be resolved at this offset");
  }
  if (d.grid) {
    const glm::ivec3 g = *d.grid;
    for (int a = 0; a < 3; ++a) {
      if (g[a] < 1)
        return Status::Error("grid", "resolution must be >= 1 on every axis, got " +
                                         std::to_string(g[a]));
      if (g[a] > opt.max_resolution)
        return Status::Error("grid", "resolution " + std::to_string(g[a]) +
                                         " exceeds the per-axis limit of " +
                                         std::to_string(opt.max_resolution));
    }
    const std::int64_t n = std::int64_t{g.x} * g.y * g.z;
    if (n > opt.max_voxels)
      return Status::Error("grid", std::to_string(g.x) + "x" + std::to_string(g.y) + "x" +
                                       std::to_string(g.z) + " = " + std::to_string(n) +
                                       " voxels exceeds the limit of " +
                                       std::to_string(opt.max_voxels));
  }
  if (!(opt.tbv_period == 0.0 || opt.tbv_period >= kMinTbvPeriod) || !std::isfinite(opt.tbv_period))
    return Status::Error("tbv_period", "must be 0 (per object) or a finite number of seconds >= 0.001");
  if (!(opt.tbv_voxels > 0.0) || !std::isfinite(opt.tbv_voxels))
    return Status::Error("tbv_voxels", "must be finite and > 0");
  if (!(opt.tbv_max_voxels >= opt.tbv_voxels) || !std::isfinite(opt.tbv_max_voxels))
    return Status::Error("tbv_max_voxels", "must be finite and >= tbv_voxels");
  if (!(opt.tbv_max_period > 0.0) || !std::isfinite(opt.tbv_max_period))
    return Status::Error("tbv_max_period", "must be finite and > 0");
  if (!(opt.tbv_seen_memory >= 0.0) || !std::isfinite(opt.tbv_seen_memory))
    return Status::Error("tbv_seen_memory", "must be a finite number of seconds >= 0");
  if (opt.occlusion_buffer != 0 &&
      (opt.occlusion_buffer < 8 || opt.occlusion_buffer > detail::OcclusionBuffer::kMaxSide))
    return Status::Error("occlusion_buffer", "must be 0 (off) or a width in pixels from 8 to " +
                                                 std::to_string(detail::OcclusionBuffer::kMaxSide) +
                                                 ", got " + std::to_string(opt.occlusion_buffer));

  std::unordered_map<ObjectId, std::size_t> seen;
  seen.reserve(d.objects.size());
  MeshPlacementCheck meshes;  // Each mesh validated once, however many objects place it.
  for (std::size_t i = 0; i < d.objects.size(); ++i) {
    const ObjectDesc& o = d.objects[i];
    auto [it, fresh] = seen.emplace(o.id, i);
    if (!fresh)
      return Status::Error(obj_field(i, "id"), "duplicate id " + std::to_string(o.id) +
                                                   " (also objects[" +
                                                   std::to_string(it->second) + "])");
    if (!finite3(o.center)) return Status::Error(obj_field(i, "center"), "must be finite");
    if (max_abs(o.center) > kMaxCoordinate)
      return Status::Error(obj_field(i, "center"), "magnitude exceeds " + number_text(kMaxCoordinate));
    if (o.shape == Shape::Mesh) {
      if (Status s = meshes.check(o, "objects[" + std::to_string(i) + "]"); !s) return s;
    } else if (o.shape == Shape::Sphere) {
      if (!std::isfinite(o.radius) || !(o.radius > 0.0))
        return Status::Error(obj_field(i, "radius"), "must be > 0, got " + number_text(o.radius));
      if (o.radius > kMaxCoordinate)
        return Status::Error(obj_field(i, "radius"), "exceeds " + number_text(kMaxCoordinate));
    } else {
      if (!finite3(o.half_extent))
        return Status::Error(obj_field(i, "max"), "box extents must be finite");
      for (int a = 0; a < 3; ++a)
        if (!(o.half_extent[a] >= 0.0))
          return Status::Error(obj_field(i, "min"), "box min must be <= max on every axis");
      if (max_abs(o.half_extent) > kMaxCoordinate)
        return Status::Error(obj_field(i, "max"), "box extent exceeds " + number_text(kMaxCoordinate));
    }
    if (o.dynamic && (!std::isfinite(o.max_speed) || !(o.max_speed >= 0.0)))
      return Status::Error(obj_field(i, "max_speed"),
                           "must be finite and >= 0, got " + number_text(o.max_speed));
  }
  return Status::Ok();
}

/// `lo` and `hi` (lo <= hi) rounded outwards to multiples of q, a power of
/// two chosen so that their sum, difference and halves are exact
/// (set_box_corners). With m = max(|lo|, |hi|) <= 2^e, e as small as can be,
/// q = 2^(e-52): multiples of q up to 2^e have at most 53 significant bits,
/// their sums up to 2^(e+1) too, and halves of those are multiples of q/2
/// up to 2^e. Rounding keeps the magnitudes at most 2^e (a multiple of q),
/// so rounding again finds the same e and changes nothing. q is at least
/// 2^-1073, so that halves stay above the smallest subnormal.
void round_corners_out(double* lo, double* hi) {
  const double m = std::fmax(std::fabs(*lo), std::fabs(*hi));
  if (m == 0.0) return;
  int e = 0;
  const double f = std::frexp(m, &e);  // m = f * 2^e, f in [0.5, 1)
  if (f == 0.5) --e;                   // m = 2^(e-1) exactly
  const double q = std::ldexp(1.0, std::max(e - 52, -1073));
  // Dividing by a power of two is exact here (the quotients are at most 2^52).
  *lo = std::floor(*lo / q) * q;
  *hi = std::ceil(*hi / q) * q;
}

}  // namespace

void set_box_corners(const Vec3& lo, const Vec3& hi, ObjectDesc* out) {
  out->shape = Shape::Box;
  for (int a = 0; a < 3; ++a) {
    double l = lo[a], h = hi[a];
    round_corners_out(&l, &h);
    out->center[a] = (l + h) * 0.5;
    out->half_extent[a] = (h - l) * 0.5;
  }
}

glm::ivec3 Scene::auto_resolution(const SceneDesc& desc, const SceneOptions& opt) {
  // Total for any input (callers may ask before validating): an axis with
  // no usable extent gets one voxel.
  Vec3 ext = desc.bounds_max - desc.bounds_min;
  for (int a = 0; a < 3; ++a)
    if (!(ext[a] > 0.0) || !std::isfinite(ext[a])) ext[a] = 1.0;
  const double target = static_cast<double>(std::max<std::int64_t>(1, opt.auto_voxels));
  // The cube root of volume / target, in logarithms: the product of three
  // extents of 1e-100 would underflow (and of three of 1e12 come near
  // overflow), where each extent alone is fine.
  double h = std::exp((std::log(ext.x) + std::log(ext.y) + std::log(ext.z) - std::log(target)) / 3.0);
  glm::ivec3 r{1};
  // h grows by a quarter a round: a few thousand rounds reach from the
  // smallest voxel to the largest extent, however unequal the extents.
  for (int iter = 0; iter < 5000; ++iter) {
    for (int a = 0; a < 3; ++a)
      r[a] = clamp_floor(std::round(ext[a] / h), 1, std::max(1, opt.max_resolution));
    const double n = double(r.x) * r.y * r.z;
    if (n <= 2.0 * target || (r.x == 1 && r.y == 1 && r.z == 1)) break;
    h *= 1.25;  // Flat bounds: the cube-root guess overshoots on the long axes.
  }
  return r;
}

namespace {

/// Polls a BuildControl every 2^16 steps of work and keeps the count.
class BuildMeter {
 public:
  explicit BuildMeter(const BuildControl* c) : c_(c) {}
  /// Counts n steps; false once the caller cancelled.
  bool tick(std::uint64_t n = 1) {
    steps_ += n;
    if (steps_ < next_) return true;
    next_ = steps_ + (std::uint64_t{1} << 16);
    if (c_ && c_->cancelled && c_->cancelled()) cancelled_ = true;
    return !cancelled_;
  }
  bool cancelled() const { return cancelled_; }
  std::uint64_t steps() const { return steps_; }
  std::uint64_t max_bytes() const { return c_ ? c_->max_bytes : 0; }

 private:
  const BuildControl* c_;
  std::uint64_t steps_ = 0, next_ = 0;
  bool cancelled_ = false;
};

std::string mib_text(std::uint64_t bytes) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.1f MiB", static_cast<double>(bytes) / (1024.0 * 1024.0));
  return buf;
}

Status build_cancelled() { return Status::Cancelled("scene build cancelled"); }

/// Validates `desc`, chooses the grid and sets up the objects of `s`: every
/// part of a scene but its grid layers.
Status prepare(const SceneDesc& desc, const SceneOptions& options, Scene::Impl& s) {
  if (Status st = validate_desc(desc, options); !st) return st;
  s.options = options;
  s.res = desc.grid ? *desc.grid : Scene::auto_resolution(desc, options);
  if (!desc.grid && std::int64_t{s.res.x} * s.res.y * s.res.z > options.max_voxels)
    return Status::Exhausted("grid", "automatic resolution exceeds max_voxels");
  s.spec.res = s.res;
  s.spec.bounds_min = desc.bounds_min;
  s.spec.bounds_max = desc.bounds_max;
  s.spec.voxel_size = (desc.bounds_max - desc.bounds_min) / Vec3(s.res);
  s.inv_vs = 1.0 / s.spec.voxel_size;
  s.slop_bounds = std::fmax(max_abs(desc.bounds_min), max_abs(desc.bounds_max));
  s.pyr = detail::Pyramid::make(s.res);
  s.cell_base[1] = 0;
  for (int l = 1; l < detail::kMaxLevels; ++l)
    s.cell_base[static_cast<std::size_t>(l) + 1] = s.cell_base[static_cast<std::size_t>(l)] + (l < s.pyr.levels ? s.pyr.cells(l) : 0);
  s.objs.reserve(desc.objects.size());
  s.slot_of.reserve(desc.objects.size());
  for (const ObjectDesc& d : desc.objects) {
    Obj o;
    o.id = d.id;
    o.shape = d.shape;
    o.dynamic = d.dynamic;
    o.max_speed = d.dynamic ? d.max_speed : 0.0;
    o.center = d.center;
    o.radius = d.shape == Shape::Sphere ? d.radius : 0.0;
    o.half = d.shape == Shape::Sphere ? Vec3(d.radius) : d.half_extent;
    if (d.shape == Shape::Mesh) {
      o.mesh = d.mesh;
      o.mesh_origin = d.center;
      o.mesh_rotation = unit_rotation(d.rotation);
      o.mesh_rotation_given = d.rotation;
      o.mesh_scale = d.scale;
      o.mesh_centroid = mesh_centroid(*d.mesh);
      double model = 0.0;
      for (const Vec3& v : d.mesh->vertices) model = std::fmax(model, max_abs(v));
      o.mesh_extent = d.scale * std::sqrt(3.0) * model;
      if (o.dynamic) o.radius = d.scale * mesh_reach(*d.mesh, o.mesh_centroid);
      s.place_mesh(o);
    }
    o.last_move_t = std::numeric_limits<double>::quiet_NaN();
    if (o.dynamic) {
      // Voxels its box can touch wherever it goes: one more than its size
      // in voxels per axis (capped by the grid).
      double n = 1.0;
      for (int a = 0; a < 3; ++a)
        n *= std::fmin(std::ceil(2.0 * o.half[a] * s.inv_vs[a]) + 1.0, static_cast<double>(s.res[a]));
      o.no_opacity = !(n <= static_cast<double>(detail::kDynOpacityMaxVoxels)) || options.occlusion_buffer > 0 ||
                     o.shape == Shape::Mesh;
    }
    s.slot_of.emplace(o.id, static_cast<std::uint32_t>(s.objs.size()));
    s.objs.push_back(o);
    if (o.dynamic) ++s.dynamic_count;
  }
  return Status::Ok();
}

/// A static mesh's vertices placed and mapped to grid coordinates, and how
/// far a voxel (or brick) is grown for their rounding: the placement's and
/// the mapping's (slop) allowances, in voxels.
struct GridMesh {
  std::vector<Vec3> g;
  Vec3 grow{0.0};
  GridMesh(const Scene::Impl& s, const Obj& o) : g(o.mesh->vertices.size()) {
    const ObjectDesc d = o.mesh_desc();
    for (std::size_t i = 0; i < g.size(); ++i) g[i] = s.to_grid(place(d, o.mesh->vertices[i]));
    grow = (o.mesh_allowance() + s.slop(max_abs(o.center) + max_abs(o.half))) * s.inv_vs + 1e-9;
  }
};

/// The voxels static mesh `o` touches, from its triangles: each triangle
/// against the voxels of its own box, by the separating-axis test with the
/// voxel grown by the rounding allowance of placing and mapping its
/// vertices (a rounding only adds a voxel the mesh touches within it).
/// emit(0, voxel) once a voxel, in index order. False when cancelled.
template <class Emit>
bool mesh_voxels(const Scene::Impl& s, const Obj& o, BuildMeter& meter, Emit&& emit) {
  const Mesh& mesh = *o.mesh;
  const GridMesh gm(s, o);
  const std::vector<Vec3>& g = gm.g;
  const Vec3 grow = gm.grow;
  std::vector<std::int64_t> voxels;
  for (const auto& t : mesh.triangles) {
    const Vec3 &a = g[t[0]], &b = g[t[1]], &c = g[t[2]];
    const Vec3 lo = glm::min(a, glm::min(b, c)) - grow, hi = glm::max(a, glm::max(b, c)) + grow;
    glm::ivec3 v0, v1;
    bool empty = false;
    for (int k = 0; k < 3; ++k) {
      // Voxel i spans [i, i+1]: it meets [lo, hi] iff ceil(lo) - 1 <= i <= floor(hi).
      v0[k] = clamp_floor(std::ceil(lo[k]) - 1.0, 0, s.res[k] - 1);
      v1[k] = clamp_floor(hi[k], -1, s.res[k] - 1);
      empty = empty || hi[k] < 0.0 || lo[k] > s.res[k];
    }
    if (empty) continue;
    std::uint64_t n = 0;
    for (int z = v0.z; z <= v1.z; ++z)
      for (int y = v0.y; y <= v1.y; ++y)
        for (int x = v0.x; x <= v1.x; ++x) {
          const Vec3 centre(x + 0.5, y + 0.5, z + 0.5);
          ++n;
          if (detail::triangle_meets_box(a, b, c, centre, 0.5 + grow)) voxels.push_back(s.index(x, y, z));
        }
    if (!meter.tick(n + 1)) return false;
  }
  std::sort(voxels.begin(), voxels.end());
  voxels.erase(std::unique(voxels.begin(), voxels.end()), voxels.end());
  for (const std::int64_t i : voxels) {
    const int x = static_cast<int>(i % s.res.x);
    const int y = static_cast<int>((i / s.res.x) % s.res.y);
    const int z = static_cast<int>(i / (std::int64_t{s.res.x} * s.res.y));
    emit(0, glm::ivec3(x, y, z));
  }
  return true;
}

/// Splits static object `slot` into the cells it is stored in (cells.h):
/// emit(level, cell). False when cancelled.
template <class Emit>
bool static_cells(const Scene::Impl& s, std::uint32_t slot, BuildMeter& meter, Emit&& emit) {
  const Obj& o = s.objs[slot];
  if (o.shape == Shape::Mesh) return mesh_voxels(s, o, meter, emit);
  const double sl = s.slop(max_abs(o.center) + o.radius + max_abs(o.half));
  const VoxBox vb = s.touch_range(o.box_lo(), o.box_hi(), sl);
  // A box touches exactly the voxels of its touch range; a ball's touched
  // voxels are a convex set of it, tested at a cell's corners.
  const bool ball = o.shape == Shape::Sphere;
  // Within a brick the surface cuts, a ball's voxels row by row: the voxels
  // of row (y, z) it touches are those meeting [cx - w, cx + w], w the half
  // chord left by the row's distance from the centre (touches()'s test,
  // solved for x; widened, so a rounding only adds a voxel).
  const Vec3 cg = s.to_grid(o.center);
  const double rr = o.radius + s.slop(max_abs(o.center) + o.radius + max_abs(o.half));
  const Vec3& vs = s.spec.voxel_size;
  auto gap = [&](int a, int i) {
    const double d = std::fmax(0.0, std::fmax(static_cast<double>(i) - cg[a], cg[a] - static_cast<double>(i + 1)));
    return d * vs[a];
  };
  auto ball_rows = [&](const VoxBox& in) {
    if (!ball) return false;
    for (int z = in.lo.z; z <= in.hi.z; ++z) {
      const double dz = gap(2, z);
      for (int y = in.lo.y; y <= in.hi.y; ++y) {
        const double dy = gap(1, y);
        const double rem = rr * rr - dy * dy - dz * dz;
        if (!(rem >= 0.0)) continue;
        const double w = std::sqrt(rem) * (1.0 + 1e-12) * s.inv_vs.x + 1e-9 + 1e-12 * std::fabs(cg.x);
        const double x0 = std::fmax(std::ceil(cg.x - w) - 1.0, static_cast<double>(in.lo.x));
        const double x1 = std::fmin(std::floor(cg.x + w), static_cast<double>(in.hi.x));
        for (double x = x0; x <= x1; x += 1.0) emit(0, glm::ivec3(static_cast<int>(x), y, z));
      }
    }
    return true;
  };
  return detail::decompose(
      s.pyr, 0, vb,
      [&](const VoxBox& r) {
        return !ball || detail::corners_pass(r, [&](int x, int y, int z) { return s.touches(o, o.center, x, y, z); });
      },
      ball_rows, false, emit, [&](std::uint64_t n) { return meter.tick(n); });
}

/// Entries (cells of levels >= 1) a dynamic object can hold at most: its
/// box grown by its largest TBV growth (a TBV replaces the object's own
/// entries, never adds to them), clamped to the grid.
std::uint64_t dynamic_entries(const Scene::Impl& s, const Obj& o) {
  const double period = s.options.tbv_period > 0.0 ? s.options.tbv_period : s.max_period(o);
  const double grow = 1.5 * o.max_speed * period;  // The period's jitter is below 1.5.
  const Vec3 lo = glm::max(o.box_lo() - grow, s.spec.bounds_min), hi = glm::min(o.box_hi() + grow, s.spec.bounds_max);
  const VoxBox vb = s.touch_range(glm::min(lo, o.box_lo()), glm::max(hi, o.box_hi()), s.slop(max_abs(lo) + max_abs(hi)));
  std::uint64_t n = 0;
  if (vb.empty()) return 0;
  detail::decompose(
      s.pyr, 1, VoxBox{vb.lo >> detail::kBrickShift, vb.hi >> detail::kBrickShift}, [](const VoxBox&) { return true; },
      [](const VoxBox&) { return false; }, true, [&](int, const glm::ivec3&) { ++n; },
      [](std::uint64_t) { return true; });
  return n;
}

/// What the scene costs with `per_level` static entries, in the terms of
/// SceneCost; the refusal when it exceeds the meter's limit.
/// `counted`: objects counted so far (all: the figure is the scene's; fewer:
/// a lower bound, and a refusal says so).
/// What meshes add with the buffer on (bytes): the scene's (static meshes'
/// placed vertices, their triangles' brick entries and the bricks' offsets)
/// and a worker's (a drawn mark per static triangle, a dynamic mesh's
/// placed vertices while drawn).
/// `own`: the meshes' own vertices and triangles (mesh_bytes()).
struct MeshCost {
  std::uint64_t bytes = 0, scratch = 0, own = 0;
};

bool count_triangle_bricks(const Scene::Impl& s, const Obj& o, BuildMeter& meter, std::uint64_t* n);

Status scene_cost(const Scene::Impl& s, const std::array<std::uint64_t, detail::kMaxLevels>& per_level,
                  std::uint64_t dyn_entries, const BuildMeter& meter, SceneCost* cost, std::size_t counted,
                  const MeshCost& mesh = {}) {
  const auto nvox = static_cast<std::uint64_t>(s.spec.voxel_count());
  const bool buffer = s.options.occlusion_buffer > 0;
  std::uint64_t entries = 0, offsets = 0;
  for (int l = 0; l < s.pyr.levels; ++l) {
    const std::uint64_t e = per_level[static_cast<std::size_t>(l)];
    entries += e;
    if (l == 0 || e > 0) offsets += s.pyr.cells(l) + 1;
  }
  const std::uint64_t bricks = s.dynamic_count > 0 ? s.pyr.cells(1) : 0;
  const std::uint64_t coarse = s.dynamic_count > 0 ? s.cell_base[static_cast<std::size_t>(s.pyr.levels)] - bricks : 0;
  // Opaque boxes are not known before the cover is: about one per brick is
  // a generous figure for every scene measured.
  const std::uint64_t boxes = buffer ? s.pyr.cells(1) : 0;
  cost->res = s.res;
  cost->id_entries = entries + dyn_entries;
  const std::uint64_t cells = s.cell_base[static_cast<std::size_t>(s.pyr.levels)];
  const std::uint64_t objects = s.objs.size(), dynamic = s.dynamic_count;
  // Per voxel: flags (1), the opaque boxes' owners (4, buffer on); CSR
  // offsets and entries (4 each); per brick its dynamic list head, seen
  // time and mask; per coarser cell a list head; each object's state and
  // index entry; with the buffer on, the per-brick lists (at most the
  // voxels' own entries and one box per brick); per cell of levels >= 1 its
  // static mask (8), with dynamic objects its dynamic count and mask (12) —
  // masks and counts with the buffer only — and, from level 2, the time it
  // was last seen whole (8), and at level 2 the time anything in it was
  // seen (8).
  //
  // The dynamic lists: a cell drops its stale entries only once they are
  // 16 more than twice its live ones (scene.cpp, brick_add), and a list
  // grows by doubling, so a cell that ever held one entry keeps up to 16
  // (128 bytes), and one that held L >= 2 at once up to 192 + 32 L bytes:
  // 128 bytes a dynamic cell (bricks and coarser) and 64 a dynamic entry.
  // Per dynamic object, its entries in the TBV expiry queue (a live one and
  // a stale one) and the reveal, unclaimed and wake queues, doubled by
  // their growth: 64 bytes.
  cost->bytes = nvox * (1 + (buffer ? 4 : 0)) + 4 * (offsets + entries) + boxes * sizeof(VoxBox) +
                bricks * (sizeof(detail::Brick) + 16) + coarse * (sizeof(detail::Brick) + 8) +
                (bricks > 0 && s.pyr.levels > 2 ? 8 * s.pyr.cells(2) : 0) + 128 * (bricks + coarse) +
                64 * dyn_entries + 64 * dynamic + (buffer ? 8 * cells + (bricks > 0 ? 12 * cells : 0) : 0) +
                (buffer ? 4 * (per_level[0] + 2 * (s.pyr.cells(1) + 1)) + 4 * boxes : 0) +
                objects * (sizeof(Obj) + 48) + mesh.bytes + mesh.own + (1u << 16);
  // A worker's scratch: the voxel traversal's stamps (a byte a voxel, the
  // buffer off); per object a PVS mark and a frustum mark (8) and its place
  // in the PVS (4, doubled by the list's growth); per dynamic object its
  // places in the frame's reveals and deferred TBVs (8, doubled); per box
  // and per cell a mark (4); with dynamic objects, per brick the voxels a
  // frame saw (8) and its place in their list (4, doubled), per coarser
  // cell its place in the cells seen whole (8, doubled).
  cost->scratch_bytes = (buffer ? 0 : nvox) + 16 * objects + 16 * dynamic + 4 * boxes + 4 * cells +
                        16 * bricks + 16 * coarse + mesh.scratch;
  cost->work = meter.steps() + nvox * 2;
  if (meter.max_bytes() > 0 && cost->bytes > meter.max_bytes()) {
    const std::string grid = std::to_string(s.res.x) + "x" + std::to_string(s.res.y) + "x" + std::to_string(s.res.z);
    if (counted == 0 && !s.objs.empty())
      return Status::Exhausted("memory", "the grid " + grid + " alone needs about " + mib_text(cost->bytes) +
                                             ", over the limit of " + mib_text(meter.max_bytes()));
    const std::string what =
        counted < s.objs.size()
            ? "at least " + mib_text(cost->bytes) + " (" + std::to_string(cost->id_entries) +
                  " id-list entries from its first " + std::to_string(counted) + " of " +
                  std::to_string(s.objs.size()) + " objects, grid " + grid + ")"
            : "about " + mib_text(cost->bytes) + " (" + std::to_string(cost->id_entries) + " id-list entries, grid " +
                  grid + (mesh.own > 0 ? ", meshes " + mib_text(mesh.own) : std::string()) + ")";
    return Status::Exhausted("memory", "the scene needs " + what + ", over the limit of " + mib_text(meter.max_bytes()));
  }
  for (std::uint64_t e : per_level)
    if (e > std::numeric_limits<std::uint32_t>::max() - 1)
      return Status::Exhausted("grid", "static objects fill more than 2^32 cells of one level; choose a coarser grid");
  return Status::Ok();
}

using LevelCounts = std::array<std::uint64_t, detail::kMaxLevels>;

/// Counts every static object's cells per level (no allocation), then the
/// dynamic objects' most entries, and what the scene costs.
/// The bytes of the scene's meshes, each counted once however many objects
/// place it (the objects share it): vertices, triangles and the vectors'
/// bookkeeping. A mesh is kept as given, so that is what it costs.
std::uint64_t mesh_bytes(const Scene::Impl& s) {
  std::uint64_t bytes = 0;
  std::vector<const Mesh*> seen;
  for (const Obj& o : s.objs)
    if (o.mesh) seen.push_back(o.mesh.get());
  std::sort(seen.begin(), seen.end());
  seen.erase(std::unique(seen.begin(), seen.end()), seen.end());
  for (const Mesh* m : seen)
    bytes += m->vertices.size() * sizeof(Vec3) + m->triangles.size() * sizeof(m->triangles[0]) + sizeof(Mesh) + 64;
  return bytes;
}

Status count_cost(const Scene::Impl& s, BuildMeter& meter, SceneCost* cost, LevelCounts* counts = nullptr) {
  LevelCounts per_level{};
  std::uint64_t dyn = 0;
  MeshCost mesh;
  const bool buffer = s.options.occlusion_buffer > 0;
  std::uint64_t widest = 0;  // Vertices of the largest dynamic mesh.
  // The grid alone may be over the limit: refused before any object is looked at.
  if (Status st = scene_cost(s, per_level, 0, meter, cost, 0); !st) return st;
  mesh.own = mesh_bytes(s);
  for (std::uint32_t slot = 0; slot < s.objs.size(); ++slot) {
    const Obj& o = s.objs[slot];
    if (o.dynamic) {
      dyn += dynamic_entries(s, o);
      if (o.shape == Shape::Mesh && buffer) {
        // The quad pairing, and the interior's cubes and boxes (if closed).
        const double side = std::fmin(s.spec.voxel_size.x, std::fmin(s.spec.voxel_size.y, s.spec.voxel_size.z));
        const glm::ivec3 n = detail::model_interior_cubes(*o.mesh, side / o.mesh_scale);
        const std::uint64_t cubes = std::uint64_t(n.x) * std::uint64_t(n.y) * std::uint64_t(n.z);
        mesh.bytes += 20 * o.mesh->triangles.size() + cubes + 8 * cubes / 4 + 256;
      }
      if (o.shape == Shape::Mesh && buffer && o.mesh->vertices.size() > widest) {
        mesh.scratch += 24 * (o.mesh->vertices.size() - widest);
        widest = o.mesh->vertices.size();
      }
      if (!meter.tick(8)) return build_cancelled();
      continue;
    }
    if (!static_cells(s, slot, meter, [&](int l, const glm::ivec3&) { ++per_level[static_cast<std::size_t>(l)]; }))
      return build_cancelled();
    if (o.shape == Shape::Mesh && buffer) {
      std::uint64_t entries = 0;
      if (!count_triangle_bricks(s, o, meter, &entries)) return build_cancelled();
      if (mesh.bytes == 0) mesh.bytes = 4 * (s.pyr.cells(1) + 1);
      // Placed vertices, brick entries, the quad pairing (per triangle).
      mesh.bytes += 24 * o.mesh->vertices.size() + sizeof(detail::TriRef) * entries + 20 * o.mesh->triangles.size();
      mesh.scratch += 4 * o.mesh->triangles.size();
    }
    // Stop as soon as the limit is passed: the count costs no more than
    // the budget it is checked against.
    if (Status st = scene_cost(s, per_level, dyn, meter, cost, slot + 1, mesh); !st) return st;
  }
  if (counts) *counts = per_level;
  return scene_cost(s, per_level, dyn, meter, cost, s.objs.size(), mesh);
}

/// Builds the static id lists from the counts per level: a pass over the
/// objects counts each cell's entries, another fills them (no buffer of
/// pairs: the peak stays the lists' own size).
Status build_static_lists(Scene::Impl& s, BuildMeter& meter, const LevelCounts& per_level) {
  for (int l = 0; l < s.pyr.levels; ++l) {
    detail::IdLists& lists = s.static_lists[static_cast<std::size_t>(l)];
    if (l == 0 || per_level[static_cast<std::size_t>(l)] > 0) lists.offsets.assign(s.pyr.cells(l) + 1, 0);
    lists.ids.resize(static_cast<std::size_t>(per_level[static_cast<std::size_t>(l)]));
  }
  for (std::uint32_t slot = 0; slot < s.objs.size(); ++slot) {
    if (s.objs[slot].dynamic) continue;
    if (!static_cells(s, slot, meter, [&](int l, const glm::ivec3& c) {
          ++s.static_lists[static_cast<std::size_t>(l)].offsets[s.pyr.index(l, c) + 1];
        }))
      return build_cancelled();
  }
  for (int l = 0; l < s.pyr.levels; ++l) {
    std::vector<std::uint32_t>& off = s.static_lists[static_cast<std::size_t>(l)].offsets;
    for (std::size_t i = 1; i < off.size(); ++i) off[i] += off[i - 1];
  }
  // Fill, advancing each cell's start; then shift the starts back.
  for (std::uint32_t slot = 0; slot < s.objs.size(); ++slot) {
    const Obj& o = s.objs[slot];
    if (o.dynamic) continue;
    if (!static_cells(s, slot, meter, [&](int l, const glm::ivec3& c) {
          detail::IdLists& lists = s.static_lists[static_cast<std::size_t>(l)];
          lists.ids[lists.offsets[s.pyr.index(l, c)]++] = slot;
        }))
      return build_cancelled();
    if (!s.box_inside_grid(o.box_lo(), o.box_hi())) s.list_add(s.outside_objs, s.objs[slot].outside_pos, slot);
  }
  for (int l = 0; l < s.pyr.levels; ++l) {
    std::vector<std::uint32_t>& off = s.static_lists[static_cast<std::size_t>(l)].offsets;
    if (off.empty()) continue;
    for (std::size_t i = off.size() - 1; i > 0; --i) off[i] = off[i - 1];
    off[0] = 0;
  }
  // Flags: a voxel with its own list, a voxel inside a coarser cell with one.
  const detail::IdLists& own = s.static_lists[0];
  for (std::size_t i = 0; i + 1 < own.offsets.size(); ++i)
    if (own.offsets[i + 1] > own.offsets[i]) s.vflags[i] |= Scene::Impl::kStaticIds;
  for (int l = 1; l < s.pyr.levels; ++l) {
    const detail::IdLists& lists = s.static_lists[static_cast<std::size_t>(l)];
    if (!lists.any()) continue;
    const glm::ivec3 r = s.pyr.res[l];
    for (int z = 0; z < r.z; ++z)
      for (int y = 0; y < r.y; ++y)
        for (int x = 0; x < r.x; ++x) {
          const std::size_t c = s.pyr.index(l, glm::ivec3(x, y, z));
          if (lists.offsets[c + 1] == lists.offsets[c]) continue;
          const VoxBox v = s.pyr.span(l, glm::ivec3(x, y, z), 0);
          if (!meter.tick(static_cast<std::uint64_t>(v.hi.x - v.lo.x + 1) * (v.hi.y - v.lo.y + 1) * (v.hi.z - v.lo.z + 1)))
            return build_cancelled();
          for (int vz = v.lo.z; vz <= v.hi.z; ++vz)
            for (int vy = v.lo.y; vy <= v.hi.y; ++vy)
              for (int vx = v.lo.x; vx <= v.hi.x; ++vx)
                s.vflags[static_cast<std::size_t>(s.index(vx, vy, vz))] |= Scene::Impl::kCoarseIds;
        }
  }
  return Status::Ok();
}

/// The static masks, bottom up (Scene::Impl::static_mask).
void build_static_masks(Scene::Impl& s) {
  for (int l = 1; l < s.pyr.levels; ++l) s.static_mask[static_cast<std::size_t>(l)].assign(s.pyr.cells(l), 0);
  auto bit = [](const glm::ivec3& c) { return std::uint64_t{1} << ((c.x & 3) | (c.y & 3) << 2 | (c.z & 3) << 4); };
  for (int z = 0; z < s.res.z; ++z)
    for (int y = 0; y < s.res.y; ++y)
      for (int x = 0; x < s.res.x; ++x)
        if (s.vflags[static_cast<std::size_t>(s.index(x, y, z))] &
            (Scene::Impl::kStaticIds | Scene::Impl::kStaticOpaque | Scene::Impl::kMeshInside))
          s.static_mask[1][s.pyr.index(1, glm::ivec3(x, y, z) >> detail::kCellShift)] |= bit(glm::ivec3(x, y, z));
  for (int l = 1; l + 1 < s.pyr.levels; ++l) {
    const detail::IdLists& lists = s.static_lists[static_cast<std::size_t>(l)];
    const glm::ivec3 r = s.pyr.res[static_cast<std::size_t>(l)];
    for (int z = 0; z < r.z; ++z)
      for (int y = 0; y < r.y; ++y)
        for (int x = 0; x < r.x; ++x) {
          const glm::ivec3 c(x, y, z);
          const std::size_t i = s.pyr.index(l, c);
          const bool own = lists.any() && lists.offsets[i + 1] > lists.offsets[i];
          if (own || s.static_mask[static_cast<std::size_t>(l)][i] != 0)
            s.static_mask[static_cast<std::size_t>(l) + 1][s.pyr.index(l + 1, c >> detail::kCellShift)] |= bit(c);
        }
  }
}

/// Which opaque boxes need not be drawn: those lying wholly inside one
/// static object, and those whose every voxel lies wholly inside some static
/// ball. An object's own occluder is drawn whenever the traversal reaches a
/// brick of the box (the object is stored there or above); it covers a box
/// inside it at least as near for a box object, and all but slivers at the
/// rim for a ball (its inscribed polygons). A box of voxels each inside a
/// ball, though it spans several, adds no cover beyond the balls' own discs
/// but those slivers and the ring between a ball's two discs (where the box
/// is nearer): on the walkthrough at 200x120x200 such boxes were 13% of the
/// frame's instructions for 0.3% of its PVS (docs/performance.md). The boxes
/// that close seams, across blocks or where a block meets a ball, are kept.
/// Leaving an occluder out is always conservative. Candidates for the first
/// test: the objects at the box's least corner voxel.
std::vector<std::uint8_t> redundant_boxes(const Scene::Impl& s) {
  std::vector<std::uint8_t> inside(s.opaque_boxes.size(), 0);
  const detail::IdLists& own = s.static_lists[0];
  const GridSpec& g = s.spec;
  for (std::size_t b = 0; b < s.opaque_boxes.size(); ++b) {
    const VoxBox& vb = s.opaque_boxes[b];
    const Vec3 lo = g.bounds_min + Vec3(vb.lo) * g.voxel_size, hi = g.bounds_min + Vec3(vb.hi + 1) * g.voxel_size;
    const auto i = static_cast<std::size_t>(s.index(vb.lo.x, vb.lo.y, vb.lo.z));
    std::uint32_t slots[detail::kCoverCandidates];
    std::size_t n = 0;
    for (const std::uint32_t* p = own.begin(i); p != own.end(i) && n < std::size(slots); ++p) slots[n++] = *p;
    if (s.vflags[i] & Scene::Impl::kCoarseIds) s.coarse_static(vb.lo.x, vb.lo.y, vb.lo.z, slots, &n, std::size(slots));
    for (std::size_t k = 0; k < n && !inside[b]; ++k) {
      const Obj& o = s.objs[slots[k]];
      if (o.shape == Shape::Mesh) {
        continue;  // Not drawn into the buffer: the box must be.
      } else if (o.shape == Shape::Sphere) {
        // The farthest corner from the centre within the radius.
        const Vec3 far = glm::max(glm::abs(lo - o.center), glm::abs(hi - o.center));
        inside[b] = glm::dot(far, far) <= o.radius * o.radius;
      } else {
        inside[b] = glm::all(glm::lessThanEqual(o.box_lo(), lo)) && glm::all(glm::lessThanEqual(hi, o.box_hi()));
      }
    }
    bool balls = !inside[b];
    for (int z = vb.lo.z; z <= vb.hi.z && balls; ++z)
      for (int y = vb.lo.y; y <= vb.hi.y && balls; ++y)
        for (int x = vb.lo.x; x <= vb.hi.x && balls; ++x)
          balls = (s.vflags[static_cast<std::size_t>(s.index(x, y, z))] & Scene::Impl::kInOneBall) != 0;
    inside[b] = inside[b] || balls;
  }
  return inside;
}

/// The per-brick lists of the cell traversal (Scene::Impl::brick_static,
/// brick_boxes), from the voxels' own lists and opaque owners.
/// Opaque boxes their objects already cover are left out (redundant_boxes).
void build_brick_lists(Scene::Impl& s) {
  const std::size_t bricks = s.pyr.cells(1);
  const std::vector<std::uint8_t> redundant = redundant_boxes(s);
  const detail::IdLists& own = s.static_lists[0];
  std::vector<std::uint32_t> obj_mark(s.objs.size(), ~0u), box_mark(s.opaque_boxes.size(), ~0u);
  detail::IdLists& objs = s.brick_static;
  detail::IdLists& boxes = s.brick_boxes;
  objs.offsets.assign(1, 0);
  boxes.offsets.assign(1, 0);
  objs.ids.clear();
  boxes.ids.clear();
  for (std::size_t b = 0; b < bricks; ++b) {
    std::uint64_t m = s.static_mask[1][b];
    const glm::ivec3 c(static_cast<int>(b % static_cast<std::size_t>(s.pyr.res[1].x)),
                       static_cast<int>(b / static_cast<std::size_t>(s.pyr.res[1].x) % static_cast<std::size_t>(s.pyr.res[1].y)),
                       static_cast<int>(b / (static_cast<std::size_t>(s.pyr.res[1].x) * static_cast<std::size_t>(s.pyr.res[1].y))));
    const glm::ivec3 o = c << detail::kCellShift;
    while (m != 0) {
      const int bit = __builtin_ctzll(m);
      m &= m - 1;
      const auto idx = static_cast<std::size_t>(s.index(o.x + (bit & 3), o.y + (bit >> 2 & 3), o.z + (bit >> 4)));
      const auto tag = static_cast<std::uint32_t>(b);
      if (s.vflags[idx] & Scene::Impl::kStaticIds)
        for (const std::uint32_t* p = own.begin(idx); p != own.end(idx); ++p)
          if (obj_mark[*p] != tag) {
            obj_mark[*p] = tag;
            objs.ids.push_back(*p);
          }
      if (!s.opaque_owner.empty() && (s.vflags[idx] & Scene::Impl::kStaticOpaque)) {
        const std::uint32_t box = s.opaque_owner[idx];
        if (box != detail::kNoBox && !redundant[box] && box_mark[box] != tag) {
          box_mark[box] = tag;
          boxes.ids.push_back(box);
        }
      }
    }
    objs.offsets.push_back(static_cast<std::uint32_t>(objs.ids.size()));
    boxes.offsets.push_back(static_cast<std::uint32_t>(boxes.ids.size()));
  }
}

/// Calls emit(brick, triangle) for every brick each triangle of static
/// mesh `o` meets (the separating-axis test against the brick grown as
/// mesh_voxels grows voxels). False when cancelled.
template <class Emit>
bool mesh_triangle_bricks(const Scene::Impl& s, const Obj& o, BuildMeter& meter, Emit&& emit) {
  const int side = 1 << detail::kBrickShift;
  const glm::ivec3 bres = s.pyr.res[1];
  const Mesh& mesh = *o.mesh;
  const GridMesh gm(s, o);
  const std::vector<Vec3>& g = gm.g;
  {
    const Vec3 grow = gm.grow;
    const Vec3 half = Vec3(0.5 * side) + grow;
    for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t) {
      const auto& tri = mesh.triangles[t];
      const Vec3 &a = g[tri[0]], &b = g[tri[1]], &c = g[tri[2]];
      const Vec3 lo = glm::min(a, glm::min(b, c)) - grow, hi = glm::max(a, glm::max(b, c)) + grow;
      glm::ivec3 b0, b1;
      bool empty = false;
      for (int k = 0; k < 3; ++k) {
        // Brick i spans [side i, side (i+1)].
        b0[k] = clamp_floor(std::ceil(lo[k] / side) - 1.0, 0, bres[k] - 1);
        b1[k] = clamp_floor(hi[k] / side, -1, bres[k] - 1);
        empty = empty || hi[k] < 0.0 || lo[k] > s.res[k];
      }
      if (empty) continue;
      std::uint64_t n = 0;
      for (int z = b0.z; z <= b1.z; ++z)
        for (int y = b0.y; y <= b1.y; ++y)
          for (int x = b0.x; x <= b1.x; ++x) {
            ++n;
            const Vec3 centre = (Vec3(x, y, z) + 0.5) * static_cast<double>(side);
            if (detail::triangle_meets_box(a, b, c, centre, half)) emit(s.pyr.index(1, glm::ivec3(x, y, z)), t);
          }
      if (!meter.tick(n + 1)) return false;
    }
  }
  return true;
}

/// The entries mesh_triangle_bricks makes for static mesh `o`.
bool count_triangle_bricks(const Scene::Impl& s, const Obj& o, BuildMeter& meter, std::uint64_t* n) {
  return mesh_triangle_bricks(s, o, meter, [&](std::size_t, std::uint32_t) { ++*n; });
}

/// The interiors of closed static meshes, with the buffer on: every voxel
/// some closed mesh's triangles touch gets kMeshTouched (mesh_voxels, the
/// exact triangle-box test grown by the rounding allowance); then every
/// voxel of a closed mesh's range that OpenVDB puts inside and that no
/// closed mesh touches gets kMeshInside (mesh_interior.h). Those voxels are
/// covered with boxes appended to opaque_boxes and listed per brick
/// (brick_mesh_boxes). Needs pair_mesh_triangles first (Obj::outward).
Status build_mesh_interiors(Scene::Impl& s, BuildMeter& meter) {
  std::vector<std::uint32_t> meshes;
  for (std::uint32_t slot = 0; slot < s.objs.size(); ++slot) {
    const Obj& o = s.objs[slot];
    // Closed (pair_mesh_triangles) and enclosing a volume.
    if (o.dynamic || o.shape != Shape::Mesh || o.outward == 0) continue;
    meshes.push_back(slot);
    if (!s.box_inside_grid(o.box_lo(), o.box_hi())) s.closed_mesh_beyond_grid = true;
    if (!mesh_voxels(s, o, meter, [&](int, const glm::ivec3& v) {
          s.vflags[static_cast<std::size_t>(s.index(v.x, v.y, v.z))] |= Scene::Impl::kMeshTouched;
        }))
      return build_cancelled();
  }
  bool any = false;
  for (const std::uint32_t slot : meshes) {
    const Obj& o = s.objs[slot];
    const GridMesh gm(s, o);
    const VoxBox range = s.touch_range(o.box_lo(), o.box_hi(), s.slop(max_abs(o.center) + max_abs(o.half)));
    detail::inside_voxel_centres(gm.g, *o.mesh, range, [&](int x, int y, int z) {
      std::uint8_t& f = s.vflags[static_cast<std::size_t>(s.index(x, y, z))];
      if (!(f & Scene::Impl::kMeshTouched)) {
        f |= Scene::Impl::kMeshInside;
        any = true;
      }
    });
    const glm::ivec3 n = range.empty() ? glm::ivec3(0) : range.hi - range.lo + 1;
    if (!meter.tick(static_cast<std::uint64_t>(n.x) * static_cast<std::uint64_t>(n.y) * static_cast<std::uint64_t>(n.z) +
                    4 * o.mesh->triangles.size()))
      return build_cancelled();
  }
  if (!any) return Status::Ok();
  std::vector<detail::VoxBox> boxes;
  std::vector<std::uint32_t> owner;
  detail::cover_with_boxes(s.res, s.vflags, Scene::Impl::kMeshInside, kOpaqueBoxSide, &boxes, &owner);
  const auto first = static_cast<std::uint32_t>(s.opaque_boxes.size());
  s.opaque_boxes.insert(s.opaque_boxes.end(), boxes.begin(), boxes.end());
  // Per brick, the boxes owning its interior voxels, each once.
  detail::IdLists& lists = s.brick_mesh_boxes;
  lists.offsets.assign(1, 0);
  lists.ids.clear();
  std::vector<std::uint32_t> mark(boxes.size(), ~0u);
  const glm::ivec3 bres = s.pyr.res[1];
  for (int bz = 0; bz < bres.z; ++bz)
    for (int by = 0; by < bres.y; ++by)
      for (int bx = 0; bx < bres.x; ++bx) {
        const auto tag = static_cast<std::uint32_t>(lists.offsets.size() - 1);
        const glm::ivec3 o = glm::ivec3(bx, by, bz) << detail::kBrickShift;
        const glm::ivec3 end = glm::min(o + (1 << detail::kBrickShift), s.res);
        for (int z = o.z; z < end.z; ++z)
          for (int y = o.y; y < end.y; ++y)
            for (int x = o.x; x < end.x; ++x) {
              const std::uint32_t b = owner[static_cast<std::size_t>(s.index(x, y, z))];
              if (b == detail::kNoBox || mark[b] == tag) continue;
              mark[b] = tag;
              lists.ids.push_back(first + b);
            }
        lists.offsets.push_back(static_cast<std::uint32_t>(lists.ids.size()));
      }
  return Status::Ok();
}

/// Pairs every mesh's triangles into quads (Obj::quads) and finds whether
/// it is closed and which way it runs (Obj::outward), once a mesh.
void pair_mesh_triangles(Scene::Impl& s, BuildMeter& meter) {
  struct Done {
    std::shared_ptr<const detail::MeshQuads> quads;
    std::int8_t outward = 0;
  };
  std::unordered_map<const Mesh*, Done> done;
  for (Obj& o : s.objs) {
    if (o.shape != Shape::Mesh) continue;
    auto [it, fresh] = done.try_emplace(o.mesh.get());
    if (fresh) {
      const Mesh& m = *o.mesh;
      it->second.quads = std::make_shared<const detail::MeshQuads>(detail::pair_triangles(m));
      if (detail::mesh_closed(m)) {
        // Six times the signed volume (divergence theorem), about the
        // vertices' centroid to keep the products small.
        const Vec3 c = o.mesh_centroid;
        double vol = 0.0;
        for (const auto& t : m.triangles)
          vol += glm::dot(m.vertices[t[0]] - c, glm::cross(m.vertices[t[1]] - c, m.vertices[t[2]] - c));
        it->second.outward = vol > 0.0 ? 1 : vol < 0.0 ? -1 : 0;
      }
      meter.tick(8 * m.triangles.size() + 1);
    }
    o.quads = it->second.quads;
    o.outward = it->second.outward;
    if (!o.dynamic && o.outward != 0) s.any_closed_mesh = true;
  }
  // Closed dynamic meshes' interiors in their own frames, at cubes of the
  // grid's least voxel side (in model units), once per mesh and side.
  std::map<std::pair<const Mesh*, double>, std::shared_ptr<const detail::ModelInterior>> interiors;
  const double side = std::fmin(s.spec.voxel_size.x, std::fmin(s.spec.voxel_size.y, s.spec.voxel_size.z));
  for (Obj& o : s.objs) {
    if (!o.dynamic || o.shape != Shape::Mesh || o.outward == 0) continue;
    const double h = side / o.mesh_scale;
    auto& in = interiors[{o.mesh.get(), h}];
    if (!in) {
      double model = 0.0;
      for (const Vec3& v : o.mesh->vertices) model = std::fmax(model, max_abs(v));
      in = std::make_shared<const detail::ModelInterior>(detail::model_interior(*o.mesh, h, 1e-9 * model));
      meter.tick(8 * o.mesh->triangles.size() + 1);
    }
    if (!in->boxes.empty()) o.interior = in;
  }
}

/// The static mesh triangles of each brick (Scene::Impl::brick_tris), for
/// the cell traversal with the buffer on: counted, then filled.
Status build_brick_triangles(Scene::Impl& s, BuildMeter& meter) {
  std::uint64_t total = 0;
  for (Obj& o : s.objs) {
    if (o.dynamic || o.shape != Shape::Mesh) continue;
    o.tri_base = static_cast<std::uint32_t>(total);
    total += o.mesh->triangles.size();
    if (total > std::numeric_limits<std::uint32_t>::max())
      return Status::Exhausted("grid", "static meshes hold more than 2^32 triangles in all");
  }
  if (total == 0) return Status::Ok();
  s.static_triangles = static_cast<std::uint32_t>(total);
  std::vector<std::uint32_t>& off = s.brick_tri_offsets;
  off.assign(s.pyr.cells(1) + 1, 0);
  std::uint64_t entries = 0;
  auto static_mesh = [](const Obj& o) { return !o.dynamic && o.shape == Shape::Mesh; };
  for (const Obj& o : s.objs)
    if (static_mesh(o) && !mesh_triangle_bricks(s, o, meter, [&](std::size_t b, std::uint32_t) {
          ++off[b + 1];
          ++entries;
        }))
      return build_cancelled();
  if (entries > std::numeric_limits<std::uint32_t>::max())
    return Status::Exhausted("grid", "static mesh triangles meet more than 2^32 bricks in all; choose a coarser grid");
  for (std::size_t i = 1; i < off.size(); ++i) off[i] += off[i - 1];
  s.brick_tris.resize(static_cast<std::size_t>(entries));
  std::vector<std::uint32_t> next(off.begin(), off.end() - 1);
  for (std::uint32_t slot = 0; slot < s.objs.size(); ++slot) {
    Obj& o = s.objs[slot];
    if (!static_mesh(o)) continue;
    if (!mesh_triangle_bricks(s, o, meter, [&](std::size_t b, std::uint32_t t) {
          s.brick_tris[next[b]++] = detail::TriRef{slot, t};
        }))
      return build_cancelled();
    // The vertices the buffer draws, placed as the bricks were found.
    const ObjectDesc d = o.mesh_desc();
    o.placed.resize(o.mesh->vertices.size());
    for (std::size_t i = 0; i < o.placed.size(); ++i) o.placed[i] = place(d, o.mesh->vertices[i]);
  }
  return Status::Ok();
}

}  // namespace

Status Scene::estimate(const SceneDesc& desc, const SceneOptions& options, SceneCost* out,
                       const BuildControl* control) {
  Impl s;
  if (Status st = prepare(desc, options, s); !st) return st;
  BuildMeter meter(control);
  SceneCost cost;
  if (Status st = count_cost(s, meter, &cost); !st) return st;
  *out = cost;
  return Status::Ok();
}

Status Scene::create(const SceneDesc& desc, const SceneOptions& options, std::unique_ptr<Scene>* out,
                     const BuildControl* control) {
  auto impl = std::make_unique<Impl>();
  Impl& s = *impl;
  if (Status st = prepare(desc, options, s); !st) return st;
  BuildMeter meter(control);
  LevelCounts per_level{};
  {
    // Refused before the grid's layers are allocated.
    SceneCost cost;
    if (Status st = count_cost(s, meter, &cost, &per_level); !st) return st;
  }
  const std::size_t nvox = static_cast<std::size_t>(s.spec.voxel_count());
  s.vflags.assign(nvox, 0);
  if (Status st = build_static_lists(s, meter, per_level); !st) return st;

  // Static cover, once: from every static object touching the voxel (its
  // own list, then the coarser cells', kCoverCandidates at most).
  const detail::IdLists& own = s.static_lists[0];
  for (int z = 0; z < s.res.z; ++z)
    for (int y = 0; y < s.res.y; ++y) {
      if (!meter.tick(static_cast<std::uint64_t>(s.res.x))) return build_cancelled();
      for (int x = 0; x < s.res.x; ++x) {
        const auto i = static_cast<std::size_t>(s.index(x, y, z));
        const std::uint8_t f = s.vflags[i];
        if ((f & (Impl::kStaticIds | Impl::kCoarseIds)) == 0) continue;
        std::uint32_t slots[detail::kCoverCandidates];
        const std::uint32_t* first = own.begin(i);
        auto n = static_cast<std::size_t>(own.end(i) - first);
        if (f & Impl::kCoarseIds) {
          std::size_t k = 0;
          for (const std::uint32_t* p = own.begin(i); p != own.end(i) && k < std::size(slots); ++p) slots[k++] = *p;
          s.coarse_static(x, y, z, slots, &k, std::size(slots));
          first = slots, n = k;
        }
        if (!s.union_covers(first, n, x, y, z)) continue;
        s.vflags[i] |= Impl::kStaticOpaque;
        if (s.in_one_ball(first, n, x, y, z)) s.vflags[i] |= Impl::kInOneBall;
      }
    }
  if (s.options.occlusion_buffer > 0) {
    detail::cover_with_boxes(s.res, s.vflags, Impl::kStaticOpaque, kOpaqueBoxSide, &s.opaque_boxes,
                             &s.opaque_owner);
    pair_mesh_triangles(s, meter);
    if (Status st = build_mesh_interiors(s, meter); !st) return st;
  }
  // The cell traversal's summaries: only the buffer's traversal reads them.
  const bool cells = s.options.occlusion_buffer > 0;
  if (cells) {
    build_static_masks(s);
    build_brick_lists(s);
    if (Status st = build_brick_triangles(s, meter); !st) return st;
  }

  if (s.dynamic_count > 0) {
    s.bricks_res = s.pyr.res[1];
    s.bricks.resize(s.pyr.cells(1));
    for (int l = 2; l < s.pyr.levels; ++l) s.coarse_dyn[static_cast<std::size_t>(l)].resize(s.pyr.cells(l));
    for (int l = 1; cells && l < s.pyr.levels; ++l) {
      s.dyn_count[static_cast<std::size_t>(l)].assign(s.pyr.cells(l), 0);
      s.dyn_mask[static_cast<std::size_t>(l)].assign(s.pyr.cells(l), 0);
    }
    s.seen_at.assign(s.bricks.size(), -std::numeric_limits<double>::infinity());
    s.seen_mask.assign(s.bricks.size(), 0);
    for (int l = 2; l < s.pyr.levels; ++l)
      s.cell_seen_at[static_cast<std::size_t>(l)].assign(s.pyr.cells(l), -std::numeric_limits<double>::infinity());
    if (s.pyr.levels > 2) s.cell_any_seen_at.assign(s.pyr.cells(2), -std::numeric_limits<double>::infinity());
    // Until a viewer has looked, every object may be visible: discretize all
    // dynamic objects now; those no viewer claims get TBVs after a frame.
    for (std::uint32_t slot = 0; slot < s.objs.size(); ++slot) {
      Obj& o = s.objs[slot];
      if (!o.dynamic) continue;
      if (!meter.tick(64)) return build_cancelled();
      o.tbv_period = s.initial_period(o);
      s.discretize(slot);
      o.pending_unclaimed = true;
      s.unclaimed.push_back(slot);
    }
    s.pending = FrameStats{};
  }
  out->reset(new Scene(std::move(impl)));
  return Status::Ok();
}

}  // namespace voxvis
