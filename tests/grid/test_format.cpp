// Tests of the batch formats (format.h, docs/formats.md) and of the
// deterministic generators (generate.h).
#include <cmath>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include <glm/geometric.hpp>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "voxvis/format.h"
#include "voxvis/generate.h"

namespace voxvis {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

// A valid multi-line scene. Line numbers matter to the tests below.
constexpr const char* kScene = R"({
  "format": "voxvis-scene/1",
  "bounds": {"min": [0, 0, 0], "max": [100, 60, 100]},
  "grid": [50, 30, 50],
  "objects": [
    {"id": 7, "shape": "sphere", "center": [10, 20, 30], "radius": 1.5},
    {"id": 8, "shape": "box", "min": [1, 2, 3], "max": [5, 4, 3], "dynamic": true, "max_speed": 2.5},
    {"id": 9, "shape": "sphere", "center": [-5, 70, 200], "radius": 0.25,
     "dynamic": true, "max_speed": 0}
  ]
}
)";

SceneDesc parse_ok(const std::string& text) {
  SceneDesc desc;
  FormatError err;
  EXPECT_TRUE(parse_scene(text, "scene.json", &desc, &err)) << err.str();
  return desc;
}

FormatError parse_bad(const std::string& text) {
  SceneDesc desc;
  FormatError err;
  EXPECT_FALSE(parse_scene(text, "scene.json", &desc, &err)) << "accepted:\n" << text;
  return err;
}

/// A one-object scene document with `object` as the object's JSON text.
std::string with_object(const std::string& object) {
  return "{\n"
         "  \"format\": \"voxvis-scene/1\",\n"
         "  \"bounds\": {\"min\": [0, 0, 0], \"max\": [10, 10, 10]},\n"
         "  \"objects\": [\n"
         "    {\"id\": 1, \"shape\": \"sphere\", \"center\": [1, 1, 1], \"radius\": 1},\n"
         "    " + object + "\n"
         "  ]\n"
         "}\n";
}
constexpr int kObjectLine = 6;  // Line of the second object in with_object(); the first is on 5.

/// A scene document whose root members after "format" are `members`.
std::string with_root(const std::string& members) {
  return "{\n  \"format\": \"voxvis-scene/1\",\n" + members + "\n}\n";
}

// ---------------------------------------------------------------------------
// FormatError

TEST(FormatError, StrOmitsEmptyParts) {
  EXPECT_EQ((FormatError{"scene.json", 12, "objects[3].radius", "must be > 0, got -1"}).str(),
            "scene.json:12: objects[3].radius: must be > 0, got -1");
  EXPECT_EQ((FormatError{"scene.json", 0, "grid", "too big"}).str(), "scene.json: grid: too big");
  EXPECT_EQ((FormatError{"scene.json", 3, "", "malformed"}).str(), "scene.json:3: malformed");
  EXPECT_EQ((FormatError{"", 0, "--grid", "bad"}).str(), "--grid: bad");
  EXPECT_EQ((FormatError{"", 0, "", "bad"}).str(), "bad");
  EXPECT_EQ((FormatError{"", 4, "", "bad"}).str(), "line 4: bad");
}

// ---------------------------------------------------------------------------
// Scene parsing: accepted documents

TEST(SceneFormat, ParsesSpheresBoxesAndDynamics) {
  const SceneDesc d = parse_ok(kScene);
  EXPECT_EQ(d.bounds_min, Vec3(0, 0, 0));
  EXPECT_EQ(d.bounds_max, Vec3(100, 60, 100));
  ASSERT_TRUE(d.grid.has_value());
  EXPECT_EQ(*d.grid, glm::ivec3(50, 30, 50));
  ASSERT_EQ(d.objects.size(), 3u);

  const ObjectDesc& s = d.objects[0];
  EXPECT_EQ(s.id, 7u);
  EXPECT_EQ(s.shape, Shape::Sphere);
  EXPECT_EQ(s.center, Vec3(10, 20, 30));
  EXPECT_EQ(s.radius, 1.5);
  EXPECT_FALSE(s.dynamic);
  EXPECT_EQ(s.max_speed, 0.0);

  const ObjectDesc& b = d.objects[1];
  EXPECT_EQ(b.id, 8u);
  EXPECT_EQ(b.shape, Shape::Box);
  EXPECT_EQ(b.center, Vec3(3, 3, 3));
  EXPECT_EQ(b.half_extent, Vec3(2, 1, 0));  // min == max on z: a flat box.
  EXPECT_TRUE(b.dynamic);
  EXPECT_EQ(b.max_speed, 2.5);

  // Outside the bounds is allowed; max_speed 0 is allowed.
  const ObjectDesc& o = d.objects[2];
  EXPECT_EQ(o.center, Vec3(-5, 70, 200));
  EXPECT_TRUE(o.dynamic);
  EXPECT_EQ(o.max_speed, 0.0);
}

TEST(SceneFormat, GridIsOptionalAndObjectsMayBeEmpty) {
  const SceneDesc d = parse_ok(with_root(
      "  \"bounds\": {\"min\": [-1, -2, -3], \"max\": [1, 2, 3]},\n  \"objects\": []"));
  EXPECT_FALSE(d.grid.has_value());
  EXPECT_TRUE(d.objects.empty());
}

TEST(SceneFormat, AcceptsIntegralFloatsExtremeIdsAndLimits) {
  const SceneDesc d = parse_ok(with_object(
      R"({"id": 4294967295, "shape": "sphere", "center": [1e12, -1e12, 0.5], "radius": 1e12})"));
  EXPECT_EQ(d.objects[1].id, 4294967295u);
  EXPECT_EQ(d.objects[1].center.x, 1e12);
  const SceneDesc d2 =
      parse_ok(with_object(R"({"id": 7.0, "shape": "sphere", "center": [1, 1, 1], "radius": 1})"));
  EXPECT_EQ(d2.objects[1].id, 7u);
  parse_ok(with_object(R"({"id": 0, "shape": "sphere", "center": [1, 1, 1], "radius": 1})"));
}

