// import_cmd.cpp — `voxvis import`: model files through the importer
// (voxvis/import.h) to a voxvis-scene/1 file and its names table
// (docs/importing.md; docs/formats.md, "Names table").
#include "import_cmd.h"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "child_process.h"
#include "cli.h"
#include "common.h"
#include "output_file.h"
#include "voxvis/format.h"
#include "voxvis/import.h"
#include "voxvis/mesh.h"

namespace voxvis::cli {
namespace {

constexpr double kMaxId = 4294967295.0;

int arg_error(const std::string& flag, const std::string& message) {
  return report(FormatError{"", 0, flag, message});
}

/// The scene's bounds: the objects' box grown by `margin` times its largest
/// extent on every side (so that a flat model gets a thickness), kept
/// within kMaxCoordinate.
void scene_bounds(const Vec3& lo, const Vec3& hi, double margin, SceneDesc* desc) {
  const Vec3 extent = hi - lo;
  const double m = margin * std::max({extent.x, extent.y, extent.z});
  for (int a = 0; a < 3; ++a) {
    double pad = m;
    // A flat axis needs some thickness even with --margin 0.
    if (!(hi[a] - lo[a] + 2.0 * pad > 0.0)) pad = std::max(1e-3 * std::max({extent.x, extent.y, extent.z}), 1e-9);
    desc->bounds_min[a] = std::max(lo[a] - pad, -kMaxCoordinate);
    desc->bounds_max[a] = std::min(hi[a] + pad, kMaxCoordinate);
  }
}

std::string count_text(std::size_t n, const char* one, const char* many) {
  return with_commas(n) + " " + (n == 1 ? one : many);
}

}  // namespace

std::string names_path_for(const std::string& scene_out) {
  const std::string ext = ".json";
  if (scene_out.size() > ext.size() && scene_out.compare(scene_out.size() - ext.size(), ext.size(), ext) == 0)
    return scene_out.substr(0, scene_out.size() - ext.size()) + ".names.json";
  return scene_out + ".names.json";
}

namespace {

/// The import itself and the files written, in the child process; the
/// reading of every model is announced on `progress_fd` ("<path>\n").
int import_and_write(const ImportArgs& args, import::ImportOptions options, const int grid[3],
                     const std::string& names_out, std::uint64_t memory, int progress_fd);

/// Runs import_and_write in a child process and waits for it at most
/// args.timeout seconds. assimp reads files voxvis does not control, and a
/// malformed one can crash or hang it (docs/fuzzing.md, "Findings in assimp"): the
/// child's death or a timeout becomes an error naming the file being read,
/// and the output files' temporaries are removed.
int supervise(const ImportArgs& args, const import::ImportOptions& options, const int grid[3],
              const std::string& names_out);

}  // namespace

int run_import(const ImportArgs& args) {
  // The arguments CLI11 cannot check.
  import::ImportOptions options;
  if (!import::parse_split(args.split, &options.split))
    return arg_error("--split", "must be nodes, meshes or whole, got '" + args.split + "'");
  if (args.first_id < 0 || static_cast<double>(args.first_id) > kMaxId)
    return arg_error("--first-id", "must be an object id in [0, 4294967295], got " + std::to_string(args.first_id));
  if (!args.dynamic.empty() && !args.max_speed)
    return arg_error("--dynamic", "dynamic objects need --max-speed (world units per second, a bound on the speed "
                                  "of every point of each of them)");
  if (args.max_speed) {
    if (args.dynamic.empty()) return arg_error("--max-speed", "is only allowed with --dynamic");
    if (!std::isfinite(*args.max_speed) || *args.max_speed < 0.0 || *args.max_speed > kMaxCoordinate)
      return arg_error("--max-speed", "must be a number of world units per second in [0, 1e12], got " +
                                          number_text(*args.max_speed));
    options.max_speed = *args.max_speed;
  }
  options.dynamic_names = args.dynamic;
  if (!args.grid.empty() && args.voxel_size)
    return arg_error("--voxel-size", "give either --grid or --voxel-size, not both");
  int grid[3] = {0, 0, 0};
  std::string message;
  if (!args.grid.empty() && !parse_grid_arg(args.grid, kMaxResolution, grid, &message))
    return arg_error("--grid", message);
  if (args.voxel_size && !(std::isfinite(*args.voxel_size) && *args.voxel_size > 0.0))
    return arg_error("--voxel-size", "must be a number of world units > 0, got " + number_text(*args.voxel_size));
  if (!std::isfinite(args.margin) || args.margin < 0.0 || args.margin > 10.0)
    return arg_error("--margin", "must be a fraction in [0, 10] of the models' largest extent, got " +
                                     number_text(args.margin));
  if (args.scene_out.empty() || args.scene_out == "-")
    return arg_error("--scene-out", "must name a file (the names table goes beside it)");
  if (args.names_out.empty() && is_device_or_fifo(args.scene_out))
    return arg_error("--names-out", "is needed when --scene-out is a device or a FIFO (" + args.scene_out +
                                        "): the names table's path is otherwise made from it");
  const std::string names_out = args.names_out.empty() ? names_path_for(args.scene_out) : args.names_out;
  if (names_out == args.scene_out) return arg_error("--names-out", "must differ from --scene-out");
  if (!std::isfinite(args.timeout) || args.timeout < 0.0)
    return arg_error("--timeout", "must be a number of seconds >= 0 (0: no limit), got " + number_text(args.timeout));
  if (args.max_memory_mib && (!std::isfinite(*args.max_memory_mib) || *args.max_memory_mib < 0.0 ||
                              *args.max_memory_mib > 1048576.0))
    return arg_error("--max-memory-mib", "must be a number of MiB in [0, 1048576] (0: no limit), got " +
                                             number_text(*args.max_memory_mib));
  return supervise(args, options, grid, names_out);
}

namespace {

int import_and_write(const ImportArgs& args, import::ImportOptions options, const int grid[3],
                     const std::string& names_out, std::uint64_t memory, int progress_fd) {
  // The outputs are opened before the (possibly slow) import, so that a bad
  // path fails at once; they are written whole or not at all.
  std::string message;
  OutputFile scene_file, names_file;
  if (!scene_file.open(args.scene_out, &message)) return report(FormatError{args.scene_out, 0, "", message});
  if (!names_file.open(names_out, &message)) return report(FormatError{names_out, 0, "", message});

  options.progress = [&args, progress_fd](const std::string& line) {
    if (progress_fd >= 0 && line.rfind("reading ", 0) == 0) {
      const std::string path = line.substr(8, line.rfind(" (") - 8) + "\n";
      [[maybe_unused]] const ssize_t n = ::write(progress_fd, path.data(), path.size());
    }
    if (!args.quiet) std::fprintf(stderr, "voxvis: %s\n", line.c_str());
  };
  import::ImportResult result;
  if (const Status st = import::import_files(args.models, options, &result); !st) {
    if (st.code == Status::Code::ResourceExhausted) {
      const std::string limit = memory > 0 && child_memory_limits()
                                    ? " (the model reader may take " + std::to_string(memory >> 20) +
                                          " MiB: --max-memory-mib)"
                                    : "";
      std::fprintf(stderr, "voxvis: error: %s%s\n", st.str().c_str(), limit.c_str());
      return kExitInternal;
    }
    return report_message(st.str());
  }

  const std::size_t n = result.objects.size();
  if (static_cast<double>(args.first_id) + static_cast<double>(n) - 1.0 > kMaxId)
    return arg_error("--first-id", "the " + std::to_string(n) + " objects' ids from " + std::to_string(args.first_id) +
                                       " would pass 4294967295");
  SceneDesc desc;
  Vec3 lo, hi;
  import::objects_bounds(result.objects, &lo, &hi);
  scene_bounds(lo, hi, args.margin, &desc);
  if (!args.grid.empty()) desc.grid = glm::ivec3(grid[0], grid[1], grid[2]);
  if (args.voxel_size) {
    glm::ivec3 res;
    for (int a = 0; a < 3; ++a) {
      const double cells = std::ceil((desc.bounds_max[a] - desc.bounds_min[a]) / *args.voxel_size);
      if (!(cells <= kMaxResolution))
        return arg_error("--voxel-size", number_text(*args.voxel_size) + " makes " + number_text(cells) +
                                             " voxels along " + "xyz"[a] + " (the bounds span " +
                                             number_text(desc.bounds_max[a] - desc.bounds_min[a]) + "), more than " +
                                             std::to_string(kMaxResolution));
      res[a] = std::max(1, static_cast<int>(cells));
    }
    desc.grid = res;
  }

  nlohmann::ordered_json names = nlohmann::ordered_json::array();
  std::size_t dynamic = 0;
  desc.objects.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    import::ImportedObject& o = result.objects[i];
    o.desc.id = static_cast<ObjectId>(args.first_id + static_cast<std::int64_t>(i));
    if (o.desc.dynamic) ++dynamic;
    nlohmann::ordered_json entry = {{"id", o.desc.id}, {"name", o.name}, {"source", o.source}};
    if (!o.node.empty()) entry["node"] = o.node;
    entry["meshes"] = o.meshes;
    entry["triangles"] = o.desc.mesh->triangles.size();
    entry["dynamic"] = o.desc.dynamic;
    names.push_back(std::move(entry));
    desc.objects.push_back(std::move(o.desc));
  }
  const nlohmann::ordered_json table = {{"format", "voxvis-names/1"},
                                {"scene", args.scene_out},
                                {"split", import::split_name(options.split)},
                                {"objects", std::move(names)}};
  // Names come from the files: bytes that are not UTF-8 are replaced, not refused.
  const std::string names_text = table.dump(1, ' ', false, nlohmann::ordered_json::error_handler_t::replace) + "\n";
  const std::string scene_text = scene_to_json(desc);
  if (!scene_file.write(scene_text) || !scene_file.commit(&message))
    return report(FormatError{args.scene_out, 0, "", message.empty() ? "cannot write" : message});
  if (!names_file.write(names_text) || !names_file.commit(&message))
    return report(FormatError{names_out, 0, "", message.empty() ? "cannot write" : message});

