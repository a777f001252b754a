// Tests of the CPU ray caster on triangle meshes (voxvis/raycast.h, "Meshes"):
// a mesh hides and shows as its triangles do, a ray through a shared edge or
// vertex never passes between triangles (the watertight test), a placed
// mesh (centre, rotation, scale) gives the hits of the same triangles placed
// by hand, the meshes' hierarchies give brute force's answers and are built
// once per mesh, and a mesh of about 80,000 triangles costs a few dozen
// triangle tests a ray.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "describe.h"
#include "meshes.h"
#include "scenes.h"
#include "voxvis/mesh.h"
#include "voxvis/raycast.h"

namespace voxvis::test {
namespace {

using raycast::CastOptions;
using raycast::CastStats;
using raycast::confirm_near_pixels;
using raycast::first_hit;
using raycast::frustum_objects;
using raycast::intersect;
using raycast::pixel_centres;
using raycast::project;
using raycast::RaySampling;
using raycast::visible_objects;
using raycast::voxels_in_view;

using Ids = std::vector<ObjectId>;

Camera ahead_from(const Vec3& eye) { return camera_along(eye, Vec3(0.0, 0.0, -1.0), 60.0, 1.0, 0.1, 100.0); }

/// first_hit at every pixel centre of a w x h image.
std::vector<Ids> pixel_hits(const std::vector<ObjectDesc>& objects, const Camera& cam, int w, int h) {
  std::vector<Ids> out;
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i) out.push_back(first_hit(objects, cam, -1.0 + (2.0 * i + 1.0) / w, -1.0 + (2.0 * j + 1.0) / h));
  return out;
}

TEST(RaycastMesh, MeshCubeHidesAsABoxOfTheSameSize) {
  const Vec3 c(0.3, -0.2, -6.0), half(1.1, 0.9, 0.7);
  const std::vector<ObjectDesc> spheres = {sphere(2, Vec3(0.3, -0.2, -12.0), 1.5),  // Behind: hidden.
                                           sphere(3, Vec3(1.6, 0.4, -10.0), 1.0)};  // Behind, off to a side: shows.
  std::vector<ObjectDesc> with_box = spheres, with_mesh = spheres;
  with_box.push_back(box_around(1, c, half));
  with_mesh.push_back(mesh_object(1, cube_mesh(half), c));
  const Camera cam = ahead_from(Vec3(0.0));
  const Ids seen = visible_objects(with_box, cam);
  EXPECT_EQ(seen, (Ids{1, 3}));
  EXPECT_EQ(visible_objects(with_mesh, cam), seen);
  // Pixel by pixel, the same first hits.
  const std::vector<Ids> box_px = pixel_hits(with_box, cam, 33, 27), mesh_px = pixel_hits(with_mesh, cam, 33, 27);
  int differ = 0, on_cube = 0;
  for (std::size_t p = 0; p < box_px.size(); ++p) {
    differ += box_px[p] != mesh_px[p] ? 1 : 0;
    on_cube += box_px[p] == Ids{1} ? 1 : 0;
  }
  EXPECT_EQ(differ, 0);
  EXPECT_GT(on_cube, 10);
  // The same depth: the front face at z = -5.3, 5.3 along the axis.
  double t0 = 0.0, t1 = 0.0;
  ASSERT_TRUE(intersect(with_mesh.back(), Vec3(0.0), Vec3(0.3, -0.2, -6.0), &t0, &t1));
  EXPECT_NEAR(t0, 5.3 / 6.0, 1e-13);
  EXPECT_NEAR(t1, 6.7 / 6.0, 1e-13);
  EXPECT_FALSE(intersect(with_mesh.back(), Vec3(0.0), Vec3(3.0, 0.0, -6.0), &t0, &t1));
}

TEST(RaycastMesh, AMeshIsASurfaceNotASolid) {
  // The eye inside a closed mesh cube sees its inner faces, and what lies
  // inside with it; a box of the same size (a solid) hides everything.
  const std::vector<ObjectDesc> inside_mesh = {mesh_object(1, cube_mesh(Vec3(5.0)), Vec3(0.0)),
                                               sphere(2, Vec3(0.0, 0.0, -3.0), 0.5),
                                               sphere(3, Vec3(0.0, 0.0, -20.0), 3.0)};
  std::vector<ObjectDesc> inside_box = inside_mesh;
  inside_box[0] = box_around(1, Vec3(0.0), Vec3(5.0));
  const Camera cam = ahead_from(Vec3(0.0));
  EXPECT_EQ(visible_objects(inside_mesh, cam), (Ids{1, 2}));
  EXPECT_EQ(visible_objects(inside_box, cam), (Ids{1}));
  // The far face, at depth 5, is where the centre ray meets the mesh beyond
  // the near plane.
  EXPECT_EQ(first_hit(inside_mesh, cam, 0.5, 0.5), (Ids{1}));
  EXPECT_EQ(first_hit(inside_mesh, cam, 0.0, 0.0), (Ids{2}));
}

TEST(RaycastMesh, ARayThroughASharedEdgeOrVertexHits) {
  // A square of two triangles in z = -5, split along the diagonal x = y:
  // the centre ray meets the diagonal exactly (U = 0 in both triangles), a
  // ray through the square's centre vertex of a fan of four triangles meets
  // four edges at once. Neither passes through to the sphere behind.
  auto square = std::make_shared<Mesh>();
  square->vertices = {Vec3(-1, -1, 0), Vec3(1, -1, 0), Vec3(1, 1, 0), Vec3(-1, 1, 0)};
  square->triangles = {{0, 1, 2}, {0, 2, 3}};
  auto fan = std::make_shared<Mesh>();
  fan->vertices = {Vec3(0, 0, 0), Vec3(-1, -1, 0), Vec3(1, -1, 0), Vec3(1, 1, 0), Vec3(-1, 1, 0)};
  fan->triangles = {{0, 1, 2}, {0, 2, 3}, {0, 3, 4}, {0, 4, 1}};
  const Camera cam = ahead_from(Vec3(0.0));
  for (const auto& m : {std::shared_ptr<const Mesh>(square), std::shared_ptr<const Mesh>(fan)}) {
    const std::vector<ObjectDesc> objs = {mesh_object(1, m, Vec3(0.0, 0.0, -5.0)),
                                          sphere(2, Vec3(0.0, 0.0, -10.0), 1.0)};
    EXPECT_EQ(first_hit(objs, cam, 0.0, 0.0), (Ids{1})) << m->triangles.size() << " triangles";
  }

  // A terrain placed as it is (heights in thirds, so not exact in binary),
  // and rays from an eye above it through points of its inner edges at
  // sixteenths of their length and through its vertices: each runs through
  // an edge or a vertex to within rounding, on either side. The first
  // crossing comes no later than the aimed point (t = 1): no ray slips
  // between two triangles. (A test that decides each triangle on its own
  // rounds the two triangles' coordinates apart: Moller and Trumbore's, in
  // double, lets about 2% of these rays through, and 8% of the ones below.)
  auto terrain = std::make_shared<Mesh>();
  constexpr int kCells = 8;
  for (int j = 0; j <= kCells; ++j)
    for (int i = 0; i <= kCells; ++i) terrain->vertices.push_back(Vec3(i, j, ((i * 7 + j * 13) % 5) / 3.0));
  auto at = [](int i, int j) { return static_cast<std::uint32_t>(j * (kCells + 1) + i); };
  for (int j = 0; j < kCells; ++j)
    for (int i = 0; i < kCells; ++i) {
      if ((i + j) % 2 == 0) {
        terrain->triangles.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
        terrain->triangles.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
      } else {
        terrain->triangles.push_back({at(i, j), at(i + 1, j), at(i, j + 1)});
        terrain->triangles.push_back({at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)});
      }
    }
  const ObjectDesc ground = mesh_object(1, terrain, Vec3(0.0));
  const Vec3 above(3.0, 5.0, 40.0);
  int rays = 0, late = 0;
  for (const auto& tri : terrain->triangles)
    for (int e = 0; e < 3; ++e) {
      const Vec3& a = terrain->vertices[tri[static_cast<std::size_t>(e)]];
      const Vec3& b = terrain->vertices[tri[static_cast<std::size_t>((e + 1) % 3)]];
      // The rim's edges belong to one triangle: the terrain ends there.
      auto rim = [](double u, double v) { return u == v && (u == 0.0 || u == kCells); };
      if (rim(a.x, b.x) || rim(a.y, b.y)) continue;
      for (int k = 0; k < 16; ++k) {
        const Vec3 p = a + (k / 16.0) * (b - a);
        double t0 = 0.0, t1 = 0.0;
        ++rays;
        if (!intersect(ground, above, p - above, &t0, &t1) || !(t0 <= 1.0 + 1e-12)) ++late;
      }
    }
  EXPECT_EQ(late, 0) << "of " << rays;