TEST(SceneFormat, AcceptsWindowsLineEndingsAndBom) {
  std::string text = kScene;
  std::string crlf;
  for (const char c : text) {
    if (c == '\n') crlf += '\r';
    crlf += c;
  }
  EXPECT_EQ(parse_ok(crlf).objects.size(), 3u);
  EXPECT_EQ(parse_ok("\xEF\xBB\xBF" + text).objects.size(), 3u);
}

// ---------------------------------------------------------------------------
// Scene parsing: rejections name the line and the field

struct Rejection {
  const char* name;
  std::string text;
  int line;
  std::string field;    // Exact expected FormatError::field.
  std::string message;  // Expected substring of the message.
};

void PrintTo(const Rejection& r, std::ostream* os) { *os << r.name; }

class SceneRejection : public ::testing::TestWithParam<Rejection> {};

TEST_P(SceneRejection, NamesLineAndField) {
  const Rejection& r = GetParam();
  const FormatError err = parse_bad(r.text);
  EXPECT_EQ(err.source, "scene.json");
  EXPECT_EQ(err.line, r.line) << err.str();
  EXPECT_EQ(err.field, r.field) << err.str();
  EXPECT_THAT(err.message, HasSubstr(r.message)) << err.str();
  // The rendered form carries all of it.
  EXPECT_THAT(err.str(), HasSubstr("scene.json:" + std::to_string(r.line) + ": "));
}

