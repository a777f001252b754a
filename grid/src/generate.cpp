// generate.cpp — deterministic scenes and walkthroughs (generate.h).
//
// Determinism: only std::mt19937_64, whose output sequence the standard fixes,
// and our own mappings to [0,1) below. The standard distributions
// (uniform_real_distribution, normal_distribution, ...) are implementation
// defined and would make files differ between standard libraries.
// std::sin/cos/sqrt are used for the camera path and move directions; they
// are correctly rounded or nearly so on every libm we care about, and the
// limits that matter (move length <= max_speed * dt) are checked on the final
// numbers, not assumed.
#include "voxvis/generate.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <vector>

#include <glm/geometric.hpp>

namespace voxvis {
namespace {

/// Uniform in [0, 1) with 53 random bits.
double uniform01(std::mt19937_64& rng) {
  return static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

/// Uniform in [lo, hi).
double uniform(std::mt19937_64& rng, double lo, double hi) {
  return lo + (hi - lo) * uniform01(rng);
}

/// Uniform integer in [0, n), n >= 1 (modulo bias below 2^-40 for small n).
std::uint64_t uniform_index(std::mt19937_64& rng, std::uint64_t n) { return rng() % n; }

/// Bell-shaped, mean 0, standard deviation 1: the sum of three uniforms on
/// [-1, 1) (each of variance 1/3). Bounded by 3, which keeps clusters compact.
double bell(std::mt19937_64& rng) {
  return uniform(rng, -1.0, 1.0) + uniform(rng, -1.0, 1.0) + uniform(rng, -1.0, 1.0);
}

/// Uniform direction on the unit sphere (Archimedes: z uniform in [-1, 1]).
Vec3 random_direction(std::mt19937_64& rng) {
  const double z = uniform(rng, -1.0, 1.0);
  const double phi = uniform(rng, 0.0, 2.0 * std::numbers::pi);
  const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
  return Vec3{r * std::cos(phi), r * std::sin(phi), z};
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

}  // namespace

SceneDesc make_paper_scene(const PaperSceneParams& params) {
  std::mt19937_64 rng(params.seed);
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
    for (int a = 0; a < 3; ++a) p[a] = uniform(rng, params.bounds_min[a], params.bounds_max[a]);
    clusters.push_back(p);
  }

  desc.objects.reserve(static_cast<std::size_t>(count));
  for (int i = 0; i < count; ++i) {
    const Vec3& c = clusters[uniform_index(rng, static_cast<std::uint64_t>(cluster_count))];
    Vec3 p{0.0};
    for (int a = 0; a < 3; ++a) p[a] = c[a] + kClusterSigma * bell(rng);
    // Radii 0.3 .. 2.5, skewed towards small ones (density ~ 1/sqrt).
    const double u = uniform01(rng);
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
  std::mt19937_64 rng(params.seed);
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
  const double phase0 = uniform(rng, 0.0, kTwoPi);

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
          const double step = limit * (1.0 - 1e-9) * uniform01(rng);
          const Vec3 dir = random_direction(rng);
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

}  // namespace voxvis
