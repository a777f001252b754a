// scenes.cpp — see scenes.h.
#include "scenes.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <numbers>

#include <glm/geometric.hpp>

namespace voxvis::test {

std::uint64_t mix_seed(std::uint64_t a, std::uint64_t b) {
  std::uint64_t x = a * 0x9e3779b97f4a7c15ULL + b + 0x632be59bd9b4e019ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

double test_scale() {
  const char* s = std::getenv("VOXVIS_TEST_SCALE");
  if (s == nullptr || *s == '\0') return 1.0;
  char* end = nullptr;
  const double v = std::strtod(s, &end);
  if (end == s || !std::isfinite(v) || v <= 0.0) return 1.0;
  return v;
}

int scaled(int n) {
  const double v = std::round(n * test_scale());
  return v < 1.0 ? 1 : static_cast<int>(std::min(v, 1e9));
}

RandomSceneParams random_scene_params(std::uint64_t seed) {
  Rng rng(mix_seed(seed, 0x5ce9e));
  RandomSceneParams p;
  const Vec3 extent(rng.log_uniform(10.0, 200.0), rng.log_uniform(10.0, 200.0),
                    rng.log_uniform(10.0, 200.0));
  const Vec3 origin = rng.chance(0.5) ? Vec3(0.0) : rng.in_box(Vec3(-500.0), Vec3(500.0));
  p.bounds_min = origin;
  p.bounds_max = origin + extent;
  p.grid = glm::ivec3(rng.uniform_int(2, 48), rng.uniform_int(2, 48), rng.uniform_int(2, 48));
  if (rng.chance(0.1)) p.grid[rng.uniform_int(0, 2)] = 1;  // a flat grid
  p.spheres = rng.uniform_int(10, 140);
  p.boxes = rng.uniform_int(5, 70);
  p.occluders = rng.uniform_int(0, 16);
  p.walls = rng.uniform_int(0, 12);
  p.outside = rng.uniform_int(0, 6);
  p.partly_outside = rng.uniform(0.0, 0.2);
  p.dynamic_fraction = rng.chance(0.15) ? 0.0 : rng.uniform(0.05, 0.6);
  const double voxel = std::min({extent.x / p.grid.x, extent.y / p.grid.y, extent.z / p.grid.z});
  p.max_speed = voxel * rng.log_uniform(1.0, 60.0);  // up to ~2 voxels a frame at 30 fps
  p.min_size_voxels = rng.log_uniform(0.05, 0.5);
  p.max_size_voxels = rng.log_uniform(1.0, 8.0);
  return p;
}

SceneDesc random_scene(const RandomSceneParams& p, std::uint64_t seed) {
  Rng rng(mix_seed(seed, 0x0b1ec7));
  SceneDesc desc;
  desc.bounds_min = p.bounds_min;
  desc.bounds_max = p.bounds_max;
  desc.grid = p.grid;
  const Vec3 extent = p.bounds_max - p.bounds_min;
  const Vec3 voxel = extent / Vec3(p.grid);
  const double mean_voxel = (voxel.x + voxel.y + voxel.z) / 3.0;

  auto size_voxels = [&]() { return rng.log_uniform(p.min_size_voxels, p.max_size_voxels); };
  // A centre inside the bounds, or straddling them with the given chance.
  auto place = [&](const Vec3& half) {
    if (rng.chance(p.partly_outside)) {
      Vec3 c = rng.in_box(p.bounds_min, p.bounds_max);
      const int axis = rng.uniform_int(0, 2);
      c[axis] = rng.chance(0.5) ? p.bounds_min[axis] + rng.uniform(-0.9, 0.9) * half[axis]
                                : p.bounds_max[axis] + rng.uniform(-0.9, 0.9) * half[axis];
      return c;
    }
    return rng.in_box(p.bounds_min, p.bounds_max);
  };
  auto make_dynamic = [&](ObjectDesc* o, double chance_scale) {
    if (rng.chance(p.dynamic_fraction * chance_scale)) {
      o->dynamic = true;
      o->max_speed = rng.chance(0.05) ? 0.0 : rng.uniform(0.0, p.max_speed);
    }
  };

  std::vector<ObjectDesc> objs;
  for (int i = 0; i < p.spheres; ++i) {
    ObjectDesc o;
    o.shape = Shape::Sphere;
    o.radius = 0.5 * size_voxels() * mean_voxel;
    o.center = place(Vec3(o.radius));
    make_dynamic(&o, 1.0);
    objs.push_back(o);
  }
  for (int i = 0; i < p.boxes; ++i) {
    ObjectDesc o;
    o.shape = Shape::Box;
    o.half_extent = 0.5 * Vec3(size_voxels() * voxel.x, size_voxels() * voxel.y,
                               size_voxels() * voxel.z);
    if (rng.chance(0.05)) o.half_extent[rng.uniform_int(0, 2)] = 0.0;  // flat
    o.center = place(o.half_extent);
    if (rng.chance(0.15)) {
      // Faces on voxel planes (as exactly as the world mapping allows).
      for (int a = 0; a < 3; ++a) {
        const int n = std::max(1, static_cast<int>(std::round(2.0 * o.half_extent[a] / voxel[a])));
        const int i0 = rng.uniform_int(0, std::max(0, p.grid[a] - n));
        const double lo = p.bounds_min[a] + i0 * voxel[a];
        const double hi = p.bounds_min[a] + (i0 + n) * voxel[a];
        o.center[a] = 0.5 * (lo + hi);
        o.half_extent[a] = 0.5 * (hi - lo);
      }
    }
    make_dynamic(&o, 1.0);
    objs.push_back(o);
  }
  for (int i = 0; i < p.occluders; ++i) {
    ObjectDesc o;
    o.shape = Shape::Box;
    for (int a = 0; a < 3; ++a) o.half_extent[a] = 0.5 * rng.uniform(2.0, 10.0) * voxel[a];
    const int thin = rng.uniform_int(0, 2);
    o.half_extent[thin] = 0.5 * rng.uniform(1.0, 3.0) * voxel[thin];
    o.center = rng.in_box(p.bounds_min, p.bounds_max);
    make_dynamic(&o, 0.3);
    objs.push_back(o);
  }
  for (int i = 0; i < p.walls; ++i) {
    ObjectDesc o;
    o.shape = Shape::Box;
    const int axis = rng.uniform_int(0, 2);
    for (int a = 0; a < 3; ++a) o.half_extent[a] = 0.5 * rng.uniform(3.0, 20.0) * voxel[a];
    o.half_extent[axis] = rng.chance(0.2) ? 0.0 : 0.5 * rng.uniform(0.01, 0.9) * voxel[axis];
    o.center = rng.in_box(p.bounds_min, p.bounds_max);
    if (rng.chance(0.3)) {
      // The wall's plane on a voxel plane.
      o.center[axis] = p.bounds_min[axis] + rng.uniform_int(0, p.grid[axis]) * voxel[axis];
    }
    make_dynamic(&o, 0.3);
    objs.push_back(o);
  }
  for (int i = 0; i < p.outside; ++i) {
    ObjectDesc o;
    const double s = size_voxels() * mean_voxel;
    if (rng.chance(0.5)) {
      o.shape = Shape::Sphere;
      o.radius = 0.5 * s;
    } else {
      o.shape = Shape::Box;
      o.half_extent = Vec3(0.5 * s);
    }
    Vec3 c = rng.in_box(p.bounds_min, p.bounds_max);
    const int axis = rng.uniform_int(0, 2);
    const double gap = s + rng.uniform(0.01, 0.5) * extent[axis];
    c[axis] = rng.chance(0.5) ? p.bounds_min[axis] - gap : p.bounds_max[axis] + gap;
    o.center = c;
    make_dynamic(&o, 1.0);
    objs.push_back(o);
  }

  // Unique, non-contiguous ids from a random base (sometimes 0, sometimes
  // near the top of the range); then shuffle the order.
  std::uint64_t next = 0;
  switch (rng.uniform_int(0, 3)) {
    case 0: next = 0; break;
    case 1: next = 1; break;
    case 2: next = static_cast<std::uint64_t>(rng.uniform_int(1, 1'000'000)); break;
    default: next = 0xFFFFFFFFULL - 6ULL * (objs.size() + 1); break;
  }
  for (ObjectDesc& o : objs) {
    o.id = static_cast<ObjectId>(next);
    next += static_cast<std::uint64_t>(rng.uniform_int(1, 5));
  }
  for (std::size_t i = objs.size(); i > 1; --i) {
    const std::size_t j = static_cast<std::size_t>(rng.uniform_int(0, static_cast<int>(i - 1)));
    std::swap(objs[i - 1], objs[j]);
  }
  desc.objects = std::move(objs);
  return desc;
}

namespace {

Vec3 pick_up(Rng& rng, const Vec3& dir, bool roll) {
  const Vec3 f = glm::normalize(dir);
  Vec3 up(0.0, 1.0, 0.0);
  if (roll) up = rng.unit_vector();
  for (int tries = 0; tries < 8 && glm::length(glm::cross(f, up)) < 0.2; ++tries) {
    up = rng.unit_vector();
  }
  if (glm::length(glm::cross(f, up)) < 0.2) {
    up = std::abs(f.x) < 0.5 ? Vec3(1.0, 0.0, 0.0) : Vec3(0.0, 0.0, 1.0);
  }
  return up;
}

Vec3 polyline(const std::vector<Vec3>& pts, double s) {
  const double u = s * static_cast<double>(pts.size() - 1);
  const std::size_t i = std::min(pts.size() - 2, static_cast<std::size_t>(std::max(0.0, std::floor(u))));
  const double w = std::clamp(u - static_cast<double>(i), 0.0, 1.0);
  return pts[i] * (1.0 - w) + pts[i + 1] * w;
}

}  // namespace

std::vector<Camera> random_camera_path(const SceneDesc& scene, std::uint64_t seed,
                                       const CameraPathParams& params) {
  Rng rng(mix_seed(seed, 0xca3e7a));
  const Vec3 lo = scene.bounds_min;
  const Vec3 hi = scene.bounds_max;
  const Vec3 extent = hi - lo;
  const double diag = glm::length(extent);
  const double min_extent = std::min({extent.x, extent.y, extent.z});

  const int waypoints = rng.uniform_int(2, 5);
  std::vector<Vec3> eye_pts;
  std::vector<Vec3> target_pts;
  const bool outside = rng.chance(params.outside_chance);
  for (int i = 0; i < waypoints; ++i) {
    const double m = (outside && i == 0) ? 0.8 : 0.1;
    eye_pts.push_back(rng.in_box(lo - m * extent, hi + m * extent));
    target_pts.push_back(rng.in_box(lo, hi));
  }
  const bool look_ahead = rng.chance(0.3);
  const bool roll = rng.chance(0.2);
  Camera base;
  base.fov_y_deg = rng.uniform(params.fov_min, params.fov_max);
  base.aspect = rng.uniform(params.aspect_min, params.aspect_max);
  base.near = min_extent * rng.log_uniform(params.near_min, params.near_max);
  base.far = rng.chance(params.short_far_chance) ? diag * rng.uniform(0.15, 0.8) : diag * 3.0;
  if (!(base.far > base.near)) base.far = base.near * 4.0 + diag;
  if (rng.chance(params.extreme_lens_chance)) {
    base.fov_y_deg = rng.chance(0.5) ? rng.uniform(1.0, 5.0) : rng.uniform(160.0, 179.0);
    base.aspect = rng.chance(0.5) ? rng.uniform(0.1, 0.3) : rng.uniform(3.0, 10.0);
  }
  const Vec3 fallback_dir = rng.unit_vector();
  Vec3 up = pick_up(rng, fallback_dir, roll);
  // Eye on voxel planes: which axes to snap.
  bool snap[3] = {false, false, false};
  if (scene.grid && rng.chance(params.snap_eye_chance)) {
    const int axes = rng.uniform_int(1, 3);
    for (int i = 0; i < axes; ++i) snap[rng.uniform_int(0, 2)] = true;
  }
  const bool axis_dirs = rng.chance(params.axis_dir_chance);

  std::vector<Camera> path;
  const int n = std::max(1, params.frames);
  for (int k = 0; k < n; ++k) {
    const double s = n == 1 ? 0.0 : static_cast<double>(k) / (n - 1);
    Camera c = base;
    c.eye = polyline(eye_pts, s);
    Vec3 dir;
    if (look_ahead) {
      const double s2 = std::min(1.0, s + 0.05);
      dir = polyline(eye_pts, s2) - polyline(eye_pts, std::max(0.0, s2 - 0.05));
    } else {
      dir = polyline(target_pts, s) - c.eye;
    }
    if (!(glm::length(dir) > 1e-9 * diag)) dir = fallback_dir;
    if (axis_dirs) {
      // The nearest of the axes and exact diagonals.
      const Vec3 f = glm::normalize(dir);
      Vec3 q(0.0);
      for (int a = 0; a < 3; ++a) q[a] = std::abs(f[a]) > 0.38 ? (f[a] > 0 ? 1.0 : -1.0) : 0.0;
      if (q == Vec3(0.0)) q = f;
      dir = q;
    }
    for (int a = 0; a < 3; ++a) {
      if (!snap[a]) continue;
      const double vs = extent[a] / (*scene.grid)[a];
      c.eye[a] = lo[a] + std::round((c.eye[a] - lo[a]) / vs) * vs;
    }
    c.dir = dir;
    if (glm::length(glm::cross(glm::normalize(dir), up)) < 0.1) up = pick_up(rng, dir, roll);
    c.up = up;
    path.push_back(c);
  }
  return path;
}

Mover::Mover(const SceneDesc& scene, std::uint64_t seed, double margin)
    : objects_(scene.objects), rng_(mix_seed(seed, 0x30be5)) {
  const Vec3 extent = scene.bounds_max - scene.bounds_min;
  lo_ = scene.bounds_min - margin * extent;
  hi_ = scene.bounds_max + margin * extent;
  velocity_.resize(objects_.size(), Vec3(0.0));
  for (std::size_t i = 0; i < objects_.size(); ++i) {
    if (objects_[i].dynamic) {
      velocity_[i] = rng_.unit_vector() * (rng_.uniform(0.0, 0.999) * objects_[i].max_speed);
    }
  }
}

std::vector<Move> Mover::step(double dt) {
  std::vector<Move> moves;
  for (std::size_t i = 0; i < objects_.size(); ++i) {
    ObjectDesc& o = objects_[i];
    if (!o.dynamic || o.max_speed <= 0.0) continue;
    if (rng_.chance(0.1)) {
      velocity_[i] = rng_.unit_vector() * (rng_.uniform(0.0, 0.999) * o.max_speed);
    }
    Vec3 v = velocity_[i];
    Vec3 next = o.center + v * dt;
    for (int a = 0; a < 3; ++a) {
      if ((next[a] < lo_[a] && v[a] < 0.0) || (next[a] > hi_[a] && v[a] > 0.0)) v[a] = -v[a];
    }
    velocity_[i] = v;
    next = o.center + v * dt;
    if (next == o.center) continue;
    o.center = next;
    moves.push_back({o.id, next});
  }
  return moves;
}

void apply_moves_to(std::vector<ObjectDesc>* objects, const std::vector<Move>& moves) {
  for (const Move& m : moves) {
    for (ObjectDesc& o : *objects) {
      if (o.id == m.id) {
        o.center = m.center;
        if (m.has_rotation && o.shape == Shape::Mesh) o.rotation = m.rotation;
        break;
      }
    }
  }
}

SceneDesc transform_scene(const SceneDesc& scene, double scale, const Vec3& offset) {
  SceneDesc out = scene;
  out.bounds_min = scene.bounds_min * scale + offset;
  out.bounds_max = scene.bounds_max * scale + offset;
  for (ObjectDesc& o : out.objects) {
    o.center = o.center * scale + offset;
    o.radius *= scale;
    o.half_extent *= scale;
    if (o.shape == Shape::Mesh) o.scale *= scale;
    o.max_speed *= scale;
  }
  return out;
}

std::string frames_side_by_side(const SceneDesc& a, const Camera& cam_a, const SceneDesc& b, const Camera& cam_b,
                                int frames, double hz,
                                const std::function<void(int, const FrameResult&, const FrameResult&)>& check) {
  std::unique_ptr<Scene> sa, sb;
  if (const Status st = Scene::create(a, SceneOptions{}, &sa); !st.ok) return "scene a: " + st.str();
  if (const Status st = Scene::create(b, SceneOptions{}, &sb); !st.ok) return "scene b: " + st.str();
  Scratch scratch;
  const ViewerId va = sa->add_viewer(), vb = sb->add_viewer();
  FrameResult ra, rb;
  for (int i = 0; i < frames; ++i) {
    const double t = i / hz;
    if (const Status st = sa->frame(va, cam_a, t, scratch, &ra); !st.ok)
      return "scene a, frame " + std::to_string(i) + ": " + st.str();
    if (const Status st = sb->frame(vb, cam_b, t, scratch, &rb); !st.ok)
      return "scene b, frame " + std::to_string(i) + ": " + st.str();
    check(i, ra, rb);
  }
  return "";
}

SceneDesc unit_grid(int n) {
  SceneDesc d;
  d.bounds_min = Vec3(0.0);
  d.bounds_max = Vec3(static_cast<double>(n));
  d.grid = glm::ivec3(n);
  return d;
}

Camera camera_along(const Vec3& eye, const Vec3& dir, double fov_y_deg, double aspect, double near,
                    double far) {
  Camera c;
  c.eye = eye;
  c.dir = dir;
  c.up = Vec3(0.0, 1.0, 0.0);
  c.fov_y_deg = fov_y_deg;
  c.aspect = aspect;
  c.near = near;
  c.far = far;
  return c;
}

Camera transform_camera(const Camera& cam, double scale, const Vec3& offset) {
  Camera out = cam;
  out.eye = cam.eye * scale + offset;
  out.near = cam.near * scale;
  out.far = cam.far * scale;
  return out;
}

std::vector<Move> transform_moves(const std::vector<Move>& moves, double scale, const Vec3& offset) {
  std::vector<Move> out = moves;
  for (Move& m : out) m.center = m.center * scale + offset;
  return out;
}

std::string describe_scene(const SceneDesc& scene, std::uint64_t seed) {
  char buf[256];
  const glm::ivec3 g = scene.grid.value_or(glm::ivec3(0));
  std::snprintf(buf, sizeof buf,
                "seed=%llu grid=%dx%dx%d bounds={%.17g,%.17g,%.17g}-{%.17g,%.17g,%.17g} objects=%zu",
                static_cast<unsigned long long>(seed), g.x, g.y, g.z, scene.bounds_min.x,
                scene.bounds_min.y, scene.bounds_min.z, scene.bounds_max.x, scene.bounds_max.y,
                scene.bounds_max.z, scene.objects.size());
  return buf;
}

ObjectDesc dynamic(ObjectDesc o, double max_speed) {
  o.dynamic = true;
  o.max_speed = max_speed;
  return o;
}

}  // namespace voxvis::test
