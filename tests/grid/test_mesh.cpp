// Meshes and their placement (voxvis/mesh.h): the rules every layer applies,
// and where a mesh's points go.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <random>

#include <glm/geometric.hpp>

#include "voxvis/mesh.h"

namespace voxvis {
namespace {

/// A unit tetrahedron: (0,0,0), (1,0,0), (0,1,0), (0,0,1).
std::shared_ptr<Mesh> tetrahedron() {
  auto m = std::make_shared<Mesh>();
  m->vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
  m->triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  return m;
}

ObjectDesc mesh_object(std::shared_ptr<const Mesh> mesh) {
  ObjectDesc o;
  o.id = 1;
  o.shape = Shape::Mesh;
  o.mesh = std::move(mesh);
  return o;
}

TEST(Mesh, ValidMeshPasses) {
  EXPECT_TRUE(validate_mesh(*tetrahedron(), "m").ok);
  EXPECT_TRUE(validate_mesh_object(mesh_object(tetrahedron()), "objects[0]").ok);
}

TEST(Mesh, EachRuleNamesItsField) {
  {
    Mesh m;
    const Status s = validate_mesh(m, "m");
    EXPECT_EQ(s.field, "m.triangles");
    EXPECT_NE(s.message.find("at least one triangle"), std::string::npos) << s.str();
  }
  {
    auto m = tetrahedron();
    m->triangles[2][1] = 4;
    const Status s = validate_mesh(*m, "m");
    EXPECT_EQ(s.field, "m.triangles[2]");
    EXPECT_NE(s.message.find("index 4 is out of range"), std::string::npos) << s.str();
  }
  {
    auto m = tetrahedron();
    m->triangles[1] = {0, 1, 1};  // Two corners the same.
    EXPECT_EQ(validate_mesh(*m, "m").field, "m.triangles[1]");
    m = tetrahedron();
    m->vertices.push_back(Vec3(2, 0, 0));  // On the line through vertices 0 and 1.
    m->triangles.push_back({0, 1, 4});
    const Status s = validate_mesh(*m, "m");
    EXPECT_EQ(s.field, "m.triangles[4]");
    EXPECT_NE(s.message.find("degenerate"), std::string::npos) << s.str();
  }
  for (double bad : {std::nan(""), std::numeric_limits<double>::infinity(), 2 * kMaxCoordinate}) {
    auto m = tetrahedron();
    m->vertices[3].y = bad;
    EXPECT_EQ(validate_mesh(*m, "m").field, "m.vertices[3]") << bad;
  }
  {
    ObjectDesc o = mesh_object(tetrahedron());
    o.scale = 0.0;
    EXPECT_EQ(validate_mesh_object(o, "o").field, "o.scale");
    o.scale = -1.0;
    EXPECT_EQ(validate_mesh_object(o, "o").field, "o.scale");
    o.scale = std::nan("");
    EXPECT_EQ(validate_mesh_object(o, "o").field, "o.scale");
    o.scale = 1e12;  // Places the vertex at 1e12 + ... beyond the limit once moved.
    o.center = Vec3(1.0, 0.0, 0.0);
    EXPECT_EQ(validate_mesh_object(o, "o").field, "o.scale");
  }
  {
    ObjectDesc o = mesh_object(tetrahedron());
    o.rotation = Quat(1.0, 0.1, 0.0, 0.0);  // Norm 1.005.
    const Status s = validate_mesh_object(o, "o");
    EXPECT_EQ(s.field, "o.rotation");
    EXPECT_NE(s.message.find("unit quaternion"), std::string::npos) << s.str();
    o.rotation = Quat(1.0 + 5e-7, 0.0, 0.0, 0.0);  // Within the tolerance.
    EXPECT_TRUE(validate_mesh_object(o, "o").ok);
  }
  {
    ObjectDesc o = mesh_object(nullptr);
    EXPECT_EQ(validate_mesh_object(o, "o").field, "o.mesh");
  }
}

TEST(Mesh, PlaceRotatesScalesThenTranslates) {
  ObjectDesc o = mesh_object(tetrahedron());
  o.center = Vec3(10, 20, 30);
  o.scale = 2.0;
  // A quarter turn about y: x goes to -z.
  o.rotation = Quat(std::sqrt(0.5), 0.0, std::sqrt(0.5), 0.0);
  const Vec3 p = place(o, Vec3(1, 0, 0));
  EXPECT_NEAR(p.x, 10.0, 1e-12);
  EXPECT_NEAR(p.y, 20.0, 1e-12);
  EXPECT_NEAR(p.z, 28.0, 1e-12);
  Vec3 lo, hi;
  mesh_bounds(o, &lo, &hi);
  EXPECT_NEAR(lo.x, 10.0, 1e-12);
  EXPECT_NEAR(hi.x, 12.0, 1e-12);  // Model z = 1 goes to world x = +2.
  EXPECT_NEAR(lo.z, 28.0, 1e-12);
  EXPECT_NEAR(hi.z, 30.0, 1e-12);
  Vec3 lo2, hi2;
  object_bounds(o, &lo2, &hi2);
  EXPECT_EQ(lo, lo2);
  EXPECT_EQ(hi, hi2);
}

TEST(Mesh, CentroidBallHoldsTheMeshUnderAnyRotation) {
  auto m = tetrahedron();
  m->vertices[3] = Vec3(0.2, -3.0, 7.5);
  const Vec3 c = mesh_centroid(*m);
  const double reach = mesh_reach(*m, c);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n;
  for (int k = 0; k < 200; ++k) {
    ObjectDesc o = mesh_object(m);
    o.rotation = unit_rotation(Quat(n(rng), n(rng), n(rng), n(rng)));
    o.scale = std::exp(n(rng));
    o.center = Vec3(n(rng), n(rng), n(rng)) * 100.0;
    const Vec3 wc = place(o, c);
    for (const Vec3& v : m->vertices) EXPECT_LE(glm::length(place(o, v) - wc), o.scale * reach * (1 + 1e-12));
  }
}

}  // namespace
}  // namespace voxvis
