// Tests of the ground truth itself (tests/support/raycast.*, scenes.*), so
// that the visibility property tests can trust it. None of these use the
// engine.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

#include "raycast.h"
#include "scenes.h"

namespace voxvis::test {
namespace {

Camera looking_down_minus_z() {
  return camera_along(Vec3(0.0), Vec3(0.0, 0.0, -1.0), 60.0, 1.0, 0.1, 100.0);
}

using Ids = std::vector<ObjectId>;

TEST(Raycast, BasisIsOrthonormalAndRayDepthIsT) {
  Camera c = looking_down_minus_z();
  c.dir = Vec3(1.0, 2.0, -3.0);
  c.up = Vec3(0.3, 1.0, 0.1);
  ViewBasis b;
  ASSERT_TRUE(make_basis(c, &b));
  EXPECT_NEAR(glm::length(b.f), 1.0, 1e-15);
  EXPECT_NEAR(glm::length(b.right), 1.0, 1e-15);
  EXPECT_NEAR(glm::length(b.up), 1.0, 1e-15);
  EXPECT_NEAR(glm::dot(b.f, b.right), 0.0, 1e-15);
  EXPECT_NEAR(glm::dot(b.f, b.up), 0.0, 1e-15);
  EXPECT_NEAR(glm::dot(b.right, b.up), 0.0, 1e-15);
  EXPECT_NEAR(glm::dot(b.ray_dir(0.7, -0.4), b.f), 1.0, 1e-15);
  EXPECT_NEAR(b.tany, std::tan(30.0 * 3.14159265358979323846 / 180.0), 1e-15);
}

TEST(Raycast, RejectsInvalidCameras) {
  ViewBasis b;
  Camera c = looking_down_minus_z();
  c.up = c.dir;
  EXPECT_FALSE(make_basis(c, &b));
  c = looking_down_minus_z();
  c.fov_y_deg = 0.0;
  EXPECT_FALSE(make_basis(c, &b));
  c.fov_y_deg = 180.0;
  EXPECT_FALSE(make_basis(c, &b));
  c = looking_down_minus_z();
  c.near = c.far;
  EXPECT_FALSE(make_basis(c, &b));
  c = looking_down_minus_z();
  c.eye.x = std::nan("");
  EXPECT_FALSE(make_basis(c, &b));
  EXPECT_TRUE(visible_objects({sphere(1, Vec3(0, 0, -5), 1)}, c).empty());
}

TEST(Raycast, IntersectSphereAndBox) {
  double t0 = 0.0;
  double t1 = 0.0;
  ASSERT_TRUE(intersect(sphere(1, Vec3(0, 0, -5), 1), Vec3(0.0), Vec3(0, 0, -1), &t0, &t1));
  EXPECT_DOUBLE_EQ(t0, 4.0);
  EXPECT_DOUBLE_EQ(t1, 6.0);
  EXPECT_FALSE(intersect(sphere(1, Vec3(0, 2.0001, -5), 2), Vec3(0.0), Vec3(0, 0, -1), &t0, &t1));
  ASSERT_TRUE(intersect(box_around(1, Vec3(0, 0, -5), Vec3(1, 1, 1)), Vec3(0.0), Vec3(0, 0, -1), &t0, &t1));
  EXPECT_DOUBLE_EQ(t0, 4.0);
  EXPECT_DOUBLE_EQ(t1, 6.0);
  // A flat box (half extent 0 along the ray) is hit at a single depth.
  ASSERT_TRUE(intersect(box_around(1, Vec3(0, 0, -5), Vec3(1, 1, 0)), Vec3(0.0), Vec3(0, 0, -1), &t0, &t1));
  EXPECT_DOUBLE_EQ(t0, 5.0);
  EXPECT_DOUBLE_EQ(t1, 5.0);
  // Ray parallel to a slab: inside it (on its face, too) or not.
  ASSERT_TRUE(intersect(box_around(1, Vec3(0, 1, -5), Vec3(1, 1, 1)), Vec3(0.0), Vec3(0, 0, -1), &t0, &t1));
  EXPECT_FALSE(intersect(box_around(1, Vec3(0, 1.5, -5), Vec3(1, 1, 1)), Vec3(0, -0.6, 0), Vec3(0, 0, -1),
                         &t0, &t1));
  // A flat box in the plane of a parallel ray contains the ray's segment.
  ASSERT_TRUE(intersect(box_around(1, Vec3(0, 0, -5), Vec3(1, 0, 1)), Vec3(0.0), Vec3(0, 0, -1), &t0, &t1));
  EXPECT_DOUBLE_EQ(t0, 4.0);
  // Eye inside: the interval straddles 0.
  ASSERT_TRUE(intersect(sphere(1, Vec3(0.0), 1), Vec3(0.0), Vec3(0, 0, -1), &t0, &t1));
  EXPECT_LT(t0, 0.0);
  EXPECT_GT(t1, 0.0);
}

TEST(Raycast, SingleSphereInFrontIsVisible) {
  const std::vector<ObjectDesc> objs = {sphere(7, Vec3(0, 0, -10), 1.0)};
  EXPECT_EQ(visible_objects(objs, looking_down_minus_z()), Ids{7});
  EXPECT_EQ(first_hit(objs, looking_down_minus_z(), 0.0, 0.0), Ids{7});
  // A small one off-centre, still in view.
  const std::vector<ObjectDesc> small = {sphere(3, Vec3(3, -2, -10), 0.3)};
  EXPECT_EQ(visible_objects(small, looking_down_minus_z()), Ids{3});
}

TEST(Raycast, SphereBehindBigBoxIsHidden) {
  const std::vector<ObjectDesc> objs = {
      box_around(1, Vec3(0, 0, -5), Vec3(50, 50, 0.5)),
      sphere(2, Vec3(0, 0, -20), 3.0),
  };
  EXPECT_EQ(visible_objects(objs, looking_down_minus_z()), Ids{1});
  // Open a window in the wall (four boxes around a hole): now visible.
  const std::vector<ObjectDesc> window = {
      box_around(1, Vec3(-26, 0, -5), Vec3(25, 50, 0.5)),  box_around(3, Vec3(26, 0, -5), Vec3(25, 50, 0.5)),
      box_around(4, Vec3(0, 26, -5), Vec3(1, 25, 0.5)),    box_around(5, Vec3(0, -26, -5), Vec3(1, 25, 0.5)),
      sphere(2, Vec3(0, 0, -20), 3.0),
  };
  const Ids v = visible_objects(window, looking_down_minus_z());
  EXPECT_TRUE(std::binary_search(v.begin(), v.end(), ObjectId{2}));
}

TEST(Raycast, ObjectBehindEyeIsNotVisible) {
  const std::vector<ObjectDesc> objs = {sphere(1, Vec3(0, 0, 10), 2.0)};
  EXPECT_TRUE(visible_objects(objs, looking_down_minus_z()).empty());
  EXPECT_TRUE(frustum_objects(objs, looking_down_minus_z()).empty());
}

TEST(Raycast, ObjectOutsideFovIsNotVisible) {
  // At depth 10 the half-height of the 60° frustum is 10*tan(30°) ≈ 5.77.
  const std::vector<ObjectDesc> objs = {sphere(1, Vec3(0, 8, -10), 1.0),
                                        sphere(2, Vec3(-9, 0, -10), 1.0)};
  RaySampling s;
  s.corners = true;
  EXPECT_TRUE(visible_objects(objs, looking_down_minus_z(), s).empty());
  EXPECT_TRUE(frustum_objects(objs, looking_down_minus_z()).empty());
  // Wider fov brings them in.
  Camera wide = looking_down_minus_z();
  wide.fov_y_deg = 120.0;
  EXPECT_EQ(visible_objects(objs, wide, s), (Ids{1, 2}));
}

TEST(Raycast, ObjectBeyondFarIsNotVisible) {
  const std::vector<ObjectDesc> objs = {sphere(1, Vec3(0, 0, -200), 2.0),
                                        sphere(2, Vec3(0, 0, -101), 2.0)};
  // Sphere 2 spans depths 99..103: the part before far = 100 is visible.
  EXPECT_EQ(visible_objects(objs, looking_down_minus_z()), Ids{2});
  EXPECT_EQ(frustum_objects(objs, looking_down_minus_z()), Ids{2});
}

TEST(Raycast, ObjectBeforeNearIsClippedAndDoesNotBlock) {
  Camera c = looking_down_minus_z();
  c.near = 1.0;
  // A box covering the whole view at depth 0.5..0.9, wholly before near.
  const std::vector<ObjectDesc> objs = {
      box_around(1, Vec3(0, 0, -0.7), Vec3(100, 100, 0.2)),
      sphere(2, Vec3(0, 0, -10), 1.0),
  };
  EXPECT_EQ(visible_objects(objs, c), Ids{2});
  EXPECT_EQ(first_hit(objs, c, 0.0, 0.0), Ids{2});
  EXPECT_EQ(frustum_objects(objs, c), Ids{2});
  // An object straddling the near plane is visible (and blocks): entered at near.
  const std::vector<ObjectDesc> straddle = {
      box_around(1, Vec3(0, 0, -1.0), Vec3(100, 100, 0.2)),
      sphere(2, Vec3(0, 0, -10), 1.0),
  };
  EXPECT_EQ(visible_objects(straddle, c), Ids{1});
}

TEST(Raycast, EyeInsideAnObjectSeesOnlyIt) {
  const std::vector<ObjectDesc> objs = {sphere(1, Vec3(0.0), 5.0), sphere(2, Vec3(0, 0, -10), 1.0)};
  EXPECT_EQ(visible_objects(objs, looking_down_minus_z()), Ids{1});
}

TEST(Raycast, TiesMakeBothVisible) {
  // Two boxes sharing the front face plane and overlapping in x: the ray
  // through the overlap enters both at the same depth.
  const std::vector<ObjectDesc> objs = {box_around(1, Vec3(-0.5, 0, -5), Vec3(1, 1, 1)),
                                        box_around(2, Vec3(0.5, 0, -5), Vec3(1, 1, 1))};
  EXPECT_EQ(first_hit(objs, looking_down_minus_z(), 0.0, 0.0), (Ids{1, 2}));
}

TEST(Raycast, CornerRaysReachTheFrustumEdge) {
  // A thin rod straddling the frustum's right plane x = depth*tanx (tanx is
  // tan(45°), about 1), reaching only 0.001 into the frustum: the corner rays
  // with x = 1 hit it.
  Camera c = looking_down_minus_z();
  c.fov_y_deg = 90.0;
  const std::vector<ObjectDesc> objs = {box_around(1, Vec3(10, 0, -10), Vec3(0.001, 1, 0.001))};
  RaySampling s;
  s.corners = true;
  EXPECT_EQ(visible_objects(objs, c, s), Ids{1});
  EXPECT_EQ(frustum_objects(objs, c), Ids{1});
}

TEST(Raycast, FrustumObjectsIsTheAabbTest) {
  // A sphere just outside the frustum's corner edge whose AABB is not outside
  // any single plane: the AABB test keeps it (documented over-approximation).
  Camera c = looking_down_minus_z();
  c.fov_y_deg = 90.0;
  // Corner edge direction (1,1,-1); a sphere of radius 1 pushed out diagonally.
  const double k = 10.0;
  const Vec3 out = glm::normalize(Vec3(1, 1, 0)) * 2.2;
  const std::vector<ObjectDesc> objs = {sphere(1, Vec3(k, k, -k) + out, 1.0)};
  RaySampling s;
  s.corners = true;
  EXPECT_TRUE(visible_objects(objs, c, s).empty());
  EXPECT_EQ(frustum_objects(objs, c), Ids{1});
}

TEST(Raycast, TiledCastingEqualsBruteForce) {
  // The tiling/ordering accelerations must not change the answer: compare
  // with first_hit over the same (unjittered) rays.
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    RandomSceneParams p = random_scene_params(seed);
    p.spheres = std::min(p.spheres, 40);
    p.boxes = std::min(p.boxes, 20);
    const SceneDesc scene = random_scene(p, seed);
    const std::vector<Camera> path = random_camera_path(scene, seed, {.frames = 3});
    for (const Camera& cam : path) {
      RaySampling s;
      s.cols = 24;
      s.rows = 20;
      s.jitter = false;
      s.corners = true;
      const Ids fast = visible_objects(scene.objects, cam, s);
      Ids brute;
      for (int cy = 0; cy < s.rows; ++cy) {
        for (int cx = 0; cx < s.cols; ++cx) {
          const Ids h = first_hit(scene.objects, cam, -1.0 + 2.0 * (cx + 0.5) / s.cols,
                                  -1.0 + 2.0 * (cy + 0.5) / s.rows);
          brute.insert(brute.end(), h.begin(), h.end());
        }
      }
      for (int cy = 0; cy <= s.rows; ++cy) {
        for (int cx = 0; cx <= s.cols; ++cx) {
          const double x = cx == s.cols ? 1.0 : -1.0 + 2.0 * cx / s.cols;
          const double y = cy == s.rows ? 1.0 : -1.0 + 2.0 * cy / s.rows;
          const Ids h = first_hit(scene.objects, cam, x, y);
          brute.insert(brute.end(), h.begin(), h.end());
        }
      }
      std::sort(brute.begin(), brute.end());
      brute.erase(std::unique(brute.begin(), brute.end()), brute.end());
      EXPECT_EQ(fast, brute) << describe_scene(scene, seed) << " " << describe(cam);
    }
  }
}

TEST(Raycast, FrustumObjectsIsSupersetOfVisible) {
  int nonempty = 0;
  for (std::uint64_t seed = 100; seed < 100 + static_cast<std::uint64_t>(scaled(12)); ++seed) {
    const SceneDesc scene = random_scene(random_scene_params(seed), seed);
    for (const Camera& cam : random_camera_path(scene, seed, {.frames = 4})) {
      RaySampling s;
      s.cols = 48;
      s.rows = 48;
      s.corners = true;
      const Ids vis = visible_objects(scene.objects, cam, s);
      const Ids vfc = frustum_objects(scene.objects, cam);
      EXPECT_TRUE(missing_ids(vfc, vis).empty())
          << describe_scene(scene, seed) << " " << describe(cam) << " missing "
          << describe_ids(missing_ids(vfc, vis));
      EXPECT_TRUE(std::is_sorted(vis.begin(), vis.end()));
      EXPECT_TRUE(std::adjacent_find(vis.begin(), vis.end()) == vis.end());
      nonempty += vis.empty() ? 0 : 1;
    }
  }
  EXPECT_GT(nonempty, 0);
}

TEST(Raycast, DeterministicForASeed) {
  const SceneDesc scene = random_scene(random_scene_params(5), 5);
  const Camera cam = random_camera_path(scene, 5, {.frames = 2})[1];
  RaySampling s;
  s.seed = 99;
  EXPECT_EQ(visible_objects(scene.objects, cam, s), visible_objects(scene.objects, cam, s));
  const SceneDesc again = random_scene(random_scene_params(5), 5);
  ASSERT_EQ(again.objects.size(), scene.objects.size());
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    EXPECT_EQ(again.objects[i].id, scene.objects[i].id);
    EXPECT_EQ(again.objects[i].center, scene.objects[i].center);
  }
}

