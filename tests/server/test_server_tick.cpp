// The Tick stream against the engine: one viewer's ticks (with moves, in
// both encodings) equal an in-process Scene driven by the same moves and
// frames; several viewers of a static scene, joining and leaving, each equal
// the engine's answers for their own cameras; a bad entry fails alone; a
// flood of ticks is shed latest-wins without losing a move; a move of an
// unknown or static object ends the stream naming it; IdSet's two forms
// round-trip.
#include <algorithm>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "scenes.h"
#include "server_process.h"
#include "voxvis/client.h"
#include "voxvis/format.h"
#include "voxvis/scene.h"
#include "wire/ids.h"

namespace voxvis::servertest {
namespace {

std::unique_ptr<client::Client> tick_client(const ServerProcess& server) {
  return std::make_unique<client::Client>(grpc::CreateChannel(server.address(), grpc::InsecureChannelCredentials()),
                                          std::string(), server.address());
}

/// The engine's input exactly as the server parses `json`.
std::unique_ptr<Scene> mirror(const std::string& json, SceneDesc* desc) {
  FormatError ferr;
  EXPECT_TRUE(parse_scene(json, "scene_json", desc, &ferr)) << ferr.str();
  std::unique_ptr<Scene> scene;
  EXPECT_TRUE(Scene::create(*desc, SceneOptions{}, &scene).ok);
  return scene;
}

TEST(TickStream, OneViewerEqualsTheEngineWithMovesInBothEncodings) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  const auto client = tick_client(server);
  test::RandomSceneParams p;
  p.dynamic_fraction = 0.4;
  p.max_speed = 10.0;
  for (v1::PvsEncoding encoding : {v1::PVS_FULL, v1::PVS_DELTA}) {
    SCOPED_TRACE(v1::PvsEncoding_Name(encoding));
    const std::uint64_t seed = 31;
    const std::string json = scene_to_json(test::random_scene(p, seed));
    SceneDesc desc;
    const std::unique_ptr<Scene> scene = mirror(json, &desc);
    ASSERT_TRUE(scene);
    const std::string id = std::string("tick-") + v1::PvsEncoding_Name(encoding);
    ASSERT_TRUE(api.create_scene_json(id, json).ok());
    const ViewerId viewer = scene->add_viewer();
    Scratch scratch;
    test::CameraPathParams cp;
    cp.frames = 60;
    const std::vector<Camera> path = test::random_camera_path(desc, seed, cp);
    test::Mover mover(desc, seed);
    client::TickSession session(*client);
    session.open(id, encoding);
    std::size_t wake_changes = 0, pvs_changes = 0;
    std::vector<ObjectId> last;
    for (std::size_t i = 0; i < path.size(); ++i) {
      SCOPED_TRACE("tick " + std::to_string(i));
      const double t = static_cast<double>(i + 1) / 30.0;
      // Moves on most ticks, none on some.
      const std::vector<Move> moves = i % 4 == 3 ? std::vector<Move>{} : mover.step(1.0 / 30.0);
      client::TickAnswer answer;
      ASSERT_TRUE(session.tick(i, t, moves, {{7, path[i]}}, {}, &answer)) << session.finish().error_message();
      MoveReport report;
      if (!moves.empty()) {
        ASSERT_TRUE(scene->apply_moves(t, moves, &report).ok);
      }
      FrameResult result;
      ASSERT_TRUE(scene->frame(viewer, path[i], t, scratch, &result).ok);
      ASSERT_EQ(answer.viewers.size(), 1u);
      const client::TickViewerAnswer& a = answer.viewers[0];
      EXPECT_EQ(a.viewer, 7u);
      EXPECT_TRUE(a.error.empty()) << a.error_field << ": " << a.error;
      EXPECT_EQ(a.t, t);
      EXPECT_EQ(a.result.pvs, result.pvs);
      EXPECT_EQ(a.result.wake, result.wake);
      EXPECT_EQ(counters(a.result.stats), counters(result.stats));
      EXPECT_EQ(answer.moves_applied, report.applied);
      EXPECT_EQ(answer.too_fast, report.too_fast);
      EXPECT_EQ(answer.ticks_skipped, 0u);
      // The scene's wake list follows the engine's after the tick.
      EXPECT_EQ(session.wake(), scene->wake_set());
      wake_changes += answer.wake_changed;
      pvs_changes += a.result.pvs != last;
      last = a.result.pvs;
    }
    EXPECT_TRUE(session.finish().ok());
    // The walk must change both, or this checks little.
    EXPECT_GE(wake_changes, 3u);
    EXPECT_GE(pvs_changes, 10u);
  }
}

TEST(TickStream, ViewersOfAStaticSceneJoinAndLeave) {
  // Without dynamic objects a viewer's answer depends on its camera alone,
  // whatever the other viewers of the tick do and in whatever order the
  // server runs them.
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  const auto client = tick_client(server);
  test::RandomSceneParams p;
  p.dynamic_fraction = 0.0;
  const std::string json = scene_to_json(test::random_scene(p, 41));
  SceneDesc desc;
  const std::unique_ptr<Scene> scene = mirror(json, &desc);
  ASSERT_TRUE(scene);
  ASSERT_TRUE(api.create_scene_json("static", json).ok());
  constexpr int kViewers = 5;
  test::CameraPathParams cp;
  cp.frames = 30;
  std::vector<std::vector<Camera>> paths;
  for (int v = 0; v < kViewers; ++v) paths.push_back(test::random_camera_path(desc, 100 + v, cp));
  // Viewer v is in the ticks [join, leave) of its schedule; viewer 4 leaves
  // and comes back.
  const int join[kViewers] = {0, 0, 3, 5, 0};
  const int leave[kViewers] = {30, 12, 30, 20, 9};
  client::TickSession session(*client);
  session.open("static", v1::PVS_DELTA);
  Scratch scratch;
  std::map<std::uint64_t, ViewerId> engine;  // The mirror's viewers.
  std::size_t answered = 0;
  for (int i = 0; i < cp.frames; ++i) {
    SCOPED_TRACE("tick " + std::to_string(i));
    std::vector<client::TickCamera> cams;
    std::vector<std::uint64_t> left;
    for (int v = 0; v < kViewers; ++v) {
      const bool in = (i >= join[v] && i < leave[v]) || (v == 4 && i >= 15);
      const bool was = i > 0 && ((i - 1 >= join[v] && i - 1 < leave[v]) || (v == 4 && i - 1 >= 15));
      if (in) cams.push_back({static_cast<std::uint64_t>(1000 + v), paths[v][static_cast<std::size_t>(i)]});
      if (was && !in) left.push_back(static_cast<std::uint64_t>(1000 + v));
    }
    // Answered in an order of the client's choosing: reversed every other tick.
    if (i % 2) std::reverse(cams.begin(), cams.end());
    client::TickAnswer answer;
    ASSERT_TRUE(session.tick(i, i / 30.0, {}, cams, left, &answer)) << session.finish().error_message();
    for (std::uint64_t id : left) {
      scene->remove_viewer(engine.at(id));
      engine.erase(id);
    }
    ASSERT_EQ(answer.viewers.size(), cams.size());
    for (std::size_t k = 0; k < cams.size(); ++k) {
      const client::TickViewerAnswer& a = answer.viewers[k];
      EXPECT_EQ(a.viewer, cams[k].viewer);
      EXPECT_TRUE(a.error.empty()) << a.error_field << ": " << a.error;
      if (!engine.count(a.viewer)) engine[a.viewer] = scene->add_viewer();
      FrameResult result;
      ASSERT_TRUE(scene->frame(engine[a.viewer], cams[k].camera, i / 30.0, scratch, &result).ok);
      EXPECT_EQ(a.result.pvs, result.pvs) << "viewer " << a.viewer;
      ++answered;
    }
  }
  EXPECT_TRUE(session.finish().ok());
  EXPECT_GT(answered, 80u);
}

TEST(TickStream, ABadEntryFailsAlone) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  const auto client = tick_client(server);
  test::RandomSceneParams p;
  p.dynamic_fraction = 0.0;
  const SceneDesc desc = test::random_scene(p, 51);
  ASSERT_TRUE(api.create_scene_json("bad", scene_to_json(desc)).ok());
  test::CameraPathParams cp;
  cp.frames = 2;
  const std::vector<Camera> path = test::random_camera_path(desc, 51, cp);
  Camera wide = path[0];
  wide.fov_y_deg = 190.0;
  Camera flat = path[0];
  flat.up = flat.dir;
  client::TickSession session(*client);
  session.open("bad", v1::PVS_FULL);
  client::TickAnswer answer;
  ASSERT_TRUE(session.tick(1, 0.0, {}, {{1, path[0]}, {2, wide}, {1, path[1]}, {3, flat}, {4, path[1]}}, {}, &answer))
      << session.finish().error_message();
  ASSERT_EQ(answer.viewers.size(), 5u);
  EXPECT_TRUE(answer.viewers[0].error.empty());
  EXPECT_GT(answer.viewers[0].result.stats.time_us, 0.0);
  EXPECT_EQ(answer.viewers[1].error_field, "viewers[1].camera.fov_y_deg");
  EXPECT_NE(answer.viewers[1].error.find("190"), std::string::npos) << answer.viewers[1].error;
  EXPECT_EQ(answer.viewers[2].error_field, "viewers[2].viewer");
  EXPECT_NE(answer.viewers[2].error.find("twice"), std::string::npos) << answer.viewers[2].error;
  EXPECT_EQ(answer.viewers[3].error_field.rfind("viewers[3].camera.", 0), 0u) << answer.viewers[3].error_field;
  EXPECT_TRUE(answer.viewers[4].error.empty());
  EXPECT_EQ(answer.viewers[1].result.stats.time_us, 0.0);
  // The stream goes on, and a refused viewer may be answered next time.
  ASSERT_TRUE(session.tick(2, 0.1, {}, {{2, path[1]}}, {}, &answer)) << session.finish().error_message();
  EXPECT_TRUE(answer.viewers[0].error.empty());
  // Whole-request errors end the stream, naming the field.
  ASSERT_FALSE(session.tick(2, 0.2, {}, {{2, path[1]}}, {}, &answer));
  const grpc::Status st = session.finish();
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("tick: must increase"), std::string::npos) << st.error_message();
}