  // A closed mesh, rotated, scaled, off the origin, seen from afar: rays
  // aimed at random points of its edges and at its vertices (each passes
  // within rounding of the edge, on either side) all meet it there, and the
  // sphere behind it never shows. Only edges well inside the side facing the
  // eye: a ray along an edge of the silhouette grazes the mesh and may
  // rightly miss it.
  const auto ball = icosphere(3);
  const ObjectDesc o = mesh_object(1, ball, Vec3(3.0e3, -2.0e3, 1.5e3), rotation_about(Vec3(1, 2, 3), 0.7), 37.0);
  const Vec3 centre = place(o, Vec3(0.0));
  const std::vector<ObjectDesc> objs = {o, sphere(2, centre + Vec3(0.0, 0.0, -500.0), 100.0)};
  const Vec3 eye = centre + Vec3(13.0, -7.0, 900.0);
  Rng rng(42);
  rays = 0;
  int missed = 0, through = 0;
  for (const auto& tri : ball->triangles)
    for (int e = 0; e < 3; ++e) {
      const Vec3 a = place(o, ball->vertices[tri[static_cast<std::size_t>(e)]]);
      const Vec3 b = place(o, ball->vertices[tri[static_cast<std::size_t>((e + 1) % 3)]]);
      for (const double s : {0.0, rng.uniform(0.0, 1.0)}) {
        const Vec3 p = a + s * (b - a);
        if (glm::dot(glm::normalize(p - centre), glm::normalize(eye - p)) < 0.2) continue;
        double t0 = 0.0, t1 = 0.0;
        ++rays;
        if (!intersect(o, eye, p - eye, &t0, &t1) || !(t0 <= 1.0 + 1e-9)) ++missed;
        Camera cam_at = camera_along(eye, p - eye, 10.0, 1.0, 0.1, 5000.0);
        cam_at.up = Vec3(0.3, 1.0, 0.2);
        if (first_hit(objs, cam_at, 0.0, 0.0) != Ids{1}) ++through;
      }
    }
  EXPECT_EQ(missed, 0) << "of " << rays;
  EXPECT_EQ(through, 0) << "of " << rays;
  EXPECT_GT(rays, 1500);
}

