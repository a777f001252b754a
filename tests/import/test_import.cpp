// The importer in process (voxvis/import.h): counts and bounds of real models
// of Debian's assimp-testmodels, node transforms on a small glTF whose
// placed vertices are known, the three splits, a dynamic object's placement
// against the static one's, the dropped triangles, and refused files.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "files.h"
#include "models.h"
#include "voxvis/import.h"
#include "voxvis/mesh.h"
#include "voxvis/scene.h"

namespace voxvis::test {
namespace {

using ::testing::HasSubstr;
using import::ImportedObject;
using import::ImportOptions;
using import::ImportResult;
using import::Split;

class Import : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string tmpl = (std::filesystem::temp_directory_path() / "voxvis-import-XXXXXX").string();
    ASSERT_NE(::mkdtemp(tmpl.data()), nullptr);
    dir_ = tmpl;
  }
  void TearDown() override {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  std::string write(const std::string& name, const std::string& text) {
    const std::string p = (dir_ / name).string();
    spit(p, text);
    return p;
  }
  static ImportResult import_ok(const std::vector<std::string>& paths, const ImportOptions& options = {}) {
    ImportResult r;
    const Status st = import::import_files(paths, options, &r);
    EXPECT_TRUE(st.ok) << st.str();
    return r;
  }
  std::filesystem::path dir_;
};

/// Every placed vertex of an object, in the mesh's vertex order.
std::vector<Vec3> placed(const ObjectDesc& o) {
  std::vector<Vec3> out;
  for (const Vec3& v : o.mesh->vertices) out.push_back(place(o, v));
  return out;
}

std::size_t triangles(const ImportResult& r) {
  std::size_t n = 0;
  for (const ImportedObject& o : r.objects) n += o.desc.mesh->triangles.size();
  return n;
}

void expect_near(const Vec3& a, const Vec3& b, double tol = 1e-9) {
  EXPECT_NEAR(a.x, b.x, tol);
  EXPECT_NEAR(a.y, b.y, tol);
  EXPECT_NEAR(a.z, b.z, tol);
}

/// The scene the engine would build from the objects: it must accept them.
void expect_engine_accepts(const ImportResult& r) {
  SceneDesc desc;
  ASSERT_TRUE(import::objects_bounds(r.objects, &desc.bounds_min, &desc.bounds_max));
  desc.bounds_min -= Vec3(1.0);
  desc.bounds_max += Vec3(1.0);
  ObjectId id = 1;
  for (const ImportedObject& o : r.objects) {
    desc.objects.push_back(o.desc);
    desc.objects.back().id = id++;
  }
  std::unique_ptr<Scene> scene;
  const Status st = Scene::create(desc, {}, &scene);
  EXPECT_TRUE(st.ok) << st.str();
}

TEST_F(Import, GltfSampleBoxHasTwelveTrianglesInTheUnitCube) {
  const std::string model = test_model("glTF2/BoxTextured-glTF/BoxTextured.gltf");
  if (model.empty()) GTEST_SKIP() << "assimp-testmodels is not installed (/usr/share/assimp/models)";
  const ImportResult r = import_ok({model});
  ASSERT_EQ(r.objects.size(), 1u);
  EXPECT_EQ(triangles(r), 12u);
  EXPECT_EQ(r.objects[0].desc.mesh->vertices.size(), 8u);  // Joined by position.
  Vec3 lo, hi;
  ASSERT_TRUE(import::objects_bounds(r.objects, &lo, &hi));
  expect_near(lo, Vec3(-0.5), 1e-6);
  expect_near(hi, Vec3(0.5), 1e-6);
  EXPECT_EQ(r.objects[0].source, model);
  expect_engine_accepts(r);
}

TEST_F(Import, ObjSampleBoxHasTwelveTrianglesInTheUnitCube) {
  const std::string model = test_model("OBJ/box.obj");
  if (model.empty()) GTEST_SKIP() << "assimp-testmodels is not installed (/usr/share/assimp/models)";
  const ImportResult r = import_ok({model});
  ASSERT_EQ(r.objects.size(), 1u);
  EXPECT_EQ(triangles(r), 12u);  // Six quads.
  Vec3 lo, hi;
  ASSERT_TRUE(import::objects_bounds(r.objects, &lo, &hi));
  expect_near(lo, Vec3(-0.5));
  expect_near(hi, Vec3(0.5));
  expect_engine_accepts(r);
}

TEST_F(Import, LargerSamplesImportAndBuild) {
  for (const char* rel : {"glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb", "OBJ/spider.obj",
                          "IFC/AC14-FZK-Haus.ifc"}) {
    const std::string model = test_model(rel);
    if (model.empty()) GTEST_SKIP() << "assimp-testmodels is not installed (/usr/share/assimp/models)";
    const ImportResult r = import_ok({model});
    EXPECT_GT(r.objects.size(), 1u) << rel;
    EXPECT_GT(triangles(r), 1000u) << rel;
    EXPECT_EQ(r.stats.triangles, triangles(r));
    expect_engine_accepts(r);
  }
}

TEST_F(Import, NodeTransformsPlaceTheVertices) {
  const ImportResult r = import_ok({write("level.gltf", level_gltf())});
  ASSERT_EQ(r.objects.size(), 3u);
  const ImportedObject& mover = r.objects[0];
  EXPECT_EQ(mover.name, "Mover");
  EXPECT_THAT(mover.node, HasSubstr("Level/Mover"));
  EXPECT_FALSE(mover.desc.dynamic);
  // Static: the world matrix is baked, the placement is the identity.
  EXPECT_EQ(mover.desc.center, Vec3(0.0));
  EXPECT_EQ(mover.desc.scale, 1.0);
  // (0,0,0) (1,0,0) (0,1,0): scaled 2, turned 90 degrees about y (x -> -z),
  // moved by (1, 2, 3) + (10, 0, 0).
  const std::vector<Vec3> m = placed(mover.desc);
  ASSERT_EQ(m.size(), 3u);
  expect_near(m[0], Vec3(11, 2, 3), 1e-6);
  expect_near(m[1], Vec3(11, 2, 1), 1e-6);
  expect_near(m[2], Vec3(11, 4, 3), 1e-6);

  const ImportedObject& wall = r.objects[1];
  EXPECT_EQ(wall.name, "Wall");
  EXPECT_EQ(wall.desc.mesh->triangles.size(), 2u);  // Two primitives, merged.
  EXPECT_EQ(wall.meshes.size(), 2u);
  Vec3 lo, hi;
  mesh_bounds(wall.desc, &lo, &hi);
  expect_near(lo, Vec3(10, 0, 0));
  expect_near(hi, Vec3(11, 3, 0));

  const std::vector<Vec3> t = placed(r.objects[2].desc);
  EXPECT_EQ(r.objects[2].name, "Twin");
  expect_near(t[0], Vec3(10, 0, -5));
  expect_near(t[1], Vec3(11, 0, -5));
  expect_near(t[2], Vec3(10, 1, -5));
  expect_engine_accepts(r);
}

TEST_F(Import, SplitModes) {
  const std::string model = write("level.gltf", level_gltf());
  ImportOptions options;
  options.split = Split::Meshes;
  const ImportResult meshes = import_ok({model}, options);
  ASSERT_EQ(meshes.objects.size(), 4u);  // Mover's Tri, Wall's two primitives, Twin's Tri.
  for (const ImportedObject& o : meshes.objects) EXPECT_EQ(o.desc.mesh->triangles.size(), 1u);
  EXPECT_THAT(meshes.objects[1].name, HasSubstr("Quad"));
  EXPECT_THAT(meshes.objects[1].node, HasSubstr("Wall"));

  options.split = Split::Whole;
  const ImportResult whole = import_ok({model, model}, options);
  ASSERT_EQ(whole.objects.size(), 2u);  // One per file.
  EXPECT_EQ(whole.objects[0].name, "level.gltf");
  EXPECT_EQ(whole.objects[0].desc.mesh->triangles.size(), 4u);

  options.split = Split::Nodes;
  const ImportResult nodes = import_ok({model}, options);
  EXPECT_EQ(nodes.objects.size(), 3u);
  // The same triangles in every split, placed the same.
  std::vector<Vec3> a, b;
  for (const ImportedObject& o : nodes.objects)
    for (const auto& tri : o.desc.mesh->triangles)
      for (auto k : tri) a.push_back(place(o.desc, o.desc.mesh->vertices[k]));
  for (const ImportedObject& o : meshes.objects)
    for (const auto& tri : o.desc.mesh->triangles)
      for (auto k : tri) b.push_back(place(o.desc, o.desc.mesh->vertices[k]));
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) expect_near(a[i], b[i], 0.0);
}

