// The real server against hostile and careless clients: times that would spin
// the engine, viewers pushing a scene's clock, ids of any length, a delete
// racing a create, floods from one client, work of clients that left, and a
// shutdown with work queued. Each test names the behaviour it pins down.
#include <atomic>
#include <chrono>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "scenes.h"
#include "server_process.h"
#include "voxvis/format.h"

namespace voxvis::servertest {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

/// GetPvs with its own deadline (the harness's default is 30 s).
grpc::Status get_pvs(const Api& api, const std::string& id, double t, const Camera& cam,
                     v1::GetPvsResponse* out, Seconds timeout = Seconds(10)) {
  grpc::ClientContext ctx;
  api.prepare(&ctx, timeout);
  v1::GetPvsRequest req;
  req.set_scene_id(id);
  req.set_t(t);
  to_proto(cam, req.mutable_camera());
  return api.stub().GetPvs(&ctx, req, out);
}

/// A scene whose frames take milliseconds: 5,000 spheres seen from outside.
v1::SceneDescription heavy_scene() {
  v1::SceneDescription d;
  to_proto(lattice_scene(5000, 100, 11), &d);
  return d;
}
Camera heavy_camera() { return look(Vec3(-20, 50, 50), Vec3(1, 0, 0)); }

// --- Time -------------------------------------------------------------------

// Before the time range, the second GetPvs at t = 1e308 on a scene with a
// hidden moving object never returned and took a worker for ever.
TEST(Hardening, HugeTimesAreRefusedAndNeverHangAWorker) {
  ServerProcess server({"--workers", "1"});
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  ASSERT_TRUE(api.create_scene_json("w", wall_scene_json()).ok());
  v1::GetPvsResponse r;
  ASSERT_TRUE(get_pvs(api, "w", 0.0, wall_camera(), &r).ok());
  for (double bad : {1e308, -1e308, 1.7e15, 1e14, -2e10}) {
    for (int repeat = 0; repeat < 2; ++repeat) {
      const grpc::Status s = get_pvs(api, "w", bad, wall_camera(), &r, Seconds(5));
      EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << bad << ": " << show(s);
      EXPECT_THAT(s.error_message(), HasSubstr("t: must be a finite time")) << bad;
    }
  }
  // The only worker is free: a normal frame is answered.
  EXPECT_TRUE(get_pvs(api, "w", 0.5, wall_camera(), &r, Seconds(5)).ok());
  {
    ViewStream v(api, "w");
    v.send(1, 1e300, wall_camera());
    v1::ViewResponse resp;
    EXPECT_FALSE(v.read(&resp));
    const grpc::Status s = v.finish();
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(s);
    EXPECT_THAT(s.error_message(), HasSubstr("t: must be a finite time"));
  }
  {
    SimStream sim(api, "w");
    sim.send(1, 1e300, {{2, Vec3(10, 10, 15)}});
    v1::MoveAck ack;
    EXPECT_FALSE(sim.wait_ack(&ack, Seconds(10)));
    const grpc::Status s = sim.finish();
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(s);
    EXPECT_THAT(s.error_message(), HasSubstr("batch.t: must be a finite time"));
  }
  v1::SceneInfo info;
  ASSERT_TRUE(api.stats("w", &info).ok());
  EXPECT_LE(info.time(), 1.5);
}

// A viewer's frame runs at most --max-view-lead beyond the simulation's clock,
// so GetPvs(t = 1e9) from the lowest role no longer moves every later batch to
// 1e9 (where each move was flagged too fast), nor is such a time saved.
TEST(Hardening, ViewersCannotPushASceneClockAhead) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  ASSERT_TRUE(api.create_scene_json("w", wall_scene_json()).ok());
  {
    SimStream sim(api, "w");
    v1::MoveAck ack;
    ASSERT_TRUE(sim.move(1, 1.0, {{2, Vec3(10, 10, 15)}}, &ack));
    EXPECT_EQ(ack.t(), 1.0);
    v1::GetPvsResponse r;
    ASSERT_TRUE(get_pvs(api, "w", 1e9, wall_camera(), &r).ok());
    EXPECT_LE(r.t(), 2.0) << "a viewer may lead the simulation by at most 1 s (default)";
    EXPECT_GE(r.t(), 1.0);
    // A move 0.5 s later, well within max_speed 100, is not too fast.
    ASSERT_TRUE(sim.move(2, 1.5, {{2, Vec3(12, 10, 15)}}, &ack));
    EXPECT_EQ(ack.too_fast_size(), 0);
    EXPECT_LE(ack.t(), 2.0);
    EXPECT_TRUE(sim.finish().ok());
  }
  ASSERT_EQ(server.terminate(), 0);
  ASSERT_TRUE(server.restart());
  v1::SceneInfo info;
  ASSERT_TRUE(server.api().stats("w", &info).ok());
  EXPECT_LE(info.time(), 2.0) << "the saved clock";
}