TEST(TickStream, ViewerLimits) {
  // A stream keeps at most 1,024 viewers: a new one beyond is refused in its
  // entry until others are named in `left`; a tick of more than 1,024
  // viewers ends the stream.
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  const auto client = tick_client(server);
  test::RandomSceneParams p;
  p.dynamic_fraction = 0.0;
  p.spheres = 20;
  p.boxes = 10;
  const SceneDesc desc = test::random_scene(p, 81);
  ASSERT_TRUE(api.create_scene_json("limits", scene_to_json(desc)).ok());
  test::CameraPathParams cp;
  cp.frames = 1;
  const Camera cam = test::random_camera_path(desc, 81, cp)[0];
  std::vector<client::TickCamera> all;
  for (std::uint64_t v = 0; v < 1024; ++v) all.push_back({v, cam});
  client::TickSession session(*client);
  session.open("limits", v1::PVS_DELTA);
  client::TickAnswer answer;
  ASSERT_TRUE(session.tick(1, 0.0, {}, all, {}, &answer)) << session.finish().error_message();
  ASSERT_EQ(answer.viewers.size(), 1024u);
  for (const auto& a : answer.viewers) ASSERT_TRUE(a.error.empty()) << a.error;
  ASSERT_TRUE(session.tick(2, 0.0, {}, {{5000, cam}, {3, cam}}, {}, &answer)) << session.finish().error_message();
  EXPECT_EQ(answer.viewers[0].error_field, "viewers[0].viewer");
  EXPECT_NE(answer.viewers[0].error.find("1024"), std::string::npos) << answer.viewers[0].error;
  EXPECT_TRUE(answer.viewers[1].error.empty()) << "viewers kept are still answered";
  ASSERT_TRUE(session.tick(3, 0.0, {}, {{5000, cam}}, {0}, &answer)) << session.finish().error_message();
  EXPECT_TRUE(answer.viewers[0].error.empty()) << answer.viewers[0].error;
  all.push_back({9999, cam});
  EXPECT_FALSE(session.tick(4, 0.0, {}, all, {}, &answer));
  const grpc::Status st = session.finish();
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("viewers: at most 1024 a tick, got 1025"), std::string::npos)
      << st.error_message();
}

