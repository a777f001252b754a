// The hard cases of meshes, each against the ray caster (zero misses), with
// the occlusion buffer on and off: walls of many thin triangles, slits
// between meshes, meshes crossing the near plane, meshes with holes, and
// mesh scenes at huge and tiny scales and far from the origin.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "engine_check.h"
#include "meshes.h"
#include "scenes.h"
#include "voxvis/scene.h"

namespace voxvis::test {
namespace {

/// A square wall in the plane z = 0 of its model frame, [-1, 1]^2, as a
/// fan of `n` slivers from one corner; with `slit` > 0, two such walls side
/// by side (x < -slit/2 and x > slit/2) leaving a slit between them.
std::shared_ptr<const Mesh> sliver_wall(int n, double slit) {
  auto m = std::make_shared<Mesh>();
  auto fan = [&](double x0, double x1) {
    const auto base = static_cast<std::uint32_t>(m->vertices.size());
    m->vertices.push_back(Vec3(x0, -1.0, 0.0));
    // The far sides, corner to corner, split into n steps.
    for (int k = 0; k <= n; ++k) {
      const double s = static_cast<double>(k) / n;
      m->vertices.push_back(s <= 0.5 ? Vec3(x1, -1.0 + 4.0 * s, 0.0) : Vec3(x1 - (x1 - x0) * (2.0 * s - 1.0), 1.0, 0.0));
    }
    for (int k = 0; k < n; ++k)
      m->triangles.push_back({base, base + 1 + static_cast<std::uint32_t>(k), base + 2 + static_cast<std::uint32_t>(k)});
  };
  if (slit > 0.0) {
    fan(-1.0, -0.5 * slit);
    fan(0.5 * slit, 1.0);
  } else {
    fan(-1.0, 1.0);
  }
  return m;
}

/// A scene of `meshes` and spheres of radius `r` scattered over the bounds
/// [0, 32]^3, all scaled by `scale` and moved by `offset`.
SceneDesc scene_of(const std::vector<ObjectDesc>& meshes, double scale, const Vec3& offset, std::uint64_t seed) {
  SceneDesc d;
  d.bounds_min = offset;
  d.bounds_max = offset + Vec3(32.0 * scale);
  d.grid = glm::ivec3(32);
  Rng rng(seed);
  for (ObjectDesc o : meshes) {
    o.center = offset + o.center * scale;
    o.scale *= scale;
    d.objects.push_back(o);
  }
  for (int k = 0; k < 40; ++k)
    d.objects.push_back(sphere(static_cast<ObjectId>(100 + k), offset + rng.in_box(Vec3(1.0), Vec3(31.0)) * scale,
                               rng.uniform(0.2, 1.0) * scale));
  return d;
}

void check(const SceneDesc& d, std::uint64_t seed, const std::string& what, const CameraPathParams& params = {}) {
  for (int buffer : {160, 0}) {
    SceneOptions opt;
    opt.occlusion_buffer = buffer;
    const std::string label = what + (buffer ? " buffer on" : " buffer off");
    EngineHarness h(d, opt, label);
    ASSERT_TRUE(h.status().ok) << label << ": " << h.status().str();
    const std::vector<Camera> path = random_camera_path(d, seed, params);
    for (std::size_t k = 0; k < path.size(); ++k) {
      const std::string err = h.frame(path[k], 0.0);
      ASSERT_TRUE(err.empty()) << err;
    }
  }
}

TEST(MeshHardCases, WallsOfManyThinTriangles) {
  CameraPathParams few;
  few.frames = 12;
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(std::max(1, scaled(2))); ++seed) {
    Rng rng(seed);
    std::vector<ObjectDesc> walls;
    for (int k = 0; k < 4; ++k)
      walls.push_back(mesh_object(static_cast<ObjectId>(k + 1), sliver_wall(rng.uniform_int(50, 200), 0.0),
                                  rng.in_box(Vec3(8.0), Vec3(24.0)), rotation_about(rng.unit_vector(), rng.uniform(0.0, 6.3)),
                                  rng.uniform(4.0, 12.0)));
    check(scene_of(walls, 1.0, Vec3(0.0), seed), seed, "sliver walls seed " + std::to_string(seed), few);
    if (HasFatalFailure()) return;
  }
}

TEST(MeshHardCases, SlitsBetweenMeshes) {
  // Walls split by slits from a hundredth of a voxel to half a voxel, on and
  // off voxel planes, with the spheres behind them; cameras along the view
  // through the slit and at random.
  for (double slit : {0.0006, 0.005, 0.03}) {
    std::vector<ObjectDesc> walls = {
        mesh_object(1, sliver_wall(20, slit), Vec3(16.0, 16.0, 16.0), Quat(1, 0, 0, 0), 16.0),
        mesh_object(2, sliver_wall(7, slit), Vec3(16.37, 16.0, 20.0), rotation_about(Vec3(0, 1, 0), 0.3), 15.0)};
    SceneDesc d = scene_of(walls, 1.0, Vec3(0.0), 7);
    d.objects.push_back(sphere(90, Vec3(16.0, 16.0, 28.0), 0.4));
    const std::string what = "slit " + std::to_string(slit);
    check(d, 11, what);
    if (HasFatalFailure()) return;
    for (int buffer : {160, 0}) {
      SceneOptions opt;
      opt.occlusion_buffer = buffer;
      EngineHarness h(d, opt, what);
      ASSERT_TRUE(h.status().ok);
      for (double x : {15.99, 16.0, 16.003}) {
        const std::string err = h.frame(camera_along(Vec3(x, 16.0, 2.0), Vec3(0.0, 0.0, 1.0), 20.0), 0.0);
        ASSERT_TRUE(err.empty()) << err;
      }
    }
  }
}

TEST(MeshHardCases, MeshesCrossingTheNearPlaneAndHoles) {
  // Closed and open meshes (a cube with a triangle missing: what is inside
  // shows through the hole), large near planes that cut into them, eyes
  // right beside their faces.
  auto holed = std::make_shared<Mesh>(*cube_mesh(Vec3(1.0)));
  holed->triangles.erase(holed->triangles.begin() + 4);
  std::vector<ObjectDesc> meshes = {mesh_object(1, holed, Vec3(10.0, 16.0, 16.0), rotation_about(Vec3(1, 1, 0), 0.4), 5.0),
                                    mesh_object(2, cube_mesh(Vec3(1.0, 0.5, 2.0)), Vec3(22.0, 16.0, 16.0), Quat(1, 0, 0, 0), 4.0),
                                    mesh_object(3, icosphere(2), Vec3(16.0, 26.0, 12.0), Quat(1, 0, 0, 0), 5.0)};
  SceneDesc d = scene_of(meshes, 1.0, Vec3(0.0), 3);
  for (int k = 0; k < 4; ++k) d.objects.push_back(sphere(static_cast<ObjectId>(80 + k), Vec3(10.0 + 0.5 * k, 16.0, 16.0), 0.5));
  CameraPathParams near;
  near.near_min = 0.02;
  near.near_max = 0.3;
  check(d, 5, "near planes", near);
  if (HasFatalFailure()) return;
  for (int buffer : {160, 0}) {
    SceneOptions opt;
    opt.occlusion_buffer = buffer;
    EngineHarness h(d, opt, "beside faces");
    ASSERT_TRUE(h.status().ok);
    Rng rng(8);
    for (int k = 0; k < 12; ++k) {
      Camera c = camera_along(Vec3(22.0 + 4.0 * (k % 2 ? 1.0 : -1.0) * 1.0001, 16.0 + rng.uniform(-1.0, 1.0), 16.0),
                              rng.unit_vector(), rng.uniform(40.0, 150.0));
      c.near = rng.log_uniform(1e-3, 3.0);
      const std::string err = h.frame(c, 0.0);
      ASSERT_TRUE(err.empty()) << err;
    }
  }
}

TEST(MeshHardCases, HugeAndTinyScalesFarFromTheOrigin) {
  Rng rng(21);
  for (double scale : {1e-6, 1e6})
    for (const Vec3& offset : {Vec3(0.0), Vec3(1e5 * scale, -3e4 * scale, 5e4 * scale)}) {
      std::vector<ObjectDesc> meshes;
      for (int k = 0; k < 5; ++k)
        meshes.push_back(mesh_object(static_cast<ObjectId>(k + 1), k % 2 ? icosphere(1) : sliver_wall(30, 0.0),
                                     rng.in_box(Vec3(8.0), Vec3(24.0)), rotation_about(rng.unit_vector(), rng.uniform(0.0, 6.3)),
                                     rng.uniform(3.0, 8.0)));
      check(scene_of(meshes, scale, offset, 9), 13, "scale " + std::to_string(scale) + " offset " + std::to_string(offset.x));
      if (HasFatalFailure()) return;
    }
}

}  // namespace
}  // namespace voxvis::test
