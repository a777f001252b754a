// main.cpp — the `voxvis` command line: argument parsing only; the work is in
// replay.cpp, generate_cmd.cpp, export_cmd.cpp and, for the commands that talk to
// voxvis-server, load_cmd.cpp, view_cmd.cpp, simulate_cmd.cpp and loadgen_cmd.cpp.
#include <cmath>
#include <cstdio>
#include <exception>
#include <string>

#include <CLI/CLI.hpp>

#include "cli.h"
#include "import_cmd.h"

#ifndef VOXVIS_VERSION
#define VOXVIS_VERSION "unknown"
#endif

namespace {

/// The options of every command that talks to voxvis-server; with `fleet`,
/// --servers too (the commands that name a scene, and those that visit every
/// server).
void add_net_options(CLI::App* cmd, voxvis::cli::NetArgs* net, bool fleet = true) {
  CLI::Option* server = cmd->add_option("--server", net->server, "Server address")
                            ->capture_default_str()
                            ->type_name("HOST:PORT");
  if (fleet) {
    cmd->add_option("--servers", net->servers,
                    "A fleet instead of one server: each scene goes to its owner by rendezvous hashing "
                    "over the shards' names (an entry without NAME= is named by its host's first DNS "
                    "label, a StatefulSet pod's name, or by HOST:PORT for an IP address; "
                    "docs/deploy.md)")
        ->type_name("[NAME=]HOST:PORT,...")
        ->excludes(server);
  }
  cmd->add_option("--token-file", net->token_file,
                  "File holding the bearer token (first non-comment line); default "
                  "$VOXVIS_TOKEN_FILE, else no token. Never pass tokens on the command line.")
      ->type_name("FILE");
  cmd->add_option("--tls-ca", net->tls_ca, "PEM root certificates; enables TLS")
      ->type_name("FILE");
  cmd->add_option("--tls-server-name", net->tls_server_name,
                  "Name to check the server's certificate against (default: the host of --server)")
      ->type_name("NAME");
}

/// The region flags (replay, view, tick, loadgen): set on every frame's
/// camera, over the frames file's fields.
void add_region_options(CLI::App* cmd, voxvis::cli::RegionArgs* region) {
  cmd->add_option("--eye-extent", region->eye_extent,
                  "Every frame's answer holds for every eye of the box eye +- H (world units, each in "
                  "[0, 1e12]; H alone: the same on all three axes)")
      ->type_name("H|HX,HY,HZ");
  cmd->add_flag("--omnidirectional", region->omnidirectional,
                "Every frame's answer holds in every direction (near and far still bound distance)");
  cmd->add_option_function<double>(
         "--horizon", [region](const double& s) { region->horizon = s; },
         "Every frame's answer holds until this many seconds after its time, each moving object anywhere "
         "its max_speed reaches (in [0, 1e9])")
      ->type_name("SECONDS");
}

/// The headless renderer's options (verify, report).
void add_egl_options(CLI::App* cmd, voxvis::cli::EglArgs* egl) {
  cmd->add_option("--egl-platform", egl->platform, "EGL platform: auto, device or surfaceless")
      ->type_name("NAME")
      ->capture_default_str();
  cmd->add_option("--egl-device", egl->device,
                  "EGL device index as eglQueryDevicesEXT lists them (device platform); default: the first "
                  "GPU, else the software one")
      ->type_name("N");
  cmd->add_option("--id-readback", egl->id_readback,
                  "How the id pass's visible set comes back: set (a compute pass gathers the ids seen, only "
                  "those are read), image (the whole id image), auto (set on a GPU, image on a software "
                  "renderer)")
      ->type_name("auto|set|image")
      ->capture_default_str();
  cmd->add_option("--query-readback", egl->query_readback,
                  "How occlusion queries' results come back: batch (a round at once through a query buffer, "
                  "OpenGL 4.4), each (one read per query)")
      ->type_name("batch|each")
      ->capture_default_str();
}

int run(int argc, char** argv) {
  using voxvis::cli::kExitError;
  using voxvis::cli::kExitOk;

  CLI::App app{
      "voxvis — occlusion culling on a regular voxel grid.\n"
      "Computes, for every camera frame, the potentially visible set (PVS): the ids\n"
      "of the objects that may be visible. File formats: docs/formats.md."};
  app.name("voxvis");
  app.set_version_flag("--version", std::string("voxvis ") + VOXVIS_VERSION);
  app.require_subcommand(1);
  app.footer(
      "Examples:\n"
      "  voxvis generate --preset paper --scene-out scene.json --frames-out frames.jsonl\n"
      "  voxvis replay --scene scene.json --frames frames.jsonl --out pvs.jsonl\n"
      "  voxvis verify --scene scene.json --frames frames.jsonl --pvs pvs.jsonl --resolution 640x360\n"
      "  voxvis export --scene scene.json --frames frames.jsonl --frame 120 --vdb frame120.vdb\n"
      "  voxvis import level.glb --scene-out level.json --dynamic Door --max-speed 2\n"
      "  voxvis load --server 127.0.0.1:50051 --scene scene.json --id paper\n"
      "  voxvis view --scene paper --frames frames.jsonl --out pvs.jsonl\n"
      "  voxvis tick --scene paper --frames frames.jsonl --viewers 24 --out pvs-dir\n"
      "  voxvis loadgen --scene paper --viewers 500 --rate 60 --duration 30\n"
      "\n"
      "Exit status: 0 success, 2 invalid input or arguments (the message names\n"
      "file:line: field) or an error from the server (its code and message),\n"
      "1 internal error, 3 (verify) a visible object missing from a PVS, 4 (health)\n"
      "the server is not serving.");
  app.failure_message([](const CLI::App* /*app*/, const CLI::Error& e) {
    return std::string("voxvis: error: ") + e.what() + "\nRun with --help for more information.\n";
  });

  // voxvis replay
  voxvis::cli::ReplayArgs replay;
  double tbv_period = -1.0;
  CLI::App* replay_cmd = app.add_subcommand(
      "replay",
      "Replay a frames file against a scene and write one PVS line per frame.");
  replay_cmd->add_option("--scene", replay.engine.scene, "Scene file (JSON, format voxvis-scene/1)")
      ->required()
      ->type_name("FILE");
  replay_cmd->add_option("--frames", replay.frames,
                         "Frames file (JSON Lines: one camera and optional moves per line)")
      ->required()
      ->type_name("FILE");
  replay_cmd->add_option("--grid", replay.engine.grid,
                         "Grid resolution overriding the scene's, voxels per axis (e.g. 64,32,64)")
      ->type_name("NX,NY,NZ");
  replay_cmd->add_option("--out", replay.out,
                         "Output file (JSON Lines), written whole or not at all; default stdout")
      ->type_name("FILE");
  CLI::Option* tbv_opt = replay_cmd->add_option(
      "--tbv-period", tbv_period,
      "Fixed validity period of temporal bounding volumes, seconds (default: adaptive)")
      ->type_name("SECONDS");
  replay_cmd->add_option("--occlusion-buffer", replay.engine.occlusion_buffer,
                         "Width in pixels of the conservative occlusion buffer (8..4096, "
                         "or 0: off; default 160)")
      ->type_name("PIXELS");
  add_region_options(replay_cmd, &replay.region);
  replay_cmd->add_flag("-q,--quiet", replay.quiet, "No progress line and no summary on stderr");
  replay_cmd->footer(
      "Output: one line per frame, {\"frame\", \"pvs\", \"wake\", \"stats\"}; ids ascending.\n"
      "Progress (on a terminal) and a timing summary go to stderr unless --quiet.");

  // voxvis verify
  voxvis::cli::VerifyArgs verify;
  double verify_tbv = -1.0;
  CLI::App* verify_cmd = app.add_subcommand(
      "verify",
      "Render every frame headlessly (EGL, else the CPU ray caster) and report the visible objects missing "
      "from its PVS.");
  verify_cmd->add_option("--scene", verify.engine.scene, "Scene file (JSON, format voxvis-scene/1)")
      ->required()
      ->type_name("FILE");
  verify_cmd->add_option("--frames", verify.frames, "Frames file (JSON Lines), as for replay")
      ->required()
      ->type_name("FILE");
  verify_cmd->add_option("--pvs", verify.pvs,
                         "PVS lines to check (replay's or view's output); default: run the engine")
      ->type_name("FILE");
  verify_cmd->add_option("--out", verify.out, "Output file (JSON Lines); default stdout")->type_name("FILE");
  verify_cmd->add_option("--resolution", verify.resolution, "Pixels of the rendered frames")
      ->type_name("WxH")
      ->capture_default_str();
  verify_cmd->add_option("--reference", verify.reference,
                         "Who finds the visible set at the pixel centres: egl (the headless renderer), raycast "
                         "(the CPU ray caster), auto (EGL when a context starts, else the ray caster)")
      ->type_name("auto|egl|raycast")
      ->capture_default_str();
  verify_cmd->add_option("--method", verify.method,
                         "With EGL, ids: one id buffer read back; queries: one occlusion query per object")
      ->type_name("ids|queries")
      ->capture_default_str();
  verify_cmd->add_flag("--full", verify.full,
                       "With --method queries, probe every object in the frustum, so that misses are "
                       "caught (the id buffer always sees them all)");
  verify_cmd->add_option("--first-frame", verify.first_frame, "First frame to verify (0-based)")
      ->type_name("N")
      ->capture_default_str();
  verify_cmd->add_option("--frame-count", verify.frame_count, "Frames to verify; -1: to the end")
      ->type_name("N")
      ->capture_default_str();
  add_egl_options(verify_cmd, &verify.egl);
  verify_cmd->add_option("--grid", verify.engine.grid, "Grid resolution for the engine, as for replay")
      ->type_name("NX,NY,NZ");
  CLI::Option* verify_tbv_opt =
      verify_cmd->add_option("--tbv-period", verify_tbv, "TBV period for the engine, as for replay")
          ->type_name("SECONDS");
  verify_cmd->add_option("--occlusion-buffer", verify.engine.occlusion_buffer,
                         "Occlusion buffer width for the engine, as for replay (0: off; default 160)")
      ->type_name("PIXELS");
  add_region_options(verify_cmd, &verify.region);
  verify_cmd->add_option("--region-eyes", verify.region_eyes,
                         "Region frames: eyes sampled at random in the eye box besides its centre and 8 "
                         "corners (0..1000)")
      ->type_name("N")
      ->capture_default_str();
  verify_cmd->add_option("--horizon-frames", verify.horizon_frames,
                         "Region frames: frame j's PVS also checked against the objects where frames "
                         "j+1..j+K put them, while within its horizon_s (0..1000)")
      ->type_name("K")
      ->capture_default_str();
  verify_cmd->add_flag("-q,--quiet", verify.quiet, "No progress, miss lines or summary on stderr");
  verify_cmd->footer(
      "Output: one line per frame, {\"frame\", \"visible\", \"missed\", \"pvs_size\", \"stats\"}.\n"
      "Exit status 3 when any visible object was missing from a PVS (docs/verify.md).");

  // voxvis verify-merge
  voxvis::cli::VerifyMergeArgs merge;
  CLI::App* merge_cmd = app.add_subcommand(
      "verify-merge", "Join the slices of a verification split over workers, check them, summarise.");
  merge_cmd->add_option("slices", merge.slices, "`voxvis verify --out` files of the slices, any order")
      ->required()
      ->type_name("SLICE");
  merge_cmd->add_option("--out", merge.out, "The joined output (JSON Lines); default stdout")->type_name("FILE");
  merge_cmd->add_option("--frames", merge.frames, "Frames the slices must cover, 0 to N-1 (a lost slice is an error)")
      ->check(CLI::NonNegativeNumber)
      ->type_name("N");
  merge_cmd->footer(
      "The slices are sorted by their first frame; a gap or an overlap is an error naming\n"
      "the file. The summary (stderr) counts as `verify`'s: missed object-frames, edge-only\n"
      "sightings dismissed, visible, PVS, tightness. Exit 3 when a frame has a miss.");

  // voxvis export
  voxvis::cli::ExportArgs exp;
  double export_tbv = -1.0;
  CLI::App* export_cmd = app.add_subcommand(
      "export", "Write the scene's voxels, and one frame's culling, as OpenVDB grids (for Houdini, Blender).");
  export_cmd->add_option("--scene", exp.engine.scene, "Scene file (JSON, format voxvis-scene/1)")
      ->required()
      ->type_name("FILE");
  CLI::Option* export_frames_opt =
      export_cmd->add_option("--frames", exp.frames, "Frames file (JSON Lines), as for replay")->type_name("FILE");
  CLI::Option* export_frame_opt =
      export_cmd->add_option("--frame", exp.frame,
                             "0-based frame of --frames whose culling to write (frames 0..K are replayed)")
          ->type_name("K");
  export_frame_opt->needs(export_frames_opt);
  export_frames_opt->needs(export_frame_opt);
  export_cmd->add_option("--vdb", exp.vdb, "OpenVDB file to write, whole or not at all")
      ->required()
      ->type_name("FILE");
  export_cmd->add_option("--grid", exp.engine.grid, "Grid resolution overriding the scene's, as for replay")
      ->type_name("NX,NY,NZ");
  CLI::Option* export_tbv_opt =
      export_cmd->add_option("--tbv-period", export_tbv, "TBV period for the engine, as for replay")
          ->type_name("SECONDS");
  export_cmd->add_option("--occlusion-buffer", exp.engine.occlusion_buffer,
                         "Occlusion buffer width, as for replay (0: off, the voxel traversal; default 160)")
      ->type_name("PIXELS");
  export_cmd->add_flag("-q,--quiet", exp.quiet, "No progress line and no summary on stderr");
  export_cmd->footer(
      "Grids: opaque (bool: static opacity) and objects (int32: objects touching each voxel,\n"
      "dynamic ones where frame K's moves left them); with --frame, visited and occluded\n"
      "(bool: what frame K's traversal did) and pvs (bool: voxels of frame K's PVS objects).\n"
      "Index (i,j,k) is voxel (i,j,k); the transform puts its centre at\n"
      "bounds.min + (i+0.5, j+0.5, k+0.5) * voxel_size (docs/formats.md, \"VDB export\").");

  // voxvis report
  voxvis::cli::ReportArgs rep;
  CLI::App* report_cmd = app.add_subcommand(
      "report", "Run every configuration on the same frames: time per frame against tightness and misses.");
  report_cmd->add_option("--scene", rep.scene, "Scene file (JSON, format voxvis-scene/1)")->required()->type_name("FILE");
  report_cmd->add_option("--frames", rep.frames, "Frames file (JSON Lines)")->required()->type_name("FILE");
  report_cmd->add_option("--configs", rep.configs, "Configurations (JSON); default: the standard sweep")
      ->type_name("FILE");
  report_cmd->add_option("--out", rep.out, "Output directory: report.json, report.md, tradeoff.png")
      ->type_name("DIR")
      ->capture_default_str();
  report_cmd->add_option("--resolution", rep.resolution, "Pixels of the exact reference and of the levels")
      ->type_name("WxH")
      ->capture_default_str();
  report_cmd->add_option("--reference", rep.reference,
                         "Who finds the exactly visible sets at the pixel centres: egl (the headless renderer), "
                         "raycast (the CPU ray caster), auto (EGL when a context starts, else the ray caster); "
                         "refinement levels need EGL either way")
      ->type_name("auto|egl|raycast")
      ->capture_default_str();
  report_cmd->add_option("--cost-model", rep.cost_model,
                         "near-optimal's model of the GPU: loaded from FILE, else measured and saved there "
                         "(default: $XDG_CACHE_HOME/voxvis/cost-model.json, else ~/.cache/voxvis/)")
      ->type_name("FILE");
  report_cmd->add_option("--frame-count", rep.frame_count, "Use the first N frames; -1: all")
      ->type_name("N")
      ->capture_default_str();
  add_egl_options(report_cmd, &rep.egl);
  report_cmd->add_flag("-q,--quiet", rep.quiet, "No progress bar or summary on stderr");

  // voxvis generate
  voxvis::cli::GenerateArgs gen;
  CLI::App* gen_cmd = app.add_subcommand(
      "generate", "Write a deterministic example scene and camera walkthrough.");
  gen_cmd->add_option("--preset", gen.preset,
                      "Scene preset: paper (clusters of spheres, some moving, as in Batagelo & Wu), "
                      "indoor (rooms, walls and doorways), voxel-world (terrain of unit blocks, path "
                      "over the surface), voxel-cave (the same world, path through a cave), city "
                      "(box buildings and parked cars, path along a street), arena (a Quake-3-sized level "
                      "of rooms, corridors and two storeys with 24 players running through it, a "
                      "first-person walk)")
      ->type_name("NAME")
      ->capture_default_str();
  gen_cmd->add_option("--scene-out", gen.scene_out, "Scene file to write")
      ->required()
      ->type_name("FILE");
  gen_cmd->add_option("--frames-out", gen.frames_out, "Frames file to write")
      ->required()
      ->type_name("FILE");
  gen_cmd->add_option_function<std::string>(
             "--size", [&gen](const std::string& text) { gen.size = text; },
                      "Not paper: indoor, rooms per side, N or XxZ (1..100, default 6x3); voxel-world "
                      "and voxel-cave, columns per side (16..256, default 64); city, blocks per side "
                      "(1..64, default 8); arena, rooms per side (2..32, default 4)")
      ->type_name("N|XxZ");
  gen_cmd->add_option_function<int>(
             "--objects", [&gen](const int& n) { gen.objects = n; }, "paper: number of spheres (default 5000)")
      ->type_name("N");
  gen_cmd->add_option_function<int>(
             "--dynamic", [&gen](const int& n) { gen.dynamic = n; },
             "paper: how many of them move (default 200); arena: players (0..1000, default 24)")
      ->type_name("N");
  gen_cmd->add_option("--frames", gen.frames, "Number of frames (60 per second), 0..100000")
      ->type_name("N")
      ->capture_default_str();
  gen_cmd->add_option_function<std::string>(
             "--seed", [&gen](const std::string& text) { gen.seed = text; },
             "Random seed of the scene (default 1 for paper; for the others the benchmarks' seed: "
             "indoor 7, voxel-world and voxel-cave 11, city 5, arena 3); paper's walkthrough uses seed + 1")
      ->type_name("N");
  gen_cmd->footer(
      "The same arguments always produce byte-identical files. Only paper and arena\n"
      "have moving objects; the other presets are static and their frames carry no moves.\n"
      "Examples:\n"
      "  voxvis generate --preset paper --scene-out paper.json --frames-out paper.jsonl\n"
      "  voxvis generate --preset indoor --size 4x2 --scene-out indoor.json --frames-out indoor.jsonl\n"
      "  voxvis generate --preset voxel-cave --frames 600 --scene-out cave.json --frames-out cave.jsonl\n"
      "  voxvis generate --preset city --size 4 --seed 9 --scene-out city.json --frames-out city.jsonl\n"
      "  voxvis generate --preset arena --frames 600 --scene-out arena.json --frames-out arena.jsonl");

  // voxvis import
  voxvis::cli::ImportArgs imp;
  CLI::App* import_cmd = app.add_subcommand(
      "import", "Import model files (glTF, OBJ, FBX, Collada, IFC, PLY, ...) as a scene of triangle meshes.");
  import_cmd->add_option("models", imp.models, "Model files, imported in this order")->required()->type_name("MODEL");
  import_cmd->add_option("--scene-out", imp.scene_out, "Scene file to write (JSON, format voxvis-scene/1)")
      ->required()
      ->type_name("FILE");
  import_cmd->add_option("--names-out", imp.names_out,
                         "Names table to write: id -> node or mesh name and source file (default: the scene "
                         "file's name with .names.json)")
      ->type_name("FILE");
  import_cmd->add_option("--first-id", imp.first_id, "Id of the first object; the others follow in order")
      ->type_name("N")
      ->capture_default_str();
  import_cmd->add_option("--split", imp.split,
                         "What becomes one object: nodes (each node holding meshes, its meshes merged), meshes "
                         "(each mesh of each node), whole (each file)")
      ->type_name("nodes|meshes|whole")
      ->capture_default_str();
  import_cmd->add_option("--dynamic", imp.dynamic,
                         "Objects that move: those whose name, node name or node path is NAME (each NAME must "
                         "match one); placed by their node's translation, rotation and scale")
      ->type_name("NAME");
  import_cmd->add_option_function<double>(
                "--max-speed", [&imp](const double& v) { imp.max_speed = v; },
                "The dynamic objects' speed bound, world units per second (required with --dynamic)")
      ->type_name("SPEED");
  import_cmd->add_option("--grid", imp.grid, "Grid resolution of the scene (default: the engine's choice)")
      ->type_name("NX,NY,NZ");
  import_cmd->add_option_function<double>(
                "--voxel-size", [&imp](const double& v) { imp.voxel_size = v; },
                "Voxel edge, world units: the grid is the bounds divided by it (instead of --grid)")
      ->type_name("SIZE");
  import_cmd->add_option("--margin", imp.margin,
                         "Bounds around the models, per side, as a fraction of their largest extent")
      ->type_name("FRACTION")
      ->capture_default_str();
  import_cmd->add_option("--timeout", imp.timeout,
                         "Seconds the import may take (0: no limit); a model reader stuck on a malformed file is "
                         "stopped with an error naming the file")
      ->type_name("SECONDS")
      ->capture_default_str();
  import_cmd->add_option_function<double>(
                "--max-memory-mib", [&imp](const double& v) { imp.max_memory_mib = v; },
                "Memory the model reader may take, MiB (0: no limit; default: half the machine's memory, at least "
                "1024); a file that needs more is an error naming it, not a process the system kills")
      ->type_name("MIB");
  import_cmd->add_flag("-q,--quiet", imp.quiet, "No progress or summary on stderr");
  import_cmd->footer(
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

  // voxvis load
  voxvis::cli::LoadArgs load;
  CLI::App* load_cmd = app.add_subcommand(
      "load", "Create a scene on the server from a scene file (checked here first).");
  add_net_options(load_cmd, &load.net);
  load_cmd->add_option("--scene", load.scene, "Scene file (JSON, format voxvis-scene/1)")
      ->required()
      ->type_name("FILE");
  load_cmd->add_option("--id", load.id,
                       "Scene id: 1-64 characters from [A-Za-z0-9._-] (default: the file's stem)")
      ->type_name("ID");
  load_cmd->footer("Prints the scene's id, grid resolution and object counts. Needs an admin token.");

  // voxvis scenes
  voxvis::cli::NetArgs scenes_net;
  CLI::App* scenes_cmd = app.add_subcommand("scenes", "List the server's scenes.");
  add_net_options(scenes_cmd, &scenes_net);
  scenes_cmd->footer("One line per scene: id, grid, objects, open viewers, frames served.");

  // voxvis delete
  voxvis::cli::NetArgs delete_net;
  std::string delete_id;
  CLI::App* delete_cmd = app.add_subcommand("delete", "Delete a scene on the server.");
  add_net_options(delete_cmd, &delete_net);
  delete_cmd->add_option("--id", delete_id, "Scene id")->required()->type_name("ID");
  delete_cmd->footer("Its open streams end with NOT_FOUND. Needs an admin token.");

  // voxvis rebalance
  voxvis::cli::RebalanceArgs rebalance;
  CLI::App* rebalance_cmd = app.add_subcommand(
      "rebalance", "Move every scene of a fleet to the server that owns it (after the fleet changed).");
  add_net_options(rebalance_cmd, &rebalance.net);
  rebalance_cmd->get_option("--servers")->required();
  rebalance_cmd->add_option("--drain", rebalance.drain,
                            "Servers leaving the fleet (not in --servers): every scene they hold moves "
                            "to its owner among --servers")
      ->type_name("[NAME=]HOST:PORT,...");
  rebalance_cmd->add_flag("--dry-run", rebalance.dry_run, "Print the moves without making them");
  rebalance_cmd->footer(
      "Lists every server's scenes (those served, and those a server keeps for another\n"
      "shard); each scene not on its owner is exported (its scene file and its dynamic\n"
      "objects' current positions), created on the owner, then deleted where it was.\n"
      "One line per move. A scene found on two servers is left alone and reported.\n"
      "Needs an admin token on every server. Exit status 2 when any move failed.");

  // voxvis health
  voxvis::cli::HealthArgs health;
  CLI::App* health_cmd = app.add_subcommand(
      "health", "Ask a server's health service (grpc.health.v1) whether it serves.");
  add_net_options(health_cmd, &health.net, false);
  health_cmd->add_option("--service", health.service, "Health service name; default: the whole server")
      ->type_name("NAME");
  health_cmd->add_option("--timeout", health.timeout, "Seconds to wait for the connection and the answer")
      ->capture_default_str()
      ->type_name("SECONDS");
  health_cmd->footer(
      "Prints the status (SERVING, NOT_SERVING, ...). Exit status: 0 SERVING, 4 not\n"
      "serving, unknown, unreachable or no answer within the timeout, 2 bad arguments.\n"
      "No token is needed. For container health checks and scripts; Kubernetes asks\n"
      "the same service with its native gRPC probes.");

  // voxvis view
  voxvis::cli::ViewArgs view;
  CLI::App* view_cmd = app.add_subcommand(
      "view", "Replay a frames file against a scene on the server, as one viewer.");
  add_net_options(view_cmd, &view.net);
  view_cmd->add_option("--scene", view.scene, "Scene id on the server")->required()->type_name("ID");
  view_cmd->add_option("--frames", view.frames,
                       "Frames file (JSON Lines: one camera and optional moves per line)")
      ->required()
      ->type_name("FILE");
  view_cmd->add_option("--out", view.out,
                       "Output file (JSON Lines), written whole or not at all; default stdout")
      ->type_name("FILE");
  view_cmd->add_flag("--delta", view.delta,
                     "Ask for PVS deltas and reassemble them (same output)");
  add_region_options(view_cmd, &view.region);
  view_cmd->add_flag("-q,--quiet", view.quiet, "No progress line and no summary on stderr");
  view_cmd->add_option("--every", view.every,
                       "Print a one-line summary of every Nth frame on stderr (PVS size and "
                       "change, wake list, engine time, round trip)")
      ->check(CLI::Range(0, 1000000))
      ->type_name("N");
  view_cmd->footer(
      "Lock-step: a line's moves are sent (Simulate) and acknowledged, then its camera\n"
      "(View, frame number = 0-based frame index, time = the line's t). Output: the\n"
      "lines `voxvis replay` writes, {\"frame\", \"pvs\", \"wake\", \"stats\"}, computed by\n"
      "the server. Moves need a simulation token.");

  // voxvis tick
  voxvis::cli::TickArgs tick;
  CLI::App* tick_cmd = app.add_subcommand(
      "tick", "Replay a frames file against a scene on the server as ticks: every viewer in one message.");
  add_net_options(tick_cmd, &tick.net);
  tick_cmd->add_option("--scene", tick.scene, "Scene id on the server")->required()->type_name("ID");
  tick_cmd->add_option("--frames", tick.frames, "Frames file (JSON Lines: one camera and optional moves per line)")
      ->required()
      ->type_name("FILE");
  tick_cmd->add_option("--viewers", tick.viewers,
                       "Viewers a tick, each walking the recording from its own start (line v*n/N)")
      ->check(CLI::Range(1, 1024))
      ->type_name("N");
  tick_cmd->add_option("--out", tick.out,
                       "One viewer: the output file (default stdout); several: a directory for "
                       "viewer-<k>.jsonl. Written whole or not at all")
      ->type_name("PATH");
  tick_cmd->add_flag("--delta", tick.delta, "Ask for PVS deltas and reassemble them (same output)");
  add_region_options(tick_cmd, &tick.region);
  tick_cmd->add_flag("-q,--quiet", tick.quiet, "No progress line and no summary on stderr");
  tick_cmd->footer(
      "Lock-step, one Tick stream: tick k carries line k's moves and time and each viewer's\n"
      "camera. Output: per viewer, the lines `voxvis replay` writes, {\"frame\", \"pvs\",\n"
      "\"wake\", \"stats\"}, frame = the tick; viewer 0's equal replay's. Moves need a\n"
      "simulation token.");

  // voxvis simulate
  voxvis::cli::SimulateArgs sim;
  CLI::App* sim_cmd = app.add_subcommand(
      "simulate", "Send a frames file's moves to the server and print wake-list changes.");
  add_net_options(sim_cmd, &sim.net);
  sim_cmd->add_option("--scene", sim.scene, "Scene id on the server")->required()->type_name("ID");
  sim_cmd->add_option("--frames", sim.frames, "Frames file; each line's moves are one batch")
      ->required()
      ->type_name("FILE");
  sim_cmd->add_option("--rate", sim.rate,
                      "Batches per second, paced by the wall clock (default: as fast as "
                      "acknowledged)")
      ->type_name("HZ");
  sim_cmd->add_flag("-q,--quiet", sim.quiet, "No summary on stderr");
  sim_cmd->footer(
      "Batch seq = 0-based line index, t = the line's t. Output: one line per wake-list\n"
      "change, {\"seq\": <latest ack before it, null before any>, \"version\", \"size\",\n"
      "\"wake\": [the whole list, ascending]}. Needs a simulation token.");

  // voxvis loadgen
  voxvis::cli::LoadgenArgs gen_load;
  CLI::App* loadgen_cmd = app.add_subcommand(
      "loadgen", "Load a server with many concurrent viewers and report latencies.");
  add_net_options(loadgen_cmd, &gen_load.net);
  loadgen_cmd->add_option("--scene", gen_load.scene, "Scene id on the server")
      ->required()
      ->type_name("ID");
  loadgen_cmd->add_option("--viewers", gen_load.viewers, "Concurrent View streams (with --tick: viewers in each tick)")
      ->required()
      ->type_name("N");
  loadgen_cmd->add_option("--rate", gen_load.rate, "Frames per second per viewer (with --tick: ticks per second)")
      ->required()
      ->type_name("HZ");
  loadgen_cmd->add_option("--duration", gen_load.duration, "Seconds of sending")
      ->required()
      ->type_name("SECONDS");
  loadgen_cmd->add_option("--frames", gen_load.frames,
                          "Cameras to loop over, each viewer from its own offset (default: an "
                          "orbit inside the scene's bounds)")
      ->type_name("FILE");
  loadgen_cmd->add_flag("--delta", gen_load.delta, "Ask for PVS deltas");
  add_region_options(loadgen_cmd, &gen_load.region);
  loadgen_cmd->add_option("--json", gen_load.json, "Also write the report as JSON")
      ->type_name("FILE");
  loadgen_cmd->add_option("--connections", gen_load.connections,
                          "TCP connections the streams are spread over (default: one per 100 "
                          "viewers)")
      ->type_name("N");
  loadgen_cmd->add_flag("--tick", gen_load.tick,
                        "One Tick stream whose every request carries all viewers' cameras (a game "
                        "server's tick), instead of a View stream per viewer");
  loadgen_cmd->add_option("--metrics", gen_load.metrics,
                          "The server's metrics address (its --metrics): report its CPU time per "
                          "answer, and the engine's part of it")
      ->type_name("HOST:PORT");
  loadgen_cmd->add_flag("-q,--quiet", gen_load.quiet, "No progress line on stderr");
  loadgen_cmd->footer(
      "Latency: from sending a frame to receiving the answer carrying its number;\n"
      "frames per second: answers over the time from the start to the last answer;\n"
      "first answer: from a stream's first send to its first answer; answer gaps:\n"
      "between two answers of one stream (the first gap is the first answer's wait).\n"
      "A tick that finds the viewer's previous write still outstanding is skipped\n"
      "(\"send skipped\"). With --tick, latency is a whole tick's, answers count one\n"
      "per viewer answered, and the server's skips are ticks replaced by newer ones.\n"
      "With --metrics, the server's CPU seconds (process_cpu_seconds_total) and the\n"
      "engine's (voxvis_frame_engine_seconds) over the run, per answer it counted for\n"
      "the scene. Report on stdout; exit 2 if a stream ended with an error.");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? kExitOk : kExitError;
  }

  // --tbv-period, when given: 0 (adaptive) or at least a millisecond.
  const auto take_tbv = [](const CLI::Option* opt, double value, voxvis::cli::EngineArgs* engine) {
    if (opt->count() == 0) return true;
    if (!std::isfinite(value) || !(value == 0.0 || value >= voxvis::kMinTbvPeriod)) return false;
    engine->tbv_period = value;
    return true;
  };
  const voxvis::FormatError bad_tbv{"", 0, "--tbv-period",
                                    "must be 0 (adaptive) or a finite number of seconds >= " +
                                        voxvis::number_text(voxvis::kMinTbvPeriod)};
  if (replay_cmd->parsed()) {
    if (!take_tbv(tbv_opt, tbv_period, &replay.engine)) return voxvis::cli::report(bad_tbv);
    return voxvis::cli::run_replay(replay);
  }
  if (verify_cmd->parsed()) {
    if (!take_tbv(verify_tbv_opt, verify_tbv, &verify.engine)) return voxvis::cli::report(bad_tbv);
    return voxvis::cli::run_verify(verify);
  }
  if (export_cmd->parsed()) {
    if (!take_tbv(export_tbv_opt, export_tbv, &exp.engine)) return voxvis::cli::report(bad_tbv);
    exp.frame_given = export_frame_opt->count() > 0;
    return voxvis::cli::run_export(exp);
  }
  if (merge_cmd->parsed()) return voxvis::cli::run_verify_merge(merge);
  if (report_cmd->parsed()) return voxvis::cli::run_report(rep);
  if (gen_cmd->parsed()) return voxvis::cli::run_generate(gen);
  if (import_cmd->parsed()) return voxvis::cli::run_import(imp);
  // A fleet (--servers): the scene's owner is the server.
  int route_code = kExitOk;
  const auto routed = [&route_code](voxvis::cli::NetArgs* net, const std::string& scene) {
    return voxvis::cli::route_scene(net, scene, &route_code);
  };
  if (load_cmd->parsed()) return voxvis::cli::run_load(load);
  if (scenes_cmd->parsed()) return voxvis::cli::run_scenes(scenes_net);
  if (delete_cmd->parsed()) return routed(&delete_net, delete_id) ? voxvis::cli::run_delete(delete_net, delete_id) : route_code;
  if (rebalance_cmd->parsed()) return voxvis::cli::run_rebalance(rebalance);
  if (health_cmd->parsed()) return voxvis::cli::run_health(health);
  if (view_cmd->parsed()) return routed(&view.net, view.scene) ? voxvis::cli::run_view(view) : route_code;
  if (tick_cmd->parsed()) return routed(&tick.net, tick.scene) ? voxvis::cli::run_tick(tick) : route_code;
  if (sim_cmd->parsed()) return routed(&sim.net, sim.scene) ? voxvis::cli::run_simulate(sim) : route_code;
  if (loadgen_cmd->parsed())
    return routed(&gen_load.net, gen_load.scene) ? voxvis::cli::run_loadgen(gen_load) : route_code;
  return kExitError;  // Unreachable: a subcommand is required.
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "voxvis: internal error: %s\n", e.what());
  } catch (...) {
    std::fprintf(stderr, "voxvis: internal error\n");
  }
  return voxvis::cli::kExitInternal;
}
