// import_cmd.h — `voxvis import`: model files (glTF, OBJ, FBX, IFC, ...) to a
// scene file and its names table (docs/importing.md).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace voxvis::cli {

struct ImportArgs {
  std::vector<std::string> models;    ///< Model files, imported in this order.
  std::string scene_out;              ///< voxvis-scene/1 file to write.
  std::string names_out;              ///< Names table; empty: scene_out's stem + ".names.json".
  std::int64_t first_id = 1;          ///< The first object's id; the others follow.
  std::string split = "nodes";        ///< nodes | meshes | whole.
  std::vector<std::string> dynamic;   ///< Names of the objects that move.
  std::optional<double> max_speed;    ///< Of the dynamic objects; required with --dynamic.
  std::string grid;                   ///< "NX,NY,NZ"; empty: the engine's choice (or --voxel-size).
  std::optional<double> voxel_size;   ///< World units; the grid follows from the bounds.
  double margin = 0.02;               ///< Bounds' margin per side, a fraction of the largest extent.
  double timeout = 600.0;             ///< Seconds the import may take; 0: no limit.
  /// MiB of memory the model reader may take (0: no limit); unset: half the
  /// machine's memory, at least 1 GiB (default_child_memory_bytes).
  std::optional<double> max_memory_mib;
  bool quiet = false;
};

int run_import(const ImportArgs& args);

/// The names table's path for a scene file: "level.json" -> "level.names.json".
std::string names_path_for(const std::string& scene_out);

}  // namespace voxvis::cli