std::vector<Rejection> scene_rejections() {
  const std::string bounds = "  \"bounds\": {\"min\": [0, 0, 0], \"max\": [10, 10, 10]},\n";
  const auto obj = [](const std::string& o) { return with_object(o); };
  const int L = kObjectLine;
  const std::string f = "objects[1]";
  return {
      // Malformed JSON: the line of the offending token.
      {"MissingComma", "{\n  \"format\": \"voxvis-scene/1\"\n  \"bounds\": {}\n}", 3, "",
       "malformed JSON"},
      {"TrailingComma", with_root(bounds + "  \"objects\": [1, 2,]"), 4, "", "malformed JSON"},
      {"Unterminated", "{\n  \"format\": \"voxvis-scene/1\",\n  \"objects\": [\n", 3, "",
       "malformed JSON"},
      {"Empty", "", 1, "", "malformed JSON"},
      {"TrailingGarbage", with_root(bounds + "  \"objects\": []") + "x\n", 6, "",
       "malformed JSON"},
      {"BadLiteral", obj(R"({"id": 1, "shape": "sphere", "center": [1, 1, 1], "radius": tru})"), L,
       "", "malformed JSON"},
      {"Comment", with_root(bounds + "  // no comments in JSON\n  \"objects\": []"), 4, "",
       "malformed JSON"},
      {"DuplicateKey",
       obj("{\"id\": 2, \"shape\": \"sphere\",\n     \"center\": [1, 1, 1], \"radius\": 1, "
           "\"radius\": 2}"),
       L + 1, f, "duplicate key 'radius', first at line 7"},
      // Overflow to infinity: the only way to write a non-finite number.
      {"Infinity", obj(R"({"id": 2, "shape": "sphere", "center": [1, 1, 1], "radius": 1e999})"), L,
       f + ".radius", "out of range"},
      {"NegativeInfinityInArray",
       obj(R"({"id": 2, "shape": "sphere", "center": [1, -1e999, 1], "radius": 1})"), L,
       f + ".center[1]", "out of range"},
      // Document structure.
      {"NotAnObject", "[1, 2, 3]", 1, "", "must be a JSON object"},
      {"MissingFormat", "{\n  \"objects\": []\n}", 1, "", "missing required key 'format'"},
      {"WrongFormat", "{\n  \"format\": \"voxvis-scene/2\",\n  \"objects\": []\n}", 2, "format",
       "unsupported format"},
      {"FormatNotString", "{\n  \"format\": 1,\n  \"objects\": []\n}", 2, "format",
       "unsupported format 1"},
      {"MissingBounds", with_root("  \"objects\": []"), 1, "", "missing required key 'bounds'"},
      {"UnknownRootKey", with_root(bounds + "  \"objects\": [],\n  \"foo\": 1"), 5, "",
       "unknown key 'foo'"},
      {"BoundsNotObject", with_root("  \"bounds\": [0, 0, 0],\n  \"objects\": []"), 3, "bounds",
       "must be an object"},
      {"BoundsMissingMax", with_root("  \"bounds\": {\"min\": [0, 0, 0]},\n  \"objects\": []"), 3,
       "bounds", "missing required key 'max'"},
      {"BoundsUnknownKey",
       with_root("  \"bounds\": {\"min\": [0, 0, 0], \"max\": [1, 1, 1], \"mid\": 2},\n"
                 "  \"objects\": []"),
       3, "bounds", "unknown key 'mid'"},
      {"BoundsShortArray",
       with_root("  \"bounds\": {\n    \"min\": [0, 0],\n    \"max\": [1, 1, 1]},\n"
                 "  \"objects\": []"),
       4, "bounds.min", "must be an array of 3 numbers, got 2 elements"},
      {"BoundsStringElement",
       with_root("  \"bounds\": {\"min\": [0, \"0\", 0], \"max\": [1, 1, 1]},\n  \"objects\": []"),
       3, "bounds.min[1]", "must be a number, got string \"0\""},
      {"BoundsMinEqualsMax",
       with_root("  \"bounds\": {\"min\": [0, 5, 0],\n  \"max\": [1, 5, 1]},\n  \"objects\": []"),
       4, "bounds.max", "max.y = 5 <= min.y = 5"},
      {"BoundsMinAboveMax",
       with_root("  \"bounds\": {\"min\": [3, 0, 0], \"max\": [1, 5, 1]},\n  \"objects\": []"),
       3, "bounds.max", "max.x = 1 <= min.x = 3"},
      {"BoundsTooLarge",
       with_root("  \"bounds\": {\"min\": [0, 0, -2e12], \"max\": [1, 1, 1]},\n  \"objects\": []"),
       3, "bounds.min[2]", "magnitude must be at most 1e+12, got -2e+12"},
      {"MissingObjects", with_root("  \"bounds\": {\"min\": [0, 0, 0], \"max\": [1, 1, 1]}"), 1, "",
       "missing required key 'objects'"},
      {"ObjectsNotArray", with_root(bounds + "  \"objects\": {}"), 4, "objects",
       "must be an array"},
      {"ObjectNotObject", with_root(bounds + "  \"objects\": [\n    3\n  ]"), 5, "objects[0]",
       "must be an object"},
      // Grid.
      {"GridZero", with_root(bounds + "  \"grid\": [0, 10, 10],\n  \"objects\": []"), 4, "grid[0]",
       "must be an integer >= 1"},
      {"GridNegative", with_root(bounds + "  \"grid\": [10, -3, 10],\n  \"objects\": []"), 4,
       "grid[1]", "must be an integer >= 1 (voxels along the axis), got -3"},
      {"GridFraction", with_root(bounds + "  \"grid\": [10, 10, 2.5],\n  \"objects\": []"), 4,
       "grid[2]", "got 2.5"},
      {"GridHuge", with_root(bounds + "  \"grid\": [100000, 10, 10],\n  \"objects\": []"), 4,
       "grid[0]", "must be at most 8192"},
      {"GridHugeUnsigned",
       with_root(bounds + "  \"grid\": [18446744073709551615, 10, 10],\n  \"objects\": []"), 4,
       "grid[0]", "must be at most 8192"},
      {"GridTwoEntries", with_root(bounds + "  \"grid\": [10, 10],\n  \"objects\": []"), 4, "grid",
       "got 2 elements"},
      // Objects.
      {"UnknownShape", obj(R"({"id": 2, "shape": "cone", "center": [1, 1, 1], "radius": 1})"), L,
       f + ".shape", "unknown shape \"cone\""},
      {"ShapeNotString", obj(R"({"id": 2, "shape": 3, "center": [1, 1, 1], "radius": 1})"), L,
       f + ".shape", "got 3"},
      {"MissingShape", obj(R"({"id": 2, "center": [1, 1, 1], "radius": 1})"), L, f,
       "missing required key 'shape'"},
      {"UnknownObjectKey",
       obj("{\"id\": 2, \"shape\": \"sphere\", \"center\": [1, 1, 1], \"radius\": 1,\n"
           "     \"colour\": \"red\"}"),
       L + 1, f, "unknown key 'colour'"},
      {"MissingId", obj(R"({"shape": "sphere", "center": [1, 1, 1], "radius": 1})"), L, f,
       "missing required key 'id'"},
      {"FractionalId", obj(R"({"id": 7.5, "shape": "sphere", "center": [1, 1, 1], "radius": 1})"),
       L, f + ".id", "must be an integer in [0, 4294967295], got 7.5"},
      {"NegativeId", obj(R"({"id": -1, "shape": "sphere", "center": [1, 1, 1], "radius": 1})"), L,
       f + ".id", "got -1"},
      {"IdTooLarge",
       obj(R"({"id": 4294967296, "shape": "sphere", "center": [1, 1, 1], "radius": 1})"), L,
       f + ".id", "got 4294967296"},
      {"IdString", obj(R"({"id": "7", "shape": "sphere", "center": [1, 1, 1], "radius": 1})"), L,
       f + ".id", "got string \"7\""},
      {"DuplicateId", obj(R"({"id": 1, "shape": "sphere", "center": [2, 2, 2], "radius": 1})"), L,
       f + ".id", "duplicate id 1, first at line 5 (objects[0])"},
      {"NegativeRadius",
       obj(R"({"id": 2, "shape": "sphere", "center": [1, 1, 1], "radius": -1})"), L,
       f + ".radius", "must be > 0, got -1"},
      {"ZeroRadius", obj(R"({"id": 2, "shape": "sphere", "center": [1, 1, 1], "radius": 0})"), L,
       f + ".radius", "must be > 0, got 0"},
      {"HugeRadius",
       obj(R"({"id": 2, "shape": "sphere", "center": [1, 1, 1], "radius": 1.5e12})"), L,
       f + ".radius", "must be at most 1e+12"},
      {"RadiusNotNumber",
       obj(R"({"id": 2, "shape": "sphere", "center": [1, 1, 1], "radius": null})"), L,
       f + ".radius", "must be a number, got null"},
      {"MissingRadius", obj(R"({"id": 2, "shape": "sphere", "center": [1, 1, 1]})"), L, f,
       "missing required key 'radius'"},
      {"CenterTooLarge",
       obj(R"({"id": 2, "shape": "sphere", "center": [1, 1e13, 1], "radius": 1})"), L,
       f + ".center[1]", "magnitude must be at most 1e+12"},
      {"CenterFourElements",
       obj(R"({"id": 2, "shape": "sphere", "center": [1, 1, 1, 1], "radius": 1})"), L,
       f + ".center", "got 4 elements"},
      {"CenterNotArray", obj(R"({"id": 2, "shape": "sphere", "center": 1, "radius": 1})"), L,
       f + ".center", "must be an array of 3 numbers, got 1"},
      {"SphereWithMin",
       obj(R"({"id": 2, "shape": "sphere", "center": [1, 1, 1], "radius": 1, "min": [0, 0, 0]})"),
       L, f, "'min' is not allowed for a sphere"},
      {"BoxWithRadius",
       obj(R"({"id": 2, "shape": "box", "min": [0, 0, 0], "max": [1, 1, 1], "radius": 1})"), L, f,
       "'radius' is not allowed for a box"},
      {"BoxMinAboveMax",
       obj("{\"id\": 2, \"shape\": \"box\",\n     \"min\": [0, 3, 0],\n     \"max\": [1, 1, 1]}"),
       L + 2, f + ".max", "max.y = 1 < min.y = 3"},
      {"BoxMissingMax", obj(R"({"id": 2, "shape": "box", "min": [0, 0, 0]})"), L, f,
       "missing required key 'max'"},
      {"BoxTooLarge", obj(R"({"id": 2, "shape": "box", "min": [0, 0, 0], "max": [1, 1, 2e12]})"), L,
       f + ".max[2]", "magnitude must be at most"},
      {"DynamicNotBool",
       obj(R"({"id": 2, "shape": "sphere", "center": [1, 1, 1], "radius": 1, "dynamic": "yes"})"),
       L, f + ".dynamic", "must be true or false, got string \"yes\""},
      {"DynamicWithoutSpeed",
       obj(R"({"id": 2, "shape": "sphere", "center": [1, 1, 1], "radius": 1, "dynamic": true})"), L,
       f, "dynamic objects need max_speed"},
      {"SpeedWithoutDynamic",
       obj(R"({"id": 2, "shape": "sphere", "center": [1, 1, 1], "radius": 1, "max_speed": 2})"), L,
       f + ".max_speed", "only allowed with \"dynamic\": true"},
      {"SpeedWithStatic",
       obj("{\"id\": 2, \"shape\": \"sphere\", \"center\": [1, 1, 1], \"radius\": 1,\n"
           "     \"dynamic\": false, \"max_speed\": 2}"),
       L + 1, f + ".max_speed", "only allowed with \"dynamic\": true"},
      {"NegativeSpeed",
       obj(R"({"id": 2, "shape": "sphere", "center": [1, 1, 1], "radius": 1, "dynamic": true, "max_speed": -2})"),
       L, f + ".max_speed", "must be >= 0, got -2"},
      {"SpeedNotNumber",
       obj(R"({"id": 2, "shape": "sphere", "center": [1, 1, 1], "radius": 1, "dynamic": true, "max_speed": "fast"})"),
       L, f + ".max_speed", "must be a number"},
  };
}