// One batch may advance the clock by at most --max-time-step; the first one
// on a scene adopts the backend's epoch (seconds since 1970 here).
TEST(Hardening, OneBatchAdvancesTheClockByABoundedStep) {
  ServerProcess server({"--max-time-step", "60"});
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  ASSERT_TRUE(api.create_scene_json("w", wall_scene_json()).ok());
  SimStream sim(api, "w");
  v1::MoveAck ack;
  const double epoch = 1.7e9;
  ASSERT_TRUE(sim.move(1, epoch, {{2, Vec3(10, 10, 15)}}, &ack));
  EXPECT_EQ(ack.t(), epoch);
  ASSERT_TRUE(sim.move(2, epoch + 60, {}, &ack));
  sim.send(3, epoch + 60 + 61, {});
  EXPECT_FALSE(sim.wait_ack(&ack, Seconds(10)));
  const grpc::Status s = sim.finish();
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(s);
  EXPECT_THAT(s.error_message(), HasSubstr("batch.t:"));
  EXPECT_THAT(s.error_message(), HasSubstr("at most 60 s"));
  v1::SceneInfo info;
  ASSERT_TRUE(api.stats("w", &info).ok());
  EXPECT_EQ(info.time(), epoch + 60);
}

// --- Ids --------------------------------------------------------------------

// Every call checks the scene id before anything could echo it: an
// 8,000-character id once came back in NOT_FOUND messages, over the client's
// metadata limit, which broke the other streams of that connection.
TEST(Hardening, LongIdsAreRefusedWithoutEchoOnEveryCall) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  ASSERT_TRUE(api.create_scene_json("w", wall_scene_json()).ok());
  ViewStream watcher(api, "w");  // Same connection as the bad calls.
  v1::ViewResponse vr;
  ASSERT_TRUE(watcher.frame(1, 0.0, wall_camera(), &vr));

  const std::string long_id(8000, 'q');
  const auto expect_refused = [&](const grpc::Status& s, const char* call) {
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << call << ": " << show(s);
    EXPECT_THAT(s.error_message(), HasSubstr("scene_id: must be 1-64 characters")) << call;
    EXPECT_LT(s.error_message().size(), 200u) << call;
    EXPECT_THAT(s.error_message(), Not(HasSubstr("qqqqqqqq"))) << call;
  };
  v1::SceneInfo info;
  expect_refused(api.stats(long_id, &info), "GetSceneStats");
  expect_refused(api.delete_scene(long_id), "DeleteScene");
  v1::GetPvsResponse pr;
  expect_refused(api.get_pvs(long_id, 0.0, wall_camera(), &pr), "GetPvs");
  expect_refused(api.create_scene_json(long_id, wall_scene_json()), "CreateScene");
  {
    ViewStream v(api, long_id);
    v.send(1, 0.0, wall_camera());
    v1::ViewResponse r;
    EXPECT_FALSE(v.read(&r));
    expect_refused(v.finish(), "View");
  }
  {
    SimStream sim(api, long_id);
    expect_refused(sim.finish(), "Simulate");
  }
  for (const std::string& id :
       std::vector<std::string>{"", ".hidden", "a/b", std::string(65, 'x')}) {
    expect_refused(api.stats(id, &info), "GetSceneStats");
  }
  // The connection and its other stream are unharmed.
  EXPECT_TRUE(watcher.frame(2, 0.1, wall_camera(), &vr));
  EXPECT_TRUE(watcher.finish().ok());
}

// --- Scene lifecycle ----------------------------------------------------------

