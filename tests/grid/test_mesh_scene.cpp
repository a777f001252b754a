// Meshes in the scene grid: the voxels a static mesh touches come from its
// triangles (never from its box alone), it is culled like any object, it
// adds no opacity and hides nothing, and a dynamic mesh moves and rotates
// under the same rules as the other objects (docs/design.md, "Meshes").
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <set>
#include <vector>

#include "engine_check.h"
#include "scene_impl.h"
#include "scenes.h"
#include "voxvis/mesh.h"
#include "voxvis/scene.h"

namespace voxvis::test {
namespace {

/// Slots of objects stored along voxel (x, y, z)'s chain of cells.
bool holds(const Scene::Impl& s, std::uint32_t slot, int x, int y, int z) {
  for (int l = 0; l < s.pyr.levels; ++l) {
    const detail::IdLists& lists = s.static_lists[static_cast<std::size_t>(l)];
    if (lists.offsets.empty()) continue;
    const int sh = detail::kCellShift * l;
    const std::size_t c = s.pyr.index(l, glm::ivec3(x >> sh, y >> sh, z >> sh));
    if (std::find(lists.begin(c), lists.end(c), slot) != lists.end(c)) return true;
  }
  return false;
}

ObjectDesc mesh_object(ObjectId id, std::vector<Vec3> vertices, std::vector<std::array<std::uint32_t, 3>> triangles) {
  auto m = std::make_shared<Mesh>();
  m->vertices = std::move(vertices);
  m->triangles = std::move(triangles);
  ObjectDesc o;
  o.id = id;
  o.shape = Shape::Mesh;
  o.mesh = std::move(m);
  return o;
}

/// A square of side 2h in the plane z = 0 of its model frame, two triangles.
ObjectDesc quad(ObjectId id, double h) {
  return mesh_object(id, {Vec3(-h, -h, 0), Vec3(h, -h, 0), Vec3(h, h, 0), Vec3(-h, h, 0)}, {{0, 1, 2}, {0, 2, 3}});
}


TEST(MeshScene, StaticMeshVoxelsComeFromItsTrianglesNotItsBox) {
  // A thin sliver along the grid's diagonal: its box is the whole grid, its
  // triangles touch a few voxels along the diagonal.
  SceneDesc d = unit_grid(20);
  ObjectDesc o = mesh_object(1, {Vec3(0.5, 0.5, 0.5), Vec3(19.5, 19.5, 19.5), Vec3(19.5, 19.6, 19.5)}, {{0, 1, 2}});
  o.center = Vec3(0.0);
  d.objects.push_back(o);
  std::unique_ptr<Scene> scene;
  ASSERT_TRUE(Scene::create(d, {}, &scene).ok);
  const Scene::Impl& s = scene->impl();
  // Every point of the triangle lies in a voxel that holds the mesh.
  const Vec3 a(0.5), b(19.5), c(19.5, 19.6, 19.5);
  std::set<std::int64_t> near;  // Voxels within 0.05 of a sampled point.
  for (int i = 0; i <= 400; ++i)
    for (int j = 0; i + j <= 400; ++j) {
      const double u = i / 400.0, v = j / 400.0;
      const Vec3 p = a + u * (b - a) + v * (c - a);
      const glm::ivec3 q = glm::min(glm::ivec3(glm::floor(p)), glm::ivec3(19));
      ASSERT_TRUE(holds(s, 0, q.x, q.y, q.z)) << p.x << "," << p.y << "," << p.z;
      for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const Vec3 r = p + 0.05 * Vec3(dx, dy, dz);
            const glm::ivec3 w = glm::ivec3(glm::floor(r));
            if (glm::all(glm::greaterThanEqual(w, glm::ivec3(0))) && glm::all(glm::lessThan(w, glm::ivec3(20))))
              near.insert(s.index(w.x, w.y, w.z));
          }
    }
  // And no voxel away from it holds it.
  int stored = 0;
  for (int z = 0; z < 20; ++z)
    for (int y = 0; y < 20; ++y)
      for (int x = 0; x < 20; ++x)
        if (holds(s, 0, x, y, z)) {
          ++stored;
          EXPECT_TRUE(near.count(s.index(x, y, z))) << x << "," << y << "," << z;
        }
  EXPECT_GE(stored, 20);
  EXPECT_LT(stored, 200);  // The box would be 8,000.
  // Its box is still what bounds it for culling.
  EXPECT_LE(s.objs[0].box_lo().x, 0.5);
  EXPECT_GE(s.objs[0].box_hi().y, 19.6);
  // The estimate bounds what was stored, from the triangles' sizes alone
  // (mesh_cost.h), within a small factor of it.
  SceneCost cost;
  ASSERT_TRUE(Scene::estimate(d, {}, &cost).ok);
  std::uint64_t entries = 0;
  for (int l = 0; l < s.pyr.levels; ++l) entries += s.static_lists[static_cast<std::size_t>(l)].ids.size();
  EXPECT_GE(cost.id_entries, entries);
  EXPECT_LE(cost.id_entries, 3 * entries);
}

TEST(MeshScene, PlacementAppliesToTheVoxels) {
  // The same square, rotated a quarter turn about x (into the plane y = 5)
  // and scaled 3x: it stands in the voxels around y = 5 only.
  SceneDesc d = unit_grid(20);
  ObjectDesc o = quad(1, 1.0);
  o.center = Vec3(10.0, 5.0, 10.0);
  o.scale = 3.0;
  o.rotation = Quat(std::sqrt(0.5), std::sqrt(0.5), 0.0, 0.0);
  d.objects.push_back(o);
  std::unique_ptr<Scene> scene;
  ASSERT_TRUE(Scene::create(d, {}, &scene).ok);
  const Scene::Impl& s = scene->impl();
  for (int z = 0; z < 20; ++z)
    for (int y = 0; y < 20; ++y)
      for (int x = 0; x < 20; ++x) {
        const bool expect = x >= 6 && x <= 13 && z >= 6 && z <= 13 && (y == 4 || y == 5);
        const bool clearly_out = x < 6 || x > 13 || z < 6 || z > 13 || y < 4 || y > 5;
        if (expect && !(x == 6 || x == 13 || z == 6 || z == 13)) {
          EXPECT_TRUE(holds(s, 0, x, y, z)) << x << "," << y << "," << z;
        }
        if (clearly_out) {
          EXPECT_FALSE(holds(s, 0, x, y, z)) << x << "," << y << "," << z;
        }
      }
}

TEST(MeshScene, CulledLikeAnyObjectAndHidesThroughTheBuffer) {
  SceneDesc d = unit_grid(32);
  // A wall of boxes across the view at z = 16 (voxels 15), a mesh behind it.
  d.objects.push_back(box_between(1, Vec3(0, 0, 15), Vec3(32, 32, 16)));
  ObjectDesc hidden = quad(2, 2.0);
  hidden.center = Vec3(16, 16, 24);
  d.objects.push_back(hidden);
  // A mesh square in front of the wall, a ball right behind the square.
  ObjectDesc screen = quad(3, 3.0);
  screen.center = Vec3(16, 16, 8);
  d.objects.push_back(screen);
  d.objects.push_back(sphere(4, Vec3(16, 16, 10), 1.0));
  for (int ob : {0, 160}) {
    SceneOptions opt;
    opt.occlusion_buffer = ob;
    std::unique_ptr<Scene> scene;
    ASSERT_TRUE(Scene::create(d, opt, &scene).ok);
    Scratch scratch;
    const ViewerId v = scene->add_viewer();
    FrameResult r;
    ASSERT_TRUE(scene->frame(v, camera_along(Vec3(16, 16, 1), Vec3(0, 0, 1), 60.0), 0.0, scratch, &r).ok);
    const auto has = [&](ObjectId id) { return std::binary_search(r.pvs.begin(), r.pvs.end(), id); };
    EXPECT_TRUE(has(1)) << ob;
    EXPECT_FALSE(has(2)) << "buffer " << ob << ": the wall hides the mesh behind it";
    EXPECT_TRUE(has(3)) << ob;
    // A mesh adds no opacity to the voxels, but its triangles occlude in
    // the buffer (the square's two as one quad, so no seam on its diagonal).
    EXPECT_EQ(has(4), ob == 0) << "buffer " << ob;
  }
}

TEST(MeshScene, BadMeshesAreRefusedNamingTheField) {
  SceneDesc d = unit_grid(8);
  ObjectDesc o = quad(1, 1.0);
  auto m = std::make_shared<Mesh>(*o.mesh);
  m->triangles[1][2] = 9;
  o.mesh = m;
  d.objects.push_back(sphere(5, Vec3(1), 0.5));
  d.objects.push_back(o);
  std::unique_ptr<Scene> scene;
  const Status s = Scene::create(d, {}, &scene);
  EXPECT_FALSE(s.ok);
  EXPECT_EQ(s.field, "objects[1].mesh.triangles[1]") << s.str();
  d.objects[1] = quad(1, 1.0);
  d.objects[1].rotation = Quat(2.0, 0.0, 0.0, 0.0);
  EXPECT_EQ(Scene::create(d, {}, &scene).field, "objects[1].rotation");
}

TEST(MeshScene, DynamicMeshMovesAndRotates) {
  SceneDesc d = unit_grid(32);
  d.objects.push_back(box_between(1, Vec3(0, 0, 15), Vec3(32, 32, 16)));
  ObjectDesc o = quad(2, 1.0);
  o.center = Vec3(16, 16, 24);
  o.dynamic = true;
  o.max_speed = 100.0;
  d.objects.push_back(o);
  d.objects.push_back(test::dynamic(sphere(3, Vec3(4, 4, 24), 0.5), 10.0));
  std::unique_ptr<Scene> scene;
  ASSERT_TRUE(Scene::create(d, {}, &scene).ok);
  Scratch scratch;
  const ViewerId v = scene->add_viewer();
  const Camera cam = camera_along(Vec3(16, 16, 1), Vec3(0, 0, 1), 60.0);
  FrameResult r;
  double t = 0.0;
  for (int k = 0; k < 5; ++k, t += 0.1) ASSERT_TRUE(scene->frame(v, cam, t, scratch, &r).ok);
  EXPECT_FALSE(std::binary_search(r.pvs.begin(), r.pvs.end(), ObjectId{2}));
  // Rotations: only for meshes, and unit.
  Move bad{3, Vec3(4, 4, 24), true, Quat(1, 0, 0, 0)};
  Status st = scene->apply_moves(t, std::vector<Move>{bad});
  EXPECT_EQ(st.field, "moves[0].rotation") << st.str();
  Move denorm{2, Vec3(16, 16, 24), true, Quat(1, 1, 0, 0)};
  st = scene->apply_moves(t, std::vector<Move>{denorm});
  EXPECT_EQ(st.field, "moves[0].rotation") << st.str();
  // Turned a quarter about y and brought in front of the wall.
  const Quat q(std::sqrt(0.5), 0.0, std::sqrt(0.5), 0.0);
  ASSERT_TRUE(scene->apply_moves(t, std::vector<Move>{Move{2, Vec3(16, 16, 8), true, q}}).ok);
  const std::vector<Move> now = scene->dynamic_centers();
  ASSERT_EQ(now.size(), 2u);
  EXPECT_EQ(now[0].id, 2u);
  EXPECT_EQ(now[0].center, Vec3(16, 16, 8));
  EXPECT_TRUE(now[0].has_rotation);
  EXPECT_NEAR(now[0].rotation.y, std::sqrt(0.5), 1e-15);
  EXPECT_FALSE(now[1].has_rotation);
  ASSERT_TRUE(scene->frame(v, cam, t, scratch, &r).ok);
  EXPECT_TRUE(std::binary_search(r.pvs.begin(), r.pvs.end(), ObjectId{2}));
  EXPECT_TRUE(std::binary_search(r.wake.begin(), r.wake.end(), ObjectId{2}));
  // A move whose centroid outruns max_speed is reported too fast.
  MoveReport report;
  ASSERT_TRUE(scene->apply_moves(t + 0.1, std::vector<Move>{Move{2, Vec3(16, 16, 4)}}, &report).ok);
  EXPECT_TRUE(report.too_fast.empty());
  ASSERT_TRUE(scene->apply_moves(t + 0.11, std::vector<Move>{Move{2, Vec3(16, 30, 4)}}, &report).ok);
  EXPECT_EQ(report.too_fast, std::vector<ObjectId>{2});
}

}  // namespace
}  // namespace voxvis::test