TEST(Raycast, TransformedSceneGivesTheSameAnswerOnSimpleScenes) {
  const std::vector<ObjectDesc> objs = {
      box_around(1, Vec3(0, 0, -5), Vec3(2, 2, 0.5)),
      sphere(2, Vec3(0, 0, -20), 3.0),
      sphere(3, Vec3(4, 1, -12), 1.0),
  };
  SceneDesc scene;
  scene.bounds_min = Vec3(-30);
  scene.bounds_max = Vec3(30);
  scene.objects = objs;
  const Vec3 offset(1e6, -1e6, 1e6);
  const SceneDesc moved = transform_scene(scene, 1e-3, offset);
  const Camera cam = looking_down_minus_z();
  EXPECT_EQ(visible_objects(objs, cam), visible_objects(moved.objects, transform_camera(cam, 1e-3, offset)));
}

// --- the generators ---------------------------------------------------------

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

TEST(RayCast, VoxelsInViewAreThoseRaysCrossUpToTheirFirstHit) {
  // Unit voxels, 10 a side; one ray (a 1x1 sampling) along the row y = z = 5.
  const Vec3 lo(0.0), hi(10.0);
  const glm::ivec3 res(10);
  RaySampling one;
  one.cols = one.rows = 1;
  one.jitter = false;
  const Camera along = camera_along(Vec3(0.5, 5.5, 5.5), Vec3(1, 0, 0), 1.0, 1.0, 0.05, 1000.0);
  // Nothing in the way: every voxel of the row.
  EXPECT_EQ(voxels_in_view({}, along, lo, hi, res, one), 10u);
  // A wall filling x in [5, 6]: up to and including the voxel of the hit.
  const std::vector<ObjectDesc> wall = {box_between(1, Vec3(5, 0, 0), Vec3(6, 10, 10))};
  EXPECT_EQ(voxels_in_view(wall, along, lo, hi, res, one), 6u);
  // From outside the grid, the row from where the ray enters it.
  const Camera outside = camera_along(Vec3(-20.0, 5.5, 5.5), Vec3(1, 0, 0), 1.0, 1.0, 0.05, 1000.0);
  EXPECT_EQ(voxels_in_view(wall, outside, lo, hi, res, one), 6u);
  // A far plane at 3.2 stops it in the fourth voxel.
  const Camera short_far = camera_along(Vec3(0.5, 5.5, 5.5), Vec3(1, 0, 0), 1.0, 1.0, 0.05, 3.2);
  EXPECT_EQ(voxels_in_view(wall, short_far, lo, hi, res, one), 4u);
  // A diagonal ray in the plane z = 5.5 crosses a voxel boundary on every
  // step in x or y: from (0.5, 0.5) to the far corner, 19 voxels.
  const Camera diagonal = camera_along(Vec3(0.5, 0.5, 5.5), Vec3(1, 1.0 + 1e-9, 0), 1.0, 1.0, 0.05, 1000.0);
  EXPECT_EQ(voxels_in_view({}, diagonal, lo, hi, res, one), 19u);
}

}  // namespace
}  // namespace voxvis::test
