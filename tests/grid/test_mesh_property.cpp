// The visibility property with meshes: random scenes of spheres and boxes
// with static and dynamic meshes among them (cubes, spheres of triangles,
// triangle soups; rotated, scaled, moving and turning), random cameras, every
// frame checked against the ray caster, which hits the meshes' triangles:
// zero misses, with the occlusion buffer on and off.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "engine_check.h"
#include "meshes.h"
#include "scenes.h"
#include "voxvis/scene.h"

namespace voxvis::test {
namespace {

constexpr double kDt = 1.0 / 30.0;

/// random_scene's objects and 4 to 8 meshes placed inside its bounds; even
/// ones static, odd ones dynamic.
SceneDesc scene_with_meshes(std::uint64_t seed) {
  SceneDesc d = random_scene(random_scene_params(seed), seed);
  Rng rng(mix_seed(seed, 0x3e5));
  const Vec3 ext = d.bounds_max - d.bounds_min;
  const double size = std::fmin(ext.x, std::fmin(ext.y, ext.z));
  ObjectId next = 1;
  for (const ObjectDesc& o : d.objects) next = std::max(next, o.id + 1);
  const int n = rng.uniform_int(4, 8);
  for (int k = 0; k < n; ++k) {
    std::shared_ptr<const Mesh> mesh;
    switch (rng.uniform_int(0, 2)) {
      case 0: mesh = cube_mesh(Vec3(rng.uniform(0.2, 1.0), rng.uniform(0.2, 1.0), rng.uniform(0.2, 1.0))); break;
      case 1: mesh = icosphere(rng.uniform_int(0, 2)); break;
      default: mesh = triangle_soup(rng.uniform_int(1, 12), mix_seed(seed, static_cast<std::uint64_t>(k))); break;
    }
    const Vec3 c = d.bounds_min + Vec3(rng.uniform(0.1, 0.9), rng.uniform(0.1, 0.9), rng.uniform(0.1, 0.9)) * ext;
    const Quat q = rotation_about(rng.unit_vector(), rng.uniform(0.0, 6.3));
    ObjectDesc o = mesh_object(next++, mesh, c, q, size * rng.uniform(0.02, 0.15));
    if (k % 2 == 1) {
      o.dynamic = true;
      o.max_speed = size * rng.uniform(0.05, 0.5);
    }
    d.objects.push_back(o);
  }
  return d;
}

void run(std::uint64_t seed, int frames, bool buffer) {
  const SceneDesc scene = scene_with_meshes(seed);
  const std::string label = describe_scene(scene, seed) + (buffer ? " buffer on" : " buffer off");
  SceneOptions opt;
  if (!buffer) opt = buffer_off(opt);
  EngineHarness h(scene, opt, label);
  ASSERT_TRUE(h.status().ok) << label << ": " << h.status().str();
  const std::vector<Camera> path = random_camera_path(scene, seed, {.frames = frames});
  Mover mover(scene, seed);
  Rng rng(mix_seed(seed, 0x707));
  for (int f = 0; f < frames; ++f) {
    const double t = f * kDt;
    if (f > 0) {
      std::vector<Move> moves = mover.step(kDt);
      // Half the moving meshes also turn (a soup's centroid is off its origin:
      // turning moves it, a move the engine may find too fast, and reveals).
      for (Move& m : moves)
        for (const ObjectDesc& o : h.objects())
          if (o.id == m.id && o.shape == Shape::Mesh &&
              rng.uniform_int(0, 1) == 1) {
            m.has_rotation = true;
            m.rotation = rotation_about(Vec3(0.3, 1.0, -0.2), 0.2 * f) * o.rotation;
          }
      MoveReport report;
      const Status ms = h.move(t, moves, &report);
      ASSERT_TRUE(ms.ok) << label << " frame " << f << ": " << ms.str();
    }
    const std::string err = h.frame(path[static_cast<std::size_t>(f)], t);
    ASSERT_TRUE(err.empty()) << err;
  }
}

TEST(MeshProperty, RandomScenesWithMeshesHaveZeroMisses) {
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(scaled(12)); ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    run(seed, std::max(2, scaled(15)), seed % 2 == 0);
    if (HasFatalFailure()) return;
  }
}

}  // namespace
}  // namespace voxvis::test