INSTANTIATE_TEST_SUITE_P(All, SceneRejection, ::testing::ValuesIn(scene_rejections()),
                         [](const auto& param_info) { return std::string(param_info.param.name); });

TEST(SceneFormat, LinesInALongDocument) {
  // Errors deep in a long document point at the right line.
  std::string text = "{\n  \"format\": \"voxvis-scene/1\",\n";
  text += "  \"bounds\": {\"min\": [0, 0, 0], \"max\": [10, 10, 10]},\n  \"objects\": [\n";
  for (int i = 0; i < 200; ++i) {
    // Each object spans three lines: {, "id"/"shape", "center"/"radius"}.
    text += "    {\n      \"id\": " + std::to_string(i) + ", \"shape\": \"sphere\",\n";
    text += "      \"center\": [1, 1, 1], \"radius\": " + std::string(i == 150 ? "-3" : "1") +
            "}" + (i + 1 < 200 ? "," : "") + "\n";
  }
  text += "  ]\n}\n";
  const FormatError err = parse_bad(text);
  EXPECT_EQ(err.field, "objects[150].radius");
  EXPECT_EQ(err.line, 4 + 150 * 3 + 3);
  EXPECT_EQ(err.str(), "scene.json:457: objects[150].radius: must be > 0, got -3");
}

TEST(SceneFormat, NumberAtEndOfLineKeepsItsLine) {
  // The lexer reads one character past a number; a newline there must not
  // move the reported line.
  for (const char* radius : {"-2", "1e999"}) {
    const std::string text =
        "{\n  \"format\": \"voxvis-scene/1\",\n  \"bounds\": {\"min\": [0, 0, 0], \"max\": [1, 1, 1]},\n"
        "  \"objects\": [\n    {\"id\": 1, \"shape\": \"sphere\", \"center\": [1, 1, 1],\n"
        "     \"radius\": " + std::string(radius) + "\n\n    }\n  ]\n}\n";
    const FormatError err = parse_bad(text);
    EXPECT_EQ(err.field, "objects[0].radius") << radius;
    EXPECT_EQ(err.line, 6) << radius;
  }
  // Same for a syntax error right after a number at the end of a line.
  const FormatError err = parse_bad(
      "{\n  \"format\": \"voxvis-scene/1\",\n  \"objects\": [1,\n    2\n    x]\n}\n");
  EXPECT_EQ(err.line, 5);
}

TEST(SceneFormat, DeepNestingIsRefusedNotCrashed) {
  std::string text = "{\"format\": \"voxvis-scene/1\", \"objects\": ";
  text += std::string(100000, '[');
  const FormatError err = parse_bad(text);
  EXPECT_THAT(err.message, HasSubstr("nesting deeper"));
}

TEST(SceneFormat, InvalidUtf8IsMalformed) {
  const FormatError err = parse_bad(with_root("  \"bounds\": {\"min\": [0, 0, 0], \"max\": [1, 1, 1]},\n"
                                              "  \"objects\": [],\n  \"\xff\": 1"));
  EXPECT_EQ(err.line, 5);
  EXPECT_THAT(err.message, HasSubstr("malformed JSON"));
}

// ---------------------------------------------------------------------------
// Round trips

TEST(SceneFormat, RoundTripIsExact) {
  SceneDesc d;
  d.bounds_min = Vec3(-12.25, 0.1, 3e-7);
  d.bounds_max = Vec3(1e12, 60.000000000000014, 100);
  d.grid = glm::ivec3(8192, 1, 33);
  ObjectDesc s;
  s.id = 4294967295u;
  s.center = Vec3(0.1, -0.30000000000000004, 1.0 / 3.0);
  s.radius = 2.5e-300;
  s.dynamic = true;
  s.max_speed = 1.0 / 7.0;
  d.objects.push_back(s);
  ObjectDesc b;
  b.id = 0;
  b.shape = Shape::Box;
  b.center = Vec3(1.5, -2.25, 0);
  b.half_extent = Vec3(0.5, 0, 1024);
  d.objects.push_back(b);

  const std::string text = scene_to_json(d);
  const SceneDesc back = parse_ok(text);
  EXPECT_EQ(back.bounds_min, d.bounds_min);
  EXPECT_EQ(back.bounds_max, d.bounds_max);
  EXPECT_EQ(back.grid, d.grid);
  ASSERT_EQ(back.objects.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    const ObjectDesc& x = d.objects[i];
    const ObjectDesc& y = back.objects[i];
    EXPECT_EQ(y.id, x.id);
    EXPECT_EQ(y.shape, x.shape);
    EXPECT_EQ(y.center, x.center);
    EXPECT_EQ(y.radius, x.shape == Shape::Sphere ? x.radius : 0.0);
    EXPECT_EQ(y.half_extent, x.half_extent);
    EXPECT_EQ(y.dynamic, x.dynamic);
    EXPECT_EQ(y.max_speed, x.max_speed);
  }
  // And the text is stable, its length foreseen exactly.
  EXPECT_EQ(scene_to_json(back), text);
  EXPECT_EQ(scene_json_bytes(d), text.size());
}

