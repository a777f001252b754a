// Tests of the random scenes, camera paths and object motion of the tests'
// support (tests/support/scenes.*), so that the property tests can trust
// them. (The ray caster's own tests are in tests/raycast.)
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include <glm/geometric.hpp>

#include "raycast.h"
#include "scenes.h"

namespace voxvis::test {
namespace {

TEST(Scenes, RngMappings) {
  Rng rng(42);
  for (int i = 0; i < 10000; ++i) {
    const double u = rng.uniform();
    ASSERT_GE(u, 0.0);
    ASSERT_LT(u, 1.0);
    const int k = rng.uniform_int(-3, 5);
    ASSERT_GE(k, -3);
    ASSERT_LE(k, 5);
    ASSERT_NEAR(glm::length(rng.unit_vector()), 1.0, 1e-12);
  }
  Rng a(7);
  Rng b(7);
  for (int i = 0; i < 100; ++i) ASSERT_EQ(a.bits(), b.bits());
  // mt19937_64's 10000th output is fixed by the standard.
  std::mt19937_64 g;
  g.discard(9999);
  EXPECT_EQ(g(), 9981545732273789042ULL);
}

TEST(Scenes, RandomScenesAreValid) {
  for (std::uint64_t seed = 0; seed < 30; ++seed) {
    const RandomSceneParams p = random_scene_params(seed);
    const SceneDesc scene = random_scene(p, seed);
    ASSERT_TRUE(scene.grid.has_value());
    std::vector<ObjectId> ids;
    for (const ObjectDesc& o : scene.objects) {
      ids.push_back(o.id);
      if (o.shape == Shape::Sphere) {
        EXPECT_GT(o.radius, 0.0);
      } else {
        EXPECT_GE(o.half_extent.x, 0.0);
        EXPECT_GE(o.half_extent.y, 0.0);
        EXPECT_GE(o.half_extent.z, 0.0);
      }
      EXPECT_GE(o.max_speed, 0.0);
      if (!o.dynamic) {
        EXPECT_EQ(o.max_speed, 0.0);
      }
    }
    std::sort(ids.begin(), ids.end());
    EXPECT_TRUE(std::adjacent_find(ids.begin(), ids.end()) == ids.end()) << "seed " << seed;
    for (const Camera& c : random_camera_path(scene, seed)) {
      ViewBasis b;
      EXPECT_TRUE(make_basis(c, &b)) << "seed " << seed << " " << describe(c);
    }
  }
}

TEST(Scenes, MoverRespectsMaxSpeed) {
  const double dt = 1.0 / 30.0;
  for (std::uint64_t seed = 0; seed < 10; ++seed) {
    const SceneDesc scene = random_scene(random_scene_params(seed), seed);
    Mover mover(scene, seed);
    std::vector<ObjectDesc> prev = mover.objects();
    for (int f = 0; f < 60; ++f) {
      const std::vector<Move> moves = mover.step(dt);
      const std::vector<ObjectDesc>& now = mover.objects();
      for (std::size_t i = 0; i < now.size(); ++i) {
        const double d = glm::length(now[i].center - prev[i].center);
        if (!now[i].dynamic) {
          ASSERT_EQ(d, 0.0);
        } else {
          ASSERT_LE(d, now[i].max_speed * dt) << "seed " << seed << " " << describe(now[i]);
        }
      }
      std::vector<ObjectDesc> check = prev;
      apply_moves_to(&check, moves);
      for (std::size_t i = 0; i < now.size(); ++i) ASSERT_EQ(check[i].center, now[i].center);
      prev = now;
    }
  }
}

}  // namespace
}  // namespace voxvis::test
