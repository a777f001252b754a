// build_validate.cpp — a scene's description checked (ids unique, finite
// values, radius > 0, min <= max, meshes and their placements, the grid
// within the options), the grid it gets, and its objects set up for the
// build (prepare). What it costs is build_cost.cpp's; the build itself,
// build.cpp's.
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <unordered_map>

#include "build_parts.h"
#include "numeric.h"
#include "occlusion_buffer.h"
#include "scene_impl.h"

namespace voxvis {

using detail::Obj;
using detail::VoxBox;
using detail::clamp_floor;
using detail::finite3;
using detail::kUlp;
using detail::max_abs;

namespace {

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
    return Status::Error("tbv_period",
                         "must be 0 (per object) or a finite number of seconds >= " + number_text(kMinTbvPeriod));
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

namespace build {

Status prepare(const SceneDesc& desc, const SceneOptions& options, Scene::Impl& s, BuildMeter& meter) {
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
  // A mesh's own figures, taken once however many objects place it.
  struct ModelFigures {
    Vec3 centroid;
    double extent, reach;
  };
  std::unordered_map<const Mesh*, ModelFigures> models;
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
      auto [fig, fresh] = models.try_emplace(d.mesh.get());
      if (fresh) {
        fig->second.centroid = mesh_centroid(*d.mesh);
        double model = 0.0;
        for (const Vec3& v : d.mesh->vertices) model = std::fmax(model, max_abs(v));
        fig->second.extent = model;
        fig->second.reach = mesh_reach(*d.mesh, fig->second.centroid);
      }
      o.mesh_centroid = fig->second.centroid;
      o.mesh_extent = d.scale * std::sqrt(3.0) * fig->second.extent;
      if (o.dynamic) o.radius = d.scale * fig->second.reach;
      s.place_mesh(o);  // A static mesh's box: every vertex placed.
      if (!meter.tick(o.dynamic ? 1 : d.mesh->vertices.size())) return build_cancelled();
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
    (o.dynamic ? s.dynamic_slots : s.static_slots).push_back(static_cast<std::uint32_t>(s.objs.size()));
    if (o.dynamic) s.max_dynamic_speed = std::fmax(s.max_dynamic_speed, o.max_speed);
    s.objs.push_back(o);
    if (o.dynamic) ++s.dynamic_count;
  }
  s.static_slots.shrink_to_fit();  // 4 bytes an object in all (build_cost.cpp).
  s.dynamic_slots.shrink_to_fit();
  return Status::Ok();
}

}  // namespace build
}  // namespace voxvis
