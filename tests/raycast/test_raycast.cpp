// Tests of the CPU ray caster (raycast/, voxvis::raycast): its definitions
// on hand-made scenes, and the hierarchy's answers against brute force (every
// object tested on every ray) on random scenes with their hard cases — eyes
// on voxel corners, axis views, extreme lenses, huge and tiny coordinates,
// objects outside the bounds, exact ties. None of these use the engine.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "describe.h"
#include "scenes.h"
#include "voxvis/raycast.h"

namespace voxvis::test {
namespace {

using raycast::CastOptions;
using raycast::CastStats;
using raycast::confirm_near_pixels;
using raycast::first_hit;
using raycast::frustum_objects;
using raycast::intersect;
using raycast::make_basis;
using raycast::pixel_centres;
using raycast::RaySampling;
using raycast::ViewBasis;
using raycast::visible_near_pixel;
using raycast::visible_objects;
using raycast::voxels_in_view;

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

TEST(Raycast, CellCentresAndCornersAreTheRaysOfFirstHit) {
  // The sampling is what the header says: with no jitter, the union of
  // first_hit (brute force) over the cell centres and corners.
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

// --- the hierarchy against brute force --------------------------------------

/// Brute force, the definition: every object on every ray.
Ids brute_force(const std::vector<ObjectDesc>& objects, const Camera& cam, const RaySampling& s) {
  CastOptions o;
  o.threads = 1;
  o.brute_force = true;
  return visible_objects(objects, cam, s, o);
}

/// The hierarchy, on one thread and on three, gives brute force's answer.
/// Returns that answer.
Ids expect_as_brute_force(const std::vector<ObjectDesc>& objects, const Camera& cam, const RaySampling& s,
                          const std::string& what) {
  const Ids want = brute_force(objects, cam, s);
  CastOptions one;
  one.threads = 1;
  CastStats st;
  const Ids fast = visible_objects(objects, cam, s, one, &st);
  EXPECT_EQ(fast, want) << what << " " << describe(cam) << "\n  only the hierarchy's: "
                        << describe_ids(missing_ids(want, fast))
                        << "\n  only brute force's: " << describe_ids(missing_ids(fast, want));
  EXPECT_LE(st.in_frustum, objects.size());
  EXPECT_EQ(st.threads, 1);
  CastOptions three;
  three.threads = 3;
  EXPECT_EQ(visible_objects(objects, cam, s, three), fast) << what << " " << describe(cam);
  return want;
}

TEST(Raycast, HierarchyEqualsBruteForceOnRandomScenes) {
  // Paths with more than their share of hard cases: eyes on voxel planes,
  // edges and corners, axis and diagonal views, extreme lenses, starts
  // outside the bounds; scenes with objects outside the bounds; the same
  // at huge and tiny coordinates.
  CameraPathParams hard;
  hard.frames = 4;
  hard.snap_eye_chance = 0.4;
  hard.axis_dir_chance = 0.3;
  hard.extreme_lens_chance = 0.2;
  hard.outside_chance = 0.2;
  struct Transform {
    double scale;
    Vec3 offset;
  };
  const Transform transforms[] = {{1.0, Vec3(0.0)}, {1e-5, Vec3(3e7, -3e7, 3e7)}, {1e5, Vec3(4e9, -4e9, 4e9)}};
  std::size_t visible = 0;
  int frames = 0;
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(scaled(10)); ++seed) {
    const SceneDesc scene = random_scene(random_scene_params(seed), seed);
    const std::vector<Camera> path = random_camera_path(scene, mix_seed(seed, 77), hard);
    for (const Transform& t : transforms) {
      const SceneDesc moved = transform_scene(scene, t.scale, t.offset);
      for (std::size_t k = 0; k < path.size(); ++k) {
        const Camera cam = transform_camera(path[k], t.scale, t.offset);
        RaySampling jittered;
        jittered.cols = 32;
        jittered.rows = 24;
        jittered.corners = true;
        jittered.seed = seed * 31 + k;
        const std::string what = describe_scene(scene, seed) + " scale " + std::to_string(t.scale) + " frame " +
                                 std::to_string(k);
        visible += expect_as_brute_force(moved.objects, cam, jittered, what).size();
        expect_as_brute_force(moved.objects, cam, pixel_centres(41, 23), what);
        ++frames;
      }
    }
  }
  EXPECT_GT(visible, static_cast<std::size_t>(frames));  // Not a comparison of empty sets.
}

TEST(Raycast, HierarchyKeepsEveryTie) {
  // A wall of unit boxes in z in [0, 1] seen head on from an eye on a grid
  // corner: the ray straight ahead (the centre pixel of an odd image) meets
  // the corner shared by four boxes, rays through shared edges meet two, all
  // entered at the same depth.
  std::vector<ObjectDesc> wall;
  ObjectId id = 1;
  for (int x = -4; x < 4; ++x)
    for (int y = -4; y < 4; ++y) wall.push_back(box_between(id++, Vec3(x, y, 0), Vec3(x + 1, y + 1, 1)));
  const Camera ahead = camera_along(Vec3(0.0, 0.0, 10.0), Vec3(0, 0, -1), 60.0, 1.0, 0.05, 100.0);
  const Ids centre = expect_as_brute_force(wall, ahead, pixel_centres(1, 1), "wall, one ray");
  // Boxes [-1, 0] and [0, 1] on both axes.
  EXPECT_EQ(centre.size(), 4u) << describe_ids(centre);
  expect_as_brute_force(wall, ahead, pixel_centres(63, 63), "wall");
  RaySampling corners;
  corners.cols = 16;
  corners.rows = 16;
  corners.jitter = false;
  corners.corners = true;
  expect_as_brute_force(wall, ahead, corners, "wall, corner rays");

  // The eye inside three objects: all three are entered at `near` on every
  // ray, and nothing behind them shows.
  std::vector<ObjectDesc> around = {sphere(1, Vec3(0.0), 2.0), sphere(2, Vec3(0.5, 0.0, 0.0), 3.0),
                                    box_around(3, Vec3(0.0), Vec3(1.0, 1.0, 1.0)),
                                    sphere(4, Vec3(0.0, 0.0, -20.0), 5.0)};
  EXPECT_EQ(expect_as_brute_force(around, camera_along(Vec3(0.0), Vec3(0, 0, -1)), pixel_centres(17, 9), "eye inside"),
            (Ids{1, 2, 3}));

  // Fifty spheres with one centre and radius (a leaf that cannot be split
  // by centres) in front of a wall: all fifty tie on every ray that meets
  // them.
  std::vector<ObjectDesc> same;
  for (ObjectId k = 1; k <= 50; ++k) same.push_back(sphere(k, Vec3(0.0, 0.0, -5.0), 1.0));
  same.push_back(box_around(100, Vec3(0.0, 0.0, -8.0), Vec3(10.0, 10.0, 0.5)));
  const Ids all = expect_as_brute_force(same, camera_along(Vec3(0.0), Vec3(0, 0, -1)), pixel_centres(16, 16),
                                        "one centre");
  EXPECT_EQ(all.size(), 51u);
}

TEST(Raycast, HierarchyEqualsBruteForceOnDegenerateLayouts) {
  // Centres spaced geometrically (the surface-area split degenerates into a
  // deep chain, so the build falls back to median splits), a dense row of
  // abutting flat boxes, and objects of wildly different sizes.
  std::vector<ObjectDesc> objs;
  ObjectId id = 1;
  double x = 1e-3;
  for (int k = 0; k < 120; ++k, x *= 1.25) objs.push_back(sphere(id++, Vec3(x, 0.1 * (k % 7), -3.0 - 0.01 * k), 0.3 * x));
  for (int k = 0; k < 100; ++k)
    objs.push_back(box_between(id++, Vec3(-50.0 + k, -2.0, -40.0), Vec3(-49.0 + k, 2.0, -40.0)));
  objs.push_back(box_around(id++, Vec3(0.0, -1e4, 0.0), Vec3(1e5, 1.0, 1e5)));
  objs.push_back(sphere(id++, Vec3(3.0, 1.0, -10.0), 1e-6));
  for (const Vec3& dir : {Vec3(0, 0, -1), Vec3(1, 0, -1), Vec3(0.3, -0.2, -1), Vec3(1, 0, 0)}) {
    const Camera cam = camera_along(Vec3(0.0, 0.5, 0.0), dir, 90.0, 1.5, 1e-3, 1e6);
    RaySampling s;
    s.cols = 48;
    s.rows = 32;
    s.corners = true;
    expect_as_brute_force(objs, cam, s, "degenerate");
  }
}

TEST(Raycast, PixelCentresAreTheRenderersSampling) {
  // Pixel (i, j) samples x = -1 + (2i+1)/W, y = -1 + (2j+1)/H (voxvis/render.h).
  const SceneDesc scene = random_scene(random_scene_params(3), 3);
  const Camera cam = random_camera_path(scene, 3, {.frames = 1})[0];
  const int w = 13;
  const int h = 7;
  Ids by_pixel;
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i) {
      const Ids hit = first_hit(scene.objects, cam, -1.0 + (2.0 * i + 1.0) / w, -1.0 + (2.0 * j + 1.0) / h);
      by_pixel.insert(by_pixel.end(), hit.begin(), hit.end());
    }
  std::sort(by_pixel.begin(), by_pixel.end());
  by_pixel.erase(std::unique(by_pixel.begin(), by_pixel.end()), by_pixel.end());
  EXPECT_EQ(visible_objects(scene.objects, cam, pixel_centres(w, h)), by_pixel);
}

TEST(Raycast, VisibleNearAPixelNeedsRaysOfPositiveMeasure) {
  // 33 x 33 pixels: the centre pixel (16, 16) samples x = y = 0, the view
  // direction -z. A wall of two unit-deep boxes meeting at x = 0 (their front
  // faces at depth 2); a plate of zero width in the plane x = 0, which holds
  // the eye, seen edge-on; a ball touching the wall's front plane from
  // behind at the centre ray only. At the centre ray all four are entered at
  // depth 2: a tie, where the plate is seen along an edge and the ball at a
  // point, sets of rays of measure zero.
  const Camera cam = looking_down_minus_z();
  const std::vector<ObjectDesc> objs = {box_between(1, Vec3(-1, -1, -3), Vec3(0, 1, -2)),
                                        box_between(2, Vec3(0, -1, -3), Vec3(1, 1, -2)),
                                        box_between(3, Vec3(0, -1, -3), Vec3(0, 1, -2)),
                                        sphere(4, Vec3(0, 0, -3), 1.0)};
  const int n = 33;
  ASSERT_EQ(first_hit(objs, cam, -1.0 + (2.0 * 16 + 1.0) / n, -1.0 + (2.0 * 16 + 1.0) / n), (Ids{1, 2, 3, 4}));
  // Edge and point ties: not visible near the pixel.
  EXPECT_FALSE(visible_near_pixel(objs, cam, n, n, 16, 16, 3));
  EXPECT_FALSE(visible_near_pixel(objs, cam, n, n, 16, 16, 4));
  // Faces: both boxes of the wall, one on each side of the seam the centre
  // ray runs along.
  EXPECT_TRUE(visible_near_pixel(objs, cam, n, n, 16, 16, 1));
  EXPECT_TRUE(visible_near_pixel(objs, cam, n, n, 16, 16, 2));
  // A face tied over an area (a copy of box 1): visible too; away from it,
  // or absent, not.
  std::vector<ObjectDesc> copy = objs;
  copy.push_back(box_between(5, Vec3(-1, -1, -3), Vec3(0, 1, -2)));
  EXPECT_TRUE(visible_near_pixel(copy, cam, n, n, 16, 16, 5));
  EXPECT_FALSE(visible_near_pixel(copy, cam, n, n, 20, 16, 5));
  EXPECT_FALSE(visible_near_pixel(objs, cam, n, n, 16, 16, 99));
  // Over an image: the plate and the ball only ever tie along the centre
  // row and column, so they are dismissed wherever they showed; a box
  // showing at a pixel of its own is confirmed; with no id image every
  // pixel is tried (ball 4 nowhere first, box 2 somewhere).
  std::vector<ObjectId> pixel_ids(static_cast<std::size_t>(n * n), 1);
  pixel_ids[static_cast<std::size_t>(16 * n + 16)] = 3;
  pixel_ids[static_cast<std::size_t>(16 * n + 15)] = 4;
  pixel_ids[static_cast<std::size_t>(10 * n + 20)] = 2;
  Ids confirmed, dismissed;
  confirm_near_pixels(objs, cam, n, n, pixel_ids, {4, 3, 2}, &confirmed, &dismissed);
  EXPECT_EQ(confirmed, Ids{2});
  EXPECT_EQ(dismissed, (Ids{3, 4}));
  confirm_near_pixels(objs, cam, n, n, {}, {2, 4}, &confirmed, &dismissed);
  EXPECT_EQ(confirmed, Ids{2});
  EXPECT_EQ(dismissed, Ids{4});
}

TEST(Raycast, VisibleNearAPixelIsFirstHitOnTheConesRays) {
  // visible_near_pixel prunes by projected bounding boxes; the answer is
  // first_hit's (brute force) on the cone's four rays, 1e-3 pixel from the
  // centre at 0.4 + k*pi/2 radians, on random scenes; and confirm_near_pixels
  // over every pixel is the union.
  std::size_t seen = 0;
  for (std::uint64_t seed = 21; seed <= 24; ++seed) {
    RandomSceneParams p = random_scene_params(seed);
    p.spheres = std::min(p.spheres, 40);
    p.boxes = std::min(p.boxes, 20);
    const SceneDesc scene = random_scene(p, seed);
    for (const Camera& cam : random_camera_path(scene, seed, {.frames = 2})) {
      const int w = 16;
      const int h = 12;
      Ids near_some, all;
      for (const ObjectDesc& o : scene.objects) all.push_back(o.id);
      for (int j = 0; j < h; ++j)
        for (int i = 0; i < w; ++i) {
          Ids brute;
          for (int k = 0; k < 4; ++k) {
            const double a = 0.4 + k * std::numbers::pi / 2.0;
            const Ids hit = first_hit(scene.objects, cam, -1.0 + (2.0 * i + 1.0 + 2e-3 * std::cos(a)) / w,
                                      -1.0 + (2.0 * j + 1.0 + 2e-3 * std::sin(a)) / h);
            brute.insert(brute.end(), hit.begin(), hit.end());
          }
          for (const ObjectDesc& o : scene.objects) {
            const bool first = std::find(brute.begin(), brute.end(), o.id) != brute.end();
            EXPECT_EQ(visible_near_pixel(scene.objects, cam, w, h, i, j, o.id), first)
                << describe_scene(scene, seed) << " " << describe(cam) << " pixel " << i << "," << j << " id " << o.id;
            if (first) near_some.push_back(o.id);
          }
        }
      std::sort(near_some.begin(), near_some.end());
      near_some.erase(std::unique(near_some.begin(), near_some.end()), near_some.end());
      Ids confirmed, dismissed;
      confirm_near_pixels(scene.objects, cam, w, h, {}, all, &confirmed, &dismissed);
      EXPECT_EQ(confirmed, near_some);
      EXPECT_EQ(confirmed.size() + dismissed.size(), all.size());
      seen += near_some.size();
    }
  }
  EXPECT_GT(seen, 20u);
}

TEST(Raycast, VoxelsInViewAreThoseRaysCrossUpToTheirFirstHit) {
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
