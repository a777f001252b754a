// models.h — small model files with known contents for the importer's tests:
// a glTF 2.0 document whose one buffer (embedded as a data URI) holds a unit
// square's four corners and three index lists, and the nodes the test gives.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace voxvis::test {

/// The path of a model of Debian's assimp-testmodels, or empty when the
/// package is not installed.
inline std::string test_model(const std::string& relative) {
  const std::string root = "/usr/share/assimp/models/";
  const std::string p = root + relative;
  FILE* f = std::fopen(p.c_str(), "rb");
  if (f == nullptr) return "";
  std::fclose(f);
  return p;
}

inline std::string base64(const std::vector<std::uint8_t>& bytes) {
  static const char* digits = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    const std::uint32_t b0 = bytes[i];
    const std::uint32_t b1 = i + 1 < bytes.size() ? bytes[i + 1] : 0;
    const std::uint32_t b2 = i + 2 < bytes.size() ? bytes[i + 2] : 0;
    const std::uint32_t v = (b0 << 16) | (b1 << 8) | b2;
    out += digits[(v >> 18) & 63];
    out += digits[(v >> 12) & 63];
    out += i + 1 < bytes.size() ? digits[(v >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? digits[v & 63] : '=';
  }
  return out;
}

/// A glTF document with two meshes over the corners (0,0,0), (1,0,0),
/// (1,1,0), (0,1,0) of the unit square: mesh 0 "Tri", one primitive, the
/// triangle (0,0,0) (1,0,0) (0,1,0); mesh 1 "Quad", two primitives, the
/// triangles (0,0,0) (1,0,0) (1,1,0) and (0,0,0) (1,1,0) (0,1,0). `nodes`
/// is the JSON array of nodes, `roots` that of the scene's root nodes.
/// The 72 bytes of the glTF documents' one buffer: the corners (48), then
/// three index lists of three, each padded to 8 bytes (24).
inline std::vector<std::uint8_t> gltf_buffer() {
  const float corners[4][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  const std::uint16_t idx[12] = {0, 1, 3, 0, 0, 1, 2, 0, 0, 2, 3, 0};
  std::vector<std::uint8_t> buf(sizeof corners + sizeof idx);
  std::memcpy(buf.data(), corners, sizeof corners);
  std::memcpy(buf.data() + sizeof corners, idx, sizeof idx);
  return buf;
}

/// gltf_with_nodes, its buffer at `uri` (a data URI by default; a file's
/// path relative to the document, to test external references).
inline std::string gltf_with_nodes(const std::string& nodes, const std::string& roots, const std::string& uri = "") {
  const std::string buffer_uri = uri.empty() ? "data:application/octet-stream;base64," + base64(gltf_buffer()) : uri;
  return R"({
  "asset": {"version": "2.0"},
  "scene": 0,
  "scenes": [{"nodes": )" + roots + R"(}],
  "nodes": )" + nodes + R"(,
  "meshes": [
    {"name": "Tri", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]},
    {"name": "Quad", "primitives": [{"attributes": {"POSITION": 0}, "indices": 2},
                                    {"attributes": {"POSITION": 0}, "indices": 3}]}
  ],
  "buffers": [{"byteLength": 72, "uri": ")" + buffer_uri + R"("}],
  "bufferViews": [
    {"buffer": 0, "byteOffset": 0, "byteLength": 48, "target": 34962},
    {"buffer": 0, "byteOffset": 48, "byteLength": 24, "target": 34963}
  ],
  "accessors": [
    {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
    {"bufferView": 1, "byteOffset": 0, "componentType": 5123, "count": 3, "type": "SCALAR"},
    {"bufferView": 1, "byteOffset": 8, "componentType": 5123, "count": 3, "type": "SCALAR"},
    {"bufferView": 1, "byteOffset": 16, "componentType": 5123, "count": 3, "type": "SCALAR"}
  ]
}
)";
}

/// The level the tests import: a root "Level" moved by (10, 0, 0) holding
/// "Mover" (Tri; translated (1, 2, 3), turned 90 degrees about y, scaled 2),
/// "Wall" (Quad; scaled (1, 3, 1)) and "Twin" (Tri again; translated (0, 0, -5)).
inline std::string level_gltf() {
  return gltf_with_nodes(R"([
    {"name": "Level", "translation": [10, 0, 0], "children": [1, 2, 3]},
    {"name": "Mover", "mesh": 0, "translation": [1, 2, 3], "rotation": [0, 0.70710678118654752, 0, 0.70710678118654752],
     "scale": [2, 2, 2]},
    {"name": "Wall", "mesh": 1, "scale": [1, 3, 1]},
    {"name": "Twin", "mesh": 0, "translation": [0, 0, -5]}
  ])",
                         "[0]");
}

}  // namespace voxvis::test
