// fleet_cmd.cpp — a fleet of servers (--servers): routing a scene to its
// owner, and `voxvis rebalance`, which moves every scene to its owner after
// the fleet changed (docs/deploy.md, "Scenes over many servers"). A scene
// moves only when its server agrees it is misplaced (keeps it unserved for
// another shard): one it still serves could acknowledge moves the copy would
// lose, so it is reported and left.
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "cli.h"
#include "common.h"
#include "options.h"
#include "voxvis/client.h"
#include "voxvis/routing.h"

namespace voxvis::cli {

bool fleet_of(const NetArgs& net, std::vector<routing::Shard>* shards, int* exit_code) {
  shards->clear();
  if (net.servers.empty()) {
    shards->push_back({net.server, net.server});
    return true;
  }
  std::string message;
  if (!routing::parse_servers(net.servers, shards, &message)) {
    *exit_code = report(FormatError{"", 0, "--servers", message});
    return false;
  }
  return true;
}

bool route_scene(NetArgs* net, const std::string& scene_id, int* exit_code) {
  if (net->servers.empty()) return true;
  std::vector<routing::Shard> shards;
  if (!fleet_of(*net, &shards, exit_code)) return false;
  net->server = shards[routing::owner(shards, scene_id)].address;
  return true;
}

namespace {

struct Found {
  std::size_t shard;  // Where the scene is.
  bool kept;          // Kept for another shard rather than served.
};

}  // namespace

int run_rebalance(const RebalanceArgs& args) {
  std::vector<routing::Shard> shards;
  int code = kExitOk;
  if (!fleet_of(args.net, &shards, &code)) return code;
  // Owners are the fleet's shards; servers being drained follow them, as
  // sources only.
  const std::size_t owners = shards.size();
  if (!args.drain.empty()) {
    std::vector<routing::Shard> leaving;
    std::string message;
    if (!routing::parse_servers(args.drain, &leaving, &message)) return report(FormatError{"", 0, "--drain", message});
    for (const routing::Shard& l : leaving) {
      for (const routing::Shard& s : shards) {
        if (s.name == l.name || s.address == l.address)
          return report(FormatError{"", 0, "--drain", "'" + l.name + "' (" + l.address + ") is also in --servers"});
      }
      shards.push_back(l);
    }
  }
  const std::vector<routing::Shard> fleet(shards.begin(), shards.begin() + static_cast<std::ptrdiff_t>(owners));
  std::vector<std::unique_ptr<client::Client>> clients;
  for (const routing::Shard& shard : shards) {
    NetArgs one = args.net;
    one.server = shard.address;
    clients.push_back(open_client(one, &code));
    if (clients.back() == nullptr) return code;
  }

  // Where every scene is now. A server that cannot be listed stops the
  // rebalance: a scene it holds could otherwise be created a second time.
  std::map<std::string, std::vector<Found>> where;
  for (std::size_t i = 0; i < shards.size(); ++i) {
    v1::ListScenesResponse list;
    if (const grpc::Status st = clients[i]->list_scenes(&list); !st.ok()) {
      report_status(st, shards[i].address, "");
      std::fprintf(stderr, "voxvis: error: nothing moved: every server must answer\n");
      return kExitError;
    }
    for (const v1::SceneInfo& s : list.scenes()) where[s.scene_id()].push_back({i, false});
    for (const v1::MisplacedScene& m : list.misplaced()) where[m.scene_id()].push_back({i, true});
  }

  std::size_t moved = 0, failed = 0, in_place = 0;
  for (const auto& [id, found] : where) {
    const std::size_t owner = routing::owner(fleet, id);
    if (found.size() > 1) {
      std::string on;
      for (const Found& f : found) on += (on.empty() ? "" : ", ") + shards[f.shard].name;
      std::fprintf(stderr, "voxvis: error: scene '%s' is on %zu servers (%s); left alone: delete the stale "
                   "copies, then run rebalance again\n", id.c_str(), found.size(), on.c_str());
      ++failed;
      continue;
    }
    const std::size_t from = found[0].shard;
    if (from == owner && found[0].kept) {
      // The server itself says another shard owns it: its --fleet and this
      // list disagree; moving cannot mend that.
      std::fprintf(stderr, "voxvis: error: scene '%s' is on %s, its owner by --servers, but that server keeps it "
                   "unserved for another shard: its --fleet and --servers disagree\n", id.c_str(),
                   shards[from].name.c_str());
      ++failed;
      continue;
    }
    if (from == owner) {
      ++in_place;
      continue;
    }
    if (!found[0].kept) {
      // Its server serves it as its own (its --fleet is the old list, or it
      // has no --shard): it may acknowledge moves after an export, which the
      // copy would lose. Moved only once that server agrees it is misplaced.
      std::fprintf(stderr, "voxvis: error: scene '%s' is served by %s, but its owner by --servers is %s: left "
                   "there, since %s may still acknowledge moves the copy would lose; restart %s with the fleet's "
                   "--fleet (it then keeps the scene unserved), then run rebalance again\n", id.c_str(),
                   shards[from].name.c_str(), shards[owner].name.c_str(), shards[from].name.c_str(),
                   shards[from].name.c_str());
      ++failed;
      continue;
    }
    std::printf("%s: %s -> %s%s\n", id.c_str(), shards[from].name.c_str(), shards[owner].name.c_str(),
                args.dry_run ? " (dry run)" : "");
    std::fflush(stdout);
    if (args.dry_run) {
      ++moved;
      continue;
    }
    v1::ExportSceneResponse exported;
    // The source agrees the scene is misplaced: it serves it to nobody and
    // refuses its moves. Exported and deleted only while that holds.
    if (const grpc::Status st = clients[from]->export_scene(id, &exported, true); !st.ok()) {
      report_status(st, shards[from].address, "export of scene '" + id + "'");
      ++failed;
      continue;
    }
    v1::SceneInfo info;
    const grpc::Status created = clients[owner]->create_scene(
        id, exported.scene_json(), exported.has_positions() ? &exported.positions() : nullptr, &info);
    if (!created.ok()) {
      // Left where it was: nothing is lost.
      report_status(created, shards[owner].address, "creating scene '" + id + "' on its owner");
      ++failed;
      continue;
    }
    if (const grpc::Status st = clients[from]->delete_scene(id, true); !st.ok()) {
      // Served by its owner now; the old copy is stale and is reported on
      // the next run as a scene on two servers.
      report_status(st, shards[from].address, "deleting the old copy of scene '" + id + "'");
      ++failed;
      continue;
    }
    ++moved;
  }
  std::fprintf(stderr, "voxvis: %zu scenes: %zu %s, %zu already on their owner, %zu failed\n", where.size(),
               moved, args.dry_run ? "to move" : "moved", in_place, failed);
  return failed == 0 ? kExitOk : kExitError;
}

Command add_rebalance_command(CLI::App& app) {
  auto args = std::make_shared<RebalanceArgs>();
  CLI::App* cmd = app.add_subcommand(
      "rebalance", "Move every scene of a fleet to the server that owns it (after the fleet changed).");
  add_net_options(cmd, &args->net);
  cmd->get_option("--servers")->required();
  cmd->add_option("--drain", args->drain,
                  "Servers leaving the fleet (not in --servers): every scene they hold moves "
                  "to its owner among --servers")
      ->type_name("[NAME=]HOST:PORT,...");
  cmd->add_flag("--dry-run", args->dry_run, "Print the moves without making them");
  cmd->footer(
      "Lists every server's scenes (those served, and those a server keeps for another\n"
      "shard); each scene not on its owner is exported (its scene file and its dynamic\n"
      "objects' current positions), created on the owner, then deleted where it was.\n"
      "One line per move. A scene found on two servers is left alone and reported.\n"
      "Needs an admin token on every server. Exit status 2 when any move failed.");
  return {cmd, [args] { return run_rebalance(*args); }};
}

}  // namespace voxvis::cli
