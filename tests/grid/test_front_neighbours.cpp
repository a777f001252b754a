// Voxels and small static objects hidden by the static opaque voxels beside
// them on the eye's side (Traversal::front_blocked, docs/design.md "Front
// neighbours"). Every frame goes through EngineHarness: zero misses against
// the ray caster (visible: the first hit on rays of positive measure).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "engine_check.h"
#include "raycast.h"
#include "scenes.h"
#include "voxvis/scene.h"

namespace voxvis::test {
namespace {

using Ids = std::vector<ObjectId>;

Camera looking(Vec3 eye, Vec3 at, double fov = 70.0) { return camera_along(eye, at - eye, fov, 16.0 / 9.0, 0.01); }

bool contains(const Ids& v, ObjectId id) { return std::binary_search(v.begin(), v.end(), id); }

/// Ground of unit blocks, n x 2 x n (two layers), on a grid of unit voxels
/// with room above; returns the id of block (x, y, z).
struct Ground {
  SceneDesc scene;
  int n = 10;
  ObjectId id(int x, int y, int z) const { return static_cast<ObjectId>(1 + x + n * (y + 2 * z)); }
};

Ground make_ground(int n) {
  Ground g;
  g.n = n;
  g.scene.bounds_min = Vec3(0.0);
  g.scene.bounds_max = Vec3(n, 8.0, n);
  g.scene.grid = glm::ivec3(n, 8, n);
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < 2; ++y)
      for (int x = 0; x < n; ++x)
        g.scene.objects.push_back(box_between(g.id(x, y, z), Vec3(x, y, z), Vec3(x + 1, y + 1, z + 1)));
  std::sort(g.scene.objects.begin(), g.scene.objects.end(),
            [](const ObjectDesc& a, const ObjectDesc& b) { return a.id < b.id; });
  return g;
}

TEST(FrontNeighbours, BlocksUnderTheGroundAreHidden) {
  // The lower layer touches the upper layer's voxels, which the traversal
  // reaches; every lower block but the row at the ground's near edge (whose
  // neighbour towards the eye lies beyond the grid) has opaque neighbours on
  // the eye's side, so none of those may be in the PVS, with or without
  // the occlusion buffer.
  const Ground g = make_ground(10);
  for (int ob : {0, 128}) {
    SceneOptions o;
    o.occlusion_buffer = ob;
    EngineHarness h(g.scene, o, "ground ob=" + std::to_string(ob));
    ASSERT_TRUE(h.status().ok) << h.status().str();
    const Camera cam = looking(Vec3(5.3, 6.7, -4.0), Vec3(5.0, 0.0, 6.0));
    const std::string err = h.frame(cam, 0.0);
    ASSERT_TRUE(err.empty()) << err;
    const Ids& pvs = h.last().pvs;
    int lower_edge = 0;
    for (int z = 0; z < g.n; ++z)
      for (int x = 0; x < g.n; ++x) {
        if (z >= 1) {
          EXPECT_FALSE(contains(pvs, g.id(x, 0, z))) << "lower block " << x << ", " << z << " ob=" << ob;
        }
        if (z == 0 && contains(pvs, g.id(x, 0, z))) ++lower_edge;
      }
    EXPECT_GT(lower_edge, 0) << "the near edge's lower blocks show their sides";
    EXPECT_GT(h.last().stats.front_objects_culled, 0u);
  }
}

TEST(FrontNeighbours, EyeOnVoxelPlanesStaysConservative) {
  // Eyes exactly on voxel planes (one, two and three axes), looking along
  // axes and diagonals: the rule cannot tell the eye's side there and must
  // not guess. Zero misses with the corner rays the harness casts.
  const Ground g = make_ground(8);
  EngineHarness h(g.scene, buffer_off(), "ground, eye on planes");
  ASSERT_TRUE(h.status().ok);
  int f = 0;
  for (const Vec3 eye : {Vec3(4.0, 3.0, -2.0), Vec3(4.0, 2.0, -2.5), Vec3(3.0, 2.0, 1.0), Vec3(0.0, 2.0, 0.0),
                         Vec3(4.5, 2.0, 4.5)})
    for (const Vec3 at : {Vec3(4.0, 0.0, 4.0), Vec3(8.0, 0.0, 8.0), Vec3(0.0, 0.0, 8.0), Vec3(4.0, 0.0, 8.0)}) {
      if (at.x == eye.x && at.z == eye.z) continue;
      const std::string err = h.frame(looking(eye, at, 90.0), 0.1 * f++);
      ASSERT_TRUE(err.empty()) << err;
    }
}

TEST(FrontNeighbours, ATieAlongAnEdgeIsNotVisible) {
  // Block A = (0,0,0) has opaque neighbours B = (1,0,0) and C = (0,1,0) and
  // air at (1,1,0). Seen from (3.5, 3.5, 0.5) straight down the diagonal,
  // the centre ray meets A, B and C together on their common edge: a tie on
  // a set of rays of measure zero. Every ray beside it meets B or C first,
  // so A is not visible (raycast.h) and the rule drops it.
  SceneDesc s;
  s.bounds_min = Vec3(0.0);
  s.bounds_max = Vec3(4.0);
  s.grid = glm::ivec3(4);
  s.objects = {box_between(1, Vec3(0, 0, 0), Vec3(1, 1, 1)), box_between(2, Vec3(1, 0, 0), Vec3(2, 1, 1)),
               box_between(3, Vec3(0, 1, 0), Vec3(1, 2, 1)), box_between(4, Vec3(2, 0, 0), Vec3(3, 1, 1)),
               box_between(5, Vec3(0, 2, 0), Vec3(1, 3, 1))};
  Camera cam;
  cam.eye = Vec3(3.5, 3.5, 0.5);
  cam.dir = Vec3(-1.0, -1.0, 0.0);
  cam.up = Vec3(0.0, 0.0, 1.0);
  cam.fov_y_deg = 30.0;
  cam.aspect = 1.0;
  cam.near = 0.01;
  cam.far = 100.0;
  ASSERT_TRUE(contains(first_hit(s.objects, cam, 0.0, 0.0), 1)) << "the centre ray ties on the edge";
  for (const double a : {0.0, 0.4, 1.3, 2.9, 4.4}) {
    const Ids beside = first_hit(s.objects, cam, 1e-6 * std::cos(a), 1e-6 * std::sin(a));
    EXPECT_FALSE(contains(beside, 1)) << "a ray beside the edge at angle " << a << ": " << describe_ids(beside);
  }
  for (int ob : {0, 64}) {
    SceneOptions o;
    o.occlusion_buffer = ob;
    EngineHarness h(s, o, "edge tie ob=" + std::to_string(ob));
    ASSERT_TRUE(h.status().ok);
    const std::string err = h.frame(cam, 0.0);
    ASSERT_TRUE(err.empty()) << err;
    EXPECT_FALSE(contains(h.last().pvs, 1)) << "ob=" << ob;
    EXPECT_TRUE(contains(h.last().pvs, 2) && contains(h.last().pvs, 3)) << "ob=" << ob;
  }
}

TEST(FrontNeighbours, VoxelWorldZeroMissesAndTighter) {
  // The voxel world's surface and cave paths: zero misses, and the rule
  // removes blocks under the surface that touch voxels in view.
  for (bool cave : {false, true}) {
    const ScenePath p = make_voxel_world(32, std::max(4, scaled(12)), cave, 5);
    EngineHarness h(p.scene, buffer_off(), cave ? "voxel world, cave" : "voxel world, surface");
    ASSERT_TRUE(h.status().ok);
    std::uint64_t culled = 0;
    for (std::size_t f = 0; f < p.cameras.size(); ++f) {
      const std::string err = h.frame(p.cameras[f], static_cast<double>(f) / 60.0);
      ASSERT_TRUE(err.empty()) << err;
      culled += h.last().stats.front_objects_culled;
    }
    EXPECT_GT(culled, 0u) << (cave ? "cave" : "surface");
  }
}

}  // namespace
}  // namespace voxvis::test
