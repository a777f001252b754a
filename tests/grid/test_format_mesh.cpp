// Mesh objects and rotating moves in the batch formats (docs/formats.md):
// parsed with their placement's defaults, every rule refused naming the line
// and field, and written back exactly.
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "voxvis/format.h"
#include "voxvis/mesh.h"

namespace voxvis {
namespace {

using ::testing::HasSubstr;

/// A scene whose second object (line 6) is `object`.
std::string scene_with(const std::string& object) {
  return "{\n"
         "  \"format\": \"voxvis-scene/1\",\n"
         "  \"bounds\": {\"min\": [0, 0, 0], \"max\": [10, 10, 10]},\n"
         "  \"objects\": [\n"
         "    {\"id\": 1, \"shape\": \"sphere\", \"center\": [1, 1, 1], \"radius\": 1},\n"
         "    " + object + "\n"
         "  ]\n"
         "}\n";
}

const std::string kQuad =
    R"("vertices": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], "triangles": [[0, 1, 2], [0, 2, 3]])";

TEST(MeshFormat, ParsesAMeshWithDefaultsAndWithPlacement) {
  SceneDesc d;
  FormatError err;
  ASSERT_TRUE(parse_scene(scene_with(R"({"id": 2, "shape": "mesh", )" + kQuad + "}"), "s.json", &d, &err)) << err.str();
  const ObjectDesc& o = d.objects[1];
  EXPECT_EQ(o.shape, Shape::Mesh);
  ASSERT_TRUE(o.mesh);
  EXPECT_EQ(o.mesh->vertices.size(), 4u);
  EXPECT_EQ(o.mesh->triangles.size(), 2u);
  EXPECT_EQ(o.mesh->triangles[1][2], 3u);
  EXPECT_EQ(o.center, Vec3(0.0));
  EXPECT_EQ(o.rotation, Quat(1, 0, 0, 0));
  EXPECT_EQ(o.scale, 1.0);
  ASSERT_TRUE(parse_scene(scene_with(R"({"id": 2, "shape": "mesh", "center": [5, 5, 5], "rotation": [0, 0, 1, 0], "scale": 2.5, "dynamic": true, "max_speed": 3, )" +
                                     kQuad + "}"),
                          "s.json", &d, &err))
      << err.str();
  EXPECT_EQ(d.objects[1].center, Vec3(5.0));
  EXPECT_EQ(d.objects[1].rotation, Quat(0, 0, 1, 0));
  EXPECT_EQ(d.objects[1].scale, 2.5);
  EXPECT_TRUE(d.objects[1].dynamic);
}

TEST(MeshFormat, RejectionsNameLineAndField) {
  struct Case {
    std::string object, field, message;
  };
  const std::string m = R"({"id": 2, "shape": "mesh", )";
  const std::vector<Case> cases = {
      {m + R"("triangles": [[0, 1, 2]]})", "objects[1]", "missing required key 'vertices'"},
      {m + R"("vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]]})", "objects[1]", "missing required key 'triangles'"},
      {m + R"("vertices": [], "triangles": []})", "objects[1].triangles", "at least one triangle"},
      {m + R"("vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "triangles": [[0, 1, 3]]})", "objects[1].triangles[0]",
       "index 3 is out of range"},
      {m + R"("vertices": [[0, 0, 0], [1, 0, 0], [2, 0, 0]], "triangles": [[0, 1, 2]]})", "objects[1].triangles[0]",
       "degenerate"},
      {m + R"("vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "triangles": [[0, 1, -2]]})",
       "objects[1].triangles[0][2]", "vertex index"},
      {m + R"("vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "triangles": [[0, 1]]})", "objects[1].triangles[0]",
       "3 vertex indices"},
      {m + R"("vertices": [[0, 0, 0], [1, 0, 0], [0, 1e999, 0]], "triangles": [[0, 1, 2]]})",
       "objects[1].vertices[2][1]", "out of range"},
      {m + R"("vertices": [[0, 0, 0], [1, 0, 0], [0, 2e12, 0]], "triangles": [[0, 1, 2]]})",
       "objects[1].vertices[2][1]", "magnitude"},
      {m + kQuad + R"(, "rotation": [1, 0, 0, 0.5]})", "objects[1].rotation", "unit quaternion"},
      {m + kQuad + R"(, "rotation": [1, 0, 0]})", "objects[1].rotation", "unit quaternion"},
      {m + kQuad + R"(, "scale": 0})", "objects[1].scale", "> 0"},
      {m + kQuad + R"(, "scale": 1e12, "center": [5e11, 0, 0]})", "objects[1].scale", "beyond"},
      {m + kQuad + R"(, "radius": 1})", "objects[1]", "'radius' is not allowed for a mesh"},
      {R"({"id": 2, "shape": "sphere", "center": [1, 1, 1], "radius": 1, "scale": 2})", "objects[1]",
       "'scale' is only allowed for a mesh"},
      {R"({"id": 2, "shape": "cone"})", "objects[1].shape", "\"mesh\""},
  };
  for (const Case& c : cases) {
    SceneDesc d;
    FormatError err;
    EXPECT_FALSE(parse_scene(scene_with(c.object), "s.json", &d, &err)) << c.object;
    EXPECT_EQ(err.line, 6) << err.str();
    EXPECT_EQ(err.field, c.field) << err.str();
    EXPECT_THAT(err.message, HasSubstr(c.message)) << err.str();
  }
}

