// Hard cases for the engine: degenerate eye positions and directions, extreme
// fov and aspect, voxel-aligned geometry, slits thinner than a voxel, things
// outside the grid, far-from-origin and scaled coordinates, non-cubic voxels,
// huge TBVs, moves faster than max_speed, and every validation error the API
// can return. Each frame is checked by EngineHarness: zero misses against the
// ray caster (jittered rays plus the exact cell corners and frustum edges),
// result invariants and finite stats.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>

#include <glm/geometric.hpp>

#include "engine_check.h"
#include "raycast.h"
#include "scenes.h"
#include "voxvis/scene.h"

namespace voxvis::test {
namespace {

using Ids = std::vector<ObjectId>;
constexpr double kDt = 1.0 / 30.0;
const double kNaN = std::numeric_limits<double>::quiet_NaN();

Camera camera(Vec3 eye, Vec3 dir, Vec3 up = Vec3(0, 1, 0), double fov = 60.0, double aspect = 1.0,
              double near = 0.01, double far = 1000.0) {
  Camera c;
  c.eye = eye;
  c.dir = dir;
  c.up = up;
  c.fov_y_deg = fov;
  c.aspect = aspect;
  c.near = near;
  c.far = far;
  return c;
}

/// A valid up for `dir`: +y unless dir is (nearly) vertical, then +z.
Vec3 up_for(const Vec3& dir) {
  const Vec3 f = glm::normalize(dir);
  return std::abs(f.y) > 0.9 ? Vec3(0, 0, 1) : Vec3(0, 1, 0);
}

bool contains(const Ids& v, ObjectId id) { return std::binary_search(v.begin(), v.end(), id); }

/// The six axis directions and the eight exact diagonals.
std::vector<Vec3> axis_and_diagonal_dirs() {
  std::vector<Vec3> d = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  for (int sx : {-1, 1}) {
    for (int sy : {-1, 1}) {
      for (int sz : {-1, 1}) d.emplace_back(sx, sy, sz);
    }
  }
  return d;
}

/// Bounds 32 x 16 x 64 on an 8 x 4 x 16 grid: 4-unit voxels, so voxel planes
/// are exact binary numbers and the world-to-grid mapping is exact.
SceneDesc exact_grid_scene(std::uint64_t seed, double dynamic_fraction) {
  RandomSceneParams p;
  p.bounds_min = Vec3(0.0);
  p.bounds_max = Vec3(32.0, 16.0, 64.0);
  p.grid = glm::ivec3(8, 4, 16);
  p.spheres = 50;
  p.boxes = 50;
  p.occluders = 10;
  p.walls = 8;
  p.outside = 4;
  p.dynamic_fraction = dynamic_fraction;
  p.max_speed = 8.0;
  return random_scene(p, seed);
}

// --- eye on voxel faces, edges, corners; axis and diagonal directions ------

TEST(HardCases, EyeOnVoxelFacesEdgesAndCorners) {
  for (std::uint64_t seed : {1ULL, 2ULL}) {
    const SceneDesc scene = exact_grid_scene(seed, 0.3);
    EngineHarness h(scene, {}, describe_scene(scene, seed));
    ASSERT_TRUE(h.status().ok) << h.status().str();
    const std::vector<Vec3> eyes = {
        {8.0, 5.3, 21.7},    // on an x face
        {8.0, 8.0, 21.7},    // on an x-y edge
        {8.0, 8.0, 24.0},    // on a voxel corner
        {0.0, 0.0, 0.0},     // the grid's min corner
        {32.0, 16.0, 64.0},  // the grid's max corner
        {32.0, 8.0, 30.1},   // on the max x face of the grid
        {16.0, 0.0, 32.0},   // on the min y face, at a voxel edge
        {4.0, 12.0, 60.0},   // interior voxel corner
    };
    Mover mover(scene, seed);
    double t = 0.0;
    int frame = 0;
    for (const Vec3& eye : eyes) {
      for (const Vec3& dir : axis_and_diagonal_dirs()) {
        if (frame++ > 0) {
          t += kDt;
          ASSERT_TRUE(h.move(t, mover.step(kDt)).ok);
        }
        for (double fov : {60.0, 90.0}) {
          const std::string err = h.frame(camera(eye, dir, up_for(dir), fov, 1.0, 0.01, 200.0), t);
          ASSERT_TRUE(err.empty()) << err;
        }
      }
    }
  }
}

TEST(HardCases, AxisDirectionsWithEveryValidUp) {
  const SceneDesc scene = exact_grid_scene(3, 0.0);
  EngineHarness h(scene, {}, describe_scene(scene, 3));
  ASSERT_TRUE(h.status().ok) << h.status().str();
  const Vec3 eye(13.0, 7.0, 30.0);
  const std::vector<Vec3> axes = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  for (const Vec3& dir : axes) {
    for (const Vec3& up : axes) {
      if (glm::length(glm::cross(dir, up)) == 0.0) continue;
      const std::string err = h.frame(camera(eye, dir, up, 75.0, 1.5), 0.0);
      ASSERT_TRUE(err.empty()) << err;
    }
  }
}

// --- fov and aspect extremes ----------------------------------------------

TEST(HardCases, ExtremeFovAndAspect) {
  const SceneDesc scene = exact_grid_scene(4, 0.2);
  EngineHarness h(scene, {}, describe_scene(scene, 4));
  ASSERT_TRUE(h.status().ok) << h.status().str();
  const std::vector<std::pair<Vec3, Vec3>> views = {
      {{16.0, 8.0, 2.0}, {0.1, 0.05, 1.0}},     // inside, down the long axis
      {{16.0, 8.0, 32.0}, {1.0, 0.3, -0.2}},    // inside, across
      {{-40.0, 30.0, -40.0}, {1.0, -0.5, 1.5}},  // outside looking in
      {{8.0, 8.0, 24.0}, {1.0, 1.0, 1.0}},      // voxel corner, diagonal
  };
  double t = 0.0;
  for (const auto& [eye, dir] : views) {
    for (double fov : {1.0, 2.0, 10.0, 45.0, 90.0, 135.0, 170.0, 179.0}) {
      for (double aspect : {0.1, 0.3, 1.0, 3.0, 10.0}) {
        t += kDt;
        const std::string err = h.frame(camera(eye, dir, up_for(dir), fov, aspect, 0.01, 500.0), t);
        ASSERT_TRUE(err.empty()) << "fov " << fov << " aspect " << aspect << ": " << err;
      }
    }
  }
  // The API's own aspect limits.
  for (double aspect : {1e-3, 1e3}) {
    t += kDt;
    const std::string err = h.frame(camera({16, 8, 32}, {0.3, 0.1, 1}, {0, 1, 0}, 60.0, aspect), t);
    ASSERT_TRUE(err.empty()) << "aspect " << aspect << ": " << err;
  }
}

// --- voxel-aligned geometry -------------------------------------------------

TEST(HardCases, BoxesAlignedToVoxelPlanes) {
  // Boxes whose faces lie on voxel planes (4-unit voxels), some one voxel,
  // some slabs, and eyes on those planes looking along them (grazing rays).
  SceneDesc scene;
  scene.bounds_min = Vec3(0.0);
  scene.bounds_max = Vec3(32.0, 16.0, 64.0);
  scene.grid = glm::ivec3(8, 4, 16);
  Rng rng(5);
  ObjectId id = 1;
  for (int i = 0; i < 80; ++i) {
    glm::ivec3 a(rng.uniform_int(0, 7), rng.uniform_int(0, 3), rng.uniform_int(0, 15));
    glm::ivec3 b = a + glm::ivec3(rng.uniform_int(0, 2), rng.uniform_int(0, 1), rng.uniform_int(0, 3));
    b = glm::min(b, glm::ivec3(7, 3, 15));
    ObjectDesc o = box_between(id++, Vec3(a) * 4.0, Vec3(b + 1) * 4.0);
    if (rng.chance(0.2)) o = dynamic(o, 4.0);
    scene.objects.push_back(o);
  }
  // A few small spheres tangent to voxel planes.
  for (int i = 0; i < 20; ++i) {
    const Vec3 c = Vec3(rng.uniform_int(0, 7), rng.uniform_int(0, 3), rng.uniform_int(0, 15)) * 4.0 +
                   Vec3(2.0);
    scene.objects.push_back(sphere(id++, c, 2.0));
  }
  EngineHarness h(scene, {}, "aligned boxes seed=5");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  const std::vector<Vec3> eyes = {{16.0, 8.0, 0.0}, {16.0, 8.0, 32.0}, {4.0, 4.0, 8.0},
                                  {0.0, 8.0, 32.0}, {32.0, 0.0, 64.0}, {16.0, 12.0, 70.0}};
  double t = 0.0;
  for (const Vec3& eye : eyes) {
    for (const Vec3& dir : axis_and_diagonal_dirs()) {
      t += kDt;
      const std::string err = h.frame(camera(eye, dir, up_for(dir), 90.0, 1.0, 0.01, 300.0), t);
      ASSERT_TRUE(err.empty()) << err;
    }
    // Grazing: looking along the plane y = eye.y.
    for (const Vec3& dir : {Vec3(1, 0, 0.3), Vec3(-0.2, 0, 1), Vec3(0.7, 0, -0.7)}) {
      t += kDt;
      const std::string err = h.frame(camera(eye, dir, Vec3(0, 1, 0), 40.0, 2.0, 0.01, 300.0), t);
      ASSERT_TRUE(err.empty()) << err;
    }
  }
}

// --- thin walls and slits ---------------------------------------------------

struct SlitCase {
  const char* name;
  std::vector<ObjectDesc> walls;
  ObjectDesc target;
  Camera cam;
};

/// Bounds 0..40 on an 8^3 grid (5-unit voxels). Walls are several voxels
/// thick with a gap thinner than a voxel; the target behind is seen through
/// the gap.
std::vector<SlitCase> slit_cases() {
  std::vector<SlitCase> cases;
  const double big = 100.0;
  {
    // A vertical slit x in (19.9, 20.1) — on the voxel plane x = 20 — through
    // a wall z in [20, 30] (two voxels).
    SlitCase c{"slit on a voxel plane", {}, {}, {}};
    c.walls = {box_between(1, {-big, -big, 20}, {19.9, big, 30}), box_between(2, {20.1, -big, 20}, {big, big, 30})};
    c.target = sphere(10, {20.0, 20.0, 5.0}, 1.0);
    c.cam = camera({20.0, 20.0, 50.0}, {0, 0, -1});
    cases.push_back(c);
  }
  {
    // A horizontal slit inside a voxel: y in (22.45, 22.55), wall z in [15, 35].
    SlitCase c{"slit inside a voxel", {}, {}, {}};
    c.walls = {box_between(1, {-big, -big, 15}, {big, 22.45, 35}), box_between(2, {-big, 22.55, 15}, {big, big, 35})};
    c.target = box_between(10, {10.0, 21.0, 2.0}, {30.0, 24.0, 4.0});
    c.cam = camera({13.0, 22.5, 39.0}, {0.1, 0, -1});
    cases.push_back(c);
  }
  {
    // A pinhole 0.1 x 0.1 at (12.5, 27.5) in a wall z in [10, 30], seen
    // obliquely enough that only a thin pencil of rays passes.
    SlitCase c{"pinhole", {}, {}, {}};
    const double x0 = 12.45;
    const double x1 = 12.55;
    const double y0 = 27.45;
    const double y1 = 27.55;
    c.walls = {box_between(1, {-big, -big, 10}, {x0, big, 30}), box_between(2, {x1, -big, 10}, {big, big, 30}),
               box_between(3, {x0, -big, 10}, {x1, y0, 30}), box_between(4, {x0, y1, 10}, {x1, big, 30})};
    c.target = sphere(10, {12.5, 27.5, 1.0}, 0.5);
    c.cam = camera({12.5 + 0.002, 27.5 - 0.001, 39.9}, {0, 0, -1}, {0, 1, 0}, 30.0);
    cases.push_back(c);
  }
  {
    // A slit between two boxes that touch voxel planes from both sides, with
    // the eye outside the grid.
    SlitCase c{"slit, eye outside", {}, {}, {}};
    c.walls = {box_between(1, {-big, -big, 25}, {big, 15.0, 35}), box_between(2, {-big, 15.05, 25}, {big, big, 35})};
    c.target = sphere(10, {20.0, 15.025, 8.0}, 0.5);
    c.cam = camera({20.0, 15.025, 80.0}, {0, 0, -1}, {0, 1, 0}, 20.0, 1.0, 0.1, 500.0);
    cases.push_back(c);
  }
  return cases;
}

TEST(HardCases, ObjectSeenThroughASlitIsInThePvs) {
  for (const SlitCase& c : slit_cases()) {
    SCOPED_TRACE(c.name);
    SceneDesc scene;
    scene.bounds_min = Vec3(0.0);
    scene.bounds_max = Vec3(40.0);
    scene.grid = glm::ivec3(8);
    scene.objects = c.walls;
    scene.objects.push_back(c.target);
    // Hidden clutter behind the walls, off the line of sight.
    scene.objects.push_back(sphere(20, {3.0, 3.0, 3.0}, 1.0));
    scene.objects.push_back(dynamic(sphere(21, {36.0, 5.0, 4.0}, 1.0), 1.0));
    // The geometry really does let the target be seen: the ray through the
    // gap's centre toward the target hits it first.
    double x = 0.0;
    double y = 0.0;
    ASSERT_TRUE(project(c.cam, c.target.center, &x, &y));
    ASSERT_EQ(first_hit(scene.objects, c.cam, x, y), Ids{10}) << "test geometry broken";

    for (const Vec3& offset : {Vec3(0.0), Vec3(1e6), Vec3(-3e5, 7e5, 1e6)}) {
      SCOPED_TRACE("offset " + std::to_string(offset.x));
      const SceneDesc s = transform_scene(scene, 1.0, offset);
      const Camera cam = transform_camera(c.cam, 1.0, offset);
      EngineHarness h(s, {}, std::string(c.name));
      ASSERT_TRUE(h.status().ok) << h.status().str();
      for (int f = 0; f < 3; ++f) {
        const std::string err = h.frame(cam, f * kDt);
        ASSERT_TRUE(err.empty()) << err;
        EXPECT_TRUE(contains(h.last().pvs, 10)) << "frame " << f << ": target seen through the gap missing; "
                                                << describe(cam);
      }
    }
  }
}

TEST(HardCases, WallsThinnerThanAVoxel) {
  // Thin walls (0.01 .. 0.9 voxel, some flat) in front of objects; the engine
  // must not treat partly covered voxels as opaque.
  SceneDesc scene;
  scene.bounds_min = Vec3(0.0);
  scene.bounds_max = Vec3(40.0);
  scene.grid = glm::ivec3(8);
  const double thick[] = {0.0, 0.05, 0.5, 2.5, 4.5};
  ObjectId id = 1;
  for (int i = 0; i < 5; ++i) {
    const double z = 6.0 + 7.0 * i;
    scene.objects.push_back(box_between(id++, {2.0 + i, 2.0, z}, {30.0 - i, 38.0, z + thick[i]}));
  }
  Rng rng(8);
  for (int i = 0; i < 60; ++i) {
    ObjectDesc o = sphere(id++, rng.in_box(Vec3(0.0), Vec3(40.0)), rng.uniform(0.2, 1.5));
    if (i % 3 == 0) o = dynamic(o, 3.0);
    scene.objects.push_back(o);
  }
  EngineHarness h(scene, {}, "thin walls seed=8");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  Mover mover(scene, 8);
  const std::vector<Camera> cams = {
      camera({20, 20, 45}, {0, 0, -1}),      camera({20, 20, 45}, {0.4, 0.1, -1}),
      camera({35, 20, 3}, {-1, 0, 0.2}),     camera({20, 20, 6.0}, {0, 0, 1}),
      camera({20, 20, 13.0}, {0, 0.01, -1}), camera({-5, 20, 20}, {1, 0, 0}, {0, 1, 0}, 120.0)};
  for (int f = 0; f < 30; ++f) {
    const double t = f * kDt;
    if (f > 0) {
      ASSERT_TRUE(h.move(t, mover.step(kDt)).ok);
    }
    const std::string err = h.frame(cams[static_cast<std::size_t>(f) % cams.size()], t);
    ASSERT_TRUE(err.empty()) << err;
  }
}

// --- outside the grid -------------------------------------------------------

TEST(HardCases, EyeAndObjectsOutsideTheGrid) {
  SceneDesc scene = exact_grid_scene(6, 0.3);
  ObjectId id = 900000;
  // Objects beyond every face of the bounds, static and dynamic.
  for (const Vec3& c : {Vec3(60, 8, 32), Vec3(-30, 8, 32), Vec3(16, 40, 32), Vec3(16, -30, 32),
                        Vec3(16, 8, 100), Vec3(16, 8, -40), Vec3(-50, -50, -50)}) {
    scene.objects.push_back(sphere(id++, c, 3.0));
    scene.objects.push_back(dynamic(box_between(id++, c + Vec3(4.0), c + Vec3(7.0)), 6.0));
  }
  // A big one straddling the bounds.
  scene.objects.push_back(box_between(id++, {-10, -10, 60}, {40, 20, 70}));
  EngineHarness h(scene, {}, describe_scene(scene, 6) + " + outside objects");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  const std::vector<Camera> cams = {
      camera({-60, 8, 32}, {1, 0, 0}),                  // outside, looking in
      camera({-60, 8, 32}, {-1, 0, 0}),                 // outside, looking away
      camera({16, 8, 32}, {1, 0, 0}),                   // inside, looking out at x+
      camera({16, 8, 32}, {0, 0, 1}, {0, 1, 0}, 120.0),  // inside, looking out at z+
      camera({100, 100, 200}, {-84, -92, -168}),        // far outside, diagonal
      camera({16, 60, 32}, {0, -1, 0}, {0, 0, 1}),      // above, looking down
      camera({16, 8, -80}, {0, 0, 1}, {0, 1, 0}, 5.0),  // far, narrow
      camera({1e4, 8, 32}, {-1, 0, 0}, {0, 1, 0}, 1.0, 1.0, 1.0, 2e4),
      camera({32.0, 16.0, 64.0}, {1, 1, 1}),            // grid corner, looking out
  };
  Mover mover(scene, 6, 0.5);
  for (int f = 0; f < 36; ++f) {
    const double t = f * kDt;
    if (f > 0) {
      ASSERT_TRUE(h.move(t, mover.step(kDt)).ok);
    }
    const std::string err = h.frame(cams[static_cast<std::size_t>(f) % cams.size()], t);
    ASSERT_TRUE(err.empty()) << err;
  }
}

// --- transformed worlds -----------------------------------------------------

TEST(HardCases, OffsetAndScaledWorldsHaveZeroMisses) {
  struct Xf {
    double scale;
    Vec3 offset;
  };
  const Xf xfs[] = {{1.0, Vec3(0.0)},        {1.0, Vec3(1e6)},   {1e-3, Vec3(0.0)},
                    {1e-3, Vec3(1e6)},       {1e-3, Vec3(-1e6, 1e6, 3e5)}, {1e3, Vec3(-1e6)}};
  // With the occlusion buffer off and on: its rounding allowances scale
  // with the coordinates too.
  for (const auto& [seed, ob] : {std::pair{21ULL, 0}, {22ULL, 0}, {23ULL, 0}, {24ULL, 128}, {25ULL, 128}}) {
    const SceneDesc base = random_scene(random_scene_params(seed), seed);
    const std::vector<Camera> path = random_camera_path(base, seed, {.frames = 12});
    SceneOptions options;
    options.occlusion_buffer = ob;
    for (const Xf& xf : xfs) {
      SCOPED_TRACE("seed " + std::to_string(seed) + " scale " + std::to_string(xf.scale) +
                   " offset " + std::to_string(xf.offset.x) + " ob " + std::to_string(ob));
      const SceneDesc scene = transform_scene(base, xf.scale, xf.offset);
      EngineHarness h(scene, options, describe_scene(scene, seed));
      ASSERT_TRUE(h.status().ok) << h.status().str();
      Mover mover(base, seed);
      for (int f = 0; f < 12; ++f) {
        const double t = f * kDt;
        if (f > 0) {
          MoveReport report;
          ASSERT_TRUE(h.move(t, transform_moves(mover.step(kDt), xf.scale, xf.offset), &report).ok);
          EXPECT_TRUE(report.too_fast.empty()) << describe_ids(report.too_fast);
        }
        const std::string err =
            h.frame(transform_camera(path[static_cast<std::size_t>(f)], xf.scale, xf.offset), t);
        ASSERT_TRUE(err.empty()) << err;
      }
    }
  }
}

// --- non-cubic voxels -------------------------------------------------------

TEST(HardCases, NonCubicVoxels) {
  const glm::ivec3 grids[] = {{7, 40, 3}, {1, 1, 64}, {50, 2, 1}, {3, 3, 3}};
  for (std::uint64_t seed : {31ULL, 32ULL}) {
    for (const glm::ivec3& g : grids) {
      RandomSceneParams p = random_scene_params(seed);
      p.bounds_min = Vec3(-10.0, 0.0, 5.0);
      p.bounds_max = Vec3(90.0, 100.0, 105.0);
      p.grid = g;
      const SceneDesc scene = random_scene(p, seed);
      EngineHarness h(scene, {}, describe_scene(scene, seed));
      ASSERT_TRUE(h.status().ok) << h.status().str();
      const std::vector<Camera> path = random_camera_path(scene, seed, {.frames = 15});
      Mover mover(scene, seed);
      for (int f = 0; f < 15; ++f) {
        const double t = f * kDt;
        if (f > 0) {
          ASSERT_TRUE(h.move(t, mover.step(kDt)).ok);
        }
        const std::string err = h.frame(path[static_cast<std::size_t>(f)], t);
        ASSERT_TRUE(err.empty()) << err;
      }
    }
  }
}

// --- TBVs larger than the grid ---------------------------------------------

/// Bounds 0..40 on a 10^3 grid; a wall (z in [18, 26], reaching beyond the
/// bounds) hides `n` dynamic spheres at z < 16 from a camera at z = 38
/// looking down -z; a few static spheres in front.
SceneDesc hidden_behind_wall(int n, double max_speed, std::uint64_t seed) {
  SceneDesc s;
  s.bounds_min = Vec3(0.0);
  s.bounds_max = Vec3(40.0);
  s.grid = glm::ivec3(10);
  s.objects.push_back(box_between(1, {-20, -20, 18}, {60, 60, 26}));
  Rng rng(seed);
  for (int i = 0; i < 4; ++i) s.objects.push_back(sphere(2 + static_cast<ObjectId>(i), rng.in_box({12, 12, 28}, {28, 28, 32}), 1.0));
  for (int i = 0; i < n; ++i) {
    s.objects.push_back(dynamic(sphere(100 + static_cast<ObjectId>(i), rng.in_box({6, 6, 4}, {34, 34, 14}), 0.7), max_speed));
  }
  return s;
}

const Camera kWallCam = camera({20, 20, 38}, {0, 0, -1}, {0, 1, 0}, 60.0, 1.0, 0.05, 200.0);

TEST(HardCases, HugeMaxSpeedTbvsLargerThanTheGrid) {
  const SceneDesc scene = hidden_behind_wall(12, 1e6, 41);
  EngineHarness h(scene, {}, "hidden_behind_wall max_speed=1e6");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  Rng rng(41);
  for (int f = 0; f < 40; ++f) {
    const double t = f * kDt;
    if (f > 10) {
      // Legal teleports anywhere (max_speed is huge), including into view.
      std::vector<Move> moves;
      for (int j = 0; j < 3; ++j) {
        const ObjectId id = 100 + static_cast<ObjectId>(rng.uniform_int(0, 11));
        if (std::any_of(moves.begin(), moves.end(), [&](const Move& m) { return m.id == id; })) continue;
        moves.push_back({id, rng.chance(0.5) ? rng.in_box({10, 10, 27}, {30, 30, 34})
                                             : rng.in_box({-100, -100, -100}, {140, 140, 16})});
      }
      MoveReport report;
      ASSERT_TRUE(h.move(t, moves, &report).ok);
      EXPECT_TRUE(report.too_fast.empty());
    }
    const std::string err = h.frame(kWallCam, t);
    ASSERT_TRUE(err.empty()) << err;
  }
}

TEST(HardCases, LongTbvPeriodsTbvsLargerThanTheGrid) {
  SceneOptions opt;
  opt.tbv_period = 1000.0;
  opt.tbv_max_period = 1e4;
  const SceneDesc scene = hidden_behind_wall(12, 1.0, 42);
  EngineHarness h(scene, opt, "hidden_behind_wall tbv_period=1000");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  // Warm up with hidden objects at rest; then let time jump so that objects
  // may legally cross the whole scene, and walk them into view over frames.
  double t = 0.0;
  for (int f = 0; f < 10; ++f, t += kDt) {
    const std::string err = h.frame(kWallCam, t);
    ASSERT_TRUE(err.empty()) << err;
  }
  for (int f = 0; f < 30; ++f) {
    t += 5.0;  // 5 s a frame: up to 5 units of motion
    std::vector<Move> moves;
    for (const ObjectDesc& o : h.objects()) {
      if (!o.dynamic) continue;
      // Head for a point in front of the wall, at most 4.9 units a frame.
      const Vec3 goal(20.0 + (o.id % 5) * 2.0, 20.0 + (o.id % 3) * 2.0, 31.0);
      const Vec3 d = goal - o.center;
      const double len = glm::length(d);
      if (len == 0.0) continue;
      moves.push_back({o.id, o.center + d * (std::min(len, 4.9) / len)});
    }
    MoveReport report;
    ASSERT_TRUE(h.move(t, moves, &report).ok);
    EXPECT_TRUE(report.too_fast.empty()) << describe_ids(report.too_fast);
    const std::string err = h.frame(kWallCam, t);
    ASSERT_TRUE(err.empty()) << err;
  }
  // They all ended up in plain view.
  const Ids vis = visible_objects(h.objects(), kWallCam);
  EXPECT_GE(std::count_if(vis.begin(), vis.end(), [](ObjectId i) { return i >= 100; }), 6);
}

// --- the near plane ---------------------------------------------------------

TEST(HardCases, OccluderWhollyBeforeTheNearPlaneDoesNotHide) {
  // The wall (z in [18, 26]) spans depths 12..20 from an eye at z = 38; with
  // near = 21 it is clipped away and the objects behind it are visible.
  const SceneDesc scene = hidden_behind_wall(12, 1.0, 45);
  EngineHarness h(scene, {}, "hidden_behind_wall near beyond the wall");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  double t = 0.0;
  for (double near : {0.05, 21.0, 0.05, 12.5, 21.0}) {
    Camera cam = kWallCam;
    cam.near = near;
    for (int f = 0; f < 4; ++f, t += kDt) {
      const std::string err = h.frame(cam, t);
      ASSERT_TRUE(err.empty()) << "near " << near << ": " << err;
    }
    if (near == 21.0) {
      EXPECT_GE(std::count_if(h.last().pvs.begin(), h.last().pvs.end(),
                              [](ObjectId i) { return i >= 100; }), 1);
    }
  }
}

TEST(HardCases, EyeInsideAnOccluder) {
  // The eye inside the wall: with a small near plane the wall hides
  // everything else; with near beyond the wall's far face (depth 5 from
  // z = 23) the objects behind are visible.
  const SceneDesc scene = hidden_behind_wall(12, 1.0, 46);
  EngineHarness h(scene, {}, "hidden_behind_wall eye inside the wall");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  double t = 0.0;
  for (double near : {0.05, 6.0, 0.05, 3.0, 6.0}) {
    for (const Vec3& dir : {Vec3(0, 0, -1), Vec3(0.3, 0.2, -1), Vec3(0, 0, 1)}) {
      Camera cam = camera({20.0, 20.0, 23.0}, dir, {0, 1, 0}, 70.0, 1.0, near, 200.0);
      for (int f = 0; f < 2; ++f, t += kDt) {
        const std::string err = h.frame(cam, t);
        ASSERT_TRUE(err.empty()) << "near " << near << ": " << err;
      }
    }
  }
}

// --- moves faster than max_speed -------------------------------------------

TEST(HardCases, TeleportFasterThanMaxSpeedIsRevealed) {
  const SceneDesc scene = hidden_behind_wall(10, 1.0, 43);
  EngineHarness h(scene, {}, "hidden_behind_wall teleport");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  double t = 0.0;
  std::uint32_t active = 0;
  for (int f = 0; f < 20; ++f, t += kDt) {
    const std::string err = h.frame(kWallCam, t);
    ASSERT_TRUE(err.empty()) << err;
    active = h.last().stats.tbvs_active;
  }
  EXPECT_GT(active, 0u) << "hidden objects should be under TBVs by now";
  for (ObjectId id : {ObjectId{103}, ObjectId{107}}) {
    ASSERT_FALSE(contains(h.last().pvs, id));
    // Into plain view, far more than max_speed * dt away.
    MoveReport report;
    ASSERT_TRUE(h.move(t, {{id, Vec3(20.0, 20.0, 33.0)}}, &report).ok);
    EXPECT_EQ(report.applied, 1u);
    EXPECT_EQ(report.too_fast, Ids{id});
    const std::string err = h.frame(kWallCam, t);
    ASSERT_TRUE(err.empty()) << err;
    EXPECT_TRUE(contains(h.last().pvs, id)) << "teleported object " << id << " missing from the PVS";
    EXPECT_TRUE(contains(h.last().wake, id));
    EXPECT_GE(h.last().stats.speed_violations, 1u);
    // Teleport it back behind the wall: also too fast, and no miss after.
    t += kDt;
    report = {};
    ASSERT_TRUE(h.move(t, {{id, Vec3(20.0, 20.0, 8.0)}}, &report).ok);
    EXPECT_EQ(report.too_fast, Ids{id});
    for (int f = 0; f < 5; ++f, t += kDt) {
      const std::string err2 = h.frame(kWallCam, t);
      ASSERT_TRUE(err2.empty()) << err2;
    }
  }
}

TEST(HardCases, FirstMoveFasterThanMaxSpeedIsReported) {
  // Minimal case: the object has been at its initial centre since the first
  // frame (t = 0), so a 30-unit jump at t = 1 is 30x its max_speed of 1.
  SceneDesc scene;
  scene.bounds_min = Vec3(0.0);
  scene.bounds_max = Vec3(40.0);
  scene.grid = glm::ivec3(4);
  scene.objects = {dynamic(sphere(7, {5, 5, 5}, 1.0), 1.0)};
  EngineHarness h(scene);
  ASSERT_TRUE(h.status().ok) << h.status().str();
  ASSERT_TRUE(h.frame(camera({20, 20, 60}, {0, 0, -1}), 0.0).empty());
  MoveReport report;
  ASSERT_TRUE(h.move(1.0, {{7, Vec3(35, 35, 5)}}, &report).ok);
  EXPECT_EQ(report.too_fast, Ids{7}) << "a first move is not checked against max_speed";
  const std::string err = h.frame(camera({20, 20, 60}, {0, 0, -1}), 1.0);
  EXPECT_TRUE(err.empty()) << err;
  EXPECT_GE(h.last().stats.speed_violations, 1u);
  // A second jump is reported.
  report = {};
  ASSERT_TRUE(h.move(2.0, {{7, Vec3(5, 5, 5)}}, &report).ok);
  EXPECT_EQ(report.too_fast, Ids{7});
}

TEST(HardCases, TooFastMoveOfAVisibleObjectIntoHiding) {
  // The converse: an object in view jumps behind the wall, then back out
  // at legal speed much later; zero misses throughout.
  SceneDesc scene = hidden_behind_wall(4, 1.0, 44);
  scene.objects.push_back(dynamic(sphere(50, {20, 20, 30}, 1.0), 1.0));
  EngineHarness h(scene, {}, "hidden_behind_wall jump");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  double t = 0.0;
  for (int f = 0; f < 5; ++f, t += kDt) ASSERT_TRUE(h.frame(kWallCam, t).empty());
  ASSERT_TRUE(contains(h.last().pvs, 50));
  MoveReport report;
  ASSERT_TRUE(h.move(t + kDt, {{50, Vec3(20, 20, 8)}}, &report).ok);
  EXPECT_EQ(report.too_fast, Ids{50});
  t += kDt;
  for (int f = 0; f < 10; ++f, t += kDt) {
    const std::string err = h.frame(kWallCam, t);
    ASSERT_TRUE(err.empty()) << err;
  }
  t += 100.0;  // plenty of time to come back legally
  ASSERT_TRUE(h.move(t, {{50, Vec3(20, 20, 31)}}, &report).ok);
  const std::string err = h.frame(kWallCam, t);
  ASSERT_TRUE(err.empty()) << err;
  EXPECT_TRUE(contains(h.last().pvs, 50));
}

// --- validation through the API --------------------------------------------

SceneDesc small_valid_scene() {
  SceneDesc s;
  s.bounds_min = Vec3(0.0);
  s.bounds_max = Vec3(10.0);
  s.grid = glm::ivec3(5);
  s.objects = {sphere(1, {5, 5, 5}, 1.0), box_between(2, {1, 1, 1}, {2, 3, 4}),
               dynamic(sphere(3, {8, 8, 8}, 0.5), 2.0)};
  return s;
}

void expect_refused(const Status& st, const std::string& field_part, const std::string& what) {
  EXPECT_FALSE(st.ok) << what << ": accepted";
  EXPECT_FALSE(st.field.empty()) << what << ": no field named (" << st.str() << ")";
  if (field_part.empty()) return;
  // `field_part` lists acceptable substrings separated by '|'.
  bool found = false;
  std::size_t start = 0;
  while (start <= field_part.size()) {
    const std::size_t end = std::min(field_part.find('|', start), field_part.size());
    if (st.field.find(field_part.substr(start, end - start)) != std::string::npos) found = true;
    start = end + 1;
  }
  EXPECT_TRUE(found) << what << ": field '" << st.field << "' should mention '" << field_part << "'";
}

TEST(HardCasesValidation, SceneCreateRefusesBadInput) {
  struct Case {
    const char* what;
    const char* field;
    void (*mutate)(SceneDesc*);
  };
  const Case cases[] = {
      {"duplicate ids", "id", [](SceneDesc* s) { s->objects[2].id = 1; }},
      {"NaN centre", "center", [](SceneDesc* s) { s->objects[1].center.y = kNaN; }},
      {"infinite centre", "center",
       [](SceneDesc* s) { s->objects[0].center.x = std::numeric_limits<double>::infinity(); }},
      {"negative radius", "radius", [](SceneDesc* s) { s->objects[0].radius = -1.0; }},
      {"zero radius", "radius", [](SceneDesc* s) { s->objects[0].radius = 0.0; }},
      {"NaN radius", "radius", [](SceneDesc* s) { s->objects[0].radius = kNaN; }},
      {"negative half extent (min > max)", "half_extent|min|max",
       [](SceneDesc* s) { s->objects[1].half_extent.z = -0.5; }},
      {"NaN half extent", "half_extent|min|max", [](SceneDesc* s) { s->objects[1].half_extent.x = kNaN; }},
      {"negative max_speed", "max_speed", [](SceneDesc* s) { s->objects[2].max_speed = -1.0; }},
      {"NaN max_speed", "max_speed", [](SceneDesc* s) { s->objects[2].max_speed = kNaN; }},
      {"coordinate beyond kMaxCoordinate", "center",
       [](SceneDesc* s) { s->objects[0].center.x = 1e13; }},
      {"zero resolution", "grid", [](SceneDesc* s) { s->grid = glm::ivec3(0, 10, 10); }},
      {"negative resolution", "grid", [](SceneDesc* s) { s->grid = glm::ivec3(5, -1, 5); }},
      {"bounds min > max", "bounds", [](SceneDesc* s) { s->bounds_min.x = 20.0; }},
      {"empty bounds", "bounds", [](SceneDesc* s) { s->bounds_max.y = 0.0; }},
      {"NaN bounds", "bounds", [](SceneDesc* s) { s->bounds_max.z = kNaN; }},
  };
  for (const Case& c : cases) {
    SceneDesc s = small_valid_scene();
    c.mutate(&s);
    std::unique_ptr<Scene> scene;
    expect_refused(Scene::create(s, {}, &scene), c.field, c.what);
  }
  // And the valid scene works.
  EngineHarness h(small_valid_scene());
  ASSERT_TRUE(h.status().ok) << h.status().str();
  const std::string err = h.frame(camera({5, 5, 20}, {0, 0, -1}), 0.0);
  EXPECT_TRUE(err.empty()) << err;
}

TEST(HardCasesValidation, AbsurdResolutionIsRefusedQuickly) {
  for (const glm::ivec3& g : {glm::ivec3(100000), glm::ivec3(100000, 1, 1),
                              glm::ivec3(8192, 8192, 8192), glm::ivec3(2147483647, 2147483647, 2)}) {
    SceneDesc s = small_valid_scene();
    s.grid = g;
    std::unique_ptr<Scene> scene;
    const auto start = std::chrono::steady_clock::now();
    const Status st = Scene::create(s, {}, &scene);
    const double secs =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    expect_refused(st, "grid", "resolution " + std::to_string(g.x) + "x" + std::to_string(g.y) + "x" +
                                   std::to_string(g.z));
    EXPECT_LT(secs, 1.0);
    EXPECT_EQ(scene, nullptr);
  }
}

TEST(HardCasesValidation, TinyBoundsAreRefusedByTheirExtentAndAnyAcceptedExtentGetsAGrid) {
  // Bounds of [0, 1e-300]^3 were refused as "549755813888 voxels exceed the
  // limit" (the automatic resolution's cube of extents underflowed), while
  // [0, 1e-100]^3 got 84^3: an extent below the documented bound is refused
  // as such, with or without a grid.
  for (const bool with_grid : {false, true}) {
    SceneDesc s;
    s.bounds_max = Vec3(1e-300);
    if (with_grid) s.grid = glm::ivec3(4);
    std::unique_ptr<Scene> scene;
    const Status st = Scene::create(s, {}, &scene);
    EXPECT_EQ(st.field, "bounds");
    EXPECT_EQ(st.message, "extent on axis x is 1e-300; it must be at least 1e-100 world units");
  }
  // Every accepted extent gets a grid within the limits, near the automatic
  // target, however small, large or unequal the extents are.
  const SceneOptions opt;
  for (const Vec3& ext : {Vec3(1e-100), Vec3(1e-100, 1e12, 1.0), Vec3(2e12), Vec3(1e-100, 1e-100, 2e12),
                          Vec3(3e-50, 7e-50, 1e-49)}) {
    SceneDesc s;
    s.bounds_min = -0.5 * ext;
    s.bounds_max = s.bounds_min + ext;
    const glm::ivec3 g = Scene::auto_resolution(s, opt);
    const std::int64_t n = std::int64_t{g.x} * g.y * g.z;
    EXPECT_GE(std::min({g.x, g.y, g.z}), 1);
    EXPECT_LE(std::max({g.x, g.y, g.z}), opt.max_resolution);
    EXPECT_LE(n, 2 * opt.auto_voxels) << g.x << "x" << g.y << "x" << g.z;
    std::unique_ptr<Scene> scene;
    const Status st = Scene::create(s, opt, &scene);
    EXPECT_TRUE(st.ok) << ext.x << " " << ext.y << " " << ext.z << ": " << st.str();
  }
  {
    SceneDesc s;
    s.bounds_max = Vec3(1e-100);
    EXPECT_EQ(Scene::auto_resolution(s, opt), glm::ivec3(84));
  }
  // And it is total before validation (the server asks first).
  SceneDesc bad;
  bad.bounds_min = Vec3(kNaN, 5.0, -std::numeric_limits<double>::infinity());
  bad.bounds_max = Vec3(1.0, 2.0, 1.0);
  const glm::ivec3 g = Scene::auto_resolution(bad, opt);
  EXPECT_GE(std::min({g.x, g.y, g.z}), 1);
  EXPECT_LE(std::max({g.x, g.y, g.z}), opt.max_resolution);
}

TEST(HardCasesValidation, FrameRefusesBadCamerasAndStillWorks) {
  EngineHarness h(small_valid_scene());
  ASSERT_TRUE(h.status().ok) << h.status().str();
  const Camera good = camera({5, 5, 20}, {0, 0, -1});
  ASSERT_TRUE(h.frame(good, 0.0).empty());
  struct Case {
    const char* what;
    const char* field;
    void (*mutate)(Camera*);
  };
  const Case cases[] = {
      {"up parallel to dir", "up", [](Camera* c) { c->up = Vec3(0, 0, 2); }},
      {"up antiparallel to dir", "up", [](Camera* c) { c->up = Vec3(0, 0, 1); }},
      {"zero up", "up", [](Camera* c) { c->up = Vec3(0.0); }},
      {"zero dir", "dir", [](Camera* c) { c->dir = Vec3(0.0); }},
      {"fov 0", "fov", [](Camera* c) { c->fov_y_deg = 0.0; }},
      {"fov 180", "fov", [](Camera* c) { c->fov_y_deg = 180.0; }},
      {"fov negative", "fov", [](Camera* c) { c->fov_y_deg = -30.0; }},
      {"fov NaN", "fov", [](Camera* c) { c->fov_y_deg = kNaN; }},
      {"near == far", "", [](Camera* c) { c->near = c->far = 5.0; }},
      {"near > far", "", [](Camera* c) { c->near = 10.0; c->far = 5.0; }},
      {"near 0", "near", [](Camera* c) { c->near = 0.0; }},
      {"near negative", "near", [](Camera* c) { c->near = -1.0; }},
      {"far infinite", "far", [](Camera* c) { c->far = std::numeric_limits<double>::infinity(); }},
      {"NaN eye", "eye", [](Camera* c) { c->eye.x = kNaN; }},
      {"NaN dir", "dir", [](Camera* c) { c->dir.y = kNaN; }},
      {"aspect 0", "aspect", [](Camera* c) { c->aspect = 0.0; }},
      {"aspect too large", "aspect", [](Camera* c) { c->aspect = 1e4; }},
  };
  double t = 0.0;
  for (const Case& c : cases) {
    Camera cam = good;
    c.mutate(&cam);
    FrameResult r;
    t += kDt;
    expect_refused(h.scene().frame(h.viewer(), cam, t, h.scratch(), &r), c.field, c.what);
    expect_refused(validate_camera(cam), c.field, std::string("validate_camera: ") + c.what);
    const std::string err = h.frame(good, t);
    ASSERT_TRUE(err.empty()) << "after " << c.what << ": " << err;
  }
  // Time going backwards.
  FrameResult r;
  EXPECT_FALSE(h.scene().frame(h.viewer(), good, t - 1.0, h.scratch(), &r).ok);
  EXPECT_TRUE(h.frame(good, t).empty());
  EXPECT_TRUE(validate_camera(good).ok);
}

TEST(HardCasesValidation, ApplyMovesRefusesBadMovesAndStillWorks) {
  EngineHarness h(small_valid_scene());
  ASSERT_TRUE(h.status().ok) << h.status().str();
  const Camera good = camera({5, 5, 20}, {0, 0, -1});
  ASSERT_TRUE(h.frame(good, 1.0).empty());
  struct Case {
    const char* what;
    const char* field;
    std::vector<Move> moves;
    double t;
  };
  const std::vector<Case> cases = {
      {"unknown id", "id", {{99, Vec3(5.0)}}, 1.1},
      {"static id", "id", {{1, Vec3(5.0)}}, 1.1},
      {"NaN centre", "center", {{3, Vec3(8.0, kNaN, 8.0)}}, 1.1},
      {"infinite centre", "center", {{3, Vec3(std::numeric_limits<double>::infinity())}}, 1.1},
      {"valid then unknown (all or nothing)", "moves[1]", {{3, Vec3(8.0, 8.0, 8.1)}, {99, Vec3(5.0)}}, 1.1},
      {"time going backwards", "", {{3, Vec3(8.0, 8.0, 8.1)}}, 0.5},
  };
  for (const Case& c : cases) {
    MoveReport report;
    expect_refused(h.scene().apply_moves(c.t, c.moves, &report), c.field, c.what);
    EXPECT_EQ(h.scene().time(), 1.0) << c.what << ": a refused batch changed the scene time";
    const std::string err = h.frame(good, 1.0);
    ASSERT_TRUE(err.empty()) << "after " << c.what << ": " << err;
  }
  // NaN time.
  EXPECT_FALSE(h.scene().apply_moves(kNaN, std::vector<Move>{{3, Vec3(8.0)}}).ok);
  // The scene still moves objects afterwards.
  MoveReport report;
  ASSERT_TRUE(h.move(1.5, {{3, Vec3(8.0, 8.0, 8.5)}}, &report).ok);
  EXPECT_EQ(report.applied, 1u);
  EXPECT_TRUE(report.too_fast.empty());
  const std::string err = h.frame(good, 1.5);
  EXPECT_TRUE(err.empty()) << err;
}

TEST(HardCasesValidation, UnknownViewerIsRefused) {
  EngineHarness h(small_valid_scene());
  ASSERT_TRUE(h.status().ok) << h.status().str();
  FrameResult r;
  const Status st = h.scene().frame(h.viewer() + 1000, camera({5, 5, 20}, {0, 0, -1}), 0.0, h.scratch(), &r);
  EXPECT_FALSE(st.ok);
  const ViewerId v2 = h.scene().add_viewer();
  h.scene().remove_viewer(v2);
  EXPECT_FALSE(h.scene().frame(v2, camera({5, 5, 20}, {0, 0, -1}), 0.0, h.scratch(), &r).ok);
  EXPECT_TRUE(h.frame(camera({5, 5, 20}, {0, 0, -1}), 0.0).empty());
}


// --- hidden objects near the grid's boundary --------------------------------

TEST(HardCases, HiddenObjectsNearTheBoundaryStayUnderTbvs) {
  // Hidden spheres touching the bounds from inside: their TBVs would reach beyond the
  // grid, where no voxel stands for them. Growth stops at the bounds, so with
  // nothing moving they stay hidden and cost nothing frame after frame.
  SceneDesc scene = hidden_behind_wall(0, 2.0, 45);
  ObjectId id = 100;
  for (const Vec3& c : {Vec3(0.8, 20, 8), Vec3(39.2, 20, 8), Vec3(20, 0.75, 8), Vec3(20, 39.25, 0.75)})
    scene.objects.push_back(dynamic(sphere(id++, c, 0.7), 2.0));
  EngineHarness h(scene, {}, "boundary");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  double t = 0.0;
  for (int f = 0; f < 10; ++f, t += kDt) ASSERT_TRUE(h.frame(kWallCam, t).empty());
  EXPECT_EQ(h.last().stats.tbvs_active, 4u);
  std::uint32_t created = 0, revealed = 0;
  for (int f = 0; f < 30; ++f, t += kDt) {
    ASSERT_TRUE(h.frame(kWallCam, t).empty());
    created += h.last().stats.tbvs_created;
    revealed += h.last().stats.tbvs_revealed;
    EXPECT_TRUE(h.last().wake.empty() || h.last().stats.tbvs_expired > 0) << "frame " << f;
  }
  EXPECT_EQ(revealed, 0u);
  EXPECT_EQ(created, 0u);
  // Leaving the grid at a legal speed leaves the TBV: the move reveals it,
  // and once in view it is in the PVS.
  MoveReport report;
  ASSERT_TRUE(h.move(t, {{100, Vec3(0.3, 20, 8)}}, &report).ok);  // 0.5 in 1.3 s
  EXPECT_TRUE(report.too_fast.empty());
  ASSERT_TRUE(h.frame(kWallCam, t).empty());
  EXPECT_GE(h.last().stats.tbvs_revealed, 1u);
  EXPECT_TRUE(std::binary_search(h.last().wake.begin(), h.last().wake.end(), ObjectId{100}));
}

TEST(HardCases, ExpiredTbvsOfUnmovedObjectsAreRenewedInPlace) {
  // Short fixed periods: many renewals. Unmoved hidden objects keep their
  // TBVs (no new TBV is created, nothing is revealed), each renewal wakes the
  // object, and a later move into view is still caught.
  const SceneDesc scene = hidden_behind_wall(6, 1.0, 46);
  SceneOptions options;
  options.tbv_period = 0.1;
  EngineHarness h(scene, options, "renewals");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  double t = 0.0;
  for (int f = 0; f < 5; ++f, t += kDt) ASSERT_TRUE(h.frame(kWallCam, t).empty());
  ASSERT_EQ(h.last().stats.tbvs_active, 6u);
  std::uint32_t expired = 0, created = 0, revealed = 0;
  for (int f = 0; f < 60; ++f, t += kDt) {
    ASSERT_TRUE(h.frame(kWallCam, t).empty());
    expired += h.last().stats.tbvs_expired;
    created += h.last().stats.tbvs_created;
    revealed += h.last().stats.tbvs_revealed;
    EXPECT_EQ(h.last().wake.size(), h.last().stats.tbvs_expired) << "frame " << f;
  }
  EXPECT_GE(expired, 6u * 10u);  // Two seconds of 0.1 s periods.
  EXPECT_EQ(created, 0u);
  EXPECT_EQ(revealed, 0u);
  // A move into view after the renewals (too fast, as it happens): the
  // object leaves its TBV and is revealed.
  MoveReport report;
  ASSERT_TRUE(h.move(t, {{100, Vec3(20, 20, 30)}}, &report).ok);
  ASSERT_TRUE(h.frame(kWallCam, t).empty());  // The harness checks zero misses.
  EXPECT_TRUE(std::binary_search(h.last().pvs.begin(), h.last().pvs.end(), ObjectId{100}));
}

}  // namespace
}  // namespace voxvis::test
