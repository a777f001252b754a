// Bad input on the real server: every refusal has the documented code and a
// message naming the field, changes nothing, and leaves the server serving
// (a watching viewer stream on the same server keeps getting answers after
// every bad call).
#include <algorithm>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "server_process.h"
#include "voxvis/format.h"

namespace voxvis::servertest {
namespace {

using ::testing::HasSubstr;

/// A viewer that must keep being answered.
class Watcher {
 public:
  Watcher(const Api& api, const std::string& id) : stream_(api, id) {}
  void expect_served(const std::string& after) {
    ++frame_;
    v1::ViewResponse r;
    const Camera cam =
        look(Vec3(-20.0 + 0.01 * static_cast<double>(frame_), 50, 50), Vec3(1, 0, 0));
    EXPECT_TRUE(stream_.frame(frame_, 0.0, cam, &r)) << "watcher not answered after " << after;
    EXPECT_EQ(r.frame(), frame_) << after;
    EXPECT_GT(r.pvs_size(), 0) << after;
  }
  grpc::Status finish() { return stream_.finish(); }

 private:
  ViewStream stream_;
  std::uint64_t frame_ = 0;
};

v1::SceneDescription wall_description() {
  SceneDesc d;
  FormatError err;
  EXPECT_TRUE(parse_scene(wall_scene_json(), "wall", &d, &err)) << err.str();
  v1::SceneDescription p;
  to_proto(d, &p);
  return p;
}

std::vector<std::string> scene_ids(const Api& api) {
  std::vector<std::string> ids;
  EXPECT_TRUE(api.list_scenes(&ids).ok());
  return ids;
}

TEST(ServerErrors, BadInputIsRefusedAndOthersKeepBeingServed) {
  ServerProcess server({"--max-message-mib", "1"});
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  v1::SceneDescription lattice;
  to_proto(lattice_scene(200, 32, 5), &lattice);
  ASSERT_TRUE(api.create_scene("watch", lattice).ok());
  ASSERT_TRUE(api.create_scene_json("s", wall_scene_json()).ok());
  const std::vector<std::string> scenes = {"s", "watch"};
  Watcher watcher(api, "watch");
  watcher.expect_served("start");

  {  // An invalid camera ends the stream, naming the field.
    ViewStream v(api, "s");
    v1::ViewResponse r;
    ASSERT_TRUE(v.frame(1, 0.0, wall_camera(), &r));
    Camera bad = wall_camera();
    bad.fov_y_deg = 190;
    v.send(2, 0.0, bad);
    EXPECT_FALSE(v.read(&r));
    const grpc::Status s = v.finish();
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(s);
    EXPECT_THAT(s.error_message(), HasSubstr("camera.fov_y_deg"));
    v1::GetPvsResponse pvs;
    const grpc::Status g = api.get_pvs("s", 0.0, bad, &pvs);
    EXPECT_EQ(g.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(g);
    EXPECT_THAT(g.error_message(), HasSubstr("camera.fov_y_deg"));
    watcher.expect_served("fov 190");
  }
  {  // A request without a camera.
    ViewStream v(api, "s");
    v1::ViewRequest req;
    req.set_frame(1);
    v.send(req);
    v1::ViewResponse r;
    EXPECT_FALSE(v.read(&r));
    const grpc::Status s = v.finish();
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(s);
    EXPECT_THAT(s.error_message(), HasSubstr("camera"));
    watcher.expect_served("no camera");
  }
  {  // A mesh scene is served (it was once refused), and a bad mesh refused.
    const std::string mesh = R"({"format": "voxvis-scene/1", "bounds": {"min": [0, 0, 0], "max": [8, 8, 8]},
      "objects": [{"id": 1, "shape": "mesh", "center": [4, 4, 4],
                   "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "triangles": [[0, 1, 2]]}]})";
    v1::SceneInfo info;
    grpc::Status s = api.create_scene_json("m", mesh, &info);
    ASSERT_TRUE(s.ok()) << show(s);
    EXPECT_EQ(info.mesh_objects(), 1u);
    EXPECT_EQ(info.mesh_triangles(), 1u);
    v1::GetPvsResponse pvs;
    ASSERT_TRUE(api.get_pvs("m", 0.0, look(Vec3(4.2, 4.2, -3), Vec3(0, 0, 1)), &pvs).ok());
    EXPECT_EQ(ids_of(pvs.pvs()), std::vector<ObjectId>{1});
    ASSERT_TRUE(api.delete_scene("m").ok());
    std::string bad = mesh;
    bad.replace(bad.find("[[0, 1, 2]]"), 11, "[[0, 1, 1]]");
    s = api.create_scene_json("m", bad);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(s);
    EXPECT_THAT(s.error_message(), HasSubstr("objects[0].triangles[0]: is degenerate"));
    watcher.expect_served("mesh scene");
  }
  {  // Unknown scene, on every call that names one.
    const auto nf = grpc::StatusCode::NOT_FOUND;
    ViewStream v(api, "nope");
    v1::ViewResponse r;
    v.send(1, 0.0, wall_camera());
    EXPECT_FALSE(v.read(&r));
    grpc::Status s = v.finish();
    EXPECT_EQ(s.error_code(), nf) << show(s);
    EXPECT_THAT(s.error_message(), HasSubstr("nope"));
    SimStream sim(api, "nope");
    s = sim.finish();
    EXPECT_EQ(s.error_code(), nf) << show(s);
    v1::GetPvsResponse pvs;
    EXPECT_EQ(api.get_pvs("nope", 0.0, wall_camera(), &pvs).error_code(), nf);
    v1::SceneInfo info;
    EXPECT_EQ(api.stats("nope", &info).error_code(), nf);
    EXPECT_EQ(api.delete_scene("nope").error_code(), nf);
    watcher.expect_served("unknown scene");
  }
  {  // The first message of a stream must name the scene.
    ViewStream v(api, "");
    v1::ViewResponse r;
    v.send(1, 0.0, wall_camera());
    EXPECT_FALSE(v.read(&r));
    const grpc::Status s = v.finish();
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(s);
    EXPECT_THAT(s.error_message(), HasSubstr("scene_id"));
    watcher.expect_served("no scene id");
  }
  {  // A bad object, as a description and as a document.
    v1::SceneDescription d = wall_description();
    d.mutable_objects(1)->mutable_sphere()->set_radius(-1);
    grpc::Status s = api.create_scene("bad", d);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(s);
    EXPECT_THAT(s.error_message(), HasSubstr("description.objects[1].radius"));
    std::string json = wall_scene_json();
    const std::string good = R"("center": [10, 10, 15], "radius": 1,)";
    const std::size_t at = json.find(good);
    ASSERT_NE(at, std::string::npos);
    json.replace(at, good.size(), R"("center": [10, 10, 15], "radius": -1,)");
    const std::size_t line = 1 + static_cast<std::size_t>(std::count(
                                     json.begin(), json.begin() + static_cast<long>(at), '\n'));
    s = api.create_scene_json("bad", json);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(s);
    EXPECT_THAT(s.error_message(), HasSubstr("scene_json:" + std::to_string(line) + ":"));
    EXPECT_THAT(s.error_message(), HasSubstr("objects[1].radius"));
    // Scene ids are checked too, and taken ids are refused.
    s = api.create_scene_json("../etc", wall_scene_json());
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(s);
    EXPECT_THAT(s.error_message(), HasSubstr("scene_id"));
    s = api.create_scene_json("s", wall_scene_json());
    EXPECT_EQ(s.error_code(), grpc::StatusCode::ALREADY_EXISTS) << show(s);
    EXPECT_EQ(scene_ids(api), scenes);
    watcher.expect_served("bad object");
  }
  {  // A grid beyond the voxel limit, refused before any allocation.
    v1::SceneDescription d = wall_description();
    d.mutable_grid()->set_nx(8192);
    d.mutable_grid()->set_ny(8192);
    d.mutable_grid()->set_nz(8192);
    const grpc::Status s = api.create_scene("huge", d);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << show(s);
    EXPECT_THAT(s.error_message(), HasSubstr("grid"));
    EXPECT_EQ(scene_ids(api), scenes);
    watcher.expect_served("huge grid");
  }
  {  // A message above --max-message-mib, refused by gRPC itself.
    std::string json = wall_scene_json();
    json.insert(json.size() - 2, std::string(2 << 20, ' '));
    const grpc::Status s = api.create_scene_json("big", json);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << show(s);
    EXPECT_EQ(scene_ids(api), scenes);
    watcher.expect_served("2 MB message");
  }
  {  // Moves of a static object, an unknown object, the same object twice:
     // the whole batch is refused, naming the move.
    struct Case {
      std::vector<Move> moves;
      std::string field;
    };
    const std::vector<Case> cases = {
        {{{2, Vec3(10, 10, 15.1)}, {1, Vec3(10, 10, 10)}}, "batch.moves[1].id"},
        {{{99, Vec3(1, 1, 1)}}, "batch.moves[0].id"},
        {{{2, Vec3(10, 10, 15.1)}, {2, Vec3(10, 10, 15.2)}}, "batch.moves[1].id"},
    };
    for (const Case& c : cases) {
      SCOPED_TRACE(c.field);
      SimStream sim(api, "s");
      v1::MoveAck ack;
      EXPECT_FALSE(sim.move(1, 1.0, c.moves, &ack));
      const grpc::Status s = sim.finish();
      EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(s);
      EXPECT_THAT(s.error_message(), HasSubstr(c.field));
      v1::SceneInfo info;
      ASSERT_TRUE(api.stats("s", &info).ok());
      EXPECT_EQ(info.moves_applied(), 0u) << "nothing of a refused batch is applied";
      watcher.expect_served("bad move " + c.field);
    }
  }
  {  // Frame numbers must increase, times must not decrease.
    ViewStream v(api, "s");
    v1::ViewResponse r;
    ASSERT_TRUE(v.frame(5, 1.0, wall_camera(), &r));
    v.send(5, 1.0, wall_camera());
    EXPECT_FALSE(v.read(&r));
    grpc::Status s = v.finish();
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(s);
    EXPECT_THAT(s.error_message(), HasSubstr("frame"));
    watcher.expect_served("repeated frame");

    ViewStream w(api, "s");
    ASSERT_TRUE(w.frame(1, 2.0, wall_camera(), &r));
    w.send(2, 1.0, wall_camera());
    EXPECT_FALSE(w.read(&r));
    s = w.finish();
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(s);
    EXPECT_EQ(s.error_message().rfind("t:", 0), 0u) << s.error_message();
    watcher.expect_served("time going back");
  }
  const grpc::Status w = watcher.finish();
  EXPECT_TRUE(w.ok()) << show(w);
  EXPECT_EQ(server.terminate(), 0);
}

TEST(ServerErrors, MemoryBudgetRefusesLargeGrids) {
  ServerProcess server({"--memory-budget-mib", "1"});
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  v1::SceneDescription d = wall_description();
  d.mutable_grid()->set_nx(200);
  d.mutable_grid()->set_ny(200);
  d.mutable_grid()->set_nz(200);
  const grpc::Status s = api.create_scene("large", d);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << show(s);
  EXPECT_THAT(s.error_message(), HasSubstr("budget"));
  EXPECT_TRUE(scene_ids(api).empty());
  // The budget is not a blanket refusal: a tiny grid fits.
  d.mutable_grid()->set_nx(4);
  d.mutable_grid()->set_ny(4);
  d.mutable_grid()->set_nz(4);
  const grpc::Status small = api.create_scene("small", d);
  EXPECT_TRUE(small.ok()) << show(small);
  EXPECT_EQ(scene_ids(api), (std::vector<std::string>{"small"}));
  // Nothing of the refused scene was stored.
  EXPECT_EQ(server.terminate(), 0);
  ASSERT_TRUE(server.restart());
  EXPECT_EQ(scene_ids(server.api()), (std::vector<std::string>{"small"}));
  EXPECT_EQ(server.terminate(), 0);
}

}  // namespace
}  // namespace voxvis::servertest