  if (!args.quiet) {
    const import::ImportStats& s = result.stats;
    std::string line = "voxvis: wrote " + args.scene_out + ": " + count_text(n, "object", "objects") + " (" +
                       with_commas(dynamic) + " dynamic), " + count_text(s.triangles, "triangle", "triangles") +
                       ", ids " + std::to_string(args.first_id) + " to " +
                       std::to_string(args.first_id + static_cast<std::int64_t>(n) - 1) + "; names in " + names_out;
    std::vector<std::string> skipped;
    if (s.degenerate > 0) skipped.push_back(count_text(s.degenerate, "degenerate triangle", "degenerate triangles"));
    if (s.points_lines > 0) skipped.push_back(count_text(s.points_lines, "point or line", "points and lines"));
    if (s.empty_meshes > 0) skipped.push_back(count_text(s.empty_meshes, "mesh without triangles", "meshes without triangles"));
    if (!skipped.empty()) {
      line += "; skipped ";
      for (std::size_t i = 0; i < skipped.size(); ++i) line += (i > 0 ? ", " : "") + skipped[i];
    }
    std::fprintf(stderr, "%s\n", line.c_str());
  }
  return kExitOk;
}

/// The model reader's memory limit, bytes (0: none).
std::uint64_t memory_limit(const ImportArgs& args) {
  if (!args.max_memory_mib) return default_child_memory_bytes();
  return static_cast<std::uint64_t>(*args.max_memory_mib * 1048576.0);
}

int supervise(const ImportArgs& args, const import::ImportOptions& options, const int grid[3],
              const std::string& names_out) {
  const std::uint64_t memory = memory_limit(args);
  // The file being read: the last line the child announced.
  std::string announced, current = args.models.empty() ? std::string() : args.models.front();
  const ChildOutcome child = run_in_child(
      [&](int fd) {
        int code = kExitInternal;
        try {
          code = import_and_write(args, options, grid, names_out, memory, fd);
        } catch (const std::exception& e) {
          std::fprintf(stderr, "voxvis: internal error: %s\n", e.what());
        }
        return code;
      },
      args.timeout,
      [&](std::string_view chunk) {
        announced.append(chunk);
        for (std::size_t nl; (nl = announced.find('\n')) != std::string::npos; announced.erase(0, nl + 1))
          current = announced.substr(0, nl);
      },
      memory);
  if (!child.error.empty()) return report_message("cannot start the import: " + child.error);
  if (child.exited()) return child.exit_code();
  // The child died: its temporaries (OutputFile's "<path>.tmp-<pid>") go.
  for (const std::string& out : {args.scene_out, names_out})
    std::remove((renamed_path(out) + ".tmp-" + std::to_string(static_cast<long>(child.pid))).c_str());
  if (child.timed_out)
    return report(FormatError{current, 0, "",
                              "no result after " + number_text(args.timeout) +
                                  " s (--timeout): the model reader is stuck on this file (a malformed file can make "
                                  "it loop forever); give a larger --timeout if the file is only large"});
  const int sig = child.signal();
  if (sig == SIGKILL)
    return report(FormatError{current, 0, "", "the import was killed (" + signal_text(sig) +
                                                  "), most likely for running out of memory on this file"});
  const std::string memory_note = memory > 0 && child_memory_limits()
                                      ? ", or needs more than the " + std::to_string(memory >> 20) +
                                            " MiB it may take (--max-memory-mib)"
                                      : "";
  return report(FormatError{current, 0, "",
                            "the model reader crashed on this file (" + signal_text(sig) +
                                "): it is malformed, uses a feature the reader (assimp) mishandles" + memory_note});
}

}  // namespace

