// generate.cpp — deterministic scenes and walkthroughs (generate.h).
//
// Determinism: random numbers come only from voxvis::Rng (rng.h):
// std::mt19937_64, whose output sequence the standard fixes, and our own
// mappings to floating point and integers. The standard distributions
// (uniform_real_distribution, normal_distribution, ...) are implementation
// defined and would make files differ between standard libraries.
// std::sin/cos/sqrt are used for the camera paths, move directions and the
// voxel world's terrain; they are correctly rounded or nearly so on every
// libm we care about, and the limits that matter (move length <= max_speed *
// dt) are checked on the final numbers, not assumed.
#include "voxvis/generate.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <vector>

#include <glm/geometric.hpp>

#include "voxvis/rng.h"

namespace voxvis {
namespace {

/// Bell-shaped, mean 0, standard deviation 1: the sum of three uniforms on
/// [-1, 1) (each of variance 1/3). Bounded by 3, which keeps clusters compact.
double bell(Rng& rng) {
  return rng.uniform(-1.0, 1.0) + rng.uniform(-1.0, 1.0) + rng.uniform(-1.0, 1.0);
}

Vec3 clamp_to(const Vec3& p, const Vec3& lo, const Vec3& hi) {
  return Vec3{std::clamp(p.x, lo.x, hi.x), std::clamp(p.y, lo.y, hi.y),
              std::clamp(p.z, lo.z, hi.z)};
}

/// Keeps `next` inside [lo, hi] on the axes where `prev` is inside, by
/// reflecting off the walls then clamping. Both steps only shrink each
/// coordinate's distance to `prev`, so the move never gets longer.
Vec3 bounce(const Vec3& prev, Vec3 next, const Vec3& lo, const Vec3& hi) {
  for (int a = 0; a < 3; ++a) {
    if (prev[a] < lo[a] || prev[a] > hi[a]) continue;  // Started outside: leave it.
    if (next[a] > hi[a]) next[a] = 2.0 * hi[a] - next[a];
    if (next[a] < lo[a]) next[a] = 2.0 * lo[a] - next[a];
    next[a] = std::clamp(next[a], lo[a], hi[a]);
  }
  return next;
}

/// A camera of the static scenes' paths.
Camera path_camera(Vec3 eye, Vec3 dir, double fov) {
  Camera c;
  c.eye = eye;
  c.dir = dir;
  c.up = Vec3(0.0, 1.0, 0.0);
  c.fov_y_deg = fov;
  c.aspect = 16.0 / 9.0;
  c.near = 0.05;
  c.far = 500.0;
  return c;
}

}  // namespace

SceneDesc make_paper_scene(const PaperSceneParams& params) {
  Rng rng(params.seed);
  SceneDesc desc;
  desc.bounds_min = params.bounds_min;
  desc.bounds_max = params.bounds_max;

  const int count = std::max(0, params.objects);
  const int dynamic = std::clamp(params.dynamic, 0, count);
  const int cluster_count = std::max(1, params.clusters);
  constexpr double kClusterSigma = 6.0;  // World units.

  std::vector<Vec3> clusters;
  clusters.reserve(static_cast<std::size_t>(cluster_count));
  for (int c = 0; c < cluster_count; ++c) {
    Vec3 p{0.0};
    for (int a = 0; a < 3; ++a) p[a] = rng.uniform(params.bounds_min[a], params.bounds_max[a]);
    clusters.push_back(p);
  }

  desc.objects.reserve(static_cast<std::size_t>(count));
  for (int i = 0; i < count; ++i) {
    // A cluster index; the modulo bias, at most count / 2^64, is negligible.
    const Vec3& c = clusters[rng.bits() % static_cast<std::uint64_t>(cluster_count)];
    Vec3 p{0.0};
    for (int a = 0; a < 3; ++a) p[a] = c[a] + kClusterSigma * bell(rng);
    // Radii 0.3 .. 2.5, skewed towards small ones (density ~ 1/sqrt).
    const double u = rng.uniform();
    ObjectDesc o;
    o.id = static_cast<ObjectId>(i + 1);
    o.shape = Shape::Sphere;
    o.center = clamp_to(p, params.bounds_min, params.bounds_max);
    o.radius = 0.3 + 2.2 * u * u;
    o.dynamic = i < dynamic;
    o.max_speed = o.dynamic ? params.max_speed : 0.0;
    desc.objects.push_back(o);
  }
  return desc;
}

std::vector<FrameInput> make_walkthrough(const SceneDesc& scene,
                                         const WalkthroughParams& params) {
  Rng rng(params.seed);
  const int frames = std::max(0, params.frames);
  const double fps = params.fps > 0.0 ? params.fps : 60.0;
  const double dt = 1.0 / fps;
  constexpr double kTwoPi = 2.0 * std::numbers::pi;

  const Vec3 lo = scene.bounds_min;
  const Vec3 hi = scene.bounds_max;
  const Vec3 mid = (lo + hi) * 0.5;
  const Vec3 extent = hi - lo;
  const double ra = 0.35 * extent.x;
  const double rb = 0.35 * extent.z;
  const double phase0 = rng.uniform(0.0, kTwoPi);

  struct Mover {
    ObjectId id;
    double max_speed;
    Vec3 center;
  };
  std::vector<Mover> movers;
  for (const ObjectDesc& o : scene.objects) {
    if (o.dynamic) movers.push_back(Mover{o.id, o.max_speed, o.center});
  }

  std::vector<FrameInput> out;
  out.reserve(static_cast<std::size_t>(frames));
  for (int i = 0; i < frames; ++i) {
    FrameInput f;
    f.t = static_cast<double>(i) / fps;
    f.line = i + 1;

    // One lap of the ellipse over the walkthrough, eye at mid height.
    const double theta = phase0 + kTwoPi * static_cast<double>(i) / static_cast<double>(frames);
    Camera& cam = f.camera;
    cam.eye = Vec3{mid.x + ra * std::cos(theta), mid.y, mid.z + rb * std::sin(theta)};
    // Tangent of the ellipse (direction of travel), then a gentle look-around.
    const double tx = -ra * std::sin(theta);
    const double tz = rb * std::cos(theta);
    const double heading = std::atan2(tz, tx) + 0.25 * std::sin(3.0 * theta);
    const double pitch = 0.1 * std::sin(5.0 * theta + 0.7);
    cam.dir = Vec3{std::cos(pitch) * std::cos(heading), std::sin(pitch),
                   std::cos(pitch) * std::sin(heading)};
    cam.up = Vec3{0.0, 1.0, 0.0};
    cam.fov_y_deg = params.fov_y_deg;
    cam.aspect = params.aspect;
    cam.near = params.near;
    cam.far = params.far;

    if (params.moves && !movers.empty()) {
      f.moves.reserve(movers.size());
      for (Mover& m : movers) {
        // Frame 0 repeats the initial centres; later frames move at most
        // max_speed * dt (less a 1e-9 relative margin for rounding).
        if (i > 0) {
          const double limit = m.max_speed * dt;
          const double step = limit * (1.0 - 1e-9) * rng.uniform();
          const Vec3 dir = rng.unit_vector();
          const Vec3 next = bounce(m.center, m.center + dir * step, lo, hi);
          // Rounding can only matter for huge coordinates and tiny steps:
          // then stay put rather than exceed the limit.
          if (glm::length(next - m.center) <= limit * (1.0 - 1e-10)) m.center = next;
        }
        f.moves.push_back(Move{m.id, m.center});
      }
    }
    out.push_back(std::move(f));
  }
  return out;
}

ObjectDesc sphere(ObjectId id, Vec3 center, double radius) {
  ObjectDesc o;
  o.id = id;
  o.shape = Shape::Sphere;
  o.center = center;
  o.radius = radius;
  return o;
}

ObjectDesc box_around(ObjectId id, Vec3 center, Vec3 half_extent) {
  ObjectDesc o;
  o.id = id;
  o.shape = Shape::Box;
  o.center = center;
  o.half_extent = half_extent;
  return o;
}

ObjectDesc box_between(ObjectId id, Vec3 lo, Vec3 hi) {
  return box_around(id, 0.5 * (lo + hi), 0.5 * (hi - lo));
}

ScenePath make_indoor_level(int rooms_x, int rooms_z, int frames, std::uint64_t seed) {
  constexpr int kRoom = 12;  // Voxels from wall to wall, walls included.
  constexpr int kHeight = 6;
  ScenePath out;
  SceneDesc& d = out.scene;
  const int nx = rooms_x * kRoom + 1, nz = rooms_z * kRoom + 1;
  d.bounds_min = Vec3(0.0);
  d.bounds_max = Vec3(nx, kHeight, nz);
  d.grid = glm::ivec3(nx, kHeight, nz);
  ObjectId id = 1;
  d.objects.push_back(box_between(id++, Vec3(0, 0, 0), Vec3(nx, 1, nz)));                  // floor
  d.objects.push_back(box_between(id++, Vec3(0, kHeight - 1, 0), Vec3(nx, kHeight, nz)));  // ceiling
  // Walls along x (at z = k * kRoom) and along z (at x = k * kRoom), one box
  // per segment between doorways; doorways 2 voxels wide in the middle of
  // each inner wall.
  const double y0 = 1.0, y1 = kHeight - 1.0;
  for (int k = 0; k <= rooms_z; ++k) {
    const double z = k * kRoom;
    for (int r = 0; r < rooms_x; ++r) {
      const double x0 = r * kRoom, x1 = x0 + kRoom + 1;
      if (k == 0 || k == rooms_z) {
        d.objects.push_back(box_between(id++, Vec3(x0, y0, z), Vec3(x1, y1, z + 1)));
      } else {
        d.objects.push_back(box_between(id++, Vec3(x0, y0, z), Vec3(x0 + 5, y1, z + 1)));
        d.objects.push_back(box_between(id++, Vec3(x0 + 7, y0, z), Vec3(x1, y1, z + 1)));
      }
    }
  }
  for (int k = 0; k <= rooms_x; ++k) {
    const double x = k * kRoom;
    for (int r = 0; r < rooms_z; ++r) {
      const double z0 = r * kRoom + 1, z1 = z0 + kRoom - 1;
      if (k == 0 || k == rooms_x) {
        d.objects.push_back(box_between(id++, Vec3(x, y0, z0), Vec3(x + 1, y1, z1)));
      } else {
        d.objects.push_back(box_between(id++, Vec3(x, y0, z0), Vec3(x + 1, y1, z0 + 4)));
        d.objects.push_back(box_between(id++, Vec3(x, y0, z0 + 6), Vec3(x + 1, y1, z1)));
      }
    }
  }
  Rng rng(seed);
  for (int rz = 0; rz < rooms_z; ++rz)
    for (int rx = 0; rx < rooms_x; ++rx)
      for (int i = 0; i < 6; ++i) {
        const Vec3 c = Vec3(rx * kRoom, 0, rz * kRoom) +
                       Vec3(rng.uniform(2.5, kRoom - 1.5), rng.uniform(1.5, 3.0), rng.uniform(2.5, kRoom - 1.5));
        if (i % 2) {
          d.objects.push_back(sphere(id++, c, rng.uniform(0.3, 0.8)));
        } else {
          const Vec3 h(rng.uniform(0.2, 0.7), rng.uniform(0.2, 0.5), rng.uniform(0.2, 0.7));
          d.objects.push_back(box_around(id++, c, h));
        }
      }
  // Walk through the doorways of the middle row of rooms and back.
  const double zc = (rooms_z / 2) * kRoom + 6.5;
  for (int f = 0; f < frames; ++f) {
    const double s = static_cast<double>(f) / std::max(1, frames - 1);
    const double x = 2.0 + s * (nx - 4.0);
    const double yaw = 0.9 * std::sin(6.28318 * 3.0 * s);
    out.cameras.push_back(path_camera(Vec3(x, 2.7, zc), Vec3(std::cos(yaw), -0.05, std::sin(yaw)), 70.0));
  }
  return out;
}

ScenePath make_voxel_world(int size, int frames, bool cave_path, std::uint64_t seed) {
  ScenePath out;
  SceneDesc& d = out.scene;
  constexpr int kMaxH = 16;
  d.bounds_min = Vec3(0.0);
  d.bounds_max = Vec3(size, kMaxH, size);
  d.grid = glm::ivec3(size, kMaxH, size);
  Rng rng(seed);
  const double ph[4] = {rng.uniform(0, 6.28), rng.uniform(0, 6.28), rng.uniform(0, 6.28), rng.uniform(0, 6.28)};
  auto height = [&](int x, int z) {
    const double h = 8.0 + 2.5 * std::sin(0.11 * x + ph[0]) + 2.0 * std::sin(0.13 * z + ph[1]) +
                     1.0 * std::sin(0.31 * (x + z) + ph[2]);
    return std::clamp(static_cast<int>(h), 4, 12);
  };
  // A cave: a tunnel along x at z = size/2, y in [2, 4], plus a side tunnel
  // along z that opens to the sky at its end.
  const int zc = size / 2, xs = size / 3;
  auto cave = [&](int x, int y, int z) {
    if (y >= 2 && y <= 4 && std::abs(z - zc) <= 1 && x >= 3 && x <= size - 4) return true;
    if (y >= 2 && y <= 12 && std::abs(x - xs) <= 1 && z >= zc && z <= zc + size / 4) {
      const int top = 4 + std::max(0, (z - zc - size / 8));  // Rises to the surface.
      return y <= top;
    }
    return false;
  };
  ObjectId id = 1;
  for (int z = 0; z < size; ++z)
    for (int x = 0; x < size; ++x) {
      const int h = height(x, z);
      for (int y = 0; y < h; ++y)
        if (!cave(x, y, z)) d.objects.push_back(box_between(id++, Vec3(x, y, z), Vec3(x + 1, y + 1, z + 1)));
    }
  for (int f = 0; f < frames; ++f) {
    const double s = static_cast<double>(f) / std::max(1, frames - 1);
    const double yaw = 0.6 * std::sin(6.28318 * 2.0 * s);
    if (cave_path) {
      const double x = 4.0 + s * (size - 8.0);
      out.cameras.push_back(path_camera(Vec3(x, 3.5, zc + 0.5), Vec3(std::cos(yaw), -0.02, std::sin(yaw)), 70.0));
    } else {
      const double x = 2.0 + s * (size - 4.0);
      const int zi = size / 4;
      const double y = height(static_cast<int>(x), zi) + 2.5;
      out.cameras.push_back(path_camera(Vec3(x, y, zi + 0.5), Vec3(std::cos(yaw), -0.15, std::sin(yaw)), 70.0));
    }
  }
  return out;
}

ScenePath make_city(int blocks, int frames, std::uint64_t seed) {
  constexpr double kBlock = 24.0, kStreet = 8.0, kPitch = kBlock + kStreet;
  constexpr double kTop = 64.0;
  ScenePath out;
  SceneDesc& d = out.scene;
  const double side = blocks * kPitch + kStreet;
  d.bounds_min = Vec3(0.0, -1.0, 0.0);
  d.bounds_max = Vec3(side, kTop - 1.0, side);
  const int res = static_cast<int>(side / 2.0);
  d.grid = glm::ivec3(res, static_cast<int>(kTop / 2.0), res);
  Rng rng(seed);
  ObjectId id = 1;
  d.objects.push_back(box_between(id++, Vec3(0.0, -1.0, 0.0), Vec3(side, 0.0, side)));  // ground
  for (int bz = 0; bz < blocks; ++bz)
    for (int bx = 0; bx < blocks; ++bx) {
      const Vec3 o(kStreet + bx * kPitch, 0.0, kStreet + bz * kPitch);
      // Four lots with a split point and setbacks of their own.
      const double sx = rng.uniform(9.0, 15.0), sz = rng.uniform(9.0, 15.0);
      const double xs[3] = {0.0, sx, kBlock}, zs[3] = {0.0, sz, kBlock};
      for (int lz = 0; lz < 2; ++lz)
        for (int lx = 0; lx < 2; ++lx) {
          const double x0 = xs[lx] + rng.uniform(0.0, 1.5), x1 = xs[lx + 1] - rng.uniform(0.0, 1.5);
          const double z0 = zs[lz] + rng.uniform(0.0, 1.5), z1 = zs[lz + 1] - rng.uniform(0.0, 1.5);
          const double h = rng.uniform(6.0, 40.0);
          d.objects.push_back(box_between(id++, o + Vec3(x0, 0.0, z0), o + Vec3(x1, h, z1)));
        }
    }
  // Parked cars along both kerbs of every street, about one per 12 units,
  // skipping the crossings.
  for (int s = 0; s <= blocks; ++s) {
    const double c = s * kPitch + 0.5 * kStreet;  // Street centreline.
    for (int along_x = 0; along_x < 2; ++along_x)
      for (double u = kStreet; u + 5.0 < side - kStreet; u += rng.uniform(8.0, 16.0)) {
        if (std::fmod(u - kStreet, kPitch) > kBlock - 4.4) continue;  // A crossing.
        const double kerb = (rng.chance(0.5) ? -1.0 : 1.0) * 2.8;
        const Vec3 half = along_x ? Vec3(2.2, 0.75, 0.9) : Vec3(0.9, 0.75, 2.2);
        const Vec3 at = along_x ? Vec3(u + 2.2, 0.75, c + kerb) : Vec3(c + kerb, 0.75, u + 2.2);
        d.objects.push_back(box_around(id++, at, half));
      }
  }
  // Drive along the street between block rows blocks/2 - 1 and blocks/2,
  // glancing left and right.
  const double zc = (blocks / 2) * kPitch + 0.5 * kStreet;
  for (int f = 0; f < frames; ++f) {
    const double s = static_cast<double>(f) / std::max(1, frames - 1);
    const double x = 2.0 + s * (side - 4.0);
    const double yaw = 0.7 * std::sin(6.28318 * 2.5 * s);
    out.cameras.push_back(path_camera(Vec3(x, 1.7, zc + 1.0), Vec3(std::cos(yaw), 0.02, std::sin(yaw)), 60.0));
  }
  return out;
}

std::vector<FrameInput> camera_frames(const std::vector<Camera>& cameras, double fps) {
  const double rate = fps > 0.0 ? fps : 60.0;
  std::vector<FrameInput> out;
  out.reserve(cameras.size());
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    FrameInput f;
    f.t = static_cast<double>(i) / rate;
    f.line = static_cast<int>(i + 1);
    f.camera = cameras[i];
    out.push_back(std::move(f));
  }
  return out;
}

}  // namespace voxvis
