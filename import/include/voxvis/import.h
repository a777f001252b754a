// voxvis/import.h — triangle meshes from model files (glTF 2.0, OBJ, FBX,
// Collada, IFC, PLY and the other formats assimp reads) as scene objects.
//
// A model's node hierarchy is walked depth first, children in their order,
// each node's meshes in their order; every node's world matrix is the product
// of its ancestors' and its own. What becomes one object (ImportOptions::split)
// and how it is placed:
//   static   the world matrix baked into the vertices (centre 0, identity
//            rotation, scale 1);
//   dynamic  centre = the node's world translation, rotation = its world
//            rotation, scale = its uniform scale; a non-uniform scale, shear
//            or mirror is baked into the vertices (scale 1), the rotation kept.
// Both place every vertex where the node's world matrix puts it (up to
// rounding). Triangles voxvis refuses (no area, computed as validate_mesh
// does on the final vertices) are dropped and counted; points, lines and
// meshes left without a triangle are skipped and counted.
//
// The only user of assimp in voxvis: the public names here are voxvis's.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "voxvis/mesh.h"
#include "voxvis/types.h"

namespace voxvis::import {

/// What becomes one object.
enum class Split {
  Nodes,   ///< One per node that holds triangles: its meshes merged.
  Meshes,  ///< One per mesh instance (a node's mesh; a mesh two nodes use is two objects).
  Whole,   ///< One per file: every node's meshes merged.
};

/// "nodes", "meshes" or "whole"; false for anything else.
bool parse_split(const std::string& text, Split* out);
const char* split_name(Split split);

struct ImportOptions {
  Split split = Split::Nodes;
  /// Names whose objects become dynamic: an object matches when its name
  /// (ImportedObject::name) or its node's name or path equals one of them.
  std::vector<std::string> dynamic_names;
  double max_speed = 0.0;  ///< Of the dynamic objects, world units per second.
  /// Called with a line of progress ("reading level.glb (12 MB)") when set.
  std::function<void(const std::string&)> progress;
};

/// One object made from a model, before its id is given.
struct ImportedObject {
  ObjectDesc desc;                  ///< shape Mesh, id 0 (the caller numbers them).
  std::string name;                 ///< Nodes: the node's name; meshes: the mesh's (else the node's); whole: the file's.
  std::string node;                 ///< The node's path from the root, "/"-separated; whole: empty.
  std::vector<std::string> meshes;  ///< The names of the meshes it merges.
  std::string source;               ///< The model file as the caller named it.
};

/// What an import kept and what it left out.
struct ImportStats {
  std::size_t files = 0;
  std::size_t nodes = 0;             ///< Nodes visited.
  std::size_t mesh_instances = 0;    ///< Meshes of nodes that gave triangles.
  std::size_t triangles = 0;         ///< Kept.
  std::size_t vertices = 0;          ///< Kept.
  std::size_t degenerate = 0;        ///< Triangles dropped: no area (validate_mesh's rule), before or after placement.
  std::size_t points_lines = 0;      ///< Point and line primitives skipped.
  std::size_t empty_meshes = 0;      ///< Meshes without a triangle (after the drops), skipped.
  std::size_t empty_objects = 0;     ///< Objects left without a triangle, skipped.
  void add(const ImportStats& o);
};

struct ImportResult {
  std::vector<ImportedObject> objects;
  ImportStats stats;
};

/// Imports model files, in order, appending their objects to `out`. Errors
/// name the file ("level.glb: cannot import: <assimp's message>", "level.glb:
/// node 'Wall': ..."). A file that gives no triangle is an error; so is a
/// dynamic name that matches no object (checked over all files).
Status import_files(const std::vector<std::string>& paths, const ImportOptions& options, ImportResult* out);

/// Imports one model held in memory; `hint` is the format's file extension
/// ("gltf", "glb", "obj", ...), `source` names it in errors. The fuzz target's
/// entry point; a model that refers to other files (an .obj's .mtl, a
/// .gltf's buffers) cannot find them.
Status import_memory(const void* data, std::size_t size, const std::string& hint, const std::string& source,
                     const ImportOptions& options, ImportResult* out);

/// The whole triangles of one model file, node transforms baked (a static
/// import with split Whole), or when `name` is not empty only those of the
/// objects whose name, node name or node path equals it (split Nodes, and
/// mesh names as with split Meshes). For the scene file's model references.
Status load_model_mesh(const std::string& path, const std::string& name, std::shared_ptr<const Mesh>* out);

/// The world box of imported objects (object_bounds of each); false when
/// there is none.
bool objects_bounds(const std::vector<ImportedObject>& objects, Vec3* lo, Vec3* hi);

}  // namespace voxvis::import
