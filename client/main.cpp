// main.cpp — the `voxvis` command line: the app, its subcommands in the order
// `voxvis --help` lists them, and the run of the one parsed. Each subcommand
// adds its own options (add_<name>_command, cli.h) in the file that does its
// work: replay.cpp, verify_cmd.cpp, verify_merge_cmd.cpp, export_cmd.cpp,
// report_cmd.cpp, generate_cmd.cpp, import_cmd.cpp; for the commands that
// talk to voxvis-server, load_cmd.cpp (load, scenes, delete), fleet_cmd.cpp
// (rebalance), health_cmd.cpp, view_cmd.cpp, tick_cmd.cpp, simulate_cmd.cpp
// and loadgen_cmd.cpp. The options several commands share are in options.cpp.
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "cli.h"

#ifndef VOXVIS_VERSION
#define VOXVIS_VERSION "unknown"
#endif

namespace {

int run(int argc, char** argv) {
  using namespace voxvis::cli;

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

  const std::vector<Command> commands = {
      add_replay_command(app),
      add_verify_command(app),
      add_verify_merge_command(app),
      add_export_command(app),
      add_report_command(app),
      add_generate_command(app),
      add_import_command(app),
      add_load_command(app),
      add_scenes_command(app),
      add_delete_command(app),
      add_rebalance_command(app),
      add_health_command(app),
      add_view_command(app),
      add_tick_command(app),
      add_simulate_command(app),
      add_loadgen_command(app),
  };

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? kExitOk : kExitError;
  }
  for (const Command& command : commands) {
    if (command.app->parsed()) return command.run();
  }
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