TEST_F(Import, DynamicObjectsKeepTheirNodesPlacement) {
  const std::string model = write("level.gltf", level_gltf());
  const ImportResult fixed = import_ok({model});
  ImportOptions options;
  options.dynamic_names = {"Mover", "Wall"};
  options.max_speed = 4.0;
  const ImportResult moving = import_ok({model}, options);
  ASSERT_EQ(moving.objects.size(), 3u);
  const ObjectDesc& mover = moving.objects[0].desc;
  EXPECT_TRUE(mover.dynamic);
  EXPECT_EQ(mover.max_speed, 4.0);
  // Centre = the node's world translation, rotation = its world rotation,
  // uniform scale kept; the vertices stay the model's.
  expect_near(mover.center, Vec3(11, 2, 3), 1e-12);
  EXPECT_NEAR(mover.scale, 2.0, 1e-6);
  EXPECT_NEAR(std::fabs(mover.rotation.y), std::sqrt(0.5), 1e-6);
  expect_near(mover.mesh->vertices[1], Vec3(1, 0, 0), 1e-6);
  // Wall: a non-uniform scale is baked into the vertices, scale 1.
  const ObjectDesc& wall = moving.objects[1].desc;
  EXPECT_TRUE(wall.dynamic);
  EXPECT_EQ(wall.scale, 1.0);
  expect_near(wall.center, Vec3(10, 0, 0));
  EXPECT_FALSE(moving.objects[2].desc.dynamic);
  // Placed, the dynamic objects' vertices are the static import's.
  for (std::size_t i = 0; i < 2; ++i) {
    const std::vector<Vec3> a = placed(fixed.objects[i].desc), b = placed(moving.objects[i].desc);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t k = 0; k < a.size(); ++k) expect_near(a[k], b[k], 1e-12);
  }
  expect_engine_accepts(moving);
}

