// voxvis/format.h — the batch formats (docs/formats.md is the contract):
//   scene   JSON        {"format": "voxvis-scene/1", "bounds": ..., "objects": [...]}
//   frames  JSON Lines  one camera (and optional moves) per line, in time order
//   output  JSON Lines  one {"frame", "pvs", "wake", "stats"} per input frame
//
// Every parser here reads untrusted input: it never throws, and an error names
// the source, the line and the field ("scene.json:12: objects[3].radius: must
// be > 0, got -1").
#pragma once

#include <functional>
#include <iosfwd>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "voxvis/scene.h"

namespace voxvis {

/// An error in an input file: where and what.
struct FormatError {
  std::string source;  ///< File name as given by the caller.
  int line = 0;        ///< 1-based; 0 when no line applies.
  std::string field;   ///< For example "objects[3].radius"; may be empty.
  std::string message;
  std::string str() const;
};

/// One line of a frames file.
struct FrameInput {
  double t = 0.0;  ///< Seconds.
  Camera camera;
  std::vector<Move> moves;
  int line = 0;  ///< 1-based line in the frames file.
};

/// Loads the triangles of a model file that a scene's mesh object names
/// ("model", docs/formats.md): `path` resolved against
/// SceneReadOptions::base_dir, `name` the object's "model_name" (empty: the
/// whole model). On success `*out` is a mesh validate_mesh accepts; on
/// failure the Status says why (the parser puts it on the object's line).
using ModelLoader =
    std::function<Status(const std::string& path, const std::string& name, std::shared_ptr<const Mesh>* out)>;

/// How parse_scene reads what lies outside the document.
struct SceneReadOptions {
  /// Loads referenced models; empty: a reference is refused with an error
  /// saying that this program cannot load model files. The engine library
  /// reads no model format itself: the `voxvis` commands install the
  /// importer's (voxvis/import.h).
  ModelLoader load_model;
  /// The directory relative model paths are resolved against (the scene
  /// file's); empty: the current directory.
  std::string base_dir;
};

/// Parses a voxvis-scene/1 document. Checks everything Scene::create checks
/// that can be told from the file alone (shapes, finiteness, ranges, unique
/// ids), so that errors carry lines. Model references are loaded through
/// `options.load_model`, each distinct (path, name) once, its mesh shared by
/// the objects naming it.
bool parse_scene(std::string_view text, std::string_view source, SceneDesc* out,
                 FormatError* error, const SceneReadOptions& options);
/// The same without a model loader: references are refused.
bool parse_scene(std::string_view text, std::string_view source, SceneDesc* out,
                 FormatError* error);

/// The line of field `field` (as Status::field names it, e.g.
/// "objects[3].radius") in a scene document, or of its nearest enclosing
/// field; 1 when none is found. Lets callers put engine errors on a line.
int scene_field_line(std::string_view text, std::string_view field);

/// Parses one frames line (without its newline). `line` is for messages.
bool parse_frame_line(std::string_view text, std::string_view source, int line,
                      FrameInput* out, FormatError* error);

/// Whether a JSON Lines line (frames or output) is blank: only spaces, tabs
/// or '\r'. Readers skip blank lines but count them.
bool is_blank_line(std::string_view line);

/// Reads a whole frames file from `in`: every line that is not blank, in
/// order, appended to `out` with its 1-based line. Stops at the first error
/// (the frames before it stay in `out`), a read error included. A file
/// without frames is not an error here.
bool parse_frames(std::istream& in, std::string_view source, std::vector<FrameInput>* out,
                  FormatError* error);

/// Serializes a scene to voxvis-scene/1 text (used by `voxvis generate`).
std::string scene_to_json(const SceneDesc& scene);

/// The length in bytes of scene_to_json(scene), exactly, without making
/// the text: each distinct mesh's vertices and triangles are measured once
/// however many objects place it (every object writes them inline), so the
/// cost is the description's size, not the text's (a server refuses a
/// scene whose saved file would be too large before writing it).
/// `inline_meshes`, when given, is set to the part of it that the meshes'
/// vertices and triangles take.
std::uint64_t scene_json_bytes(const SceneDesc& scene, std::uint64_t* inline_meshes = nullptr);

/// Serializes one frames line.
std::string frame_to_json(const FrameInput& frame);

/// Serializes one output line, without a newline.
std::string result_to_json(std::size_t frame_index, const FrameResult& result);

}  // namespace voxvis
