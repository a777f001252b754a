// Mesh scenes on the real server: created over gRPC (a description with a
// shared mesh table, or a scene file through `voxvis load`), they answer
// View and Tick exactly as `voxvis replay` does offline for a frames file
// whose moves rotate meshes; a restarted server resumes rotated meshes from
// its data directory bit for bit; every invalid mesh and rotation is refused
// naming the field; the memory estimate counts a mesh once per scene.
//
// The scene makes rotations observable: mesh 2 is a cube on an arm (its
// triangles 5 units from its model origin along z), pivoting at the centre of
// a wall. Unrotated it is behind the wall, hidden from a camera in front;
// turned half a turn about x it is in front, visible. A server that dropped
// rotations would never show it.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "meshes.h"
#include "server_process.h"
#include "voxvis/client.h"
#include "voxvis/format.h"
#include "voxvis/generate.h"
#include "voxvis/scene.h"

namespace voxvis::servertest {
namespace {

using ::testing::HasSubstr;

constexpr double kPi = 3.14159265358979323846;

/// A cube of half size 1 whose centre is 5 units from the model origin.
std::shared_ptr<const Mesh> arm_mesh() {
  auto m = std::make_shared<Mesh>(*test::cube_mesh(Vec3(1.0)));
  for (Vec3& v : m->vertices) v += Vec3(0, 0, 5);
  return m;
}

ObjectDesc dynamic(ObjectDesc o, double max_speed) {
  o.dynamic = true;
  o.max_speed = max_speed;
  return o;
}

/// Bounds [0, 20]^3, grid 20^3; a wall (1) across z in [8.5, 11.5]; the arm
/// (2, dynamic) pivoting at (10, 10, 10); one icosphere placed three times
/// (3 and 4 static, 7 dynamic); a soup of triangles rotated and scaled (5);
/// a dynamic sphere (6).
SceneDesc swing_scene() {
  SceneDesc d;
  d.bounds_min = Vec3(0.0);
  d.bounds_max = Vec3(20.0);
  d.grid = glm::ivec3(20, 20, 20);
  ObjectDesc wall;
  wall.id = 1;
  wall.shape = Shape::Box;
  set_box_corners(Vec3(0, 0, 8.5), Vec3(20, 20, 11.5), &wall);
  d.objects.push_back(wall);
  d.objects.push_back(dynamic(test::mesh_object(2, arm_mesh(), Vec3(10, 10, 10)), 100.0));
  const std::shared_ptr<const Mesh> ball = test::icosphere(2);
  d.objects.push_back(test::mesh_object(3, ball, Vec3(5, 5, 4), test::rotation_about(Vec3(1, 1, 1), 0.3), 1.5));
  d.objects.push_back(test::mesh_object(4, ball, Vec3(15, 15, 16), Quat(1, 0, 0, 0), 2.0));
  d.objects.push_back(
      test::mesh_object(5, test::triangle_soup(50, 3), Vec3(14, 6, 4), test::rotation_about(Vec3(0, 1, 1), 1.1), 1.2));
  ObjectDesc ball6;
  ball6.id = 6;
  ball6.center = Vec3(4, 16, 4);
  ball6.radius = 0.8;
  d.objects.push_back(dynamic(ball6, 100.0));
  d.objects.push_back(dynamic(test::mesh_object(7, ball, Vec3(4, 15, 15)), 100.0));
  return d;
}

/// 40 frames at 30 Hz from in front of the wall. The arm turns from 0 to half
/// a turn about x (every fifth move without a rotation: it keeps its last),
/// the dynamic icosphere moves and turns, the sphere moves.
std::vector<FrameInput> swing_frames() {
  std::vector<FrameInput> frames;
  for (int i = 0; i < 40; ++i) {
    FrameInput f;
    f.t = i / 30.0;
    f.camera = look(Vec3(10 + 0.05 * i, 10, 1), Vec3(0, 0, 1));
    Move arm{2, Vec3(10, 10, 10)};
    if (i % 5 != 4) {
      arm.has_rotation = true;
      arm.rotation = test::rotation_about(Vec3(1, 0, 0), kPi * i / 39.0);
    }
    f.moves.push_back(arm);
    f.moves.push_back(Move{6, Vec3(4 + 0.1 * i, 16, 4)});
    f.moves.push_back(Move{7, Vec3(4 + 0.1 * i, 15, 15 - 0.2 * i), true, test::rotation_about(Vec3(1, 1, 0), 0.1 * i)});
    frames.push_back(f);
  }
  return frames;
}

std::string frames_text(const std::vector<FrameInput>& frames) {
  std::string text;
  for (const FrameInput& f : frames) text += frame_to_json(f) + "\n";
  return text;
}

bool has(const std::vector<ObjectId>& ids, ObjectId id) {
  return std::find(ids.begin(), ids.end(), id) != ids.end();
}

bool pvs_has(const std::string& line, ObjectId id) {
  const nlohmann::json j = nlohmann::json::parse(line, nullptr, false);
  if (j.is_discarded()) return false;
  for (const auto& v : j.at("pvs"))
    if (v.get<ObjectId>() == id) return true;
  return false;
}

std::vector<ObjectId> pvs_of(const Api& api, const std::string& id, double t, const Camera& cam,
                             v1::GetPvsResponse* out = nullptr) {
  v1::GetPvsResponse resp;
  const grpc::Status s = api.get_pvs(id, t, cam, &resp);
  EXPECT_TRUE(s.ok()) << show(s);
  if (out) *out = resp;
  return ids_of(resp.pvs());
}

TEST(ServerMeshes, ViewAndTickAnswerAsReplayWithRotatingMoves) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  const SceneDesc desc = swing_scene();
  const std::string scene = server.path("swing.json"), frames = server.path("frames.jsonl");
  spit(scene, scene_to_json(desc));
  spit(frames, frames_text(swing_frames()));