TEST(RaycastMesh, PlacedMeshHitsAsTheSameTrianglesPlacedByHand) {
  struct Placement {
    Vec3 center;
    Quat rotation;
    double scale;
  };
  const Placement placements[] = {{Vec3(0.5, -0.3, -8.0), rotation_about(Vec3(0, 1, 0), 0.9), 2.5},
                                  {Vec3(-1.0, 1.0, -6.0), rotation_about(Vec3(1, -1, 0.5), 2.2), 0.75},
                                  {Vec3(1e4, -2e4, -3e4), rotation_about(Vec3(0.2, 0.1, 1), -1.3), 4e3}};
  const auto meshes = {icosphere(2), triangle_soup(60, 7)};
  for (const auto& mesh : meshes)
    for (const Placement& p : placements) {
      const ObjectDesc placed = mesh_object(1, mesh, p.center, p.rotation, p.scale);
      const ObjectDesc by_hand = placed_by_hand(placed);
      Vec3 lo, hi;
      object_bounds(placed, &lo, &hi);
      const Vec3 mid = 0.5 * (lo + hi);
      const double size = glm::length(hi - lo);
      // Seen from the front, with a sphere half behind it.
      const Camera cam = camera_along(mid + Vec3(0.1, 0.2, 2.0) * size, Vec3(-0.05, -0.1, -1.0), 40.0, 1.3,
                                      1e-3 * size, 10.0 * size);
      const ObjectDesc behind = sphere(2, mid + Vec3(0.3, 0.0, -0.6) * size, 0.3 * size);
      const std::vector<ObjectDesc> a = {placed, behind}, b = {by_hand, behind};
      const std::string what = describe(placed);
      RaySampling s;
      s.cols = 48;
      s.rows = 40;
      EXPECT_EQ(visible_objects(a, cam, s), visible_objects(b, cam, s)) << what;
      const std::vector<Ids> pa = pixel_hits(a, cam, 31, 23), pb = pixel_hits(b, cam, 31, 23);
      int on_mesh = 0;
      for (std::size_t k = 0; k < pa.size(); ++k) {
        EXPECT_EQ(pa[k], pb[k]) << what << " pixel " << k;
        on_mesh += pa[k] == Ids{1} ? 1 : 0;
      }
      EXPECT_GT(on_mesh, 20) << what;
      // Depths along rays at the mesh's centre agree to rounding.
      raycast::ViewBasis vb;
      ASSERT_TRUE(raycast::make_basis(cam, &vb));
      for (int k = 0; k < 16; ++k) {
        const Vec3 d = vb.ray_dir(0.05 * k - 0.4, 0.3 - 0.04 * k);
        double a0 = 0.0, a1 = 0.0, b0 = 0.0, b1 = 0.0;
        const bool ha = intersect(placed, cam.eye, d, &a0, &a1), hb = intersect(by_hand, cam.eye, d, &b0, &b1);
        EXPECT_EQ(ha, hb) << what << " ray " << k;
        if (ha && hb) {
          EXPECT_NEAR(a0, b0, 1e-9 * std::abs(b0)) << what;
          EXPECT_NEAR(a1, b1, 1e-9 * std::abs(b1)) << what;
        }
      }
    }
}

