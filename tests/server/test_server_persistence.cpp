// The data directory across restarts: scenes created through the API and the
// positions of their dynamic objects survive a graceful stop (SIGTERM) and,
// once acknowledged or saved, a crash (SIGKILL); what cannot be loaded is
// quarantined and the rest served.
//
// The scene (wall_scene_json) makes positions observable through GetPvs: the
// dynamic sphere 2 starts behind a wall that hides it from wall_camera() and
// is moved in front of it, so the PVS contains 2 only when the move survived.
#include <signal.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "server_process.h"

namespace voxvis::servertest {
namespace {

namespace fs = std::filesystem;

const Vec3 kInFront(6.0, 10.0, 5.0);

/// The PVS of wall_camera() in `id`; empty on error (and the test fails).
std::vector<ObjectId> pvs_of(const Api& api, const std::string& id) {
  v1::GetPvsResponse resp;
  const grpc::Status s = api.get_pvs(id, 0.0, wall_camera(), &resp);
  EXPECT_TRUE(s.ok()) << s.error_code() << " " << s.error_message();
  return ids_of(resp.pvs());
}

/// The scene ids the server lists; empty on error (and the test fails).
std::vector<std::string> scene_ids(const Api& api) {
  std::vector<std::string> ids;
  const grpc::Status s = api.list_scenes(&ids);
  EXPECT_TRUE(s.ok()) << s.error_code() << " " << s.error_message();
  return ids;
}

bool has(const std::vector<ObjectId>& ids, ObjectId id) {
  return std::find(ids.begin(), ids.end(), id) != ids.end();
}

/// Moves sphere 2 in front of the wall at time t, acknowledged.
void move_in_front(const Api& api, const std::string& id, double t) {
  SimStream sim(api, id);
  v1::MoveAck ack;
  ASSERT_TRUE(sim.move(1, t, {{2, kInFront}}, &ack)) << sim.finish().error_message();
  EXPECT_EQ(ack.applied(), 1u);
  const grpc::Status s = sim.finish();
  EXPECT_TRUE(s.ok()) << s.error_message();
}

TEST(ServerPersistence, GracefulStopKeepsScenesAndPositions) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  {
    const Api api = server.api();
    ASSERT_TRUE(api.create_scene_json("walls", wall_scene_json()).ok());
    ASSERT_TRUE(api.create_scene_json("gone", wall_scene_json()).ok());
    // The design of the scene: 2 hidden at first.
    ASSERT_EQ(pvs_of(api, "walls"), (std::vector<ObjectId>{1, 3}));
    move_in_front(api, "walls", 1.5);
    ASSERT_EQ(pvs_of(api, "walls"), (std::vector<ObjectId>{1, 2, 3}));
    ASSERT_TRUE(api.delete_scene("gone").ok());
  }
  EXPECT_EQ(server.terminate(), 0);