Command add_import_command(CLI::App& app) {
  auto args = std::make_shared<ImportArgs>();
  ImportArgs* imp = args.get();
  CLI::App* cmd = app.add_subcommand(
      "import", "Import model files (glTF, OBJ, FBX, Collada, IFC, PLY, ...) as a scene of triangle meshes.");
  cmd->add_option("models", imp->models, "Model files, imported in this order")->required()->type_name("MODEL");
  cmd->add_option("--scene-out", imp->scene_out, "Scene file to write (JSON, format voxvis-scene/1)")
      ->required()
      ->type_name("FILE");
  cmd->add_option("--names-out", imp->names_out,
                  "Names table to write: id -> node or mesh name and source file (default: the scene "
                  "file's name with .names.json)")
      ->type_name("FILE");
  cmd->add_option("--first-id", imp->first_id, "Id of the first object; the others follow in order")
      ->type_name("N")
      ->capture_default_str();
  cmd->add_option("--split", imp->split,
                  "What becomes one object: nodes (each node holding meshes, its meshes merged), meshes "
                  "(each mesh of each node), whole (each file)")
      ->type_name("nodes|meshes|whole")
      ->capture_default_str();
  cmd->add_option("--dynamic", imp->dynamic,
                  "Objects that move: those whose name, node name or node path is NAME (each NAME must "
                  "match one); placed by their node's translation, rotation and scale")
      ->type_name("NAME");
  cmd->add_option_function<double>(
         "--max-speed", [imp](const double& v) { imp->max_speed = v; },
         "The dynamic objects' speed bound, world units per second (required with --dynamic)")
      ->type_name("SPEED");
  cmd->add_option("--grid", imp->grid, "Grid resolution of the scene (default: the engine's choice)")
      ->type_name("NX,NY,NZ");
  cmd->add_option_function<double>(
         "--voxel-size", [imp](const double& v) { imp->voxel_size = v; },
         "Voxel edge, world units: the grid is the bounds divided by it (instead of --grid)")
      ->type_name("SIZE");
  cmd->add_option("--margin", imp->margin,
                  "Bounds around the models, per side, as a fraction of their largest extent")
      ->type_name("FRACTION")
      ->capture_default_str();
  cmd->add_option("--timeout", imp->timeout,
                  "Seconds the import may take (0: no limit); a model reader stuck on a malformed file is "
                  "stopped with an error naming the file")
      ->type_name("SECONDS")
      ->capture_default_str();
  cmd->add_option_function<double>(
         "--max-memory-mib", [imp](const double& v) { imp->max_memory_mib = v; },
         "Memory the model reader may take, MiB (0: no limit; default: half the machine's memory, at least "
         "1024); a file that needs more is an error naming it, not a process the system kills")
      ->type_name("MIB");
  cmd->add_flag("-q,--quiet", imp->quiet, "No progress or summary on stderr");
  cmd->footer(
      "Ids are given in a stable order: files as listed, nodes depth first (children in\n"
      "the file's order), meshes in their node's order. Static objects have their node\n"
      "transforms baked into the vertices; dynamic ones keep their node's translation,\n"
      "rotation and uniform scale as centre, rotation and scale. Degenerate triangles,\n"
      "points and lines are skipped and counted (docs/importing.md). The models are read\n"
      "in a child process: a reader that crashes or hangs on a malformed file becomes an\n"
      "error naming the file.\n"
      "Examples:\n"
      "  voxvis import level.glb --scene-out level.json\n"
      "  voxvis import house.ifc props.obj --scene-out s.json --split meshes --first-id 100\n"
      "  voxvis import level.gltf --scene-out s.json --dynamic Door Lift --max-speed 3");
  return {cmd, [args] { return run_import(*args); }};
}

}  // namespace voxvis::cli