TEST(RaycastMesh, MovesRotateMeshes) {
  // A thin plate across the view hides a sphere; a move that turns it by 90
  // degrees about the vertical shows it edge on, uncovering the sphere; a
  // move without a rotation keeps the plate's last rotation, and a box
  // ignores a rotation.
  const Camera cam = ahead_from(Vec3(0.0));
  std::vector<ObjectDesc> objs = {mesh_object(1, cube_mesh(Vec3(3.0, 3.0, 0.05)), Vec3(0.0, 0.0, -5.0)),
                                  sphere(2, Vec3(0.0, 0.0, -10.0), 0.4),
                                  box_around(3, Vec3(1.0, 1.0, -3.0), Vec3(0.2, 0.2, 0.2))};
  objs[0].dynamic = objs[2].dynamic = true;
  EXPECT_EQ(visible_objects(objs, cam), (Ids{1, 3}));
  Move turn{1, Vec3(0.0, 0.0, -5.0), true, rotation_about(Vec3(0, 1, 0), std::numbers::pi / 2)};
  apply_moves_to(&objs, {turn});
  EXPECT_EQ(visible_objects(objs, cam), (Ids{1, 2, 3}));
  apply_moves_to(&objs, {Move{1, Vec3(0.0, 0.0, -5.5)}});
  EXPECT_EQ(objs[0].rotation, turn.rotation);
  EXPECT_EQ(visible_objects(objs, cam), (Ids{1, 2, 3}));
  apply_moves_to(&objs, {Move{3, Vec3(1.0, 1.0, -3.0), true, turn.rotation}});
  EXPECT_EQ(objs[2].rotation, Quat(1.0, 0.0, 0.0, 0.0));
}