TEST(MeshFormat, RoundTripIsExact) {
  SceneDesc d;
  d.bounds_min = Vec3(-1.0);
  d.bounds_max = Vec3(1.0 / 3.0, 7.0, 1e6);
  auto mesh = std::make_shared<Mesh>();
  mesh->vertices = {Vec3(0.1, 0.2, 0.3), Vec3(1.0 / 3.0, 0, 0), Vec3(0, 5e-324, 1), Vec3(-2, 1e11, 0.7)};
  mesh->triangles = {{0, 1, 2}, {1, 3, 2}, {3, 0, 1}};
  ObjectDesc o;
  o.id = 4294967295u;
  o.shape = Shape::Mesh;
  o.mesh = mesh;
  o.center = Vec3(0.1, -0.2, 1.0 / 7.0);
  o.rotation = unit_rotation(Quat(0.3, -0.4, 0.5, 0.1));
  o.scale = 1e-3;
  o.dynamic = true;
  o.max_speed = 0.25;
  d.objects.push_back(o);
  SceneDesc back;
  FormatError err;
  ASSERT_TRUE(parse_scene(scene_to_json(d), "s.json", &back, &err)) << err.str();
  ASSERT_EQ(back.objects.size(), 1u);
  const ObjectDesc& b = back.objects[0];
  EXPECT_EQ(b.shape, Shape::Mesh);
  EXPECT_EQ(b.mesh->vertices, mesh->vertices);
  EXPECT_EQ(b.mesh->triangles, mesh->triangles);
  EXPECT_EQ(b.center, o.center);
  EXPECT_EQ(b.rotation, o.rotation);
  EXPECT_EQ(b.scale, o.scale);
  EXPECT_EQ(b.max_speed, o.max_speed);
  // Its length foreseen exactly, the mesh measured once for many placements.
  EXPECT_EQ(scene_json_bytes(d), scene_to_json(d).size());
  for (ObjectId id = 0; id < 40; ++id) {
    ObjectDesc again = o;
    again.id = id;
    again.dynamic = id % 2 == 0;
    again.center = Vec3(-0.0, id * 1e-9, -1e11 / (id + 1));
    d.objects.push_back(again);
  }
  std::uint64_t meshes = 0;
  EXPECT_EQ(scene_json_bytes(d, &meshes), scene_to_json(d).size());
  SceneDesc one = d;
  one.objects.resize(1);
  std::uint64_t mesh_once = 0;
  scene_json_bytes(one, &mesh_once);
  EXPECT_EQ(meshes, 41 * mesh_once) << "every object writes its mesh inline";
}

TEST(MeshFormat, MovesMayRotate) {
  FrameInput f;
  f.t = 0.5;
  f.moves = {Move{3, Vec3(1, 2, 3)}, Move{4, Vec3(0.5), true, unit_rotation(Quat(1, 2, 3, 4))}};
  FrameInput back;
  FormatError err;
  ASSERT_TRUE(parse_frame_line(frame_to_json(f), "f.jsonl", 1, &back, &err)) << err.str();
  ASSERT_EQ(back.moves.size(), 2u);
  EXPECT_FALSE(back.moves[0].has_rotation);
  EXPECT_TRUE(back.moves[1].has_rotation);
  EXPECT_EQ(back.moves[1].rotation, f.moves[1].rotation);
  // A rotation that is not a unit quaternion names the field.
  std::string bad = frame_to_json(f);
  const std::size_t at = bad.find("\"rotation\": [");
  ASSERT_NE(at, std::string::npos);
  bad.replace(at, std::string("\"rotation\": [").size(), "\"rotation\": [3, ");
  EXPECT_FALSE(parse_frame_line(bad, "f.jsonl", 7, &back, &err));
  EXPECT_EQ(err.field, "moves[1].rotation") << err.str();
  EXPECT_EQ(err.line, 7);
}

}  // namespace
}  // namespace voxvis