TEST(SceneFormat, RoundTripOfGeneratedScene) {
  PaperSceneParams p;
  p.objects = 300;
  p.dynamic = 20;
  const SceneDesc d = make_paper_scene(p);
  const SceneDesc back = parse_ok(scene_to_json(d));
  EXPECT_EQ(scene_json_bytes(d), scene_to_json(d).size());
  ASSERT_EQ(back.objects.size(), d.objects.size());
  EXPECT_FALSE(back.grid.has_value());
  for (std::size_t i = 0; i < d.objects.size(); ++i) {
    EXPECT_EQ(back.objects[i].id, d.objects[i].id);
    EXPECT_EQ(back.objects[i].center, d.objects[i].center);
    EXPECT_EQ(back.objects[i].radius, d.objects[i].radius);
    EXPECT_EQ(back.objects[i].dynamic, d.objects[i].dynamic);
    EXPECT_EQ(back.objects[i].max_speed, d.objects[i].max_speed);
  }
}

TEST(SceneFormat, EmptySceneRoundTrips) {
  SceneDesc d;
  const std::string text = scene_to_json(d);
  EXPECT_TRUE(parse_ok(text).objects.empty());
  EXPECT_EQ(scene_json_bytes(d), text.size());
}

// ---------------------------------------------------------------------------
// Frames

constexpr const char* kFrame =
    R"({"t": 0.5, "eye": [1, 2, 3], "dir": [0, 0, -1], "up": [0, 1, 0], "fov_y_deg": 60, )"
    R"("aspect": 1.78, "near": 0.05, "far": 1000, "moves": [{"id": 8, "center": [4, 5, 6]}]})";

/// kFrame with the text `from` replaced by `to`.
std::string frame_with(const std::string& from, const std::string& to) {
  std::string s = kFrame;
  const std::size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) s.replace(at, from.size(), to);
  return s;
}

FormatError frame_bad(const std::string& text, int line = 17) {
  FrameInput f;
  FormatError err;
  EXPECT_FALSE(parse_frame_line(text, "frames.jsonl", line, &f, &err)) << "accepted: " << text;
  EXPECT_EQ(err.source, "frames.jsonl");
  EXPECT_EQ(err.line, line);
  return err;
}

TEST(FrameFormat, ParsesAFrame) {
  FrameInput f;
  FormatError err;
  ASSERT_TRUE(parse_frame_line(kFrame, "frames.jsonl", 3, &f, &err)) << err.str();
  EXPECT_EQ(f.t, 0.5);
  EXPECT_EQ(f.camera.eye, Vec3(1, 2, 3));
  EXPECT_EQ(f.camera.dir, Vec3(0, 0, -1));
  EXPECT_EQ(f.camera.up, Vec3(0, 1, 0));
  EXPECT_EQ(f.camera.fov_y_deg, 60.0);
  EXPECT_EQ(f.camera.aspect, 1.78);
  EXPECT_EQ(f.camera.near, 0.05);
  EXPECT_EQ(f.camera.far, 1000.0);
  ASSERT_EQ(f.moves.size(), 1u);
  EXPECT_EQ(f.moves[0].id, 8u);
  EXPECT_EQ(f.moves[0].center, Vec3(4, 5, 6));
  EXPECT_EQ(f.line, 3);
}

TEST(FrameFormat, MovesAreOptional) {
  FrameInput f;
  FormatError err;
  const std::string text = frame_with(R"(, "moves": [{"id": 8, "center": [4, 5, 6]}])", "");
  ASSERT_TRUE(parse_frame_line(text, "frames.jsonl", 1, &f, &err)) << err.str();
  EXPECT_TRUE(f.moves.empty());
  ASSERT_TRUE(parse_frame_line(frame_with("[{\"id\": 8, \"center\": [4, 5, 6]}]", "[]"),
                               "frames.jsonl", 1, &f, &err))
      << err.str();
  EXPECT_TRUE(f.moves.empty());
  // Trailing carriage return (CRLF files) and spaces are fine.
  ASSERT_TRUE(parse_frame_line(std::string(kFrame) + " \r", "frames.jsonl", 1, &f, &err))
      << err.str();
}