TEST(RaycastMesh, FrustumAndBoxesUseTheTriangles) {
  // The model origin (`center`) is where the mesh's vertices are measured
  // from, not the mesh: a mesh whose triangles lie far from it is in view
  // when they are, out of view when they are not.
  auto off = std::make_shared<Mesh>(*cube_mesh(Vec3(1.0)));
  for (Vec3& v : off->vertices) v += Vec3(0.0, 0.0, 50.0);
  const Camera cam = ahead_from(Vec3(0.0));
  const std::vector<ObjectDesc> in_view = {mesh_object(1, off, Vec3(0.0, 0.0, -60.0))};   // Triangles at z = -10.
  const std::vector<ObjectDesc> out_of_view = {mesh_object(1, off, Vec3(0.0, 0.0, -10.0))};  // At z = +40.
  EXPECT_EQ(frustum_objects(in_view, cam), (Ids{1}));
  EXPECT_EQ(visible_objects(in_view, cam), (Ids{1}));
  EXPECT_TRUE(frustum_objects(out_of_view, cam).empty());
  EXPECT_TRUE(visible_objects(out_of_view, cam).empty());

  // A mesh wall stops the rays as a box wall does: the same voxels in view.
  const std::vector<ObjectDesc> box_wall = {box_around(1, Vec3(0.0, 0.0, -6.0), Vec3(20.0, 20.0, 0.25))};
  const std::vector<ObjectDesc> mesh_wall = {mesh_object(1, cube_mesh(Vec3(20.0, 20.0, 0.25)), Vec3(0.0, 0.0, -6.0))};
  const Vec3 lo(-16.0), hi(16.0);
  const glm::ivec3 res(16);
  const std::size_t open = voxels_in_view({}, cam, lo, hi, res, pixel_centres(32, 32));
  const std::size_t walled = voxels_in_view(box_wall, cam, lo, hi, res, pixel_centres(32, 32));
  EXPECT_LT(walled, open);
  EXPECT_EQ(voxels_in_view(mesh_wall, cam, lo, hi, res, pixel_centres(32, 32)), walled);
}

TEST(RaycastMesh, ConfirmsAndDismissesMeshesNearPixels) {
  const Camera cam = ahead_from(Vec3(0.0));
  const std::vector<ObjectDesc> objs = {mesh_object(1, icosphere(2), Vec3(0.0, 0.0, -6.0)),
                                        mesh_object(2, icosphere(2), Vec3(0.0, 0.0, -12.0), Quat(1, 0, 0, 0), 0.5)};
  Ids confirmed, dismissed;
  confirm_near_pixels(objs, cam, 40, 40, {}, {1, 2}, &confirmed, &dismissed);
  EXPECT_EQ(confirmed, (Ids{1}));
  EXPECT_EQ(dismissed, (Ids{2}));
}

// --- the meshes' hierarchies -------------------------------------------------

Ids brute_force(const std::vector<ObjectDesc>& objects, const Camera& cam, const RaySampling& s) {
  CastOptions o;
  o.threads = 1;
  o.brute_force = true;
  return visible_objects(objects, cam, s, o);
}