TEST(TickStream, AFloodIsShedLatestWinsAndNoMoveIsLost) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  test::RandomSceneParams p;
  p.dynamic_fraction = 0.5;
  p.max_speed = 10.0;
  const SceneDesc desc = test::random_scene(p, 61);
  ASSERT_TRUE(api.create_scene_json("flood", scene_to_json(desc)).ok());
  test::CameraPathParams cp;
  cp.frames = 1;
  const Camera cam = test::random_camera_path(desc, 61, cp)[0];
  test::Mover mover(desc, 61);
  // The raw stream: every tick written before any answer is read.
  const auto client = tick_client(server);
  grpc::ClientContext ctx;
  auto stream = client->stub().Tick(&ctx);
  constexpr int kTicks = 200;
  std::size_t moves_sent = 0;
  for (int i = 0; i < kTicks; ++i) {
    v1::TickRequest r;
    if (i == 0) r.set_scene_id("flood");
    r.set_tick(static_cast<std::uint64_t>(i));
    r.set_t(i / 60.0);
    for (const Move& m : mover.step(1.0 / 60.0)) {
      v1::Move* mv = r.add_moves();
      mv->set_id(m.id);
      client::to_proto(m.center, mv->mutable_center());
      ++moves_sent;
    }
    for (std::uint64_t v = 0; v < 8; ++v) {
      v1::TickViewer* tv = r.add_viewers();
      tv->set_viewer(v);
      client::to_proto(cam, tv->mutable_camera());
    }
    ASSERT_TRUE(stream->Write(r));
  }
  ASSERT_GT(moves_sent, 0u);
  stream->WritesDone();
  v1::TickResponse resp;
  std::uint64_t last = 0, applied = 0, skipped = 0;
  int answers = 0;
  while (stream->Read(&resp)) {
    if (answers > 0) {
      EXPECT_GT(resp.tick(), last);
    }
    last = resp.tick();
    applied += resp.moves_applied();
    skipped += resp.ticks_skipped();
    EXPECT_EQ(resp.answers_size(), 8);
    ++answers;
  }
  EXPECT_TRUE(stream->Finish().ok());
  EXPECT_EQ(last, static_cast<std::uint64_t>(kTicks - 1)) << "the newest tick is always answered";
  EXPECT_EQ(static_cast<std::uint64_t>(answers) + skipped, static_cast<std::uint64_t>(kTicks));
  EXPECT_EQ(applied, moves_sent) << "every tick's moves are applied, answered or not";
  RecordProperty("answered", answers);
  std::printf("flood: %d of %d ticks answered\n", answers, kTicks);
}