TEST(FrameFormat, Rejections) {
  struct Case {
    std::string text, field, message;
  };
  const std::vector<Case> cases = {
      {"", "", "empty line"},
      {"   \r", "", "empty line"},
      {"{\"t\": 1,", "", "malformed JSON"},
      {"[1, 2]", "", "must be a JSON object"},
      {frame_with("\"t\": 0.5", "\"t\": 1e999"), "t", "out of range"},
      {frame_with("\"t\": 0.5, ", ""), "", "missing required key 't'"},
      {frame_with("\"t\": 0.5", "\"t\": \"soon\""), "t", "must be a number"},
      {frame_with("\"near\": 0.05, ", ""), "", "missing required key 'near'"},
      {frame_with("\"t\": 0.5", "\"t\": 0.5, \"zoom\": 2"), "", "unknown key 'zoom'"},
      {frame_with("\"t\": 0.5", "\"t\": 0.5, \"t\": 0.6"), "", "duplicate key 't'"},
      {frame_with("\"eye\": [1, 2, 3]", "\"eye\": [1, 2]"), "eye", "got 2 elements"},
      {frame_with("\"eye\": [1, 2, 3]", "\"eye\": [1, 2e12, 3]"), "eye[1]", "magnitude"},
      {frame_with("\"dir\": [0, 0, -1]", "\"dir\": [0, -1e999, -1]"), "dir[1]", "out of range"},
      // Camera checks come from validate_camera (the engine's rules).
      {frame_with("\"up\": [0, 1, 0]", "\"up\": [0, 0, -2]"), "up", "parallel"},
      {frame_with("\"dir\": [0, 0, -1]", "\"dir\": [0, 0, 0]"), "dir", ""},
      {frame_with("\"fov_y_deg\": 60", "\"fov_y_deg\": 180"), "fov_y_deg", ""},
      {frame_with("\"fov_y_deg\": 60", "\"fov_y_deg\": 0"), "fov_y_deg", ""},
      {frame_with("\"fov_y_deg\": 60", "\"fov_y_deg\": 5e-324"), "fov_y_deg", "must be in [1e-06, 180)"},
      {frame_with("\"aspect\": 1.78", "\"aspect\": 0"), "aspect", ""},
      {frame_with("\"near\": 0.05", "\"near\": 0"), "near", ""},
      {frame_with("\"near\": 0.05", "\"near\": 1000"), "far", ""},
      {frame_with("\"far\": 1000", "\"far\": 0.01"), "far", ""},
      // Moves.
      {frame_with("\"moves\": [", "\"moves\": 3, \"x\": ["), "", "unknown key 'x'"},
      {frame_with("[{\"id\": 8, \"center\": [4, 5, 6]}]", "{}"), "moves", "must be an array"},
      {frame_with("{\"id\": 8, \"center\": [4, 5, 6]}", "{\"id\": 8, \"center\": [4, 5, 6]}, 5"),
       "moves[1]", "must be an object"},
      {frame_with("\"id\": 8,", "\"id\": 8.5,"), "moves[0].id", "got 8.5"},
      {frame_with("\"id\": 8,", "\"id\": -8,"), "moves[0].id", "got -8"},
      {frame_with("\"id\": 8,", ""), "moves[0]", "missing required key 'id'"},
      {frame_with("\"center\": [4, 5, 6]", "\"center\": [4, 5]"), "moves[0].center",
       "got 2 elements"},
      {frame_with("\"center\": [4, 5, 6]", "\"centre\": [4, 5, 6]"), "moves[0]",
       "unknown key 'centre'"},
      {frame_with("\"center\": [4, 5, 6]}", "\"center\": [4, 5, 6]}, {\"id\": 8, \"center\": [1, 1, 1]}"),
       "moves[1].id", "duplicate id 8"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.text);
    const FormatError err = frame_bad(c.text, 17);
    EXPECT_EQ(err.field, c.field) << err.str();
    EXPECT_THAT(err.message, HasSubstr(c.message)) << err.str();
    EXPECT_THAT(err.str(), HasSubstr("frames.jsonl:17: "));
  }
}

TEST(FrameFormat, CamerasFollowTheEngineRuleExactly) {
  // One rule for the file, the wire and the engine (validate_camera): a
  // direction of any finite magnitude is accepted (the file refused dir
  // components beyond 1e12 that the server took, so such frames could not
  // be replayed), an eye beyond kMaxCoordinate is refused by both.
  for (const char* dir : {"[1e308, 0, 1]", "[0, 5e-324, -1]", "[-1e308, -1e308, 1e308]"}) {
    FrameInput f;
    FormatError err;
    const std::string text = frame_with("\"dir\": [0, 0, -1]", std::string("\"dir\": ") + dir);
    ASSERT_TRUE(parse_frame_line(text, "frames.jsonl", 1, &f, &err)) << dir << ": " << err.str();
    EXPECT_TRUE(validate_camera(f.camera).ok);
    // And it reads back as written.
    FrameInput back;
    ASSERT_TRUE(parse_frame_line(frame_to_json(f), "frames.jsonl", 1, &back, &err)) << err.str();
    EXPECT_EQ(back.camera.dir, f.camera.dir);
  }
  FrameInput f;
  FormatError err;
  ASSERT_TRUE(parse_frame_line(kFrame, "frames.jsonl", 1, &f, &err)) << err.str();
  f.camera.eye.y = 2e12;
  EXPECT_EQ(validate_camera(f.camera).field, "eye");
  EXPECT_EQ(frame_bad(frame_with("\"eye\": [1, 2, 3]", "\"eye\": [1, 2e12, 3]"), 1).field, "eye[1]");
}

TEST(FrameFormat, RoundTripIsExact) {
  FrameInput f;
  f.t = 1.0 / 60.0 * 299.0;
  f.camera.eye = Vec3(0.1, 0.2, 1e12);
  f.camera.dir = Vec3(-0.7071067811865476, 1e-300, 0.7071067811865475);
  f.camera.up = Vec3(0, 1, 0);
  f.camera.fov_y_deg = 59.999999999999993;
  f.camera.aspect = 16.0 / 9.0;
  f.camera.near = 0.05;
  f.camera.far = 1000;
  f.moves = {Move{3, Vec3(1.0 / 3.0, -2.0 / 3.0, 5e-324)}, Move{4294967295u, Vec3(0, 0, 0)}};
  const std::string text = frame_to_json(f);
  EXPECT_EQ(text.find('\n'), std::string::npos);
  FrameInput g;
  FormatError err;
  ASSERT_TRUE(parse_frame_line(text, "frames.jsonl", 9, &g, &err)) << err.str();
  EXPECT_EQ(g.t, f.t);
  EXPECT_EQ(g.camera.eye, f.camera.eye);
  EXPECT_EQ(g.camera.dir, f.camera.dir);
  EXPECT_EQ(g.camera.up, f.camera.up);
  EXPECT_EQ(g.camera.fov_y_deg, f.camera.fov_y_deg);
  EXPECT_EQ(g.camera.aspect, f.camera.aspect);
  EXPECT_EQ(g.camera.near, f.camera.near);
  EXPECT_EQ(g.camera.far, f.camera.far);
  ASSERT_EQ(g.moves.size(), 2u);
  EXPECT_EQ(g.moves[0].id, 3u);
  EXPECT_EQ(g.moves[0].center, f.moves[0].center);
  EXPECT_EQ(g.moves[1].id, 4294967295u);
  EXPECT_EQ(frame_to_json(g), text);
  // No moves: no "moves" key.
  f.moves.clear();
  EXPECT_THAT(frame_to_json(f), Not(HasSubstr("moves")));
}