/// A scene of `count` dynamic spheres (max_speed 1000) on a lattice.
v1::SceneDescription moving_crowd(int count) {
  SceneDesc d;
  d.bounds_min = Vec3(0.0);
  d.bounds_max = Vec3(100.0);
  d.grid = glm::ivec3(64);
  const int side = static_cast<int>(std::ceil(std::cbrt(count)));
  for (int i = 0; i < count; ++i) {
    const Vec3 c(1 + 98.0 * (i % side) / side, 1 + 98.0 * (i / side % side) / side,
                 1 + 98.0 * (i / side / side) / side);
    d.objects.push_back(test::dynamic(test::sphere(ObjectId(i + 1), c, 0.2), 1000.0));
  }
  v1::SceneDescription p;
  to_proto(d, &p);
  return p;
}

// DeleteScene(X) racing CreateScene(X) while the position saver holds the
// data directory: the create was acknowledged, served, and its file removed
// by the delete (12 of 100 rounds). Now the id stays taken until the delete
// is done (the create gets ABORTED or runs after it), so after every round
// a scene is served exactly when its file exists, and a restart agrees.
TEST(Hardening, DeleteRacingCreateNeverLosesAnAcknowledgedScene) {
  ServerProcess server({"--save-period", "0.01"});
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  // A busy saver: a big scene whose positions change all the time.
  const int crowd = test::scaled(60000);
  ASSERT_TRUE(api.create_scene("crowd", moving_crowd(crowd)).ok());
  std::atomic<bool> stop{false};
  std::thread mover([&] {
    SimStream sim(server.api(), "crowd");
    v1::MoveAck ack;
    std::vector<Move> moves;
    for (int i = 0; i < crowd; ++i) moves.push_back({ObjectId(i + 1), Vec3(50.0)});
    for (std::uint64_t seq = 1; !stop.load(); ++seq) {
      for (Move& m : moves) m.center.x = 50.0 + 0.001 * static_cast<double>(seq % 2);
      if (!sim.move(seq, 0.01 * static_cast<double>(seq), moves, &ack)) break;
    }
    sim.finish();
  });

  const std::string file = server.data_dir() + "/scenes/x.json";
  int aborted = 0, raced = 0;
  const int rounds = test::scaled(30);
  for (int round = 0; round < rounds; ++round) {
    v1::SceneInfo info;
    if (!api.stats("x", &info).ok()) {
      ASSERT_TRUE(api.create_scene_json("x", wall_scene_json()).ok());
    }
    grpc::Status deleted, created;
    std::thread del([&] { deleted = api.delete_scene("x"); });
    std::this_thread::sleep_for(std::chrono::milliseconds(1 + round % 3));
    created = api.create_scene_json("x", wall_scene_json());
    del.join();
    EXPECT_TRUE(deleted.ok()) << show(deleted);
    if (created.error_code() == grpc::StatusCode::ABORTED) {
      ++aborted;
      EXPECT_THAT(created.error_message(), HasSubstr("is being deleted"));
    } else if (!created.ok()) {
      ++raced;  // ALREADY_EXISTS: the create ran before the delete took the id.
      EXPECT_EQ(created.error_code(), grpc::StatusCode::ALREADY_EXISTS) << show(created);
    }
    const bool served = api.stats("x", &info).ok();
    EXPECT_EQ(served, std::filesystem::exists(file))
        << "round " << round << ": delete " << show(deleted) << ", create " << show(created);
    if (created.ok()) {
      EXPECT_TRUE(served) << "round " << round << ": an acknowledged create is served";
    }
  }
  stop.store(true);
  mover.join();
  v1::SceneInfo info;
  const bool served = api.stats("x", &info).ok();
  ASSERT_EQ(server.terminate(), 0);
  ASSERT_TRUE(server.restart());
  EXPECT_EQ(server.api().stats("x", &info).ok(), served) << "after a restart";
  std::printf("rounds %d: create aborted by a delete in progress %d, refused as existing %d\n",
              rounds, aborted, raced);
}

// --- Fairness and work nobody waits for ------------------------------------

// One client queues a thousand frames on its connection; another client's
// frame is answered after a turn of each client, not after the backlog.
TEST(Hardening, AFloodFromOneClientDoesNotStarveAnother) {
  ServerProcess server({"--workers", "1"});
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  ASSERT_TRUE(api.create_scene("heavy", heavy_scene()).ok());
  const int n = 1000;
  PvsFlood flood(server.api(), "heavy", n, 0.0, heavy_camera(), Seconds(300));
  // Give the flood time to reach the server's queue.
  ASSERT_TRUE(wait_until([&] { return flood.done() >= 2; }, Seconds(30)));
  const Api other = server.api();  // Its own connection.
  v1::GetPvsResponse r;
  ASSERT_TRUE(get_pvs(other, "heavy", 0.0, heavy_camera(), &r, Seconds(120)).ok());
  const int before = flood.done();
  EXPECT_LT(before, n / 4) << "frames of the flood answered before the other client's one";
  std::printf("flood frames answered before the other client's frame: %d of %d\n", before, n);
  flood.cancel();
}