/// The field a refusal's BadRequest names ("" when it carries none).
std::string violated_field(const grpc::Status& st) {
  v1::ErrorStatus details;
  v1::BadRequest bad;
  if (!details.ParseFromString(st.error_details()) || details.details_size() != 1 ||
      !bad.ParseFromString(details.details(0).value()) || bad.field_violations_size() != 1)
    return "";
  return bad.field_violations(0).field();
}

TEST(TickStream, AMoveOfAnUnknownOrStaticObjectEndsTheStreamNamingIt) {
  // As on Simulate: the batch is refused whole when its moves are applied,
  // the stream ends with INVALID_ARGUMENT naming moves[3].id, and no tick
  // from the bad one on is answered, even ticks written before it failed.
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  test::RandomSceneParams p;
  p.dynamic_fraction = 0.5;
  p.max_speed = 10.0;
  const SceneDesc desc = test::random_scene(p, 91);
  std::vector<ObjectDesc> dynamic, fixed;
  for (const ObjectDesc& o : desc.objects) (o.dynamic ? dynamic : fixed).push_back(o);
  ASSERT_GE(dynamic.size(), 3u);
  ASSERT_FALSE(fixed.empty());
  test::CameraPathParams cp;
  cp.frames = 1;
  const Camera cam = test::random_camera_path(desc, 91, cp)[0];
  ObjectId unknown = 1;
  while (std::any_of(desc.objects.begin(), desc.objects.end(), [&](const ObjectDesc& o) { return o.id == unknown; }))
    ++unknown;
  struct Case {
    const char* name;
    Move bad;
    const char* says;
  };
  const Case cases[] = {{"unknown", {unknown, dynamic[0].center}, "unknown object id "},
                        {"static", {fixed[0].id, fixed[0].center}, " is static and cannot move"}};
  int scene_no = 0;
  for (const Case& c : cases) {
    for (bool flood : {false, true}) {
      SCOPED_TRACE(std::string(c.name) + (flood ? ", in a flood" : ", lock-step"));
      const std::string id = "moves-" + std::to_string(scene_no++);
      ASSERT_TRUE(api.create_scene_json(id, scene_to_json(desc)).ok());
      // Three good moves, then the bad one: none of the tick's is applied.
      const auto moves = [&](int tick, bool bad) {
        std::vector<Move> m;
        for (std::size_t k = 0; k < 3; ++k) m.push_back({dynamic[k].id, dynamic[k].center + Vec3(0.01 * tick, 0, 0)});
        if (bad) m.push_back(c.bad);
        return m;
      };
      // Ticks 1..10; tick 5 carries the bad move. Lock-step: each answer is
      // read before the next tick is written; a flood writes all first.
      constexpr int kBad = 5;
      const auto client = std::make_unique<client::Client>(
          grpc::CreateChannel(server.address(), grpc::InsecureChannelCredentials()), std::string(), server.address());
      grpc::ClientContext ctx;
      auto stream = client->stub().Tick(&ctx);
      std::vector<std::uint64_t> answered;
      std::uint64_t applied = 0;
      v1::TickResponse resp;
      for (int i = 1; i <= 10; ++i) {
        v1::TickRequest r;
        r.set_scene_id(id);
        r.set_tick(static_cast<std::uint64_t>(i));
        r.set_t(i / 30.0);
        for (const Move& m : moves(i, i == kBad)) {
          v1::Move* mv = r.add_moves();
          mv->set_id(m.id);
          client::to_proto(m.center, mv->mutable_center());
        }
        v1::TickViewer* tv = r.add_viewers();
        tv->set_viewer(1);
        client::to_proto(cam, tv->mutable_camera());
        if (!stream->Write(r)) break;  // The stream has ended.
        if (!flood && stream->Read(&resp)) {
          answered.push_back(resp.tick());
          applied += resp.moves_applied();
        }
      }
      stream->WritesDone();
      while (stream->Read(&resp)) {
        answered.push_back(resp.tick());
        applied += resp.moves_applied();
      }
      const grpc::Status st = stream->Finish();
      EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(st);
      EXPECT_NE(st.error_message().find("moves[3].id: "), std::string::npos) << st.error_message();
      EXPECT_NE(st.error_message().find(c.says), std::string::npos) << st.error_message();
      EXPECT_EQ(violated_field(st), "moves[3].id");
      for (std::uint64_t t : answered) EXPECT_LT(t, static_cast<std::uint64_t>(kBad)) << "answered after the bad tick";
      if (!flood) {
        EXPECT_EQ(answered, (std::vector<std::uint64_t>{1, 2, 3, 4}));
        EXPECT_EQ(applied, 3u * (kBad - 1));
      }
      // The ticks before the bad one had all their moves applied, and no
      // other: not the bad tick's good moves, nor those of the ticks after it.
      v1::SceneInfo info;
      ASSERT_TRUE(api.stats(id, &info).ok());
      EXPECT_EQ(info.moves_applied(), 3u * (kBad - 1));
      // The scene serves on: a new stream may move the same objects.
      client::TickSession session(*client);
      session.open(id, v1::PVS_FULL);
      client::TickAnswer answer;
      EXPECT_TRUE(session.tick(1, 1.0, moves(11, false), {{1, cam}}, {}, &answer)) << session.finish().error_message();
      EXPECT_EQ(answer.moves_applied, 3u);
      EXPECT_TRUE(session.finish().ok());
    }
  }
}