namespace voxvis::test {
namespace {

// dynamic_centers reports a mesh's rotation as given, before normalization,
// so that a scene created with it (a server resuming from its saved
// positions) places the mesh bit for bit as the scene that moved it.
TEST(MeshScene, DynamicCentersGiveTheRotationAsGiven) {
  SceneDesc d = unit_grid(16);
  ObjectDesc o = quad(2, 1.0);
  o.center = Vec3(8, 8, 8);
  o.rotation = Quat(std::cos(0.3), std::sin(0.3), 0.0, 0.0) * (1.0 - 8e-7);
  o.dynamic = true;
  o.max_speed = 100.0;
  d.objects.push_back(o);
  std::unique_ptr<Scene> scene;
  ASSERT_TRUE(Scene::create(d, {}, &scene).ok);
  std::vector<Move> now = scene->dynamic_centers();
  ASSERT_EQ(now.size(), 1u);
  EXPECT_TRUE(now[0].has_rotation);
  EXPECT_EQ(now[0].rotation, o.rotation) << "the created rotation, not its normalized form";
  const Quat q = Quat(std::cos(1.1), 0.0, std::sin(1.1), 0.0) * (1.0 + 9e-7);
  ASSERT_NE(unit_rotation(q), q) << "a rotation whose normalized form differs, or this checks nothing";
  ASSERT_TRUE(scene->apply_moves(0.5, std::vector<Move>{Move{2, Vec3(8, 8, 9), true, q}}).ok);
  now = scene->dynamic_centers();
  EXPECT_EQ(now[0].center, Vec3(8, 8, 9));
  EXPECT_EQ(now[0].rotation, q);
  // A move without a rotation keeps the last one given.
  ASSERT_TRUE(scene->apply_moves(0.6, std::vector<Move>{Move{2, Vec3(8, 8, 8)}}).ok);
  now = scene->dynamic_centers();
  EXPECT_EQ(now[0].rotation, q);
  // A scene created where dynamic_centers says places the mesh the same.
  d.objects[0].center = now[0].center;
  d.objects[0].rotation = now[0].rotation;
  std::unique_ptr<Scene> resumed;
  ASSERT_TRUE(Scene::create(d, {}, &resumed).ok);
  EXPECT_EQ(resumed->impl().objs[0].mesh_rotation, scene->impl().objs[0].mesh_rotation);
  EXPECT_EQ(resumed->impl().objs[0].center, scene->impl().objs[0].center);
}

// The estimate counts a mesh's vertices and triangles, once however many
// objects place it.
TEST(MeshScene, EstimateCountsEachMeshOnce) {
  // With the buffer off a mesh's bytes count once however many objects
  // place it; with it on, each static object also keeps its placed vertices
  // (the triangles it draws).
  const auto cost = [](int copies, std::size_t extra_vertices, int buffer = 0) {
    SceneDesc d = unit_grid(16);
    ObjectDesc q = quad(1, 0.5);
    auto m = std::make_shared<Mesh>(*q.mesh);
    for (std::size_t i = 0; i < extra_vertices; ++i) m->vertices.push_back(Vec3(0.25, 0.25, 0.0));
    for (int k = 0; k < copies; ++k) {
      ObjectDesc o = q;
      o.id = static_cast<ObjectId>(k + 1);
      o.mesh = m;
      o.center = Vec3(2.0 + k, 8, 8);
      d.objects.push_back(o);
    }
    SceneCost c;
    SceneOptions opt;
    opt.occlusion_buffer = buffer;
    EXPECT_TRUE(Scene::estimate(d, opt, &c).ok);
    return c.bytes;
  };
  constexpr std::size_t kExtra = 100000;  // Unused vertices: memory, no footprint.
  EXPECT_EQ(cost(1, kExtra) - cost(1, 0), kExtra * sizeof(Vec3));
  EXPECT_EQ(cost(5, kExtra) - cost(5, 0), kExtra * sizeof(Vec3));
  EXPECT_EQ(cost(5, kExtra, 160) - cost(5, 0, 160), 6 * kExtra * sizeof(Vec3));
}

}  // namespace
}  // namespace voxvis::test