// Calls whose clients have gone (deadline passed, cancelled) are answered
// without computing their frames.
TEST(Hardening, FramesOfClientsThatLeftAreNotComputed) {
  ServerProcess server({"--workers", "1"});
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  ASSERT_TRUE(api.create_scene("heavy", heavy_scene()).ok());
  const int n = 400;
  {
    PvsFlood flood(server.api(), "heavy", n, 0.0, heavy_camera(), Seconds(0.3));
    ASSERT_TRUE(flood.wait_all(Seconds(120)));
    EXPECT_GT(flood.with_code(grpc::StatusCode::DEADLINE_EXCEEDED), n / 2);
  }
  // Wait for the server to finish what it took, then count its frames.
  v1::SceneInfo info;
  std::uint64_t served = ~std::uint64_t{0};
  for (int i = 0; i < 100; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    ASSERT_TRUE(api.stats("heavy", &info).ok());
    if (info.frames_served() == served) break;
    served = info.frames_served();
  }
  EXPECT_LT(info.frames_served(), static_cast<std::uint64_t>(n / 2));
  std::printf("frames computed for %d calls whose deadline passed: %llu\n", n,
              static_cast<unsigned long long>(info.frames_served()));
}

// SIGTERM with a thousand frames queued: the queued calls are answered
// UNAVAILABLE without running, the server says how many, and exits 0.
TEST(Hardening, ShutdownAnswersQueuedWorkWithoutRunningIt) {
  ServerProcess server({"--workers", "1"});
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  ASSERT_TRUE(api.create_scene("heavy", heavy_scene()).ok());
  PvsFlood flood(server.api(), "heavy", 1000, 0.0, heavy_camera(), Seconds(300));
  ASSERT_TRUE(wait_until([&] { return flood.done() >= 2; }, Seconds(30)));
  EXPECT_EQ(server.terminate(Seconds(60)), 0);
  ASSERT_TRUE(flood.wait_all(Seconds(60)));
  EXPECT_LT(flood.with_code(grpc::StatusCode::OK), 500);
  EXPECT_GT(number_before(server.log(), " queued requests dropped"), 0) << server.log();
}

// --- Metrics and scene descriptions ---------------------------------------------

TEST(Hardening, TbvsActiveMetricFollowsTheScene) {
  ServerProcess server({"--metrics", "127.0.0.1:0"});
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  ASSERT_TRUE(api.create_scene_json("w", wall_scene_json()).ok());
  ViewStream v(api, "w");
  v1::ViewResponse r;
  // Time stands still: the sphere's TBV neither expires nor grows into view.
  for (int f = 1; f <= 3; ++f) ASSERT_TRUE(v.frame(std::uint64_t(f), 0.0, wall_camera(), &r));
  v1::SceneInfo info;
  ASSERT_TRUE(api.stats("w", &info).ok());
  ASSERT_GT(info.tbvs_active(), 0u) << "the sphere behind the wall is under a TBV";
  ASSERT_GT(server.metrics_port(), 0) << server.log();
  const std::string text = http_get(server.metrics_port(), "/metrics");
  EXPECT_THAT(text, HasSubstr("voxvis_tbvs_active{scene=\"w\"} " +
                              std::to_string(info.tbvs_active())))
      << text;
  EXPECT_TRUE(v.finish().ok());
}

// The scene file requires max_speed on dynamic objects; so does the wire.
TEST(Hardening, DynamicObjectWithoutMaxSpeedIsRefused) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  v1::SceneDescription d = moving_crowd(2);
  d.mutable_objects(1)->clear_max_speed();
  const grpc::Status s = server.api().create_scene("m", d);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(s);
  EXPECT_THAT(s.error_message(), HasSubstr("description.objects[1].max_speed: dynamic objects need"));
}

// --- Malformed messages and structured errors ----------------------------------