TEST(FrameFormat, WholeFileSkipsBlankLinesAndCountsThem) {
  // Blank lines anywhere, Windows line endings, no newline at the end.
  std::istringstream in(std::string("\n") + kFrame + "\n\n \t\r\n" + kFrame + "\r\n" + kFrame);
  std::vector<FrameInput> frames;
  FormatError err;
  ASSERT_TRUE(parse_frames(in, "frames.jsonl", &frames, &err)) << err.str();
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[0].line, 2);
  EXPECT_EQ(frames[1].line, 5);
  EXPECT_EQ(frames[2].line, 6);
  EXPECT_EQ(frames[2].moves.size(), 1u);
  EXPECT_TRUE(is_blank_line(" \t\r"));
  EXPECT_FALSE(is_blank_line(" x"));
}

TEST(FrameFormat, WholeFileStopsAtTheFirstErrorWithItsLine) {
  std::istringstream in(std::string(kFrame) + "\n\n" + frame_with("\"far\": 1000", "\"far\": 0.01") + "\n" +
                        "{\"broken\"\n");
  std::vector<FrameInput> frames;
  FormatError err;
  ASSERT_FALSE(parse_frames(in, "frames.jsonl", &frames, &err));
  EXPECT_EQ(err.str(), "frames.jsonl:3: far: must be finite and > near, got 0.01");
  ASSERT_EQ(frames.size(), 1u);  // The frames before the error.
  EXPECT_EQ(frames[0].line, 1);
}

TEST(FrameFormat, WholeFileWithoutFramesIsNotAnErrorHere) {
  for (const char* text : {"", "\n", " \r\n\t\n"}) {
    std::istringstream in(text);
    std::vector<FrameInput> frames;
    FormatError err;
    EXPECT_TRUE(parse_frames(in, "frames.jsonl", &frames, &err)) << err.str();
    EXPECT_TRUE(frames.empty());
  }
}

// ---------------------------------------------------------------------------
// Output lines

TEST(ResultFormat, OneCompactLineWithAllFields) {
  FrameResult r;
  r.pvs = {1, 5, 4294967295u};
  r.wake = {5};
  r.stats.voxels_visited = 123456789012ull;
  r.stats.shells = 17;
  r.stats.objects_discretized = 2;
  r.stats.tbvs_created = 3;
  r.stats.tbvs_revealed = 4;
  r.stats.tbvs_expired = 5;
  r.stats.tbvs_active = 6;
  r.stats.speed_violations = 7;
  r.stats.outside_tested = 8;
  r.stats.pvs_size = 3;
  r.stats.early_exit = true;
  r.stats.frustum_fallback = true;
  r.stats.front_voxels_culled = 9;
  r.stats.front_objects_culled = 10;
  r.stats.time_us = 12.3456;
  r.stats.traverse_us = 7.0004;
  r.stats.render_us = 2.5;
  r.stats.retest_us = std::numeric_limits<double>::quiet_NaN();  // Written as 0.
  const std::string line = result_to_json(42, r);
  EXPECT_EQ(line.find('\n'), std::string::npos);
  EXPECT_EQ(line.find(' '), std::string::npos);
  const nlohmann::json j = nlohmann::json::parse(line);
  EXPECT_EQ(j.size(), 4u);
  EXPECT_EQ(j.at("frame"), 42);
  EXPECT_EQ(j.at("pvs"), nlohmann::json::array({1, 5, 4294967295u}));
  EXPECT_EQ(j.at("wake"), nlohmann::json::array({5}));
  const nlohmann::json& s = j.at("stats");
  EXPECT_EQ(s.size(), 18u);  // No buffer counters: ob_width is 0 (off).
  EXPECT_NEAR(s.at("time_us").get<double>(), 12.346, 1e-9);
  EXPECT_NEAR(s.at("traverse_us").get<double>(), 7.0, 1e-9);
  EXPECT_NEAR(s.at("render_us").get<double>(), 2.5, 1e-9);
  EXPECT_EQ(s.at("retest_us").get<double>(), 0.0);
  EXPECT_EQ(s.at("voxels_visited"), 123456789012ull);
  EXPECT_EQ(s.at("shells"), 17);
  EXPECT_EQ(s.at("objects_discretized"), 2);
  EXPECT_EQ(s.at("tbvs_created"), 3);
  EXPECT_EQ(s.at("tbvs_revealed"), 4);
  EXPECT_EQ(s.at("tbvs_expired"), 5);
  EXPECT_EQ(s.at("tbvs_active"), 6);
  EXPECT_EQ(s.at("speed_violations"), 7);
  EXPECT_EQ(s.at("outside_tested"), 8);
  EXPECT_EQ(s.at("pvs_size"), 3);
  EXPECT_EQ(s.at("early_exit"), true);
  EXPECT_EQ(s.at("frustum_fallback"), true);
  EXPECT_EQ(s.at("front_voxels_culled"), 9);
  EXPECT_EQ(s.at("front_objects_culled"), 10);
}

TEST(ResultFormat, EmptyResult) {
  const std::string line = result_to_json(0, FrameResult{});
  EXPECT_THAT(line, HasSubstr("{\"frame\":0,\"pvs\":[],\"wake\":[],\"stats\":{\"time_us\":0.000,"));
  EXPECT_THAT(line, HasSubstr("\"early_exit\":false,\"frustum_fallback\":false,\"front_voxels_culled\":0,\"front_objects_culled\":0}}"));
  EXPECT_FALSE(nlohmann::json::parse(line, nullptr, false).is_discarded());
}

// ---------------------------------------------------------------------------
// Generators

