// load_cmd.cpp — scene administration on voxvis-server: `voxvis load`,
// `voxvis scenes` and `voxvis delete`.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "cli.h"
#include "common.h"
#include "model_loader.h"
#include "options.h"
#include "voxvis/client.h"
#include "voxvis/format.h"
#include "voxvis/routing.h"

namespace voxvis::cli {
namespace {

/// The file's stem as a scene id: characters outside [A-Za-z0-9._-] become
/// '_', a leading '.' too, at most 64 characters; "scene" if nothing is left.
std::string id_from_path(const std::string& path) {
  std::string id = std::filesystem::path(path).stem().string();
  for (char& c : id) {
    const bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                    c == '.' || c == '_' || c == '-';
    if (!ok) c = '_';
  }
  if (id.size() > 64) id.resize(64);
  if (!id.empty() && id[0] == '.') id[0] = '_';
  return id.empty() ? "scene" : id;
}

std::string grid_text(const v1::SceneInfo& info) {
  return std::to_string(info.grid().nx()) + "x" + std::to_string(info.grid().ny()) + "x" +
         std::to_string(info.grid().nz());
}

/// "" or ", 3 meshes of 1,204 triangles" (each distinct mesh's once).
std::string mesh_text(const v1::SceneInfo& info) {
  if (info.mesh_objects() == 0) return "";
  return ", " + std::to_string(info.mesh_objects()) + (info.mesh_objects() == 1 ? " mesh" : " meshes") + " of " +
         with_commas(info.mesh_triangles()) + " triangles";
}

}  // namespace

int run_load(const LoadArgs& args) {
  std::string id = args.id;
  std::string message;
  if (id.empty()) {
    id = id_from_path(args.scene);
  } else if (!valid_scene_id(id, &message)) {
    return report(FormatError{"", 0, "--id", message});
  }

  // Checked here first, so that errors carry this machine's file name and line.
  std::string text;
  FormatError error;
  if (!read_file(args.scene, &text, &error)) return report(error);
  SceneDesc desc;
  int models = 0;
  if (!parse_scene(text, args.scene, &desc, &error, scene_read_options(args.scene, &models))) return report(error);
  // The server reads no model file: a scene that refers to models goes with
  // their triangles inline (its lines then no longer match the file's).
  if (models > 0) text = scene_to_json(desc);

  int code = kExitOk;
  NetArgs net = args.net;
  if (!route_scene(&net, id, &code)) return code;
  const std::unique_ptr<client::Client> client = open_client(net, &code);
  if (client == nullptr) return code;
  v1::SceneInfo info;
  // The text itself, not a description: the server keeps it as written and
  // names its lines in errors (for example a grid over its memory budget).
  if (const grpc::Status st = client->create_scene(id, text, &info); !st.ok()) {
    return report_status(st, net.server, about_input(st.error_code()) ? args.scene : "");
  }
  if (!net.servers.empty()) std::printf("%s: on %s\n", id.c_str(), net.server.c_str());
  std::printf("%s: grid %s, %u objects (%u dynamic)%s\n", info.scene_id().c_str(), grid_text(info).c_str(),
              info.objects(), info.dynamic_objects(), mesh_text(info).c_str());
  return kExitOk;
}

int run_scenes(const NetArgs& net) {
  // One server, or every server of a fleet (each line then starts with its shard).
  std::vector<routing::Shard> shards;
  if (int code = kExitOk; !fleet_of(net, &shards, &code)) return code;
  int result = kExitOk;
  for (const routing::Shard& shard : shards) {
    NetArgs one = net;
    one.server = shard.address;
    int code = kExitOk;
    const std::unique_ptr<client::Client> client = open_client(one, &code);
    if (client == nullptr) return code;
    v1::ListScenesResponse list;
    if (const grpc::Status st = client->list_scenes(&list); !st.ok()) {
      result = report_status(st, one.server, "");
      continue;
    }
    const std::string prefix = net.servers.empty() ? "" : shard.name + " ";
    for (const v1::SceneInfo& s : list.scenes()) {
      std::printf("%s%s: grid %s, %u objects (%u dynamic)%s, %u viewers, %s frames served\n", prefix.c_str(),
                  s.scene_id().c_str(), grid_text(s).c_str(), s.objects(), s.dynamic_objects(),
                  mesh_text(s).c_str(), s.viewers(), with_commas(s.frames_served()).c_str());
    }
    for (const v1::MisplacedScene& m : list.misplaced()) {
      std::printf("%s%s: kept for shard %s, not served (voxvis rebalance moves it)\n", prefix.c_str(),
                  m.scene_id().c_str(), m.owner().c_str());
    }
  }
  return result;
}

int run_delete(const NetArgs& net, const std::string& id) {
  std::string message;
  if (!valid_scene_id(id, &message)) return report(FormatError{"", 0, "--id", message});
  int code = kExitOk;
  const std::unique_ptr<client::Client> client = open_client(net, &code);
  if (client == nullptr) return code;
  if (const grpc::Status st = client->delete_scene(id); !st.ok()) {
    return report_status(st, net.server, "");
  }
  std::printf("deleted %s\n", id.c_str());
  return kExitOk;
}

Command add_load_command(CLI::App& app) {
  auto args = std::make_shared<LoadArgs>();
  CLI::App* cmd = app.add_subcommand("load", "Create a scene on the server from a scene file (checked here first).");
  add_net_options(cmd, &args->net);
  cmd->add_option("--scene", args->scene, "Scene file (JSON, format voxvis-scene/1)")
      ->required()
      ->type_name("FILE");
  cmd->add_option("--id", args->id, "Scene id: 1-64 characters from [A-Za-z0-9._-] (default: the file's stem)")
      ->type_name("ID");
  cmd->footer("Prints the scene's id, grid resolution and object counts. Needs an admin token.");
  return {cmd, [args] { return run_load(*args); }};
}

Command add_scenes_command(CLI::App& app) {
  auto net = std::make_shared<NetArgs>();
  CLI::App* cmd = app.add_subcommand("scenes", "List the server's scenes.");
  add_net_options(cmd, net.get());
  cmd->footer("One line per scene: id, grid, objects, open viewers, frames served.");
  return {cmd, [net] { return run_scenes(*net); }};
}

Command add_delete_command(CLI::App& app) {
  /// The scene id to delete, and where.
  struct DeleteArgs {
    NetArgs net;
    std::string id;
  };
  auto args = std::make_shared<DeleteArgs>();
  CLI::App* cmd = app.add_subcommand("delete", "Delete a scene on the server.");
  add_net_options(cmd, &args->net);
  cmd->add_option("--id", args->id, "Scene id")->required()->type_name("ID");
  cmd->footer("Its open streams end with NOT_FOUND. Needs an admin token.");
  return {cmd, [args] { return run_routed(&args->net, args->id, [&] { return run_delete(args->net, args->id); }); }};
}

}  // namespace voxvis::cli