TEST_F(Import, DynamicNamesMatchNodePathsAndMustMatchSomething) {
  const std::string model = write("level.gltf", level_gltf());
  ImportOptions options;
  options.dynamic_names = {"Twin", "Nobody"};
  options.max_speed = 1.0;
  ImportResult r;
  const Status st = import::import_files({model}, options, &r);
  ASSERT_FALSE(st.ok);
  EXPECT_EQ(st.field, "--dynamic");
  EXPECT_THAT(st.message, HasSubstr("'Nobody'"));
  EXPECT_THAT(st.message, HasSubstr("'Mover'"));  // The names there are.
}

TEST_F(Import, DegenerateTrianglesPointsAndLinesAreDroppedAndCounted) {
  // Triangle 2 is collinear, triangle 3 repeats a vertex; a line and a point.
  const std::string obj = write("bits.obj",
                                "o Piece\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\n"
                                "f 1 2 3\nf 1 2 4\nf 1 1 3\nl 1 3\np 2\n");
  const ImportResult r = import_ok({obj});
  ASSERT_EQ(r.objects.size(), 1u);
  EXPECT_EQ(triangles(r), 1u);
  EXPECT_EQ(r.objects[0].desc.mesh->vertices.size(), 3u);  // Unused vertices dropped.
  EXPECT_EQ(r.stats.degenerate, 2u);
  EXPECT_EQ(r.stats.points_lines, 2u);
}

