// The headless renderer on triangle meshes (render/src/mesh_pass.cpp): a mesh
// is drawn as its triangles, placed by centre, rotation and scale, and
// occludes and shows as the CPU ray caster says at the same pixel centres;
// the refinement levels keep the meshes that show. Low resolutions, few
// frames (llvmpipe).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <map>
#include <memory>
#include <numbers>
#include <set>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "meshes.h"
#include "raycast.h"
#include "scenes.h"
#include "voxvis/mesh.h"
#include "voxvis/refine.h"
#include "render_check.h"
#include "voxvis/render.h"

namespace voxvis::test {
namespace {

using render::Method;
using render::Renderer;
using render::VisibleOptions;
using render::VisibleStats;
using Ids = std::vector<ObjectId>;

/// The visible set by `method` at w x h; the id image in `image` (Ids only).
Ids render_set(Renderer& r, const std::vector<ObjectDesc>& objects, const Camera& cam, int w, int h, Method method,
               std::vector<ObjectId>* image = nullptr) {
  Ids out;
  VisibleStats st;
  std::string error;
  VisibleOptions o{w, h, method};
  EXPECT_TRUE(r.visible(objects, cam, o, nullptr, &out, &st, &error)) << error;
  if (image) *image = r.last_ids();
  return out;
}

/// Pixels whose id (last_ids order: row 0 at the bottom; 0 where nothing
/// shows, or object 0) is not among the caster's first hits at that pixel
/// centre; `seen_only` counts, per object,
/// the pixels where one side sees it and the other does not.
int disagreements(const std::vector<ObjectId>& gpu, const std::vector<ObjectDesc>& objects, const Camera& cam,
                  int w, int h, std::map<ObjectId, int>* seen_only = nullptr) {
  int differ = 0;
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i) {
      const ObjectId id = gpu[static_cast<std::size_t>(j) * static_cast<std::size_t>(w) + static_cast<std::size_t>(i)];
      const Ids hits = first_hit(objects, cam, -1.0 + (2.0 * i + 1.0) / w, -1.0 + (2.0 * j + 1.0) / h);
      // 0 is nothing, or an object of id 0.
      const bool ok = (id == 0 && hits.empty()) || std::find(hits.begin(), hits.end(), id) != hits.end();
      if (ok) continue;
      ++differ;
      if (!seen_only) continue;
      if (id != 0) ++(*seen_only)[id];
      for (ObjectId c : hits) ++(*seen_only)[c];
    }
  return differ;
}

TEST(RenderMesh, MeshCubeOccludesLikeABox) {
  VOXVIS_RENDERER_OR_SKIP(r, render::Platform::Auto);
  const Vec3 c(0.3, -0.2, -6.0), half(1.1, 0.9, 0.7);
  const std::vector<ObjectDesc> rest = {sphere(2, Vec3(0.3, -0.2, -12.0), 1.5),  // Behind: hidden.
                                        sphere(3, Vec3(1.6, 0.4, -10.0), 1.0)};  // Behind, off to a side: shows.
  std::vector<ObjectDesc> with_box = rest, with_mesh = rest;
  with_box.push_back(box_around(1, c, half));
  with_mesh.push_back(mesh_object(1, cube_mesh(half), c));
  const Camera cam = camera_along(Vec3(0.0), Vec3(0, 0, -1), 60.0, 4.0 / 3.0, 0.1, 100.0);
  for (const Method m : {Method::Ids, Method::Queries}) {
    EXPECT_EQ(render_set(*r, with_box, cam, 64, 48, m), (Ids{1, 3}));
    EXPECT_EQ(render_set(*r, with_mesh, cam, 64, 48, m), (Ids{1, 3}));
  }
  std::vector<ObjectId> box_image, mesh_image;
  render_set(*r, with_box, cam, 64, 48, Method::Ids, &box_image);
  render_set(*r, with_mesh, cam, 64, 48, Method::Ids, &mesh_image);
  int differ = 0, on_cube = 0;
  for (std::size_t p = 0; p < box_image.size(); ++p) {
    differ += box_image[p] != mesh_image[p] ? 1 : 0;
    on_cube += mesh_image[p] == 1 ? 1 : 0;
  }
  EXPECT_LE(differ, 2);  // Pixel centres within single-precision rounding of an edge.
  EXPECT_GT(on_cube, 100);
  EXPECT_LE(disagreements(mesh_image, with_mesh, cam, 64, 48), 2);
}

TEST(RenderMesh, AMeshSeenThroughASlitIsFound) {
  // A wall at z = -10 with a vertical slit about 1.7 pixels wide; behind it
  // a mesh ball, seen only through the slit, and a ball hidden by the wall.
  // The wall as two boxes, then as one flat mesh of two rectangles.
  VOXVIS_RENDERER_OR_SKIP(r, render::Platform::Auto);
  constexpr int kW = 64, kH = 48;
  const Camera cam = camera_along(Vec3(0.0), Vec3(0, 0, -1), 60.0, static_cast<double>(kW) / kH, 0.1, 100.0);
  auto flat = std::make_shared<Mesh>();
  flat->vertices = {Vec3(-50, -50, 0), Vec3(-0.2, -50, 0), Vec3(-0.2, 50, 0), Vec3(-50, 50, 0),
                    Vec3(0.2, -50, 0), Vec3(50, -50, 0),   Vec3(50, 50, 0),   Vec3(0.2, 50, 0)};
  flat->triangles = {{0, 1, 2}, {0, 2, 3}, {4, 5, 6}, {4, 6, 7}};
  const std::vector<ObjectDesc> behind = {
      mesh_object(5, icosphere(3), Vec3(0.0, 1.0, -20.0), rotation_about(Vec3(1, 1, 0), 0.4), 2.0),
      sphere(6, Vec3(6.0, 0.0, -20.0), 1.0)};
  const std::vector<std::vector<ObjectDesc>> walls = {
      {box_between(1, Vec3(-50, -50, -10.5), Vec3(-0.2, 50, -10)), box_between(2, Vec3(0.2, -50, -10.5), Vec3(50, 50, -10))},
      {mesh_object(1, flat, Vec3(0.0, 0.0, -10.0))}};
  for (const auto& wall : walls) {
    std::vector<ObjectDesc> objects = wall;
    objects.insert(objects.end(), behind.begin(), behind.end());
    const Ids want = raycast::visible_objects(objects, cam, pixel_centres(kW, kH));
    ASSERT_TRUE(std::binary_search(want.begin(), want.end(), ObjectId{5}));
    ASSERT_FALSE(std::binary_search(want.begin(), want.end(), ObjectId{6}));
    for (const Method m : {Method::Ids, Method::Queries}) {
      EXPECT_EQ(render_set(*r, objects, cam, kW, kH, m), want) << wall.size() << " wall objects";
    }
    std::vector<ObjectId> image;
    render_set(*r, objects, cam, kW, kH, Method::Ids, &image);
    EXPECT_GE(std::count(image.begin(), image.end(), ObjectId{5}), 8);  // Two columns of the ball's rows.
    EXPECT_LE(disagreements(image, objects, cam, kW, kH), 2);
  }
}

TEST(RenderMesh, RotatedAndMovedMeshesRenderAsTheCasterSees) {
  // A thin plate hides a ball; turned edge on (a move with a rotation) it
  // uncovers it. Then the same, rotated about a slanted axis, scaled, and
  // the whole scene moved 3e7 away: the id image stays (coordinates go
  // relative to the eye in double before they are rounded to float).
  VOXVIS_RENDERER_OR_SKIP(r, render::Platform::Auto);
  constexpr int kW = 48, kH = 48;
  const Camera cam = camera_along(Vec3(0.0), Vec3(0, 0, -1), 60.0, 1.0, 0.1, 100.0);
  std::vector<ObjectDesc> objects = {mesh_object(1, cube_mesh(Vec3(3.0, 3.0, 0.05)), Vec3(0.0, 0.0, -5.0)),
                                     sphere(2, Vec3(0.0, 0.0, -10.0), 0.6)};
  objects[0].dynamic = true;
  EXPECT_EQ(render_set(*r, objects, cam, kW, kH, Method::Ids), (Ids{1}));
  apply_moves_to(&objects, {Move{1, Vec3(0.0, 0.0, -5.0), true, rotation_about(Vec3(0, 1, 0), std::numbers::pi / 2)}});
  std::vector<ObjectId> image;
  EXPECT_EQ(render_set(*r, objects, cam, kW, kH, Method::Ids, &image), (Ids{1, 2}));
  EXPECT_EQ(render_set(*r, objects, cam, kW, kH, Method::Queries), (Ids{1, 2}));
  EXPECT_LE(disagreements(image, objects, cam, kW, kH), 2);

  apply_moves_to(&objects, {Move{1, Vec3(0.5, -0.3, -6.0), true, rotation_about(Vec3(1, 2, 0.5), 0.9)}});
  objects[0].scale = 0.7;
  objects.push_back(mesh_object(3, icosphere(2), Vec3(-2.0, 1.0, -8.0), rotation_about(Vec3(0, 0, 1), 1.1), 1.5));
  std::vector<ObjectId> home;
  const Ids seen = render_set(*r, objects, cam, kW, kH, Method::Ids, &home);
  EXPECT_EQ(seen, raycast::visible_objects(objects, cam, pixel_centres(kW, kH)));
  EXPECT_LE(disagreements(home, objects, cam, kW, kH), 3);
  SceneDesc scene;
  scene.objects = objects;
  const Vec3 offset(3e7, -2e7, 1e7);
  const SceneDesc moved = transform_scene(scene, 1.0, offset);
  EXPECT_EQ(render_set(*r, moved.objects, transform_camera(cam, 1.0, offset), kW, kH, Method::Ids, &image), seen);
  int differ = 0;
  for (std::size_t p = 0; p < home.size(); ++p) differ += home[p] != image[p] ? 1 : 0;
  EXPECT_LE(differ, 3);
}

TEST(RenderMesh, AgreesWithTheRayCasterOnMeshScenes) {
  // Random scenes of balls and boxes with meshes among them (closed balls,
  // cubes, soups of crossing triangles; rotated, scaled, some sharing a
  // mesh) under random cameras: the GPU's first hit at every pixel centre
  // is one of the caster's, but for a few pixels where single precision
  // grazes an edge or orders a near tie.
  VOXVIS_RENDERER_OR_SKIP(r, render::Platform::Auto);
  constexpr int kW = 80, kH = 45;
  const std::shared_ptr<const Mesh> shapes[] = {icosphere(2), cube_mesh(Vec3(1.0, 0.5, 0.25)), triangle_soup(40, 3)};
  int pixels = 0, differ = 0, mesh_pixels = 0;
  for (std::uint64_t seed = 1; seed <= 3; ++seed) {
    RandomSceneParams params = random_scene_params(seed);
    params.spheres = 40;
    params.boxes = 20;
    SceneDesc scene = random_scene(params, seed);
    Rng rng(mix_seed(seed, 5));
    const double size = glm::length(scene.bounds_max - scene.bounds_min);
    for (ObjectId k = 0; k < 40; ++k)
      scene.objects.push_back(mesh_object(1000000 + k, shapes[k % 3], rng.in_box(scene.bounds_min, scene.bounds_max),
                                          rotation_about(rng.unit_vector(), rng.uniform(-3.0, 3.0)),
                                          rng.uniform(0.01, 0.08) * size));
    const std::vector<Camera> path = random_camera_path(scene, mix_seed(seed, 9));
    for (std::size_t f = 0; f < path.size(); f += 12) {
      std::vector<ObjectId> image;
      render_set(*r, scene.objects, path[f], kW, kH, Method::Ids, &image);
      std::map<ObjectId, int> seen_only;
      const int d = disagreements(image, scene.objects, path[f], kW, kH, &seen_only);
      const std::string where = describe_scene(scene, seed) + " frame " + std::to_string(f);
      EXPECT_LE(d, std::max(2, kW * kH / 200)) << where;
      for (const auto& [id, n] : seen_only) {
        EXPECT_LE(n, 2) << where << ": object " << id << " seen by one side only";
      }
      pixels += kW * kH;
      differ += d;
      mesh_pixels += static_cast<int>(std::count_if(image.begin(), image.end(), [](ObjectId id) { return id >= 1000000; }));
    }
  }
  EXPECT_LE(differ, pixels / 500) << differ << " of " << pixels;
  RecordProperty("pixels_differing", std::to_string(differ) + " of " + std::to_string(pixels));
  EXPECT_GT(mesh_pixels, 200);  // Meshes were seen.
}

TEST(RenderMesh, RefinementKeepsTheMeshesThatShow) {
  // A mesh wall in front of a crowd of small meshes and balls, the PVS all
  // of them: every level keeps what shows; a query per object drops the
  // hidden ones.
  VOXVIS_RENDERER_OR_SKIP(r, render::Platform::Auto);
  constexpr int kW = 64, kH = 48;
  const Camera cam = camera_along(Vec3(0.0), Vec3(0, 0, -1), 60.0, static_cast<double>(kW) / kH, 0.1, 100.0);
  auto flat = std::make_shared<Mesh>();
  flat->vertices = {Vec3(-4, -3, 0), Vec3(4, -3, 0), Vec3(4, 3, 0), Vec3(-4, 3, 0)};
  flat->triangles = {{0, 1, 2}, {0, 2, 3}};
  std::vector<ObjectDesc> objects = {mesh_object(1, flat, Vec3(0.0, 0.0, -10.0), rotation_about(Vec3(0, 1, 0), 0.2))};
  const auto ball = icosphere(1);
  for (int i = 0; i < 120; ++i) {
    const auto id = static_cast<ObjectId>(i + 2);
    const Vec3 at(1.6 * (i % 15 - 7), 1.6 * (i / 15 - 4), -20.0 - i % 5);
    objects.push_back(i % 2 ? sphere(id, at, 0.4) : mesh_object(id, ball, at, rotation_about(at, 0.3 * i), 0.4));
  }
  Ids pvs;
  for (const ObjectDesc& o : objects) pvs.push_back(o.id);
  std::vector<ObjectId> image;
  const Ids exact = render_set(*r, objects, cam, kW, kH, Method::Ids, &image);
  ASSERT_GT(exact.size(), 10u);
  ASSERT_LT(exact.size(), pvs.size() - 20);
  render::CostModel model;
  std::string note, error;
  ASSERT_TRUE(r->cost_model(::testing::TempDir() + "mesh-cost-model.json", &model, &note, &error)) << error;
  Ids by_queries;
  for (const char* name : {"queries", "hierarchical", "lazy-grid", "ternary", "near-optimal"}) {
    render::Level l;
    std::string message;
    ASSERT_TRUE(render::parse_level(name, &l, &message)) << message;
    Ids out;
    render::RefineStats st;
    ASSERT_TRUE(r->refine(l, objects, cam, kW, kH, pvs, &out, &st, &error)) << error;
    EXPECT_TRUE(std::includes(out.begin(), out.end(), exact.begin(), exact.end()))
        << name << " dropped " << describe_ids(missing_ids(out, exact));
    if (l.kind == render::LevelKind::Queries) {
      by_queries = out;
      EXPECT_EQ(out, exact);
    } else {
      EXPECT_TRUE(std::includes(out.begin(), out.end(), by_queries.begin(), by_queries.end())) << name;
    }
    if (l.kind == render::LevelKind::Hierarchical) {
      EXPECT_EQ(out, by_queries);
    }
  }
}

}  // namespace
}  // namespace voxvis::test
