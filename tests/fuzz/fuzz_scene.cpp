// fuzz_scene.cpp — libFuzzer target of the scene parser (parse_scene) and
// its writer (scene_to_json). An input is a scene file. Besides the
// sanitizers' checks:
//  * a refused document gets an error on one of its lines, in printable text;
//  * an accepted one survives a round trip: its written text parses back to
//    the same scene, and writing that again gives the same text (the server
//    stores scenes made from CreateScene descriptions this way, and reloads
//    them after a restart), and scene_json_bytes foresees its length exactly;
//  * scene_field_line, which puts the engine's errors on lines, finds a line
//    of the document.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "fuzz_check.h"
#include "voxvis/format.h"

namespace voxvis::fuzz {
namespace {

bool same_mesh(const Mesh& a, const Mesh& b) {
  if (a.vertices.size() != b.vertices.size() || a.triangles != b.triangles) return false;
  for (std::size_t i = 0; i < a.vertices.size(); ++i) {
    if (!same(a.vertices[i], b.vertices[i])) return false;
  }
  return true;
}

/// Exactly the same, field by field (only the fields of the object's shape).
bool same_object(const ObjectDesc& a, const ObjectDesc& b) {
  if (a.id != b.id || a.shape != b.shape || !same(a.center, b.center) || a.dynamic != b.dynamic) return false;
  if (a.dynamic && !same(a.max_speed, b.max_speed)) return false;
  switch (a.shape) {
    case Shape::Sphere:
      return same(a.radius, b.radius);
    case Shape::Box:
      return same(a.half_extent, b.half_extent);
    case Shape::Mesh:
      return a.mesh != nullptr && b.mesh != nullptr && same_mesh(*a.mesh, *b.mesh) &&
             same(a.rotation, b.rotation) && same(a.scale, b.scale);
  }
  return false;
}

/// The first difference between two scenes, or "" when they are the same.
std::string difference(const SceneDesc& a, const SceneDesc& b) {
  if (!same(a.bounds_min, b.bounds_min) || !same(a.bounds_max, b.bounds_max)) return "bounds";
  if (a.grid != b.grid) return "grid";
  if (a.objects.size() != b.objects.size()) return "objects: count";
  for (std::size_t i = 0; i < a.objects.size(); ++i) {
    if (!same_object(a.objects[i], b.objects[i])) return "objects[" + std::to_string(i) + "]";
  }
  return {};
}

void check_round_trip(const SceneDesc& scene) {
  const std::string written = scene_to_json(scene);
  SceneDesc back;
  FormatError error;
  if (!parse_scene(written, "written.json", &back, &error)) {
    fail("the written scene does not parse: " + error.str() + "\n" + written);
  }
  if (const std::string diff = difference(scene, back); !diff.empty()) {
    fail("the written scene parses to another scene (" + diff + "):\n" + written);
  }
  if (scene_to_json(back) != written) fail("writing the scene again gives another text:\n" + written);
  // The server refuses a scene by this figure before writing its text.
  if (scene_json_bytes(scene) != written.size())
    fail("scene_json_bytes says " + std::to_string(scene_json_bytes(scene)) + " bytes, the text has " +
         std::to_string(written.size()) + ":\n" + written);
}

}  // namespace
}  // namespace voxvis::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace voxvis;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  SceneDesc scene;
  FormatError error;
  if (!parse_scene(text, "fuzz.json", &scene, &error)) {
    fuzz::check_error(error, "fuzz.json", text);
    return 0;
  }
  fuzz::check_round_trip(scene);
  // The engine names fields such as objects[3].center; any such path must
  // land on a line of the document.
  const std::string field = scene.objects.empty()
                                ? std::string("grid")
                                : "objects[" + std::to_string(scene.objects.size() - 1) + "].center";
  const int line = scene_field_line(text, field);
  if (line < 1 || line > fuzz::line_count(text)) {
    fuzz::fail(field + " is on line " + std::to_string(line) + ", not a line of the input");
  }
  return 0;
}