  ASSERT_TRUE(server.restart());
  const Api api = server.api();
  std::vector<std::string> ids;
  ASSERT_TRUE(api.list_scenes(&ids).ok());
  EXPECT_EQ(ids, (std::vector<std::string>{"walls"}));
  v1::SceneInfo info;
  ASSERT_TRUE(api.stats("walls", &info).ok());
  EXPECT_EQ(info.objects(), 3u);
  EXPECT_EQ(info.dynamic_objects(), 1u);
  EXPECT_EQ(info.time(), 1.5) << "the scene's clock is saved with the positions";
  EXPECT_EQ(pvs_of(api, "walls"), (std::vector<ObjectId>{1, 2, 3}));
  EXPECT_EQ(server.terminate(), 0);
}

TEST(ServerPersistence, KillKeepsAcknowledgedScenesAndSavedPositions) {
  ServerProcess server({"--save-period", "0.2"});
  ASSERT_TRUE(server.start());
  // A scene is on disk before CreateScene answers OK.
  ASSERT_TRUE(server.api().create_scene_json("walls", wall_scene_json()).ok());
  server.kill9();

  ASSERT_TRUE(server.restart());
  {
    const Api api = server.api();
    std::vector<std::string> ids;
    ASSERT_TRUE(api.list_scenes(&ids).ok());
    ASSERT_EQ(ids, (std::vector<std::string>{"walls"}));
    ASSERT_EQ(pvs_of(api, "walls"), (std::vector<ObjectId>{1, 3}));
    move_in_front(api, "walls", 2.0);
    ASSERT_TRUE(has(pvs_of(api, "walls"), 2));
  }
  // Positions are saved every period: wait several periods, and until the
  // positions file (data directory layout, server/store.h) is there.
  std::this_thread::sleep_for(std::chrono::milliseconds(1000));
  const std::string positions = server.data_dir() + "/scenes/walls.positions";
  EXPECT_TRUE(wait_until([&] { return fs::exists(positions); }, Seconds(10)))
      << positions << " not written within 10 s of the move";
  server.kill9();

  ASSERT_TRUE(server.restart());
  const Api api = server.api();
  std::vector<std::string> ids;
  ASSERT_TRUE(api.list_scenes(&ids).ok());
  EXPECT_EQ(ids, (std::vector<std::string>{"walls"}));
  EXPECT_EQ(pvs_of(api, "walls"), (std::vector<ObjectId>{1, 2, 3}));
  EXPECT_EQ(server.terminate(), 0);
}

TEST(ServerPersistence, UnloadableEntriesAreQuarantinedAndTheRestServed) {
  ServerProcess server;
  const fs::path scenes = fs::path(server.data_dir()) / "scenes";
  const fs::path quarantine = fs::path(server.data_dir()) / "quarantine";
  fs::create_directories(scenes);
  spit((scenes / "good.json").string(), wall_scene_json());
  // Sphere 2 in front of the wall, at a time beyond the engine's clock: the
  // positions are quarantined, the scene loads at its created positions.
  spit((scenes / "good.positions").string(),
       R"({"format": "voxvis-positions/1", "t": 1e300, "moves": [{"id": 2, "center": [6, 10, 5]}]})");
  spit((scenes / "broken.json").string(), R"({"format": "voxvis-scene/1", "objects": [)");
  // A scene outside the data directory, which would load if followed.
  const std::string secret = server.path("secret.json");
  spit(secret, wall_scene_json());
  fs::create_symlink(secret, scenes / "link.json");

  ASSERT_TRUE(server.start());
  EXPECT_EQ(scene_ids(server.api()), (std::vector<std::string>{"good"}));
  EXPECT_EQ(pvs_of(server.api(), "good"), (std::vector<ObjectId>{1, 3}));
  const std::string log = server.log();
  EXPECT_NE(log.find("quarantined scene 'broken': "), std::string::npos) << log;
  EXPECT_NE(log.find((scenes / "link.json").string() + ": a symbolic link"), std::string::npos) << log;
  EXPECT_NE(log.find((scenes / "good.positions").string() + ": t: "), std::string::npos) << log;
  EXPECT_TRUE(fs::is_regular_file(quarantine / "broken.json"));
  EXPECT_TRUE(fs::is_symlink(quarantine / "link.json"));
  EXPECT_TRUE(fs::is_regular_file(quarantine / "good.positions"));
  EXPECT_FALSE(fs::exists(fs::symlink_status(scenes / "link.json")));
  EXPECT_EQ(slurp(secret), wall_scene_json()) << "the symlink's target is untouched";
  EXPECT_EQ(server.terminate(), 0);

  // Nothing is left to quarantine at the next start.
  ASSERT_TRUE(server.restart());
  EXPECT_EQ(scene_ids(server.api()), (std::vector<std::string>{"good"}));
  EXPECT_EQ(server.terminate(), 0);
  const auto count = [](const std::string& text, const std::string& needle) {
    std::size_t n = 0;
    for (std::size_t at = text.find(needle); at != std::string::npos; at = text.find(needle, at + 1)) ++n;
    return n;
  };
  EXPECT_EQ(count(server.log(), "quarantine"), count(log, "quarantine")) << server.log();
}

}  // namespace
}  // namespace voxvis::servertest
