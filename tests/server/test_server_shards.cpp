// A fleet of voxvis-servers on loopback, each started with its shard identity
// (--shard, --fleet): scenes routed by rendezvous hashing land on exactly one
// server, the others refuse them naming the owner, a restarted shard serves
// its scenes again, and `voxvis rebalance` moves every scene to its owner
// after the fleet grew, dynamic objects' positions and clock included.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "server_process.h"
#include "voxvis/fleet.h"
#include "voxvis/routing.h"

namespace voxvis::servertest {
namespace {

/// Servers a, b, c, ... each started with --shard NAME --fleet <all names>.
struct Fleet {
  std::vector<std::string> names;
  std::vector<std::unique_ptr<ServerProcess>> servers;

  void set_fleet(const std::vector<std::string>& fleet) {
    names = fleet;
    std::string list;
    for (const std::string& n : fleet) list += (list.empty() ? "" : ",") + n;
    while (servers.size() < fleet.size()) servers.push_back(std::make_unique<ServerProcess>());
    for (std::size_t i = 0; i < fleet.size(); ++i) servers[i]->extra_args() = {"--shard", fleet[i], "--fleet", list};
  }
  /// The owner's index by the routing library, as every client computes it.
  std::size_t owner(const std::string& id) const { return routing::owner(names, id); }
  /// --servers for the CLI: NAME=127.0.0.1:PORT,...
  std::string servers_arg() const {
    std::string list;
    for (std::size_t i = 0; i < names.size(); ++i)
      list += (list.empty() ? "" : ",") + names[i] + "=" + servers[i]->address();
    return list;
  }
  /// Every server's served scene ids.
  std::vector<std::vector<std::string>> listing() const {
    std::vector<std::vector<std::string>> out;
    for (const auto& s : servers) {
      std::vector<std::string> ids;
      EXPECT_TRUE(s->api().list_scenes(&ids).ok());
      out.push_back(ids);
    }
    return out;
  }
};

std::string scene_id(int i) { return "match-" + std::to_string(i); }
std::vector<std::string> all_names() { return {"a", "b", "c", "d"}; }

/// Every scene of `ids` is served by its owner and by no other server.
void expect_each_on_its_owner(const Fleet& fleet, const std::vector<std::string>& ids) {
  const auto listing = fleet.listing();
  std::map<std::string, std::vector<std::size_t>> where;
  for (std::size_t s = 0; s < listing.size(); ++s)
    for (const std::string& id : listing[s]) where[id].push_back(s);
  EXPECT_EQ(where.size(), ids.size());
  for (const std::string& id : ids) {
    ASSERT_EQ(where[id].size(), 1u) << id << " is on " << where[id].size() << " servers";
    EXPECT_EQ(where[id][0], fleet.owner(id)) << id;
  }
}

TEST(ServerShards, HundredScenesEachOnExactlyItsOwner) {
  Fleet fleet;
  fleet.set_fleet({"a", "b", "c"});
  for (auto& s : fleet.servers) ASSERT_TRUE(s->start());
  // Created through the client library's fleet: it picks each scene's server.
  std::string error;
  const std::unique_ptr<client::Fleet> routed = client::Fleet::connect(fleet.servers_arg(), {}, &error);
  ASSERT_NE(routed, nullptr) << error;
  ASSERT_EQ(routed->shards().size(), 3u);
  const std::string json = wall_scene_json();
  std::vector<std::string> ids;
  for (int i = 0; i < 100; ++i) {
    ids.push_back(scene_id(i));
    EXPECT_EQ(routed->owner(ids.back()), fleet.owner(ids.back()));
    v1::SceneInfo info;
    const grpc::Status st = routed->for_scene(ids.back()).create_scene(ids.back(), json, &info);
    ASSERT_TRUE(st.ok()) << ids.back() << ": " << show(st);
  }
  expect_each_on_its_owner(fleet, ids);
  // Rendezvous hashing spreads them: each of three shards gets some (the
  // chance that one gets none of 100 is below 1e-17).
  for (const auto& served : fleet.listing()) EXPECT_FALSE(served.empty());

  // A shard restarted on its data directory serves the same scenes again,
  // and answers for them.
  const std::vector<std::string> before = fleet.listing()[1];
  EXPECT_EQ(fleet.servers[1]->terminate(), 0);
  ASSERT_TRUE(fleet.servers[1]->restart());
  EXPECT_EQ(fleet.listing()[1], before);
  v1::GetPvsResponse pvs;
  ASSERT_TRUE(fleet.servers[1]->api().get_pvs(before.front(), 0.0, wall_camera(), &pvs).ok());
  EXPECT_EQ(ids_of(pvs.pvs()), (std::vector<ObjectId>{1, 3}));
  expect_each_on_its_owner(fleet, ids);
}

TEST(ServerShards, OtherShardsScenesAreRefusedNamingTheOwner) {
  Fleet fleet;
  fleet.set_fleet({"a", "b", "c"});
  ASSERT_TRUE(fleet.servers[0]->start());
  const Api api = fleet.servers[0]->api();
  // An id that shard a does not own, and one it does.
  std::string theirs, ours;
  for (int i = 0; theirs.empty() || ours.empty(); ++i) {
    (fleet.owner(scene_id(i)) == 0 ? ours : theirs) = scene_id(i);
  }
  const std::string owner = fleet.names[fleet.owner(theirs)];
  const std::string named = "belongs to shard '" + owner + "', not to this server ('a'";

  grpc::Status st = api.create_scene_json(theirs, wall_scene_json());
  EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << show(st);
  EXPECT_NE(st.error_message().find(named), std::string::npos) << st.error_message();
  v1::GetPvsResponse pvs;
  st = api.get_pvs(theirs, 0.0, wall_camera(), &pvs);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << show(st);
  EXPECT_NE(st.error_message().find(named), std::string::npos) << st.error_message();
  v1::SceneInfo info;
  EXPECT_EQ(api.stats(theirs, &info).error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_EQ(api.delete_scene(theirs).error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  {
    ViewStream view(api, theirs);
    v1::ViewResponse response;
    EXPECT_FALSE(view.frame(1, 0.0, wall_camera(), &response));
    st = view.finish();
    EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << show(st);
    EXPECT_NE(st.error_message().find(named), std::string::npos) << st.error_message();
  }
  // Its own ids behave as without a fleet: NOT_FOUND until created.
  EXPECT_EQ(api.stats(ours, &info).error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_TRUE(api.create_scene_json(ours, wall_scene_json()).ok());
  EXPECT_TRUE(api.stats(ours, &info).ok());
}

TEST(ServerShards, StartRefusesBadIdentitiesAndOtherShardsSceneFiles) {
  const std::string scene = make_temp_dir("shards") + "/scene.json";
  spit(scene, wall_scene_json());
  // An id shard a does not own among a, b, c.
  std::string theirs;
  for (int i = 0; theirs.empty(); ++i)
    if (routing::owner(std::vector<std::string>{"a", "b", "c"}, scene_id(i)) != 0) theirs = scene_id(i);
  const struct {
    std::vector<std::string> args;
    std::string message;
  } cases[] = {
      {{"--shard", "a"}, "--shard and --fleet go together"},
      {{"--fleet", "a,b"}, "--shard and --fleet go together"},
      {{"--shard", "a", "--fleet", "a,b,a"}, "shard 'a' is listed twice"},
      {{"--shard", "a b", "--fleet", "a b,c"}, "--shard: a shard name must be printable ASCII"},
      {{"--shard", "a", "--fleet", "a,b,c", "--scene", theirs + "=" + scene},
       "scene '" + theirs + "' belongs to shard"},
  };
  for (const auto& c : cases) {
    const std::string dir = make_temp_dir("shards");
    std::vector<std::string> argv = {VOXVIS_SERVER, "--listen", "127.0.0.1:0", "--data-dir", dir + "/data"};
    argv.insert(argv.end(), c.args.begin(), c.args.end());
    const ProcessResult r = run_program(argv, dir, Seconds(30));
    EXPECT_EQ(r.status, 2) << c.message << "\n" << r.err;
    EXPECT_NE(r.err.find(c.message), std::string::npos) << r.err;
  }
}

TEST(ServerShards, RebalanceMovesScenesToTheirOwnersWithTheirPositions) {
  Fleet fleet;
  fleet.set_fleet({"a", "b", "c"});
  for (auto& s : fleet.servers) ASSERT_TRUE(s->start());
  const std::string json = wall_scene_json();
  std::vector<std::string> ids;
  for (int i = 0; i < 30; ++i) {
    ids.push_back(scene_id(i));
    ASSERT_TRUE(fleet.servers[fleet.owner(ids.back())]->api().create_scene_json(ids.back(), json).ok());
  }
  // The scenes shard d will own once it joins: move their dynamic sphere
  // (id 2) and the clock, so that the move must carry both.
  const std::vector<std::string> all = {"a", "b", "c", "d"};
  std::vector<std::string> to_d;
  for (const std::string& id : ids)
    if (routing::owner(all, id) == 3) to_d.push_back(id);
  ASSERT_FALSE(to_d.empty());
  for (std::size_t k = 0; k < to_d.size(); ++k) {
    SimStream sim(fleet.servers[fleet.owner(to_d[k])]->api(), to_d[k]);
    Move m;
    m.id = 2;
    m.center = Vec3(10.0, 10.0, 15.0 - 0.25 * double(k % 8));
    v1::MoveAck ack;
    ASSERT_TRUE(sim.move(1, 1.5 + double(k), {m}, &ack));
    EXPECT_TRUE(sim.finish().ok());
  }
  std::map<std::string, v1::ExportSceneResponse> exported;
  for (const std::string& id : to_d) {
    ASSERT_TRUE(fleet.servers[fleet.owner(id)]->api().export_scene(id, &exported[id]).ok());
    ASSERT_TRUE(exported[id].has_positions()) << id;
  }

  // The fleet grows: every shard restarts with the new list; d starts empty.
  for (auto& s : fleet.servers) EXPECT_EQ(s->terminate(), 0);
  fleet.set_fleet(all);
  for (auto& s : fleet.servers) ASSERT_TRUE(s->start());
  // The scenes that are d's now are kept where they were, listed, not served.
  std::size_t kept = 0;
  for (std::size_t s = 0; s < 3; ++s) {
    grpc::ClientContext ctx;
    fleet.servers[s]->api().prepare(&ctx);
    v1::ListScenesResponse list;
    ASSERT_TRUE(fleet.servers[s]->api().stub().ListScenes(&ctx, {}, &list).ok());
    for (const v1::MisplacedScene& m : list.misplaced()) {
      EXPECT_EQ(m.owner(), "d");
      ++kept;
    }
  }
  EXPECT_EQ(kept, to_d.size());

  const ProcessResult r = run_program({VOXVIS_CLI, "rebalance", "--servers", fleet.servers_arg()},
                                      fleet.servers[0]->dir());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find(std::to_string(to_d.size()) + " moved"), std::string::npos) << r.err;
  expect_each_on_its_owner(fleet, ids);

  // Each moved scene has its positions and clock: exported again from d,
  // the same bytes; its frame sees the sphere where the simulation left it.
  for (const std::string& id : to_d) {
    const Api api = fleet.servers[3]->api();
    v1::ExportSceneResponse again;
    ASSERT_TRUE(api.export_scene(id, &again).ok());
    EXPECT_EQ(again.SerializeAsString(), exported[id].SerializeAsString()) << id;
    v1::SceneInfo info;
    ASSERT_TRUE(api.stats(id, &info).ok());
    EXPECT_EQ(info.time(), exported[id].positions().t());
  }
  // A second run finds nothing to move.
  const ProcessResult again = run_program({VOXVIS_CLI, "rebalance", "--servers", fleet.servers_arg()},
                                          fleet.servers[0]->dir());
  EXPECT_EQ(again.status, 0) << again.err;
  EXPECT_NE(again.err.find(" 0 moved, " + std::to_string(ids.size()) + " already on their owner"), std::string::npos)
      << again.err;
}

TEST(ServerShards, ADrainedShardHandsEverySceneToTheRest) {
  // Shrinking a,b,c,d to a,b,c: every server restarts with the new list,
  // d (no longer in it) drains: it serves nothing and keeps its scenes,
  // which `rebalance --drain` moves to their owners among a, b, c.
  Fleet fleet;
  fleet.set_fleet({"a", "b", "c", "d"});
  for (auto& s : fleet.servers) ASSERT_TRUE(s->start());
  std::vector<std::string> ids;
  for (int i = 0; i < 40; ++i) {
    ids.push_back(scene_id(i));
    ASSERT_TRUE(fleet.servers[fleet.owner(ids.back())]->api().create_scene_json(ids.back(), wall_scene_json()).ok());
  }
  const std::vector<std::string> on_d = fleet.listing()[3];
  ASSERT_FALSE(on_d.empty());
  for (auto& s : fleet.servers) EXPECT_EQ(s->terminate(), 0);
  const std::vector<std::string> three = {"a", "b", "c"};
  for (std::size_t i = 0; i < 4; ++i) fleet.servers[i]->extra_args() = {"--shard", all_names()[i], "--fleet", "a,b,c"};
  for (auto& s : fleet.servers) ASSERT_TRUE(s->start());
  EXPECT_NE(fleet.servers[3]->log().find("draining"), std::string::npos) << fleet.servers[3]->log();
  // d refuses its former scenes, naming the new owner.
  v1::SceneInfo info;
  const grpc::Status st = fleet.servers[3]->api().stats(on_d[0], &info);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(st.error_message().find("belongs to shard '" + three[routing::owner(three, on_d[0])] + "'"),
            std::string::npos)
      << st.error_message();

  std::string servers, drain = "d=" + fleet.servers[3]->address();
  for (std::size_t i = 0; i < 3; ++i) servers += (i ? "," : "") + three[i] + "=" + fleet.servers[i]->address();
  ProcessResult r = run_program({VOXVIS_CLI, "rebalance", "--servers", servers, "--drain", servers.substr(0, servers.find(','))},
                                fleet.servers[0]->dir());
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("is also in --servers"), std::string::npos) << r.err;
  r = run_program({VOXVIS_CLI, "rebalance", "--servers", servers, "--drain", drain}, fleet.servers[0]->dir());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find(std::to_string(on_d.size()) + " moved"), std::string::npos) << r.err;
  fleet.names = three;
  const auto listing = fleet.listing();
  EXPECT_TRUE(listing[3].empty());
  std::set<std::string> found;
  for (std::size_t s = 0; s < 3; ++s) {
    for (const std::string& id : listing[s]) {
      EXPECT_EQ(s, routing::owner(three, id)) << id;
      EXPECT_TRUE(found.insert(id).second) << id;
    }
  }
  EXPECT_EQ(found.size(), ids.size());
}

TEST(ServerShards, RebalanceNamesAListThatDisagreesWithTheServers) {
  // A server keeps a scene for shard b (its --fleet is a,b), while the list
  // given to rebalance has a alone: nothing can be moved, and it says why.
  ServerProcess server;
  ASSERT_TRUE(server.start());
  std::string theirs;
  for (int i = 0; theirs.empty(); ++i)
    if (routing::owner(std::vector<std::string>{"a", "b"}, scene_id(i)) == 1) theirs = scene_id(i);
  ASSERT_TRUE(server.api().create_scene_json(theirs, wall_scene_json()).ok());
  EXPECT_EQ(server.terminate(), 0);
  server.extra_args() = {"--shard", "a", "--fleet", "a,b"};
  ASSERT_TRUE(server.restart());
  const ProcessResult r =
      run_program({VOXVIS_CLI, "rebalance", "--servers", "a=" + server.address()}, server.dir());
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("scene '" + theirs + "' is on a, its owner by --servers, but that server keeps it unserved"),
            std::string::npos)
      << r.err;
}

// Before: rebalance exported a scene its source still served (a rolling
// restart not finished, the source's --fleet the old list), created it on
// the new owner and deleted it, while the source went on acknowledging
// moves; those sent between the export and the delete were lost (3 to 15
// acknowledged batches in 6 of 6 rounds), and rebalance said "0 failed".
TEST(ServerShards, RebalanceDuringARollingRestartLosesNoAcknowledgedMove) {
  // a still runs with the old list (a alone); b with the new one (a, b).
  ServerProcess a({"--shard", "a", "--fleet", "a"}), b({"--shard", "b", "--fleet", "a,b"});
  ASSERT_TRUE(a.start());
  ASSERT_TRUE(b.start());
  std::string id;
  for (int i = 0; id.empty(); ++i)
    if (routing::owner(std::vector<std::string>{"a", "b"}, scene_id(i)) == 1) id = scene_id(i);
  ASSERT_TRUE(a.api().create_scene_json(id, wall_scene_json()).ok());
  const std::string servers = "a=" + a.address() + ",b=" + b.address();

  // The simulation streams moves to a in lock step while rebalance runs.
  std::mutex mu;
  Move last{2, Vec3(10.0, 10.0, 10.0)};  // The last move a acknowledged.
  double last_t = 0.0;
  std::atomic<int> acked{0};
  std::atomic<bool> stop{false};
  std::thread simulation([&] {
    SimStream sim(a.api(), id);
    for (std::uint64_t k = 1; !stop.load(); ++k) {
      const Move m{2, Vec3(10.0, 10.0, 10.0 + 0.001 * double(k))};
      const double t = 0.01 * double(k);
      v1::MoveAck ack;
      if (!sim.move(k, t, {m}, &ack)) break;
      std::lock_guard<std::mutex> lock(mu);
      last = m;
      last_t = t;
      acked.fetch_add(1);
    }
    sim.finish();
  });
  ASSERT_TRUE(wait_until([&] { return acked.load() >= 5; }, Seconds(30)));
  // A move's export and delete of a scene its server serves are refused.
  grpc::ClientContext ctx;
  a.api().prepare(&ctx);
  v1::ExportSceneRequest req;
  req.set_scene_id(id);
  req.set_only_if_misplaced(true);
  v1::ExportSceneResponse refused;
  const grpc::Status st = a.api().stub().ExportScene(&ctx, req, &refused);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(st.error_message().find("is served here (shard 'a', whose --fleet makes it the scene's owner)"),
            std::string::npos)
      << st.error_message();
  const ProcessResult early = run_program({VOXVIS_CLI, "rebalance", "--servers", servers}, a.dir());
  const int before = acked.load();
  ASSERT_TRUE(wait_until([&] { return acked.load() >= before + 5; }, Seconds(30))) << "a acknowledges on";
  stop.store(true);
  simulation.join();
  EXPECT_EQ(early.status, 2) << early.err;
  EXPECT_NE(early.err.find("scene '" + id + "' is served by a, but its owner by --servers is b: left there"),
            std::string::npos)
      << early.err;
  EXPECT_NE(early.err.find("0 moved, 0 already on their owner, 1 failed"), std::string::npos) << early.err;
  // Nothing moved: a serves it where the last acknowledged move put it.
  std::vector<std::string> on_b;
  ASSERT_TRUE(b.api().list_scenes(&on_b).ok());
  EXPECT_TRUE(on_b.empty());
  v1::ExportSceneResponse held;
  ASSERT_TRUE(a.api().export_scene(id, &held).ok());
  ASSERT_EQ(held.positions().moves_size(), 1);
  EXPECT_EQ(held.positions().moves(0).center().z(), last.center.z);
  EXPECT_EQ(held.positions().t(), last_t);

  // The restart finishes: a takes the new list, keeps the scene for b,
  // and rebalance moves it with every acknowledged move.
  EXPECT_EQ(a.terminate(), 0);
  a.extra_args() = {"--shard", "a", "--fleet", "a,b"};
  ASSERT_TRUE(a.restart());
  const ProcessResult r =
      run_program({VOXVIS_CLI, "rebalance", "--servers", "a=" + a.address() + ",b=" + b.address()}, a.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("1 moved"), std::string::npos) << r.err;
  v1::ExportSceneResponse moved;
  ASSERT_TRUE(b.api().export_scene(id, &moved).ok());
  ASSERT_EQ(moved.positions().moves_size(), 1);
  EXPECT_EQ(moved.positions().moves(0).center().z(), last.center.z);
  EXPECT_EQ(moved.positions().t(), last_t);
  std::vector<std::string> on_a;
  ASSERT_TRUE(a.api().list_scenes(&on_a).ok());
  EXPECT_TRUE(on_a.empty());
}

TEST(ServerShards, CreateWithPositionsChecksEveryEntry) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  const auto create = [&](const std::string& id, const v1::ScenePositions& p) {
    grpc::ClientContext ctx;
    api.prepare(&ctx);
    v1::CreateSceneRequest req;
    req.set_scene_id(id);
    req.set_scene_json(wall_scene_json());
    *req.mutable_positions() = p;
    v1::SceneInfo info;
    return api.stub().CreateScene(&ctx, req, &info);
  };
  const auto move = [](std::uint32_t id, double z) {
    v1::Move m;
    m.set_id(id);
    m.mutable_center()->set_x(10);
    m.mutable_center()->set_y(10);
    m.mutable_center()->set_z(z);
    return m;
  };
  const struct {
    std::vector<v1::Move> moves;
    double t;
    std::string field;
  } cases[] = {
      {{move(1, 10)}, 0.0, "positions.moves[0].id: object 1 is not dynamic"},
      {{move(2, 14), move(2, 13)}, 0.0, "positions.moves[1].id"},
      {{move(2, 14), move(99, 13)}, 0.0, "positions.moves[1].id: no object 99"},
      {{move(2, 14)}, std::nan(""), "positions.t"},
      {{move(2, 14)}, 1e11, "positions.t"},
      {{move(2, std::nan(""))}, 0.0, "positions.moves[0].center"},
      {{move(2, 1e13)}, 0.0, "positions.moves[0].center: magnitude must be at most"},
      {{move(2, std::numeric_limits<double>::infinity())}, 0.0, "positions.moves[0].center"},
  };
  int n = 0;
  for (const auto& c : cases) {
    v1::ScenePositions p;
    p.set_t(c.t);
    for (const v1::Move& m : c.moves) *p.add_moves() = m;
    const grpc::Status st = create("bad-" + std::to_string(n++), p);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << c.field;
    EXPECT_NE(st.error_message().find(c.field), std::string::npos) << st.error_message();
  }
  {
    v1::ScenePositions p;
    p.set_t(0.0);
    *p.add_moves() = move(2, 14);
    v1::Quat* q = p.mutable_moves(0)->mutable_rotation();
    q->set_w(1);
    const grpc::Status st = create("bad-rotation", p);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(st.error_message().find("positions.moves[0].rotation"), std::string::npos) << st.error_message();
  }
  std::vector<std::string> ids;
  ASSERT_TRUE(api.list_scenes(&ids).ok());
  EXPECT_TRUE(ids.empty());

