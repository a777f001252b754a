// fuzz_import.cpp — libFuzzer target of the model importer's entry point
// (voxvis::import::import_memory): assimp's reader for the format, its
// post-processing, then voxvis's conversion (node walk, placement, the
// triangles' checks). An input is one byte choosing the format (its value
// modulo the number of formats below) followed by the model file. Besides
// the sanitizers' checks:
//  * a refused model's error names the source, in printable text, with a
//    message;
//  * an accepted one gives at least one object, every object a valid mesh
//    object (validate_mesh_object: what the scene format and the engine
//    require), the counts adding up, and a dynamic import (every object
//    named dynamic) places every vertex where the static import put it.
// assimp is Debian's, not instrumented: a crash inside it shows as a crash
// with its frames in libassimp.so (docs/fuzzing.md, "Findings in assimp").
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_check.h"
#include "voxvis/import.h"
#include "voxvis/mesh.h"

namespace voxvis::fuzz {
namespace {

constexpr const char* kHints[] = {"gltf", "glb", "obj", "ply", "stl", "off"};
constexpr std::size_t kHintCount = sizeof kHints / sizeof kHints[0];

void check_refusal(const Status& st, const std::string& source) {
  const std::string where = "error \"" + st.str() + "\": ";
  if (st.message.empty()) fail(where + "no message");
  if (st.field != source) fail(where + "does not name the source \"" + source + "\"");
  // The model's own bytes (node names, assimp's quotes of the input) may be
  // in the message; they are the user's file, not control sequences of ours,
  // so only the field is held to printable ASCII.
  if (!printable(st.field)) fail(where + "field is not printable ASCII");
}

void check_accepted(const import::ImportResult& r) {
  if (r.objects.empty()) fail("accepted with no object");
  std::size_t triangles = 0, vertices = 0;
  for (const import::ImportedObject& o : r.objects) {
    if (const Status st = validate_mesh_object(o.desc, "object"); !st)
      fail("object '" + o.name + "' is not a valid mesh object: " + st.str());
    triangles += o.desc.mesh->triangles.size();
    vertices += o.desc.mesh->vertices.size();
  }
  if (triangles != r.stats.triangles || vertices != r.stats.vertices) fail("the counts do not add up");
}

/// Largest distance between where the static and the dynamic import put a
/// vertex, relative to the vertex's magnitude (and the node's translation).
void check_dynamic_placement(const import::ImportResult& fixed, const import::ImportResult& moving) {
  // An object whose every triangle has area in one placement and none in
  // the other is kept by one import only: nothing to compare then.
  if (fixed.objects.size() != moving.objects.size()) return;
  for (std::size_t i = 0; i < fixed.objects.size(); ++i) {
    const ObjectDesc& a = fixed.objects[i].desc;
    const ObjectDesc& b = moving.objects[i].desc;
    if (!b.dynamic) fail("dynamic import: object '" + moving.objects[i].name + "' not dynamic");
    if (a.mesh->triangles.size() != b.mesh->triangles.size()) {
      // A triangle may have area in one placement and round to none in the
      // other (both are checked exactly): then the counts differ, and the
      // vertices are not compared.
      continue;
    }
    for (std::size_t t = 0; t < a.mesh->triangles.size(); ++t)
      for (std::size_t k = 0; k < 3; ++k) {
        const Vec3 pa = place(a, a.mesh->vertices[a.mesh->triangles[t][k]]);
        const Vec3 pb = place(b, b.mesh->vertices[b.mesh->triangles[t][k]]);
        const double scale = std::max({1.0, std::fabs(pa.x), std::fabs(pa.y), std::fabs(pa.z),
                                       std::fabs(b.center.x), std::fabs(b.center.y), std::fabs(b.center.z)});
        const Vec3 d = pa - pb;
        if (std::max({std::fabs(d.x), std::fabs(d.y), std::fabs(d.z)}) > 1e-6 * scale * std::max(1.0, b.scale))
          fail("dynamic import: object '" + moving.objects[i].name + "' vertex placed elsewhere than the static one");
      }
  }
}

}  // namespace
}  // namespace voxvis::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace voxvis;
  if (size < 1) return 0;
  const std::string hint = fuzz::kHints[data[0] % fuzz::kHintCount];
  const std::string source = std::string("fuzz.") + hint;
  import::ImportResult fixed;
  const Status st = import::import_memory(data + 1, size - 1, hint, source, {}, &fixed);
  if (!st) {
    fuzz::check_refusal(st, source);
    return 0;
  }
  fuzz::check_accepted(fixed);
  // Every object dynamic: its node's placement instead of the baked one.
  import::ImportOptions options;
  for (const import::ImportedObject& o : fixed.objects) options.dynamic_names.push_back(o.name);
  options.max_speed = 1.0;
  import::ImportResult moving;
  const Status st2 = import::import_memory(data + 1, size - 1, hint, source, options, &moving);
  if (!st2) {
    // The dynamic import checks the same triangles in the node's frame: it
    // may refuse a model only for a reason of that frame (a vertex too large
    // or not finite there, every triangle degenerate there).
    fuzz::check_refusal(st2, source);
    return 0;
  }
  fuzz::check_accepted(moving);
  fuzz::check_dynamic_placement(fixed, moving);
  return 0;
}