TEST_F(Import, TrianglesFlattenedByTheirNodeAreDropped) {
  // "Flat" squashes y to 0: its triangle (in the xy plane) has no area left.
  const std::string model = write("flat.gltf", gltf_with_nodes(R"([
    {"name": "Flat", "mesh": 0, "scale": [1, 0, 1]},
    {"name": "Kept", "mesh": 0}
  ])",
                                                                "[0, 1]"));
  const ImportResult r = import_ok({model});
  ASSERT_EQ(r.objects.size(), 1u);
  EXPECT_EQ(r.objects[0].name, "Kept");
  EXPECT_EQ(r.stats.degenerate, 1u);
  EXPECT_EQ(r.stats.empty_objects, 1u);
}

TEST_F(Import, BadFilesAreRefusedNamingTheFile) {
  struct Case {
    std::string path;
    std::string expect;
  };
  const std::vector<Case> cases = {
      {(dir_ / "missing.glb").string(), "cannot open"},
      {write("garbage.gltf", "{\"asset\": {\"version\": \"2.0\"}, \"nodes\": [ oops"), "cannot import"},
      {write("empty.obj", ""), "cannot import"},
      {write("unknown.xyz", "hello"), "cannot import"},
      {write("lines.obj", "v 0 0 0\nv 1 0 0\nl 1 2\n"), "no triangles found"},
      {dir_.string(), "is a directory"},
  };
  for (const Case& c : cases) {
    ImportResult r;
    const Status st = import::import_files({c.path}, {}, &r);
    EXPECT_FALSE(st.ok) << c.path;
    EXPECT_EQ(st.field, c.path);
    EXPECT_THAT(st.message, HasSubstr(c.expect)) << st.str();
  }
  // assimp's glTF reader drops a face whose index is out of range (12
  // triangles, 11 imported) and refuses a mesh left without faces.
  if (const std::string one_bad = test_model("glTF2/IndexOutOfRange/IndexOutOfRange.gltf"); !one_bad.empty()) {
    EXPECT_EQ(triangles(import_ok({one_bad})), 11u);
  }
  const std::string bad_ref = test_model("glTF2/IndexOutOfRange/AllIndicesOutOfRange.gltf");
  const std::string infinite = test_model("glTF2/BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb");
  for (const std::string& model : {bad_ref, infinite}) {
    if (model.empty()) continue;
    ImportResult r;
    const Status st = import::import_files({model}, {}, &r);
    EXPECT_FALSE(st.ok) << model;
    EXPECT_EQ(st.field, model);
  }
}

TEST_F(Import, FromMemoryWithAFormatHint) {
  const std::string text = level_gltf();
  ImportResult r;
  const Status st = import::import_memory(text.data(), text.size(), "gltf", "level", {}, &r);
  ASSERT_TRUE(st.ok) << st.str();
  EXPECT_EQ(r.objects.size(), 3u);
  ImportResult bad;
  const std::string junk = "v 1 2\nf 1 2 3\n";
  const Status st2 = import::import_memory(junk.data(), junk.size(), "obj", "junk.obj", {}, &bad);
  EXPECT_FALSE(st2.ok);
  EXPECT_EQ(st2.field, "junk.obj");
}

TEST_F(Import, ModelMeshForSceneReferences) {
  const std::string model = write("level.gltf", level_gltf());
  std::shared_ptr<const Mesh> all, wall;
  ASSERT_TRUE(import::load_model_mesh(model, "", &all).ok);
  EXPECT_EQ(all->triangles.size(), 4u);
  ASSERT_TRUE(import::load_model_mesh(model, "Wall", &wall).ok);
  EXPECT_EQ(wall->triangles.size(), 2u);
  std::shared_ptr<const Mesh> none;
  const Status st = import::load_model_mesh(model, "Door", &none);
  EXPECT_FALSE(st.ok);
  EXPECT_THAT(st.message, HasSubstr("'Door'"));
}

}  // namespace
}  // namespace voxvis::test
