// Bearer tokens and roles on the real server (--tokens FILE): no or unknown
// token is UNAUTHENTICATED, a role below the call's is PERMISSION_DENIED,
// roles nest (viewer < simulation < admin), refused calls change nothing,
// and the health service needs no token.
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "server_process.h"

namespace voxvis::servertest {
namespace {

const std::string kViewer = "viewer-token-0123456789abcdef";
const std::string kSimulation = "simulation-token-0123456789abcdef";
const std::string kAdmin = "admin-token-0123456789abcdef";

/// The status of a View stream that sends one frame.
grpc::Status view_status(const Api& api, const std::string& id) {
  ViewStream v(api, id);
  v1::ViewResponse r;
  if (v.send(1, 0.0, wall_camera())) v.read(&r);
  return v.finish();
}

/// The status of a Simulate stream that sends one batch (and whether it was
/// acknowledged).
grpc::Status simulate_status(const Api& api, const std::string& id, bool* acked) {
  SimStream sim(api, id);
  v1::MoveAck ack;
  *acked = sim.move(1, 0.0, {{2, Vec3(10, 10, 15)}}, &ack);
  return sim.finish();
}

/// The status of a Tick stream that sends one tick of one viewer, with one
/// move or none (and whether it was answered).
grpc::Status tick_status(const Api& api, const std::string& id, bool with_move, bool* answered) {
  grpc::ClientContext ctx;
  api.prepare(&ctx);
  auto stream = api.stub().Tick(&ctx);
  v1::TickRequest r;
  r.set_scene_id(id);
  r.set_tick(1);
  if (with_move) {
    v1::Move* m = r.add_moves();
    m->set_id(2);
    m->mutable_center()->set_x(10);
    m->mutable_center()->set_y(10);
    m->mutable_center()->set_z(15);
  }
  v1::TickViewer* v = r.add_viewers();
  v->set_viewer(1);
  const Camera c = wall_camera();
  for (auto [p, q] : {std::pair{c.eye, v->mutable_camera()->mutable_eye()},
                      std::pair{c.dir, v->mutable_camera()->mutable_dir()},
                      std::pair{c.up, v->mutable_camera()->mutable_up()}}) {
    q->set_x(p.x);
    q->set_y(p.y);
    q->set_z(p.z);
  }
  v->mutable_camera()->set_fov_y_deg(c.fov_y_deg);
  v->mutable_camera()->set_aspect(c.aspect);
  v->mutable_camera()->set_near(c.near);
  v->mutable_camera()->set_far(c.far);
  v1::TickResponse resp;
  *answered = stream->Write(r) && stream->Read(&resp) && resp.answers_size() == 1;
  stream->WritesDone();
  while (stream->Read(&resp)) *answered = true;
  return stream->Finish();
}

TEST(ServerRoles, TokensAndRoles) {
  ServerProcess server;
  const std::string tokens = server.path("tokens");
  spit(tokens, "# roles of the test\nviewer " + kViewer + "\nsimulation " + kSimulation +
                   "\nadmin " + kAdmin + "\n");
  server.extra_args() = {"--tokens", tokens};
  ASSERT_TRUE(server.start());
  const Api none = server.api(), unknown = server.api("unknown-token-0123456789abcdef");
  const Api viewer = server.api(kViewer), simulation = server.api(kSimulation),
            admin = server.api(kAdmin);
  ASSERT_TRUE(admin.create_scene_json("s", wall_scene_json()).ok());
  const std::vector<std::string> just_s = {"s"};
  std::vector<std::string> ids;

  for (const Api* api : {&none, &unknown}) {
    SCOPED_TRACE(api->token().empty() ? "no token" : "unknown token");
    const auto unauth = grpc::StatusCode::UNAUTHENTICATED;
    EXPECT_EQ(api->list_scenes(&ids).error_code(), unauth);
    v1::SceneInfo info;
    EXPECT_EQ(api->stats("s", &info).error_code(), unauth);
    v1::GetPvsResponse pvs;
    EXPECT_EQ(api->get_pvs("s", 0, wall_camera(), &pvs).error_code(), unauth);
    EXPECT_EQ(api->create_scene_json("x", wall_scene_json()).error_code(), unauth);
    EXPECT_EQ(api->delete_scene("s").error_code(), unauth);
    v1::ExportSceneResponse exported;
    EXPECT_EQ(api->export_scene("s", &exported).error_code(), unauth);
    EXPECT_EQ(view_status(*api, "s").error_code(), unauth);
    bool acked = true;
    EXPECT_EQ(simulate_status(*api, "s", &acked).error_code(), unauth);
    EXPECT_FALSE(acked);
    bool answered = true;
    EXPECT_EQ(tick_status(*api, "s", false, &answered).error_code(), unauth);
    EXPECT_FALSE(answered);
    ASSERT_TRUE(admin.list_scenes(&ids).ok());
    EXPECT_EQ(ids, just_s);
  }

  {
    SCOPED_TRACE("viewer");
    ASSERT_TRUE(viewer.list_scenes(&ids).ok());
    EXPECT_EQ(ids, just_s);
    v1::SceneInfo info;
    EXPECT_TRUE(viewer.stats("s", &info).ok());
    v1::GetPvsResponse pvs;
    EXPECT_TRUE(viewer.get_pvs("s", 0, wall_camera(), &pvs).ok());
    const grpc::Status v = view_status(viewer, "s");
    EXPECT_TRUE(v.ok()) << show(v);
    const auto denied = grpc::StatusCode::PERMISSION_DENIED;
    EXPECT_EQ(viewer.create_scene_json("x", wall_scene_json()).error_code(), denied);
    EXPECT_EQ(viewer.delete_scene("s").error_code(), denied);
    v1::ExportSceneResponse exported;
    EXPECT_EQ(viewer.export_scene("s", &exported).error_code(), denied);
    bool acked = true;
    EXPECT_EQ(simulate_status(viewer, "s", &acked).error_code(), denied);
    EXPECT_FALSE(acked);
    // Ticks without moves are a viewer's; with moves, a simulation's.
    bool answered = false;
    const grpc::Status tv = tick_status(viewer, "s", false, &answered);
    EXPECT_TRUE(tv.ok()) << show(tv);
    EXPECT_TRUE(answered);
    const grpc::Status tm = tick_status(viewer, "s", true, &answered);
    EXPECT_EQ(tm.error_code(), denied) << show(tm);
    EXPECT_FALSE(answered);
    ASSERT_TRUE(admin.list_scenes(&ids).ok());
    EXPECT_EQ(ids, just_s);
    ASSERT_TRUE(admin.stats("s", &info).ok());
    EXPECT_EQ(info.moves_applied(), 0u);
  }

  {
    SCOPED_TRACE("simulation");
    bool acked = false;
    const grpc::Status sim = simulate_status(simulation, "s", &acked);
    EXPECT_TRUE(sim.ok()) << show(sim);
    EXPECT_TRUE(acked);
    const grpc::Status v = view_status(simulation, "s");
    EXPECT_TRUE(v.ok()) << show(v);
    bool answered = false;
    const grpc::Status tm = tick_status(simulation, "s", true, &answered);
    EXPECT_TRUE(tm.ok()) << show(tm);
    EXPECT_TRUE(answered);
    ASSERT_TRUE(simulation.list_scenes(&ids).ok());
    const auto denied = grpc::StatusCode::PERMISSION_DENIED;
    EXPECT_EQ(simulation.delete_scene("s").error_code(), denied);
    v1::ExportSceneResponse exported;
    EXPECT_EQ(simulation.export_scene("s", &exported).error_code(), denied);
    EXPECT_EQ(simulation.create_scene_json("x", wall_scene_json()).error_code(), denied);
    ASSERT_TRUE(admin.list_scenes(&ids).ok());
    EXPECT_EQ(ids, just_s);
  }

  {
    SCOPED_TRACE("admin");
    ASSERT_TRUE(admin.create_scene_json("t", wall_scene_json()).ok());
    v1::ExportSceneResponse exported;
    ASSERT_TRUE(admin.export_scene("t", &exported).ok());
    EXPECT_EQ(exported.scene_json(), wall_scene_json());
    ASSERT_TRUE(admin.list_scenes(&ids).ok());
    EXPECT_EQ(ids, (std::vector<std::string>{"s", "t"}));
    bool acked = false;
    const grpc::Status sim = simulate_status(admin, "t", &acked);
    EXPECT_TRUE(sim.ok()) << show(sim);
    EXPECT_TRUE(acked);
    const grpc::Status v = view_status(admin, "t");
    EXPECT_TRUE(v.ok()) << show(v);
    v1::SceneInfo info;
    ASSERT_TRUE(admin.stats("t", &info).ok());
    EXPECT_EQ(info.moves_applied(), 1u);
    v1::GetPvsResponse pvs;
    EXPECT_TRUE(admin.get_pvs("t", 0, wall_camera(), &pvs).ok());
    EXPECT_TRUE(admin.delete_scene("t").ok());
    ASSERT_TRUE(admin.list_scenes(&ids).ok());
    EXPECT_EQ(ids, just_s);
  }

  // The health service answers without a token (load balancers have none).
  std::string health;
  const grpc::Status h =
      generic_unary(server.channel(), "/grpc.health.v1.Health/Check", "", &health);
  EXPECT_TRUE(h.ok()) << show(h);
  EXPECT_EQ(health, std::string("\x08\x01", 2)) << "status SERVING";
  EXPECT_EQ(server.terminate(), 0);
}

}  // namespace
}  // namespace voxvis::servertest
