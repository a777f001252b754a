// Model references in scene files (docs/formats.md, "Models by reference"):
// the reader's loader hook, its resolution of relative paths, one load per
// distinct reference shared by the objects naming it, and every refusal on
// the object's line: no loader, a failing loader, a bad key or value.
#include <memory>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "voxvis/format.h"
#include "voxvis/mesh.h"

namespace voxvis {
namespace {

using ::testing::HasSubstr;

/// A scene whose objects (from line 5, one a line) are `objects`.
std::string scene_of(const std::vector<std::string>& objects) {
  std::string s =
      "{\n"
      "  \"format\": \"voxvis-scene/1\",\n"
      "  \"bounds\": {\"min\": [0, 0, 0], \"max\": [10, 10, 10]},\n"
      "  \"objects\": [\n";
  for (std::size_t i = 0; i < objects.size(); ++i) s += "    " + objects[i] + (i + 1 < objects.size() ? ",\n" : "\n");
  return s + "  ]\n}\n";
}

struct FakeLoader {
  std::vector<std::pair<std::string, std::string>> calls;
  SceneReadOptions options(const std::string& base_dir) {
    SceneReadOptions o;
    o.base_dir = base_dir;
    o.load_model = [this](const std::string& path, const std::string& name, std::shared_ptr<const Mesh>* out) {
      calls.emplace_back(path, name);
      if (path.find("missing") != std::string::npos) return Status::Error(path, "cannot open: no such file");
      auto m = std::make_shared<Mesh>();
      m->vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
      m->triangles = {{0, 1, 2}};
      if (name == "Twice") m->triangles.push_back({0, 2, 1});
      if (name == "Flat") m->vertices[2] = Vec3(2, 0, 0);  // Degenerate: the reader checks what it gets.
      *out = std::move(m);
      return Status::Ok();
    };
    return o;
  }
};

TEST(ModelReferences, LoadsEachReferenceOnceAndSharesIt) {
  FakeLoader loader;
  const std::string text = scene_of({
      R"({"id": 1, "shape": "mesh", "model": "level.glb", "center": [5, 5, 5]})",
      R"({"id": 2, "shape": "mesh", "model": "level.glb", "scale": 2, "rotation": [0, 0, 1, 0]})",
      R"({"id": 3, "shape": "mesh", "model": "level.glb", "model_name": "Twice", "dynamic": true, "max_speed": 1})",
      R"({"id": 4, "shape": "mesh", "model": "/abs/prop.obj"})",
  });
  SceneDesc d;
  FormatError err;
  ASSERT_TRUE(parse_scene(text, "dir/s.json", &d, &err, loader.options("dir"))) << err.str();
  ASSERT_EQ(d.objects.size(), 4u);
  EXPECT_EQ(loader.calls.size(), 3u);
  EXPECT_EQ(loader.calls[0], std::make_pair(std::string("dir/level.glb"), std::string()));
  EXPECT_EQ(loader.calls[1], std::make_pair(std::string("dir/level.glb"), std::string("Twice")));
  EXPECT_EQ(loader.calls[2], std::make_pair(std::string("/abs/prop.obj"), std::string()));
  EXPECT_EQ(d.objects[0].mesh, d.objects[1].mesh);  // Shared.
  EXPECT_EQ(d.objects[0].center, Vec3(5, 5, 5));
  EXPECT_EQ(d.objects[1].scale, 2.0);
  EXPECT_EQ(d.objects[2].mesh->triangles.size(), 2u);
  EXPECT_TRUE(d.objects[2].dynamic);
  // Written back, the triangles are inline.
  SceneDesc back;
  ASSERT_TRUE(parse_scene(scene_to_json(d), "back.json", &back, &err)) << err.str();
  EXPECT_EQ(back.objects[2].mesh->triangles, d.objects[2].mesh->triangles);
}

TEST(ModelReferences, RefusalsNameTheObjectsLine) {
  struct Case {
    std::string object;
    std::string field;
    std::string message;
  };
  const std::vector<Case> cases = {
      {R"({"id": 1, "shape": "mesh", "model": "missing.glb"})", "objects[1].model",
       "cannot load 'd/missing.glb': cannot open: no such file"},
      {R"({"id": 1, "shape": "mesh", "model": 7})", "objects[1].model", "must be the path of a model file"},
      {R"({"id": 1, "shape": "mesh", "model": ""})", "objects[1].model", "must be the path of a model file"},
      {R"({"id": 1, "shape": "mesh", "model": "a.glb", "model_name": ""})", "objects[1].model_name",
       "must be the name of a node or mesh"},
      {R"({"id": 1, "shape": "mesh", "model": "a.glb", "vertices": [[0, 0, 0]]})", "objects[1]",
       "not allowed with \"model\""},
      {R"({"id": 1, "shape": "mesh", "model_name": "Door", "vertices": [[0, 0, 0]], "triangles": []})", "objects[1]",
       "only allowed with \"model\""},
      {R"({"id": 1, "shape": "box", "min": [0, 0, 0], "max": [1, 1, 1], "model": "a.glb"})", "objects[1]",
       "only allowed for a mesh"},
      {R"({"id": 1, "shape": "mesh", "model": "a.glb", "model_name": "Flat"})", "objects[1].model.triangles[0]",
       "degenerate"},
      {R"({"id": 1, "shape": "mesh", "model": "a.glb", "scale": 0})", "objects[1].scale", "must be finite and > 0"},
  };
  for (const Case& c : cases) {
    FakeLoader loader;
    SceneDesc d;
    FormatError err;
    const std::string text = scene_of({R"({"id": 0, "shape": "sphere", "center": [1, 1, 1], "radius": 1})", c.object});
    EXPECT_FALSE(parse_scene(text, "s.json", &d, &err, loader.options("d"))) << c.object;
    EXPECT_EQ(err.field, c.field) << err.str();
    EXPECT_THAT(err.message, HasSubstr(c.message)) << err.str();
    EXPECT_EQ(err.line, 6) << err.str();
  }
}

TEST(ModelReferences, WithoutALoaderAReferenceIsRefused) {
  SceneDesc d;
  FormatError err;
  EXPECT_FALSE(parse_scene(scene_of({R"({"id": 1, "shape": "mesh", "model": "level.glb"})"}), "s.json", &d, &err));
  EXPECT_EQ(err.field, "objects[0].model");
  EXPECT_EQ(err.line, 5);
  EXPECT_THAT(err.message, HasSubstr("cannot load the model file 'level.glb'"));
  EXPECT_THAT(err.message, HasSubstr("without a model importer"));
}

}  // namespace
}  // namespace voxvis