TEST(RaycastMesh, HierarchiesEqualBruteForceOnMeshScenes) {
  // Random scenes of balls and boxes with meshes among them (closed balls,
  // cubes and soups of crossing triangles, randomly placed, some sharing a
  // mesh), under random cameras with their hard cases: every triangle
  // tested on every ray gives the same answer.
  CameraPathParams hard;
  hard.frames = 3;
  hard.snap_eye_chance = 0.4;
  hard.axis_dir_chance = 0.3;
  hard.extreme_lens_chance = 0.2;
  const std::shared_ptr<const Mesh> shapes[] = {icosphere(1), cube_mesh(Vec3(1.0, 0.5, 0.25)), triangle_soup(40, 3)};
  std::size_t visible_meshes = 0;
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(scaled(6)); ++seed) {
    RandomSceneParams params = random_scene_params(seed);
    params.spheres = 40;
    params.boxes = 20;
    SceneDesc scene = random_scene(params, seed);
    Rng rng(mix_seed(seed, 5));
    const Vec3 extent = scene.bounds_max - scene.bounds_min;
    for (ObjectId k = 0; k < 30; ++k) {
      const Vec3 axis = rng.unit_vector();
      scene.objects.push_back(mesh_object(1000000 + k, shapes[k % 3], rng.in_box(scene.bounds_min, scene.bounds_max),
                                          rotation_about(axis, rng.uniform(-3.0, 3.0)),
                                          rng.uniform(0.01, 0.08) * glm::length(extent)));
    }
    for (const Camera& cam : random_camera_path(scene, mix_seed(seed, 9), hard)) {
      RaySampling s;
      s.cols = 32;
      s.rows = 24;
      s.corners = true;
      s.seed = seed;
      const Ids want = brute_force(scene.objects, cam, s);
      CastOptions three;
      three.threads = 3;
      CastStats st;
      const Ids fast = visible_objects(scene.objects, cam, s, three, &st);
      EXPECT_EQ(fast, want) << describe_scene(scene, seed) << " " << describe(cam)
                            << "\n  only the hierarchy's: " << describe_ids(missing_ids(want, fast))
                            << "\n  only brute force's: " << describe_ids(missing_ids(fast, want));
      visible_meshes += static_cast<std::size_t>(
          std::count_if(want.begin(), want.end(), [](ObjectId id) { return id >= 1000000; }));
    }
  }
  EXPECT_GT(visible_meshes, 10u);  // Not a comparison of sets without meshes.
}

TEST(RaycastMesh, ManyTrianglesAnswerQuicklyAndAreBuiltOnce) {
  // About 80,000 triangles, placed twice and filling the view: one
  // hierarchy, built by the first call and kept for the next; each ray
  // tests a few dozen triangles where brute force would test all of them.
  const auto ball = icosphere(6);
  ASSERT_EQ(ball->triangles.size(), 81920u);
  const std::vector<ObjectDesc> objs = {
      mesh_object(1, ball, Vec3(0.0, 0.0, -6.0), rotation_about(Vec3(0, 1, 0), 0.3), 1.0),
      mesh_object(2, ball, Vec3(1.0, 0.5, -10.0), Quat(1, 0, 0, 0), 2.0),
      sphere(3, Vec3(0.0, 0.0, -20.0), 1.0)};  // Hidden.
  const Camera cam = camera_along(Vec3(0.0), Vec3(0.0, 0.0, -1.0), 30.0, 1.0, 0.1, 100.0);
  RaySampling s;
  s.cols = 128;
  s.rows = 128;
  CastStats first, again;
  const Ids ids = visible_objects(objs, cam, s, {}, &first);
  EXPECT_EQ(ids, (Ids{1, 2}));
  EXPECT_EQ(first.meshes_built, 1u);
  EXPECT_EQ(visible_objects(objs, cam, s, {}, &again), ids);
  EXPECT_EQ(again.meshes_built, 0u);
  const double per_ray = static_cast<double>(again.triangle_tests) / static_cast<double>(again.rays);
  EXPECT_GT(per_ray, 0.5);  // Many rays meet a mesh.
  EXPECT_LT(per_ray, 100.0);
  RecordProperty("first_build_ms", std::to_string(first.build_ms));
  RecordProperty("cast_ms", std::to_string(again.cast_ms));
  RecordProperty("tests_per_ray", std::to_string(per_ray));
}

}  // namespace
}  // namespace voxvis::test