TEST(Generate, PaperSceneShape) {
  PaperSceneParams p;
  p.objects = 1000;
  p.dynamic = 50;
  const SceneDesc d = make_paper_scene(p);
  ASSERT_EQ(d.objects.size(), 1000u);
  EXPECT_EQ(d.bounds_min, p.bounds_min);
  EXPECT_EQ(d.bounds_max, p.bounds_max);
  double small = 0;
  for (std::size_t i = 0; i < d.objects.size(); ++i) {
    const ObjectDesc& o = d.objects[i];
    EXPECT_EQ(o.id, static_cast<ObjectId>(i + 1));
    EXPECT_EQ(o.shape, Shape::Sphere);
    EXPECT_EQ(o.dynamic, i < 50);
    EXPECT_EQ(o.max_speed, i < 50 ? p.max_speed : 0.0);
    EXPECT_GE(o.radius, 0.3);
    EXPECT_LE(o.radius, 2.5);
    if (o.radius < 1.0) ++small;
    for (int a = 0; a < 3; ++a) {
      EXPECT_GE(o.center[a], p.bounds_min[a]);
      EXPECT_LE(o.center[a], p.bounds_max[a]);
    }
  }
  EXPECT_GT(small, 400);  // Skewed towards small radii.
}

TEST(Generate, DeterministicPerSeed) {
  PaperSceneParams p;
  p.objects = 400;
  p.dynamic = 30;
  const std::string a = scene_to_json(make_paper_scene(p));
  EXPECT_EQ(a, scene_to_json(make_paper_scene(p)));
  PaperSceneParams q = p;
  q.seed = 99;
  EXPECT_NE(a, scene_to_json(make_paper_scene(q)));

  const SceneDesc scene = make_paper_scene(p);
  WalkthroughParams w;
  w.frames = 50;
  const auto text = [&](const WalkthroughParams& params) {
    std::string out;
    for (const FrameInput& f : make_walkthrough(scene, params)) out += frame_to_json(f) + "\n";
    return out;
  };
  const std::string fa = text(w);
  EXPECT_EQ(fa, text(w));
  WalkthroughParams w2 = w;
  w2.seed = 3;
  EXPECT_NE(fa, text(w2));
}

TEST(Generate, WalkthroughCamerasAndMoves) {
  PaperSceneParams p;
  p.objects = 500;
  p.dynamic = 100;
  p.max_speed = 3.0;
  const SceneDesc scene = make_paper_scene(p);
  WalkthroughParams w;
  w.frames = 600;
  w.fps = 30;
  const std::vector<FrameInput> frames = make_walkthrough(scene, w);
  ASSERT_EQ(frames.size(), 600u);

  std::vector<Vec3> pos;
  for (const ObjectDesc& o : scene.objects) pos.push_back(o.center);
  double moved = 0.0;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const FrameInput& f = frames[i];
    EXPECT_DOUBLE_EQ(f.t, static_cast<double>(i) / 30.0);
    EXPECT_TRUE(validate_camera(f.camera).ok) << validate_camera(f.camera).str();
    EXPECT_EQ(f.camera.up, Vec3(0, 1, 0));
    for (int a = 0; a < 3; ++a) {
      EXPECT_GT(f.camera.eye[a], scene.bounds_min[a]);
      EXPECT_LT(f.camera.eye[a], scene.bounds_max[a]);
    }
    // Every frame moves every dynamic object (ids 1..100), at most
    // max_speed * dt from where it was, and inside the bounds.
    ASSERT_EQ(f.moves.size(), 100u);
    const double dt = i == 0 ? 0.0 : f.t - frames[i - 1].t;
    for (std::size_t k = 0; k < f.moves.size(); ++k) {
      const Move& m = f.moves[k];
      ASSERT_EQ(m.id, static_cast<ObjectId>(k + 1));
      Vec3& prev = pos[m.id - 1];
      const double d = glm::length(m.center - prev);
      EXPECT_LE(d, p.max_speed * dt) << "frame " << i << " id " << m.id;
      moved += d;
      prev = m.center;
      for (int a = 0; a < 3; ++a) {
        EXPECT_GE(m.center[a], scene.bounds_min[a]);
        EXPECT_LE(m.center[a], scene.bounds_max[a]);
      }
    }
  }
  EXPECT_GT(moved, 0.0);

  w.moves = false;
  for (const FrameInput& f : make_walkthrough(scene, w)) EXPECT_TRUE(f.moves.empty());
}

TEST(Generate, MovesNeverExceedTheLimitNearWallsOrOutside) {
  // Objects hugging the walls or lying outside the bounds, fast and slow.
  SceneDesc scene;
  scene.bounds_min = Vec3(0, 0, 0);
  scene.bounds_max = Vec3(1, 1, 1);
  const std::vector<std::pair<Vec3, double>> objs = {
      {Vec3(0, 0, 0), 100.0},       {Vec3(1, 1, 1), 0.5},     {Vec3(0.5, 0.5, 0.5), 1e3},
      {Vec3(-5, 2, 0.5), 30.0},     {Vec3(0.5, 0.5, 0.5), 0.0}, {Vec3(1e11, 0, 0), 1e-3}};
  for (std::size_t i = 0; i < objs.size(); ++i) {
    ObjectDesc o;
    o.id = static_cast<ObjectId>(10 + i);
    o.center = objs[i].first;
    o.radius = 0.1;
    o.dynamic = true;
    o.max_speed = objs[i].second;
    scene.objects.push_back(o);
  }
  WalkthroughParams w;
  w.frames = 400;
  const std::vector<FrameInput> frames = make_walkthrough(scene, w);
  std::vector<Vec3> pos;
  for (const auto& o : objs) pos.push_back(o.first);
  for (std::size_t i = 1; i < frames.size(); ++i) {
    const double dt = frames[i].t - frames[i - 1].t;
    ASSERT_EQ(frames[i].moves.size(), objs.size());
    for (std::size_t k = 0; k < objs.size(); ++k) {
      const Vec3 c = frames[i].moves[k].center;
      EXPECT_LE(glm::length(c - pos[k]), objs[k].second * dt) << "frame " << i << " object " << k;
      pos[k] = c;
    }
  }
}

}  // namespace
}  // namespace voxvis
