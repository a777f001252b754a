// Closed meshes' interiors (grid/src/mesh_interior.h, docs/design.md
// "Meshes"): which meshes are closed; every voxel the engine marks inside a
// closed mesh lies inside what its triangles enclose (points of the voxel
// against a ray-parity test of the triangles themselves, of the outer shell
// for a mesh with a cavity); interiors close the seams a
// wall of many triangles leaves in the occlusion buffer; and zero misses
// against the ray caster with the eye outside, on and inside closed meshes.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>
#include <tuple>

#include <glm/geometric.hpp>

#include "engine_check.h"
#include "mesh_interior.h"
#include "meshes.h"
#include "scenes.h"
#include "voxvis/inspect.h"
#include "voxvis/mesh.h"
#include "voxvis/scene.h"

namespace voxvis::test {
namespace {

/// The box [-half, half] with every face cut into n x n squares of two
/// triangles, vertices shared (closed), counter-clockwise seen from outside;
/// `inward` winds every triangle the other way.
std::shared_ptr<const Mesh> tiled_box(const Vec3& half, int n, bool inward = false) {
  auto m = std::make_shared<Mesh>();
  std::map<std::tuple<int, int, int>, std::uint32_t> index;
  auto vertex = [&](int i, int j, int k) {
    auto [it, fresh] = index.try_emplace({i, j, k}, static_cast<std::uint32_t>(m->vertices.size()));
    if (fresh) m->vertices.push_back(Vec3(i, j, k) / static_cast<double>(n) * 2.0 * half - half);
    return it->second;
  };
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side)
      for (int a = 0; a < n; ++a)
        for (int b = 0; b < n; ++b) {
          auto at = [&](int u, int v) {
            int c[3];
            c[axis] = side * n;
            c[(axis + 1) % 3] = u;
            c[(axis + 2) % 3] = v;
            return vertex(c[0], c[1], c[2]);
          };
          std::uint32_t q[4] = {at(a, b), at(a + 1, b), at(a + 1, b + 1), at(a, b + 1)};
          // (u, v) x (axis) is right-handed: counter-clockwise seen from +axis.
          const bool ccw = (side == 1) != inward;
          if (ccw) {
            m->triangles.push_back({q[0], q[1], q[2]});
            m->triangles.push_back({q[0], q[2], q[3]});
          } else {
            m->triangles.push_back({q[0], q[2], q[1]});
            m->triangles.push_back({q[0], q[3], q[2]});
          }
        }
  return m;
}

/// Whether p lies inside the placed triangles of `o`, by the parity of the
/// crossings of a ray in a direction no mesh here is aligned with.
bool inside_by_parity(const ObjectDesc& o, const Vec3& p) {
  const Vec3 d = glm::normalize(Vec3(0.5772156649, 0.3183098862, 0.7071067812 + 1e-3));
  int crossings = 0;
  for (const auto& t : o.mesh->triangles) {
    const Vec3 a = place(o, o.mesh->vertices[t[0]]), b = place(o, o.mesh->vertices[t[1]]),
               c = place(o, o.mesh->vertices[t[2]]);
    const Vec3 e1 = b - a, e2 = c - a, pv = glm::cross(d, e2);
    const double det = glm::dot(e1, pv);
    if (det == 0.0) continue;
    const Vec3 s = p - a;
    const double u = glm::dot(s, pv) / det;
    const Vec3 q = glm::cross(s, e1);
    const double v = glm::dot(d, q) / det, tt = glm::dot(e2, q) / det;
    if (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && tt > 0.0) ++crossings;
  }
  return crossings % 2 == 1;
}

/// The voxels the engine marks inside a closed mesh.
std::vector<glm::ivec3> inside_voxels(const Scene& scene) {
  std::vector<glm::ivec3> out;
  inspect_grid(scene, [&](const GridRow& r) {
    for (std::size_t x = 0; x < r.opaque.size(); ++x)
      if (r.opaque[x] & GridRow::kInsideMesh) out.emplace_back(static_cast<int>(x), r.y, r.z);
  });
  return out;
}

/// A hollow box: the outer box wound outwards, a box a third of its size
/// inside it wound inwards (the cavity's walls face into it). Closed.
std::shared_ptr<const Mesh> hollow_box(int n) {
  auto m = std::make_shared<Mesh>(*tiled_box(Vec3(1.0), n));
  const std::shared_ptr<const Mesh> inner = tiled_box(Vec3(0.45), n, true);
  const auto base = static_cast<std::uint32_t>(m->vertices.size());
  m->vertices.insert(m->vertices.end(), inner->vertices.begin(), inner->vertices.end());
  for (auto t : inner->triangles) m->triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
  return m;
}

TEST(MeshInterior, ClosedMeshesAreThoseWhoseSidesRunBothWaysOnce) {
  EXPECT_TRUE(detail::mesh_closed(*cube_mesh(Vec3(1.0))));
  EXPECT_TRUE(detail::mesh_closed(*icosphere(2)));
  EXPECT_TRUE(detail::mesh_closed(*tiled_box(Vec3(1.0), 3)));
  EXPECT_TRUE(detail::mesh_closed(*tiled_box(Vec3(1.0), 3, true)));
  EXPECT_TRUE(detail::mesh_closed(*hollow_box(2)));
  EXPECT_FALSE(detail::mesh_closed(*triangle_soup(12, 5)));
  // A cube missing a triangle, and one with a triangle turned over.
  auto open = std::make_shared<Mesh>(*cube_mesh(Vec3(1.0)));
  open->triangles.pop_back();
  EXPECT_FALSE(detail::mesh_closed(*open));
  auto flipped = std::make_shared<Mesh>(*cube_mesh(Vec3(1.0)));
  std::swap(flipped->triangles[0][1], flipped->triangles[0][2]);
  EXPECT_FALSE(detail::mesh_closed(*flipped));
}

TEST(MeshInterior, InteriorVoxelsLieInsideTheTriangles) {
  Rng rng(91);
  int checked = 0;
  for (int trial = 0; trial < scaled(24); ++trial) {
    SCOPED_TRACE("trial " + std::to_string(trial));
    SceneDesc d = unit_grid(32);
    std::shared_ptr<const Mesh> mesh;
    // What encloses the mesh's inside: the mesh itself, but for the hollow
    // box, whose cavity OpenVDB's flood fill (from the unbounded outside)
    // counts as inside too (design.md: enclosed space is what a ray from
    // outside reaches only through the surface) — its outer shell.
    std::shared_ptr<const Mesh> enclosure;
    switch (trial % 5) {
      case 4: {
        const int n = rng.uniform_int(1, 3);
        mesh = hollow_box(n);
        enclosure = tiled_box(Vec3(1.0), n);
        break;
      }
      case 0: mesh = icosphere(rng.uniform_int(1, 3)); break;
      case 1: mesh = cube_mesh(Vec3(rng.uniform(0.3, 1.0), rng.uniform(0.3, 1.0), rng.uniform(0.3, 1.0))); break;
      case 2: mesh = tiled_box(Vec3(1.0, rng.uniform(0.2, 1.0), 1.0), rng.uniform_int(2, 5)); break;
      default: mesh = tiled_box(Vec3(rng.uniform(0.3, 1.0), 1.0, 0.5), 3, true); break;  // Wound inwards.
    }
    const ObjectDesc o = mesh_object(1, mesh, rng.in_box(Vec3(10.0), Vec3(22.0)),
                                     rotation_about(rng.unit_vector(), rng.uniform(0.0, 6.3)), rng.uniform(3.0, 9.0));
    d.objects.push_back(o);
    ObjectDesc around = o;
    if (enclosure) around.mesh = enclosure;
    std::unique_ptr<Scene> scene;
    ASSERT_TRUE(Scene::create(d, SceneOptions{}, &scene).ok);
    const std::vector<glm::ivec3> inside = inside_voxels(*scene);
    // Not empty: a mesh this large holds voxels well clear of its surface.
    EXPECT_GT(inside.size(), 0u);
    for (const glm::ivec3& v : inside) {
      for (int c = 0; c < 9; ++c) {
        const Vec3 p = c < 8 ? Vec3(v) + Vec3(c & 1, (c >> 1) & 1, (c >> 2) & 1) : Vec3(v) + 0.5;
        ASSERT_TRUE(inside_by_parity(around, p)) << "voxel " << v.x << "," << v.y << "," << v.z << " point " << c;
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 1000);
}

TEST(MeshInterior, OpenMeshesAndTheBufferOffHaveNone) {
  SceneDesc d = unit_grid(32);
  auto open = std::make_shared<Mesh>(*tiled_box(Vec3(1.0), 3));
  open->triangles.pop_back();
  d.objects.push_back(mesh_object(1, open, Vec3(16.0), Quat(1, 0, 0, 0), 8.0));
  std::unique_ptr<Scene> scene;
  ASSERT_TRUE(Scene::create(d, SceneOptions{}, &scene).ok);
  EXPECT_TRUE(inside_voxels(*scene).empty());
  d.objects[0] = mesh_object(1, tiled_box(Vec3(1.0), 3), Vec3(16.0), Quat(1, 0, 0, 0), 8.0);
  ASSERT_TRUE(Scene::create(d, SceneOptions{}, &scene).ok);
  EXPECT_FALSE(inside_voxels(*scene).empty());
  SceneOptions off;
  off.occlusion_buffer = 0;
  ASSERT_TRUE(Scene::create(d, off, &scene).ok);
  EXPECT_TRUE(inside_voxels(*scene).empty());
}

TEST(MeshInterior, InteriorsCloseTheSeamsOfATiledWall) {
  // A thick wall whose faces are tiled 8 x 8: the seams between its
  // squares are open in the buffer, so only its interior boxes hide the
  // ball behind it. Made open (one triangle missing, on its far side) it has
  // no interior, and the ball stays in the PVS.
  for (bool closed : {true, false}) {
    SceneDesc d = unit_grid(32);
    // 24 x 24 x 4 voxels (the model itself stretched: a placement's scale
    // is uniform).
    auto wall = std::make_shared<Mesh>(*tiled_box(Vec3(12.0, 12.0, 2.0), 8));
    if (!closed) wall->triangles.pop_back();
    d.objects.push_back(mesh_object(1, wall, Vec3(16.0, 16.0, 12.0)));
    d.objects.push_back(sphere(2, Vec3(16.0, 16.0, 24.0), 1.5));
    std::unique_ptr<Scene> scene;
    ASSERT_TRUE(Scene::create(d, SceneOptions{}, &scene).ok);
    Scratch scratch;
    const ViewerId v = scene->add_viewer();
    FrameResult r;
    ASSERT_TRUE(scene->frame(v, camera_along(Vec3(16.3, 16.2, 1.0), Vec3(0, 0, 1), 50.0), 0.0, scratch, &r).ok);
    const bool ball = std::binary_search(r.pvs.begin(), r.pvs.end(), ObjectId{2});
    EXPECT_EQ(ball, !closed) << (closed ? "closed" : "open");
  }
}

TEST(MeshInterior, ModelInteriorBoxesLieInsideTheTriangles) {
  // A dynamic mesh's interior is built in its own frame: every box's
  // corners and centre inside the triangles (ray parity, identity
  // placement), and the boxes not empty.
  for (int k = 0; k < 4; ++k) {
    const std::shared_ptr<const Mesh> mesh = k == 0 ? icosphere(2)
                                             : k == 1 ? tiled_box(Vec3(1.0, 0.4, 0.7), 3)
                                             : k == 2 ? tiled_box(Vec3(1.0), 2, true)
                                                      : hollow_box(2);
    detail::ModelInterior in;
    ASSERT_TRUE(detail::model_interior(*mesh, 0.1, 1e-9, {}, &in));
    EXPECT_FALSE(in.boxes.empty()) << k;
    ObjectDesc o = mesh_object(1, k == 3 ? tiled_box(Vec3(1.0), 2) : mesh, Vec3(0.0));
    for (const detail::ModelInterior::Box& b : in.boxes)
      for (int c = 0; c < 9; ++c) {
        const Vec3 p = c < 8 ? b.center + b.half * Vec3((c & 1) ? 1 : -1, (c & 2) ? 1 : -1, (c & 4) ? 1 : -1) : b.center;
        ASSERT_TRUE(inside_by_parity(o, p)) << "mesh " << k << " point " << c;
      }
  }
}

TEST(MeshInterior, DynamicInteriorsCloseSeamsWhereverTheMeshIs) {
  // A tiled thick wall moving and turning a little in front of a ball: its
  // interior, drawn at its placement, hides the ball; open, its seams let
  // the ball show.
  for (bool closed : {true, false}) {
    SceneDesc d = unit_grid(32);
    auto wall = std::make_shared<Mesh>(*tiled_box(Vec3(12.0, 12.0, 2.0), 8));
    if (!closed) wall->triangles.pop_back();
    ObjectDesc w = mesh_object(1, wall, Vec3(16.0, 16.0, 12.0));
    w.dynamic = true;
    w.max_speed = 100.0;
    d.objects.push_back(w);
    d.objects.push_back(sphere(2, Vec3(16.0, 16.0, 26.0), 1.0));
    EngineHarness h(d, SceneOptions{}, closed ? "closed moving wall" : "open moving wall");
    ASSERT_TRUE(h.status().ok) << h.status().str();
    for (int f = 0; f < 4; ++f) {
      if (f > 0) {
        Move m;
        m.id = 1;
        m.center = Vec3(16.0 + 0.3 * f, 16.0 - 0.2 * f, 12.0);
        m.has_rotation = true;
        m.rotation = rotation_about(Vec3(0.2, 1.0, 0.1), 0.03 * f);
        ASSERT_TRUE(h.move(0.1 * f, {m}).ok);
      }
      const std::string err = h.frame(camera_along(Vec3(16.3, 16.2, 1.0), Vec3(0, 0, 1), 40.0), 0.1 * f);
      ASSERT_TRUE(err.empty()) << err;
      const bool ball = std::binary_search(h.last().pvs.begin(), h.last().pvs.end(), ObjectId{2});
      // Once it turns, the open wall's far face's seams no longer line up
      // with its near face's in the image, and the two faces together may
      // hide the ball too: only the first frame tells them apart.
      if (closed) {
        EXPECT_FALSE(ball) << "closed frame " << f;
      } else if (f == 0) {
        EXPECT_TRUE(ball) << "open frame " << f;
      }
    }
  }
}

TEST(MeshInterior, ZeroMissesWithTheEyeInAMovingClosedMesh) {
  // A closed dynamic mesh (a vehicle: a tiled box, and a hollow one) carries
  // the eye and balls inside it while it moves and turns; other cameras
  // watch it from outside and from its walls.
  SceneDesc d = unit_grid(40);
  const std::shared_ptr<const Mesh> shells[2] = {tiled_box(Vec3(1.0), 3), hollow_box(2)};
  for (int k = 0; k < 2; ++k) {
    ObjectDesc v = mesh_object(static_cast<ObjectId>(k + 1), shells[k], Vec3(12.0 + 16.0 * k, 20.0, 20.0), Quat(1, 0, 0, 0), 6.0);
    v.dynamic = true;
    v.max_speed = 40.0;
    d.objects.push_back(v);
  }
  Rng rng(5);
  for (int k = 0; k < 20; ++k)
    d.objects.push_back(sphere(static_cast<ObjectId>(10 + k), k < 6   ? Vec3(12.0, 20.0, 20.0) + rng.in_box(Vec3(-4.0), Vec3(4.0))
                                                              : k < 10 ? Vec3(28.0, 20.0, 20.0) + rng.in_box(Vec3(-2.0), Vec3(2.0))
                                                                       : rng.in_box(Vec3(2.0), Vec3(38.0)),
                               rng.uniform(0.3, 0.8)));
  EngineHarness h(d, SceneOptions{}, "eye in a moving closed mesh");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  for (int f = 0; f < 16; ++f) {
    const double t = 0.05 * f;
    const Vec3 shift(0.4 * f, 0.0, 0.1 * f);
    const Quat q = rotation_about(Vec3(0.1, 1.0, 0.2), 0.05 * f);
    if (f > 0) {
      std::vector<Move> moves;
      for (int k = 0; k < 2; ++k) {
        Move m;
        m.id = static_cast<ObjectId>(k + 1);
        m.center = Vec3(12.0 + 16.0 * k, 20.0, 20.0) + shift;
        m.has_rotation = true;
        m.rotation = q;
        moves.push_back(m);
      }
      ASSERT_TRUE(h.move(t, moves).ok);
    }
    const Vec3 inside[2] = {Vec3(12.0, 20.0, 20.0) + shift + rng.in_box(Vec3(-3.0), Vec3(3.0)),
                            Vec3(28.0, 20.0, 20.0) + shift + rng.in_box(Vec3(-1.5), Vec3(1.5))};
    const Camera cams[3] = {camera_along(inside[f % 2], rng.unit_vector(), rng.uniform(50.0, 120.0)),
                            camera_along(Vec3(12.0, 20.0, 20.0) + shift + q * Vec3(6.0, 0.2, 0.1), rng.unit_vector(), 90.0),
                            camera_along(Vec3(20.0, 20.0, 1.0), Vec3(0.0, 0.0, 1.0) + rng.in_box(Vec3(-0.3), Vec3(0.3)), 70.0)};
    for (const Camera& c : cams) {
      const std::string err = h.frame(c, t);
      ASSERT_TRUE(err.empty()) << "frame " << f << ": " << err;
    }
  }
}

/// Spheres inside and around closed meshes (a tiled room, an icosphere, a
/// box wound inwards, a hollow box), cameras outside them, on their walls and
/// inside (the hollow box's cavity too): every frame checked against the ray caster, which sees a mesh as
/// its triangles (an eye inside a closed mesh sees what is inside it).
TEST(MeshInterior, ZeroMissesWithTheEyeOutsideOnAndInsideClosedMeshes) {
  SceneDesc d = unit_grid(40);
  d.objects.push_back(mesh_object(1, tiled_box(Vec3(10.0, 6.0, 12.0), 4), Vec3(14.0, 12.0, 16.0)));
  d.objects.push_back(mesh_object(2, icosphere(2), Vec3(30.0, 12.0, 28.0), Quat(1, 0, 0, 0), 6.0));
  d.objects.push_back(mesh_object(3, tiled_box(Vec3(1.0), 2, true), Vec3(30.0, 30.0, 10.0),
                                  rotation_about(Vec3(1, 2, 3), 0.7), 5.0));
  d.objects.push_back(mesh_object(4, hollow_box(2), Vec3(10.0, 30.0, 30.0), Quat(1, 0, 0, 0), 7.0));
  ObjectId next = 10;
  Rng rng(17);
  // In the hollow box's cavity (half side 0.45 x 7).
  for (int k = 0; k < 4; ++k) d.objects.push_back(sphere(next++, Vec3(10.0, 30.0, 30.0) + rng.in_box(Vec3(-2.0), Vec3(2.0)), 0.6));
  for (int k = 0; k < 30; ++k) {
    const Vec3 c = k < 10 ? Vec3(14.0, 12.0, 16.0) + rng.in_box(Vec3(-8.0, -4.0, -10.0), Vec3(8.0, 4.0, 10.0))
                  : k < 15 ? Vec3(30.0, 12.0, 28.0) + rng.in_box(Vec3(-3.0), Vec3(3.0))
                           : rng.in_box(Vec3(2.0), Vec3(38.0));
    d.objects.push_back(sphere(next++, c, rng.uniform(0.3, 1.2)));
  }
  for (int buffer : {160, 64}) {
    SceneOptions opt;
    opt.occlusion_buffer = buffer;
    EngineHarness h(d, opt, "closed meshes, buffer " + std::to_string(buffer));
    ASSERT_TRUE(h.status().ok) << h.status().str();
    std::vector<Camera> cams;
    // Inside the room, looking about; on its wall; inside the icosphere;
    // outside everything looking at the meshes.
    for (int k = 0; k < 8; ++k)
      cams.push_back(camera_along(Vec3(14.0, 12.0, 16.0) + rng.in_box(Vec3(-7.0, -3.0, -9.0), Vec3(7.0, 3.0, 9.0)),
                                  rng.unit_vector(), rng.uniform(40.0, 100.0)));
    cams.push_back(camera_along(Vec3(24.0, 12.0, 16.0), Vec3(-1, 0.1, 0.05), 70.0));  // On the room's wall.
    cams.push_back(camera_along(Vec3(24.0, 12.0, 16.0), Vec3(1, 0.1, 0.05), 70.0));
    cams.push_back(camera_along(Vec3(30.5, 12.2, 27.7), Vec3(0.2, -0.1, 1.0), 90.0));  // In the icosphere.
    cams.push_back(camera_along(Vec3(30.0, 30.5, 10.2), Vec3(-1.0, -0.2, 0.3), 90.0));  // In the inward box.
    cams.push_back(camera_along(Vec3(10.5, 30.2, 28.0), Vec3(0.1, 0.2, 1.0), 100.0));  // In the cavity.
    cams.push_back(camera_along(Vec3(10.5, 30.2, 28.0), Vec3(0.1, 0.2, -1.0), 100.0));
    cams.push_back(camera_along(Vec3(10.0, 30.0, 38.5), Vec3(0.0, 0.0, -1.0), 60.0));  // In its wall.
    for (int k = 0; k < 8; ++k) {
      const Vec3 eye = Vec3(rng.uniform(1.0, 39.0), rng.uniform(1.0, 39.0), rng.chance(0.5) ? 1.0 : 39.0);
      cams.push_back(camera_along(eye, Vec3(20.0) - eye + rng.in_box(Vec3(-6.0), Vec3(6.0)), rng.uniform(40.0, 90.0)));
    }
    // A near plane reaching into the room from outside it.
    Camera deep = camera_along(Vec3(14.0, 12.0, 3.2), Vec3(0, 0, 1), 60.0);
    deep.near = 1.5;
    cams.push_back(deep);
    for (std::size_t k = 0; k < cams.size(); ++k) {
      const std::string err = h.frame(cams[k], 0.0);
      ASSERT_TRUE(err.empty()) << "camera " << k << ": " << err;
    }
  }
}

}  // namespace
}  // namespace voxvis::test