  const std::string replay_out = server.path("replay.jsonl");
  ProcessResult r = run_program({VOXVIS_CLI, "replay", "--scene", scene, "--frames", frames, "--out", replay_out, "-q"},
                                server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string expected = slurp(replay_out);
  const std::vector<std::string> lines = lines_of(expected);
  ASSERT_EQ(lines.size(), 40u);
  // The arm's rotation decides what is seen: hidden at first, seen at the end.
  EXPECT_FALSE(pvs_has(lines.front(), 2)) << lines.front();
  EXPECT_TRUE(pvs_has(lines.back(), 2)) << lines.back();

  // Two scenes from the description (the mesh table), one from the file.
  v1::SceneDescription wire;
  to_proto(desc, &wire);
  ASSERT_EQ(wire.meshes_size(), 3) << "the icosphere goes once";
  v1::SceneInfo info;
  ASSERT_TRUE(api.create_scene("view", wire, &info).ok());
  EXPECT_EQ(info.objects(), 7u);
  EXPECT_EQ(info.dynamic_objects(), 3u);
  EXPECT_EQ(info.mesh_objects(), 5u);
  const std::uint64_t triangles = 12 + 320 + 50;  // The arm, the icosphere once, the soup.
  EXPECT_EQ(info.mesh_triangles(), triangles);
  ASSERT_TRUE(api.create_scene("delta", wire).ok());
  r = run_program({VOXVIS_CLI, "load", "--server", server.address(), "--scene", scene, "--id", "tick"}, server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("tick: grid 20x20x20, 7 objects (3 dynamic), 5 meshes of " +
                               std::to_string(triangles) + " triangles"));
  ASSERT_TRUE(api.stats("tick", &info).ok());
  EXPECT_EQ(info.mesh_triangles(), triangles) << "the file's inline copies are shared again";

  const std::string view_out = server.path("view.jsonl");
  r = run_program({VOXVIS_CLI, "view", "--server", server.address(), "--scene", "view", "--frames", frames, "--out",
                   view_out, "-q"},
                  server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  expect_same_output(expected, slurp(view_out), "voxvis view");
  const std::string delta_out = server.path("delta.jsonl");
  r = run_program({VOXVIS_CLI, "view", "--server", server.address(), "--scene", "delta", "--frames", frames, "--out",
                   delta_out, "-q", "--delta"},
                  server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  expect_same_output(expected, slurp(delta_out), "voxvis view --delta");
  const std::string tick_out = server.path("tick.jsonl");
  r = run_program({VOXVIS_CLI, "tick", "--server", server.address(), "--scene", "tick", "--frames", frames, "--out",
                   tick_out, "-q"},
                  server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  expect_same_output(expected, slurp(tick_out), "voxvis tick");

  // The Python example's tick client sends the rotations too.
  ASSERT_TRUE(api.create_scene("python", wire).ok());
  const std::string py_out = server.path("python.jsonl");
  r = run_program({"/usr/bin/env", "-u", "VOXVIS_TOKEN_FILE", "PYTHONDONTWRITEBYTECODE=1",
                   std::string("PYTHONPATH=") + VOXVIS_PYTHON_STUBS, VOXVIS_PYTHON,
                   std::string(VOXVIS_SOURCE_DIR) + "/examples/python/tick_client.py", "--server", server.address(),
                   "--scene", "python", "--frames", frames, "--out", py_out, "-q"},
                  server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  expect_same_output(expected, slurp(py_out), "tick_client.py");

  ASSERT_TRUE(api.stats("view", &info).ok());
  EXPECT_EQ(info.moves_applied(), 40u * 3u);
  std::vector<std::string> ids;
  ASSERT_TRUE(api.list_scenes(&ids).ok());
  EXPECT_EQ(ids, (std::vector<std::string>{"delta", "python", "tick", "view"}));
  r = run_program({VOXVIS_CLI, "scenes", "--server", server.address()}, server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("view: grid 20x20x20, 7 objects (3 dynamic), 5 meshes of 382 triangles, "));
  EXPECT_EQ(server.terminate(), 0);
}

TEST(ServerMeshes, AnImportedModelIsServedAsReplayAnswersIt) {
  // The issue's path end to end: a glTF model from Debian's
  // assimp-testmodels through `voxvis import` (one part dynamic), loaded
  // into the server with `voxvis load`, walked through with moves by
  // `voxvis view` and `voxvis tick`: the answers are replay's.
  const std::string model = "/usr/share/assimp/models/glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb";
  if (!std::filesystem::exists(model)) GTEST_SKIP() << "assimp-testmodels is not installed (" << model << ")";
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const std::string scene = server.path("engine.json"), frames = server.path("engine.jsonl");
  ProcessResult r = run_program({VOXVIS_CLI, "import", model, "--scene-out", scene, "--dynamic", "nodes[80]",
                                 "--max-speed", "40", "--grid", "48,32,64", "-q"},
                                server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  SceneDesc desc;
  FormatError error;
  ASSERT_TRUE(parse_scene(slurp(scene), scene, &desc, &error)) << error.str();
  ASSERT_GT(desc.objects.size(), 50u);
  WalkthroughParams walk;
  walk.frames = 30;
  spit(frames, frames_text(make_walkthrough(desc, walk)));
  const std::string replay_out = server.path("replay.jsonl");
  r = run_program({VOXVIS_CLI, "replay", "--scene", scene, "--frames", frames, "--out", replay_out, "-q"}, server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string expected = slurp(replay_out);
  ASSERT_EQ(lines_of(expected).size(), 30u);
  for (const char* id : {"view", "tick"}) {
    r = run_program({VOXVIS_CLI, "load", "--server", server.address(), "--scene", scene, "--id", id}, server.dir());
    ASSERT_EQ(r.status, 0) << r.err;
    const std::string out = server.path(std::string(id) + ".jsonl");
    r = run_program({VOXVIS_CLI, id, "--server", server.address(), "--scene", id, "--frames", frames, "--out", out, "-q"},
                    server.dir());
    ASSERT_EQ(r.status, 0) << r.err;
    expect_same_output(expected, slurp(out), std::string("voxvis ") + id);
  }
  EXPECT_EQ(server.terminate(), 0);
}

TEST(ServerMeshes, RestartResumesRotatedMeshesBitForBit) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const SceneDesc desc = swing_scene();
  const Camera cam = look(Vec3(10, 10, 1), Vec3(0, 0, 1));
  // Half a turn, with a norm a little off 1 (as an exporter writes one):
  // the server keeps it as given, and normalizes it as the engine does.
  const Quat turn = test::rotation_about(Vec3(1, 0, 0), kPi) * (1.0 + 3e-7);
  const Vec3 pivot(10.0 + 1.0 / 3.0, 10, 10);
  {
    const Api api = server.api();
    v1::SceneDescription wire;
    to_proto(desc, &wire);
    ASSERT_TRUE(api.create_scene("swing", wire).ok());
    EXPECT_FALSE(has(pvs_of(api, "swing", 0.0, cam), 2)) << "the arm starts hidden";
    SimStream sim(api, "swing");
    v1::MoveAck ack;
    ASSERT_TRUE(sim.move(1, 1.0, {Move{2, pivot, true, turn}, Move{7, Vec3(4, 15, 15), true, turn}}, &ack))
        << sim.finish().error_message();
    EXPECT_EQ(ack.applied(), 2u);
    EXPECT_TRUE(sim.finish().ok());
    EXPECT_TRUE(has(pvs_of(api, "swing", 1.0, cam), 2)) << "turned, the arm is in front";
  }
  EXPECT_EQ(server.terminate(), 0);

  // The positions file holds the rotation as sent, every bit.
  const nlohmann::json saved = nlohmann::json::parse(slurp(server.data_dir() + "/scenes/swing.positions"));
  ASSERT_EQ(saved.at("moves").size(), 3u);
  const nlohmann::json& arm = saved.at("moves")[0];
  EXPECT_EQ(arm.at("id"), 2);
  ASSERT_TRUE(arm.contains("rotation")) << saved.dump();
  const std::vector<double> q = arm.at("rotation").get<std::vector<double>>();
  EXPECT_EQ(q, (std::vector<double>{turn.w, turn.x, turn.y, turn.z}));
  EXPECT_EQ(arm.at("center").get<std::vector<double>>(), (std::vector<double>{pivot.x, pivot.y, pivot.z}));
  EXPECT_FALSE(saved.at("moves")[1].contains("rotation")) << "a sphere has none";

  ASSERT_TRUE(server.restart());
  const Api api = server.api();
  // The engine, created where the moves left the objects, at the saved time,
  // answers a fresh viewer exactly as the resumed server does.
  SceneDesc moved = desc;
  moved.objects[1].center = pivot;
  moved.objects[1].rotation = turn;
  moved.objects[6].center = Vec3(4, 15, 15);
  moved.objects[6].rotation = turn;
  std::unique_ptr<Scene> engine;
  ASSERT_TRUE(Scene::create(moved, SceneOptions{}, &engine).ok);
  ASSERT_TRUE(engine->apply_moves(1.0, {}).ok);
  Scratch scratch;
  FrameResult want;
  ASSERT_TRUE(engine->frame(engine->add_viewer(), cam, 1.0, scratch, &want).ok);
  v1::GetPvsResponse got;
  EXPECT_EQ(pvs_of(api, "swing", 1.0, cam, &got), want.pvs);
  EXPECT_EQ(counters(got.stats()), counters(want.stats));
  EXPECT_TRUE(has(want.pvs, 2)) << "the arm stays turned";
  // A move without a rotation keeps the restored one: still in front.
  SimStream sim(api, "swing");
  v1::MoveAck ack;
  ASSERT_TRUE(sim.move(1, 1.1, {Move{2, pivot + Vec3(0, 0.25, 0)}}, &ack)) << sim.finish().error_message();
  EXPECT_TRUE(sim.finish().ok());
  EXPECT_TRUE(has(pvs_of(api, "swing", 1.1, cam), 2));
  EXPECT_EQ(server.terminate(), 0);
}

TEST(ServerMeshes, MemoryEstimateCountsEachMeshOnce) {
  // The buffer off: with it on, each static object also keeps its placed
  // vertices (docs/design.md, "Meshes"), which the engine's own test counts.
  ServerProcess server({"--occlusion-buffer", "0"});
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  // The same layout with a coarse and a fine sphere of triangles: the fine
  // one's bytes show in the estimate, once however many objects place it,
  // from the description and from a file (whose copies are shared again).
  const auto layout = [](std::shared_ptr<const Mesh> ball, int copies) {
    SceneDesc d;
    d.bounds_min = Vec3(0.0);
    d.bounds_max = Vec3(20.0);
    d.grid = glm::ivec3(20, 20, 20);
    for (int i = 0; i < copies; ++i)
      d.objects.push_back(test::mesh_object(static_cast<ObjectId>(i + 1), ball, Vec3(2.0 + 1.5 * i, 10, 10), Quat(1, 0, 0, 0), 0.5));
    return d;
  };
  const std::shared_ptr<const Mesh> coarse = test::icosphere(1), fine = test::icosphere(5);
  const double extra = static_cast<double>((fine->vertices.size() - coarse->vertices.size()) * sizeof(Vec3) +
                                           (fine->triangles.size() - coarse->triangles.size()) * 12);
  const auto memory = [&](const std::string& id, const SceneDesc& d, bool as_json) {
    v1::SceneInfo info;
    grpc::Status s;
    if (as_json) {
      s = api.create_scene_json(id, scene_to_json(d), &info);
    } else {
      v1::SceneDescription wire;
      to_proto(d, &wire);
      s = api.create_scene(id, wire, &info);
    }
    EXPECT_TRUE(s.ok()) << show(s);
    return static_cast<double>(info.memory_bytes());
  };
  const double one = memory("fine1", layout(fine, 1), false) - memory("coarse1", layout(coarse, 1), false);
  EXPECT_GE(one, extra);
  EXPECT_LT(one, 1.5 * extra);
  const double ten = memory("fine10", layout(fine, 10), false) - memory("coarse10", layout(coarse, 10), false);
  EXPECT_GE(ten, extra);
  EXPECT_LT(ten, 1.5 * extra) << "ten instances of one mesh are counted once";
  const double file = memory("fine10j", layout(fine, 10), true) - memory("coarse10j", layout(coarse, 10), true);
  EXPECT_EQ(file, ten) << "a file's identical meshes are shared as the description's";
  EXPECT_EQ(server.terminate(), 0);
}


/// Bounds [0, 8]^3: a dynamic sphere (1), a cube mesh (2, meshes[0]: 8
/// vertices, 12 triangles) and a dynamic triangle (3, meshes[1]).
v1::SceneDescription small_mesh_scene() {
  SceneDesc d;
  d.bounds_min = Vec3(0.0);
  d.bounds_max = Vec3(8.0);
  d.grid = glm::ivec3(8, 8, 8);
  ObjectDesc s;
  s.id = 1;
  s.center = Vec3(2, 2, 2);
  s.radius = 0.5;
  d.objects.push_back(dynamic(s, 1.0));
  d.objects.push_back(test::mesh_object(2, test::cube_mesh(Vec3(1.0)), Vec3(4, 4, 4)));
  auto tri = std::make_shared<Mesh>();
  tri->vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  tri->triangles = {{0, 1, 2}};
  d.objects.push_back(dynamic(test::mesh_object(3, tri, Vec3(6, 6, 6)), 2.0));
  v1::SceneDescription wire;
  to_proto(d, &wire);
  return wire;
}

// A description is saved as a scene file whose objects each carry their
// mesh inline: instancing multiplies the file, which is refused (before it
// is written) beyond 4 x --max-message-mib, naming the figures.
TEST(ServerMeshes, InstancingBeyondWhatTheSavedFileHoldsIsRefused) {
  ServerProcess server({"--max-message-mib", "1"});
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  const auto instances = [](int copies) {
    SceneDesc d;
    d.bounds_min = Vec3(0.0);
    d.bounds_max = Vec3(20.0);
    d.grid = glm::ivec3(20, 20, 20);
    const std::shared_ptr<const Mesh> ball = test::icosphere(4);  // 2,562 vertices, 5,120 triangles.
    for (int i = 0; i < copies; ++i)
      d.objects.push_back(test::mesh_object(static_cast<ObjectId>(i + 1), ball, Vec3(1.0 + 0.6 * i, 10, 10),
                                            test::rotation_about(Vec3(0, 1, 0), 0.1 * i), 0.3));
    v1::SceneDescription wire;
    to_proto(d, &wire);
    EXPECT_LT(wire.ByteSizeLong(), std::size_t{1} << 20) << "the message itself fits";
    return wire;
  };
  v1::SceneInfo info;
  grpc::Status s = api.create_scene("few", instances(8), &info);
  ASSERT_TRUE(s.ok()) << show(s);
  EXPECT_EQ(info.mesh_triangles(), 5120u);
  s = api.create_scene("many", instances(30));
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << show(s);
  EXPECT_THAT(s.error_message(), HasSubstr("description: the scene would be saved as a file of "));
  EXPECT_THAT(s.error_message(), HasSubstr(" bytes, over the limit of 4194304 bytes (4 x --max-message-mib)"));
  EXPECT_THAT(s.error_message(), HasSubstr("each of its 30 mesh objects writes inline"));
  // Spheres alone are no instancing: 11,000 of them (a 0.6 MB message, a
  // 1.2 MB file) are created (the old estimate, 400 bytes an object, said
  // "about 4 MiB" and refused them, blaming meshes).
  SceneDesc spheres;
  spheres.bounds_min = Vec3(0.0);
  spheres.bounds_max = Vec3(1000.0);
  for (int i = 0; i < 11000; ++i) {
    ObjectDesc o;
    o.id = static_cast<ObjectId>(100 + i);
    o.center = Vec3(1.0 + (i % 100) * 9.7, 1.0 + (i / 100 % 100) * 9.3, 500.0 + i / 10000 * 3.1);
    o.radius = 0.5 + (i % 7) * 0.01;
    spheres.objects.push_back(o);
  }
  v1::SceneDescription wire;
  to_proto(spheres, &wire);
  ASSERT_GT(wire.ByteSizeLong(), std::size_t{450'000});
  s = api.create_scene("spheres", wire);
  EXPECT_TRUE(s.ok()) << show(s);
  std::vector<std::string> ids;
  ASSERT_TRUE(api.list_scenes(&ids).ok());
  EXPECT_EQ(ids, (std::vector<std::string>{"few", "spheres"}));
  EXPECT_FALSE(std::filesystem::exists(server.data_dir() + "/scenes/many.json"));
  EXPECT_EQ(server.terminate(), 0);
}

TEST(ServerMeshes, InvalidMeshesAreRefusedNamingTheField) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::string unit = "must be a unit quaternion [w, x, y, z] (norm within 1e-06 of 1), got norm ";
  struct Case {
    std::string message;  // The whole status message.
    std::function<void(v1::SceneDescription*)> mutate;
  };
  const std::vector<Case> cases = {
      {"description.meshes[0].triangles[7]: vertex index 9 is out of range (the mesh has 8 vertices)",
       [](v1::SceneDescription* d) { d->mutable_meshes(0)->set_triangles(7 * 3 + 1, 9); }},
      {"description.meshes[0].vertices[5]: must be finite and at most 1e+12 on every axis, got [nan, -1, 1]",
       [nan](v1::SceneDescription* d) { d->mutable_meshes(0)->set_vertices(5 * 3, nan); }},
      {"description.meshes[1].vertices[2]: must be finite and at most 1e+12 on every axis, got [0, 2e+12, 0]",
       [](v1::SceneDescription* d) { d->mutable_meshes(1)->set_vertices(2 * 3 + 1, 2e12); }},
      {"description.meshes[0].triangles[3]: is degenerate (its vertices 0, 0, 1 span no area); remove it",
       [](v1::SceneDescription* d) {
         d->mutable_meshes(0)->set_triangles(9, 0);
         d->mutable_meshes(0)->set_triangles(10, 0);
         d->mutable_meshes(0)->set_triangles(11, 1);
       }},
      {"description.meshes[1].triangles[0]: is degenerate (its vertices 0, 1, 2 span no area); remove it",
       [](v1::SceneDescription* d) {  // Three points on a line.
         d->mutable_meshes(1)->set_vertices(7, 0);
         d->mutable_meshes(1)->set_vertices(6, 2);
       }},
      {"description.meshes[1].triangles: a mesh needs at least one triangle",
       [](v1::SceneDescription* d) { d->mutable_meshes(1)->clear_triangles(); }},
      {"description.meshes[1].triangles: a mesh needs at least one triangle",
       [](v1::SceneDescription* d) { d->mutable_meshes(1)->Clear(); }},
      {"description.meshes[0].vertices: 25 numbers, not a multiple of 3 (x, y, z of each vertex in turn)",
       [](v1::SceneDescription* d) { d->mutable_meshes(0)->add_vertices(1.0); }},
      {"description.meshes[0].triangles: 35 indices, not a multiple of 3 (i, j, k of each triangle in turn)",
       [](v1::SceneDescription* d) { d->mutable_meshes(0)->mutable_triangles()->RemoveLast(); }},
      {"description.objects[1].mesh.index: mesh 2 is out of range (the description has 2 meshes)",
       [](v1::SceneDescription* d) { d->mutable_objects(1)->mutable_mesh()->set_index(2); }},
      {"description.objects[1].mesh.rotation: " + unit + "2",
       [](v1::SceneDescription* d) { d->mutable_objects(1)->mutable_mesh()->mutable_rotation()->set_w(2); }},
      {"description.objects[2].mesh.rotation: " + unit + "nan",
       [nan](v1::SceneDescription* d) { d->mutable_objects(2)->mutable_mesh()->mutable_rotation()->set_y(nan); }},
      {"description.objects[1].mesh.rotation: " + unit + "0",
       [](v1::SceneDescription* d) { d->mutable_objects(1)->mutable_mesh()->mutable_rotation()->Clear(); }},
      {"description.objects[1].mesh.scale: must be finite and > 0, got 0",
       [](v1::SceneDescription* d) { d->mutable_objects(1)->mutable_mesh()->set_scale(0); }},
      {"description.objects[1].mesh.scale: must be finite and > 0, got nan",
       [nan](v1::SceneDescription* d) { d->mutable_objects(1)->mutable_mesh()->set_scale(nan); }},
      {"description.objects[1].mesh.center: must be finite and at most 1e+12 on every axis, got [4, nan, 4]",
       [nan](v1::SceneDescription* d) { d->mutable_objects(1)->mutable_mesh()->mutable_center()->set_y(nan); }},
      {"description.objects[1].mesh.scale: places the mesh beyond 1e+12",
       [](v1::SceneDescription* d) { d->mutable_objects(1)->mutable_mesh()->set_scale(1e12); }},
      // A centre within the limit that takes the mesh beyond it: the
      // centre is named, not the scale (1) that fits at the origin.
      {"description.objects[1].mesh.center: places the mesh beyond 1e+12",
       [](v1::SceneDescription* d) { d->mutable_objects(1)->mutable_mesh()->mutable_center()->set_x(1e12); }},
      {"description.objects[1].max_speed: only dynamic objects have a max_speed",
       [](v1::SceneDescription* d) { d->mutable_objects(1)->set_max_speed(1); }},
      {"description.objects[2].max_speed: dynamic objects need max_speed (world units per second)",
       [](v1::SceneDescription* d) { d->mutable_objects(2)->clear_max_speed(); }},
      {"description.objects[2]: no shape: set sphere, box or mesh",
       [](v1::SceneDescription* d) { d->mutable_objects(2)->clear_mesh(); }},
  };
  ASSERT_TRUE(api.create_scene("good", small_mesh_scene()).ok()) << "the scene the cases break is valid";
  for (std::size_t i = 0; i < cases.size(); ++i) {
    SCOPED_TRACE("case " + std::to_string(i) + ": " + cases[i].message);
    v1::SceneDescription d = small_mesh_scene();
    cases[i].mutate(&d);
    const grpc::Status s = api.create_scene("bad" + std::to_string(i), d);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(s);
    if (cases[i].message.find("places the mesh beyond") != std::string::npos) {
      EXPECT_THAT(s.error_message(), HasSubstr(cases[i].message));
    } else {
      EXPECT_EQ(s.error_message(), cases[i].message);
    }
  }
  // The same rules for a scene sent as a file, naming its line.
  const std::string json = R"({"format": "voxvis-scene/1", "bounds": {"min": [0, 0, 0], "max": [8, 8, 8]},
"objects": [{"id": 1, "shape": "mesh", "center": [4, 4, 4],
  "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "triangles": [[0, 1, 3]]}]})";
  grpc::Status s = api.create_scene_json("badjson", json);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(s);
  EXPECT_EQ(s.error_message(),
            "scene_json:3: objects[0].triangles[0]: vertex index 3 is out of range (the mesh has 3 vertices)");
  std::vector<std::string> ids;
  ASSERT_TRUE(api.list_scenes(&ids).ok());
  EXPECT_EQ(ids, std::vector<std::string>{"good"}) << "nothing refused was created";

  // Moves: a rotation of a sphere, a rotation not of unit norm, on Simulate
  // and on Tick; each ends its stream naming the move.
  const auto simulate = [&](const std::vector<Move>& moves) {
    SimStream sim(api, "good");
    sim.send(1, 0.5, moves);
    v1::MoveAck ack;
    EXPECT_FALSE(sim.wait_ack(&ack));
    return sim.finish();
  };
  s = simulate({Move{3, Vec3(6, 6, 6), true, Quat(1, 0, 0, 0)}, Move{1, Vec3(2, 2, 2), true, Quat(1, 0, 0, 0)}});
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(s);
  EXPECT_EQ(s.error_message(), "batch.moves[1].rotation: object 1 is a sphere; only meshes rotate");
  s = simulate({Move{3, Vec3(6, 6, 6), true, Quat(0, 0, 0.5, 0.5)}});
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(s);
  EXPECT_EQ(s.error_message(), "batch.moves[0].rotation: " + unit + "0.7071067811865476");
  client::Client client(server.channel(), "", server.address());
  for (const auto& [moves, message] : std::vector<std::pair<std::vector<Move>, std::string>>{
           {{Move{1, Vec3(2, 2, 2), true, Quat(1, 0, 0, 0)}}, "moves[0].rotation: object 1 is a sphere; only meshes rotate"},
           {{Move{3, Vec3(6, 6, 6), true, Quat(nan, 0, 0, 0)}}, "moves[0].rotation: " + unit + "nan"}}) {
    client::TickSession session(client);
    session.open("good", v1::PVS_FULL);
    client::TickAnswer answer;
    EXPECT_FALSE(session.tick(1, 0.5, moves, {{1, look(Vec3(4, 4, -5), Vec3(0, 0, 1))}}, {}, &answer));
    const grpc::Status t = session.finish();
    EXPECT_EQ(t.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(t);
    EXPECT_EQ(t.error_message(), message);
  }
  // None of it moved anything: the scene serves on, its clock unset.
  v1::SceneInfo info;
  ASSERT_TRUE(api.stats("good", &info).ok());
  EXPECT_EQ(info.moves_applied(), 0u);
  EXPECT_FALSE(pvs_of(api, "good", 0.0, look(Vec3(4, 4, -5), Vec3(0, 0, 1))).empty());

  // Positions another server exported place meshes as moves do: a centre
  // that takes the mesh beyond the limit is the move's, not the object's.
  const auto create_at = [&](const std::string& id, const Move& m) {
    grpc::ClientContext ctx;
    api.prepare(&ctx);
    v1::CreateSceneRequest req;
    req.set_scene_id(id);
    *req.mutable_description() = small_mesh_scene();
    v1::ScenePositions* p = req.mutable_positions();
    p->set_t(1.0);
    to_proto(m, p->add_moves());
    v1::SceneInfo created;
    return api.stub().CreateScene(&ctx, req, &created);
  };
  s = create_at("far", Move{3, Vec3(1e12, 6, 6)});
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << show(s);
  EXPECT_THAT(s.error_message(), ::testing::StartsWith("positions.moves[0].center: places the mesh beyond 1e+12"));
  s = create_at("near", Move{3, Vec3(1e12 - 10, 6, 6), true, Quat(0, 0, 0, 1)});
  EXPECT_TRUE(s.ok()) << show(s);
  EXPECT_EQ(server.terminate(), 0);
}

}  // namespace
}  // namespace voxvis::servertest