  // A good one starts there, with its clock, and keeps both over a restart.
  v1::ScenePositions p;
  p.set_t(42.5);
  *p.add_moves() = move(2, 13.25);
  ASSERT_TRUE(create("placed", p).ok());
  const auto exported = [&] {
    v1::ExportSceneResponse out;
    EXPECT_TRUE(server.api().export_scene("placed", &out).ok());
    return out;
  };
  v1::ExportSceneResponse out = exported();
  EXPECT_EQ(out.scene_json(), wall_scene_json());
  ASSERT_TRUE(out.has_positions());
  EXPECT_EQ(out.positions().t(), 42.5);
  ASSERT_EQ(out.positions().moves_size(), 1);
  EXPECT_EQ(out.positions().moves(0).center().z(), 13.25);
  EXPECT_EQ(server.terminate(), 0);
  ASSERT_TRUE(server.restart());
  EXPECT_EQ(exported().SerializeAsString(), out.SerializeAsString());
}

TEST(ServerShards, ExportTooLargeForAMessageNamesTheFile) {
  // 400 spheres make a scene file well over 10 KiB: created under the
  // default message limit, exported under one of 10 KiB.
  ServerProcess server;
  ASSERT_TRUE(server.start());
  v1::SceneDescription desc;
  to_proto(lattice_scene(400, 16, 7), &desc);
  ASSERT_TRUE(server.api().create_scene("big", desc).ok());
  EXPECT_EQ(server.terminate(), 0);
  server.extra_args() = {"--max-message-mib", "0.01"};
  ASSERT_TRUE(server.restart());
  v1::ExportSceneResponse out;
  const grpc::Status st = server.api().export_scene("big", &out);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << show(st);
  EXPECT_NE(st.error_message().find("scenes/big.json"), std::string::npos) << st.error_message();
}