TEST(TickStream, IdSetsRoundTripInTheSmallerForm) {
  test::Rng rng(71);
  for (int round = 0; round < 200; ++round) {
    // Dense runs (a bitset is smaller), sparse ones (gaps are) and mixes.
    std::vector<ObjectId> ids;
    const int n = rng.uniform_int(0, 300);
    const double density = rng.uniform(0.01, 1.0);
    ObjectId next = static_cast<ObjectId>(rng.uniform_int(0, 100000));
    if (round == 0) next = 0xffffffffu - 400;  // Near the top of the range.
    for (int k = 0; k < n; ++k) {
      ids.push_back(next);
      next += 1 + static_cast<ObjectId>(rng.uniform(0.0, 1.0 / density));
    }
    v1::IdSet set;
    server::put_ids(ids, &set);
    std::vector<ObjectId> back;
    std::string why;
    ASSERT_TRUE(client::ids_from_proto(set, &back, &why)) << why;
    ASSERT_EQ(back, ids);
    // Whichever form was chosen is no larger than the other.
    const std::size_t size = set.ByteSizeLong();
    v1::IdSet gaps;
    ObjectId prev = 0;
    for (ObjectId id : ids) gaps.add_gaps(id - std::exchange(prev, id));
    EXPECT_LE(size, gaps.ByteSizeLong() + 1) << "n " << n;
  }
  std::vector<ObjectId> out;
  std::string why;
  v1::IdSet both;
  both.add_gaps(3);
  both.set_bits("\x01");
  EXPECT_FALSE(client::ids_from_proto(both, &out, &why));
  EXPECT_NE(why.find("both"), std::string::npos) << why;
  v1::IdSet repeated;
  repeated.add_gaps(3);
  repeated.add_gaps(0);
  EXPECT_FALSE(client::ids_from_proto(repeated, &out, &why));
  EXPECT_NE(why.find("gap 1 is 0"), std::string::npos) << why;
  v1::IdSet past;
  past.add_gaps(0xffffffffu);
  past.add_gaps(1);
  EXPECT_FALSE(client::ids_from_proto(past, &out, &why));
  v1::IdSet high;
  high.set_base(0xfffffff8u);
  high.set_bits(std::string("\x00\x01", 2));
  EXPECT_FALSE(client::ids_from_proto(high, &out, &why));
  EXPECT_NE(why.find("past"), std::string::npos) << why;
}

}  // namespace
}  // namespace voxvis::servertest
