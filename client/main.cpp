// main.cpp — the `voxvis` command line: argument parsing only; the work is in
// replay.cpp and generate_cmd.cpp.
#include <cmath>
#include <cstdio>
#include <exception>
#include <string>

#include <CLI/CLI.hpp>

#include "cli.h"

#ifndef VOXVIS_VERSION
#define VOXVIS_VERSION "unknown"
#endif

namespace {

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
      "\n"
      "Exit status: 0 success, 2 invalid input or arguments (the message names\n"
      "file:line: field), 1 internal error.");
  app.failure_message([](const CLI::App* /*app*/, const CLI::Error& e) {
    return std::string("voxvis: error: ") + e.what() + "\nRun with --help for more information.\n";
  });

  // voxvis replay
  voxvis::cli::ReplayArgs replay;
  double tbv_period = -1.0;
  CLI::App* replay_cmd = app.add_subcommand(
      "replay",
      "Replay a frames file against a scene and write one PVS line per frame.");
  replay_cmd->add_option("--scene", replay.scene, "Scene file (JSON, format voxvis-scene/1)")
      ->required()
      ->type_name("FILE");
  replay_cmd->add_option("--frames", replay.frames,
                         "Frames file (JSON Lines: one camera and optional moves per line)")
      ->required()
      ->type_name("FILE");
  replay_cmd->add_option("--grid", replay.grid,
                         "Grid resolution overriding the scene's, voxels per axis (e.g. 64,32,64)")
      ->type_name("NX,NY,NZ");
  replay_cmd->add_option("--out", replay.out,
                         "Output file (JSON Lines), written whole or not at all; default stdout")
      ->type_name("FILE");
  CLI::Option* tbv_opt = replay_cmd->add_option(
      "--tbv-period", tbv_period,
      "Fixed validity period of temporal bounding volumes, seconds (default: adaptive)")
      ->type_name("SECONDS");
  replay_cmd->add_flag("-q,--quiet", replay.quiet, "No progress line and no summary on stderr");
  replay_cmd->footer(
      "Output: one line per frame, {\"frame\", \"pvs\", \"wake\", \"stats\"}; ids ascending.\n"
      "Progress (on a terminal) and a timing summary go to stderr unless --quiet.");

  // voxvis generate
  voxvis::cli::GenerateArgs gen;
  CLI::App* gen_cmd = app.add_subcommand(
      "generate", "Write a deterministic example scene and camera walkthrough.");
  gen_cmd->add_option("--preset", gen.preset,
                      "Scene preset: 'paper' (clusters of spheres in 100 x 60 x 100, as in "
                      "Batagelo & Wu)")
      ->capture_default_str();
  gen_cmd->add_option("--scene-out", gen.scene_out, "Scene file to write")
      ->required()
      ->type_name("FILE");
  gen_cmd->add_option("--frames-out", gen.frames_out, "Frames file to write")
      ->required()
      ->type_name("FILE");
  gen_cmd->add_option("--objects", gen.objects, "Number of spheres")->capture_default_str();
  gen_cmd->add_option("--dynamic", gen.dynamic, "How many of them move")->capture_default_str();
  gen_cmd->add_option("--frames", gen.frames, "Number of frames (60 per second)")
      ->capture_default_str();
  gen_cmd->add_option("--seed", gen.seed,
                      "Random seed of the scene; the walkthrough uses seed + 1")
      ->capture_default_str();
  gen_cmd->footer("The same arguments always produce byte-identical files.");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? kExitOk : kExitError;
  }

  if (replay_cmd->parsed()) {
    if (tbv_opt->count() > 0) {
      if (!std::isfinite(tbv_period) || tbv_period < 0.0) {
        return voxvis::cli::report(voxvis::FormatError{
            "", 0, "--tbv-period", "must be a finite number of seconds >= 0 (0: adaptive)"});
      }
      replay.tbv_period = tbv_period;
    }
    return voxvis::cli::run_replay(replay);
  }
  if (gen_cmd->parsed()) return voxvis::cli::run_generate(gen);
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