// Bytes that are not the request message: unary calls answered UNIMPLEMENTED
// with an empty message, streams ended OK as if the client had half-closed,
// and nothing was counted. Now every method answers INVALID_ARGUMENT naming
// the message type, counted in voxvis_errors_total.
TEST(Hardening, MalformedMessagesGetAClearAnswerAndAreCounted) {
  ServerProcess server({"--metrics", "127.0.0.1:0"});
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  ASSERT_TRUE(api.create_scene_json("w", wall_scene_json()).ok());
  const std::string garbage(8, '\xff');
  const std::string prefix = "/voxvis.v1.Visibility/";
  for (const char* method : {"CreateScene", "DeleteScene", "ListScenes", "GetSceneStats", "GetPvs"}) {
    std::string response;
    const grpc::Status s = generic_unary(api.channel(), prefix + method, garbage, &response);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << method << ": " << show(s);
    EXPECT_THAT(s.error_message(), HasSubstr("request: not a valid voxvis.v1.")) << method;
    EXPECT_THAT(s.error_message(), HasSubstr("(8 bytes)")) << method;
  }
  for (const char* method : {"View", "Simulate"}) {
    std::vector<std::string> responses;
    const grpc::Status s = generic_bidi(api.channel(), prefix + method, garbage, &responses);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << method << ": " << show(s);
    EXPECT_THAT(s.error_message(), HasSubstr("request: not a valid voxvis.v1." + std::string(method) +
                                             "Request (8 bytes)"));
    EXPECT_TRUE(responses.empty()) << method;
  }
  ASSERT_GT(server.metrics_port(), 0) << server.log();
  const std::string text = http_get(server.metrics_port(), "/metrics");
  for (const char* method : {"GetPvs", "View", "Simulate", "CreateScene"}) {
    EXPECT_THAT(text, HasSubstr("voxvis_errors_total{code=\"INVALID_ARGUMENT\",method=\"" +
                                std::string(method) + "\"} 1"))
        << method;
  }
}

// Every INVALID_ARGUMENT carries a google.rpc.Status with a BadRequest naming
// the field (voxvis.v1.ErrorStatus and BadRequest are wire-compatible).
TEST(Hardening, InvalidArgumentCarriesABadRequestNamingTheField) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  ASSERT_TRUE(api.create_scene_json("w", wall_scene_json()).ok());
  Camera bad = wall_camera();
  bad.fov_y_deg = 190;
  v1::GetPvsResponse r;
  const grpc::Status s = get_pvs(api, "w", 0.0, bad, &r);
  ASSERT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(s);
  v1::ErrorStatus details;
  ASSERT_TRUE(details.ParseFromString(s.error_details())) << "no details";
  EXPECT_EQ(details.code(), static_cast<int>(grpc::StatusCode::INVALID_ARGUMENT));
  EXPECT_EQ(details.message(), s.error_message());
  ASSERT_EQ(details.details_size(), 1);
  EXPECT_EQ(details.details(0).type_url(), "type.googleapis.com/google.rpc.BadRequest");
  v1::BadRequest bad_request;
  ASSERT_TRUE(bad_request.ParseFromString(details.details(0).value()));
  ASSERT_EQ(bad_request.field_violations_size(), 1);
  EXPECT_EQ(bad_request.field_violations(0).field(), "camera.fov_y_deg");
  EXPECT_THAT(bad_request.field_violations(0).description(), HasSubstr("190"));

  // The same on a stream's end, and for an id refused before any echo.
  v1::SceneInfo info;
  const grpc::Status id = api.stats(std::string(300, 'z'), &info);
  ASSERT_EQ(id.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  ASSERT_TRUE(details.ParseFromString(id.error_details()));
  ASSERT_TRUE(bad_request.ParseFromString(details.details(0).value()));
  EXPECT_EQ(bad_request.field_violations(0).field(), "scene_id");
  SimStream sim(api, "w");
  sim.send(1, 0.0, {{99, Vec3(1, 1, 1)}});
  const grpc::Status st = sim.finish();
  ASSERT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(st);
  ASSERT_TRUE(details.ParseFromString(st.error_details()));
  ASSERT_TRUE(bad_request.ParseFromString(details.details(0).value()));
  EXPECT_EQ(bad_request.field_violations(0).field(), "batch.moves[0].id");
}

}  // namespace
}  // namespace voxvis::servertest