TEST(ServerShards, CliRoutesEachSceneToItsOwner) {
  Fleet fleet;
  fleet.set_fleet({"a", "b", "c"});
  for (auto& s : fleet.servers) ASSERT_TRUE(s->start());
  const std::string examples = std::string(VOXVIS_SOURCE_DIR) + "/examples/paper";
  const std::string dir = fleet.servers[0]->dir();
  const std::vector<std::string> all_frames = lines_of(slurp(examples + "/frames.jsonl"));
  std::string frames_text;
  for (std::size_t i = 0; i < 10; ++i) frames_text += all_frames[i] + "\n";
  const std::string frames = dir + "/frames.jsonl";
  spit(frames, frames_text);

  // Three scenes through `voxvis load --servers`: each on its owner.
  std::vector<std::string> ids;
  for (int i = 0; i < 3; ++i) {
    ids.push_back("walk-" + std::to_string(i));
    const ProcessResult r = run_program({VOXVIS_CLI, "load", "--servers", fleet.servers_arg(), "--scene",
                                         examples + "/scene.json", "--id", ids.back()},
                                        dir);
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find(fleet.servers[fleet.owner(ids.back())]->address()), std::string::npos) << r.out;
  }
  expect_each_on_its_owner(fleet, ids);

  // `view --servers` finds the scene and answers as `replay` does.
  ProcessResult r = run_program({VOXVIS_CLI, "replay", "--scene", examples + "/scene.json", "--frames", frames,
                                 "--out", dir + "/replay.jsonl", "-q"},
                                dir);
  ASSERT_EQ(r.status, 0) << r.err;
  r = run_program({VOXVIS_CLI, "view", "--servers", fleet.servers_arg(), "--scene", ids[1], "--frames", frames,
                   "--out", dir + "/view.jsonl", "-q"},
                  dir);
  ASSERT_EQ(r.status, 0) << r.err;
  expect_same_output(slurp(dir + "/replay.jsonl"), slurp(dir + "/view.jsonl"), "voxvis view --servers");

  // `scenes --servers` lists every shard's, each line led by its shard.
  r = run_program({VOXVIS_CLI, "scenes", "--servers", fleet.servers_arg()}, dir);
  ASSERT_EQ(r.status, 0) << r.err;
  for (const std::string& id : ids)
    EXPECT_NE(r.out.find(fleet.names[fleet.owner(id)] + " " + id + ": grid"), std::string::npos) << r.out;

  // A list the servers disagree with is caught by the server: the same
  // addresses under other names route elsewhere, and the refusal names the
  // shard that owns the scene.
  std::string renamed;
  for (std::size_t i = 0; i < 3; ++i)
    renamed += (i ? "," : "") + std::string(1, char('x' + i)) + "=" + fleet.servers[i]->address();
  const std::string small = dir + "/wall.json";
  spit(small, wall_scene_json());
  int refused = 0;
  for (int i = 0; i < 12; ++i) {
    r = run_program({VOXVIS_CLI, "load", "--servers", renamed, "--scene", small, "--id",
                     "other-" + std::to_string(i)},
                    dir);
    if (r.status == 0) continue;
    ++refused;
    EXPECT_EQ(r.status, 2);
    EXPECT_NE(r.err.find("FAILED_PRECONDITION"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("belongs to shard"), std::string::npos) << r.err;
  }
  EXPECT_GT(refused, 0);

  // Bad lists are named.
  for (const auto& [list, message] : std::vector<std::pair<std::string, std::string>>{
           {"a=127.0.0.1:1,,b=127.0.0.1:2", "entry 2 is empty"},
           {"127.0.0.1", "not HOST:PORT"},
           {"h.x:1,h.y:2", "shard name 'h' is given twice"},
           {"a=127.0.0.1:70000", "port in 1..65535"}}) {
    r = run_program({VOXVIS_CLI, "view", "--servers", list, "--scene", "s", "--frames", frames}, dir);
    EXPECT_EQ(r.status, 2) << list;
    EXPECT_NE(r.err.find("--servers: "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(message), std::string::npos) << r.err;
  }
  r = run_program({VOXVIS_CLI, "view", "--servers", fleet.servers_arg(), "--server", "127.0.0.1:1", "--scene", "s",
                   "--frames", frames},
                  dir);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("excludes"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace voxvis::servertest
