#include "extreme_cameras.h"

#include <cmath>

namespace voxvis::test {
namespace {

/// A direction along `unit` written with a magnitude drawn from the extremes
/// (1e308 components, denormal ones, 1e-300) or as is, with zero
/// components sometimes negative zeros.
Vec3 extreme_magnitude(Rng& rng, Vec3 v) {
  switch (rng.uniform_int(0, 4)) {
    case 0: {
      const double m = std::fmax(std::fabs(v.x), std::fmax(std::fabs(v.y), std::fabs(v.z)));
      v *= 1e308 / m;  // The largest component is 1e308.
      break;
    }
    case 1: {
      // Axis-aligned directions become a single denormal component; others
      // are scaled into the denormals as far as they go.
      const double m = std::fmax(std::fabs(v.x), std::fmax(std::fabs(v.y), std::fabs(v.z)));
      v *= 1e-300 / m;
      for (int a = 0; a < 3; ++a)
        if (std::fabs(v[a]) == 1e-300) v[a] = std::copysign(kDenormal, v[a]);
      break;
    }
    case 2: v *= 1e-300; break;
    default: break;
  }
  for (int a = 0; a < 3; ++a)
    if (v[a] == 0.0 && rng.uniform_int(0, 1) == 1) v[a] = -0.0;
  return v;
}

Vec3 random_unit(Rng& rng) {
  for (;;) {
    const Vec3 v{rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)};
    const double l = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
    if (l > 0.1 && l <= 1.0) return v / l;
  }
}

/// Axis-aligned, exactly diagonal or random.
Vec3 some_direction(Rng& rng) {
  switch (rng.uniform_int(0, 2)) {
    case 0: {
      Vec3 v(0.0);
      v[rng.uniform_int(0, 2)] = rng.uniform_int(0, 1) ? 1.0 : -1.0;
      return v;
    }
    case 1: {
      Vec3 v(0.0);
      const int zero = rng.uniform_int(0, 3);  // 3: a body diagonal.
      for (int a = 0; a < 3; ++a)
        if (a != zero) v[a] = rng.uniform_int(0, 1) ? 1.0 : -1.0;
      return v;
    }
    default: return random_unit(rng);
  }
}

double unit_cross(const Vec3& a, const Vec3& b) {
  auto n = [](const Vec3& v) {
    const double m = std::fmax(std::fabs(v.x), std::fmax(std::fabs(v.y), std::fabs(v.z)));
    const Vec3 s = v / m;
    return s / std::sqrt(s.x * s.x + s.y * s.y + s.z * s.z);
  };
  const Vec3 x = n(a), y = n(b);
  const Vec3 c{x.y * y.z - x.z * y.y, x.z * y.x - x.x * y.z, x.x * y.y - x.y * y.x};
  return std::sqrt(c.x * c.x + c.y * c.y + c.z * c.z);
}

/// An eye on the grid's bounds (corners, edges, faces), on voxel corners
/// inside, anywhere inside, or outside the bounds near or far.
Vec3 extreme_eye(Rng& rng, const SceneDesc& scene) {
  const Vec3 lo = scene.bounds_min, hi = scene.bounds_max, ext = hi - lo;
  const glm::ivec3 g = scene.grid ? *scene.grid : glm::ivec3(16);
  Vec3 e;
  switch (rng.uniform_int(0, 4)) {
    case 0:  // On the bounds: each coordinate at min, max or inside.
      for (int a = 0; a < 3; ++a) {
        const int k = rng.uniform_int(0, 2);
        e[a] = k == 0 ? lo[a] : k == 1 ? hi[a] : rng.uniform(lo[a], hi[a]);
      }
      break;
    case 1:  // On voxel planes (corners, edges, faces of voxels).
      for (int a = 0; a < 3; ++a) {
        const int i = rng.uniform_int(0, g[a]);
        e[a] = rng.uniform_int(0, 3) ? lo[a] + ext[a] * i / g[a] : rng.uniform(lo[a], hi[a]);
      }
      break;
    case 2:  // Outside, up to two extents away.
      for (int a = 0; a < 3; ++a) e[a] = rng.uniform(lo[a] - 2 * ext[a], hi[a] + 2 * ext[a]);
      break;
    case 3: {  // Far outside: a hundred thousand extents (within kMaxCoordinate).
      const double reach = std::fmin(1e5 * std::fmax(ext.x, std::fmax(ext.y, ext.z)),
                                     0.9 * kMaxCoordinate - std::fmax(std::fabs(lo.x), std::fabs(hi.x)));
      e = 0.5 * (lo + hi) + reach * random_unit(rng);
      break;
    }
    default:
      for (int a = 0; a < 3; ++a) e[a] = rng.uniform(lo[a], hi[a]);
  }
  return e;
}

}  // namespace

Camera extreme_camera(Rng& rng, const SceneDesc& scene) {
  const double scale = std::fmax(scene.bounds_max.x - scene.bounds_min.x, 1e-300);
  Camera c;
  c.eye = extreme_eye(rng, scene);
  // Look at the bounds' centre half the time, so that something is in view.
  if (rng.uniform_int(0, 1) == 0) {
    const Vec3 v = 0.5 * (scene.bounds_min + scene.bounds_max) - c.eye;
    const double m = std::fmax(std::fabs(v.x), std::fmax(std::fabs(v.y), std::fabs(v.z)));
    c.dir = m > 0.0 ? v / m : Vec3(1, 0, 0);  // Largest component 1: room for the extremes.
  } else {
    c.dir = some_direction(rng);
  }
  do {
    c.up = some_direction(rng);
  } while (!(unit_cross(c.dir, c.up) > 1e-3));
  c.dir = extreme_magnitude(rng, c.dir);
  c.up = extreme_magnitude(rng, c.up);
  const double fovs[] = {kMinFovDeg, kMinFovDeg * (1 + 1e-15), 1e-5, 0.1, 60.0, 179.0, 179.999999,
                         std::nextafter(180.0, 0.0)};
  c.fov_y_deg = fovs[rng.uniform_int(0, 7)];
  const double aspects[] = {1.0 / kMaxAspect, 0.5, 1.0, 16.0 / 9.0, kMaxAspect};
  c.aspect = aspects[rng.uniform_int(0, 4)];
  const double nears[] = {1e-300, 1e-12 * scale, 0.01 * scale};
  c.near = nears[rng.uniform_int(0, 2)];
  switch (rng.uniform_int(0, 2)) {
    case 0: c.far = c.near * (1.0 + 1e-12); break;  // A razor-thin frustum.
    case 1: c.far = 1e300; break;
    default: c.far = c.near + 10.0 * scale;
  }
  return c;
}


}  // namespace voxvis::test
