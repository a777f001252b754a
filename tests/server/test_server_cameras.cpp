// Extreme cameras over the wire: every camera the engine accepts is answered
// by GetPvs and by a View stream exactly as the engine answers it in process
// (the engine's own property test, tests/grid/test_extreme_cameras.cpp,
// checks those answers against the ray caster); cameras beyond the bounds
// are refused with the field named; nothing takes the server down.
//
// Before: one GetPvs or View frame with fov_y_deg = 5e-324 aborted the whole
// process (std::length_error escaping a worker).
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "extreme_cameras.h"
#include "scenes.h"
#include "server_process.h"
#include "voxvis/format.h"

namespace voxvis::servertest {
namespace {

using ::testing::HasSubstr;
using test::kDenormal;

/// Static (so that answers do not depend on the order of frames), with
/// occluders, walls thinner than a voxel and objects outside the bounds.
SceneDesc camera_scene() {
  test::RandomSceneParams p;
  p.grid = glm::ivec3(20, 12, 20);
  p.spheres = 40;
  p.boxes = 25;
  p.occluders = 6;
  p.walls = 6;
  p.dynamic_fraction = 0.0;
  SceneDesc d = test::random_scene(p, 0xca3e);
  d.grid = p.grid;
  return d;
}

/// The camera as a frames-file line, to replay a failure with `voxvis replay`.
std::string text(const Camera& c) {
  FrameInput f;
  f.camera = c;
  return frame_to_json(f);
}

TEST(Cameras, ExtremeCamerasAreAnsweredOverTheWireAsTheEngineAnswersThem) {
  for (const char* width : {"0", "128"}) {
    ServerProcess server({"--occlusion-buffer", width});
    ASSERT_TRUE(server.start());
    const Api api = server.api();
    const SceneDesc scene = camera_scene();
    v1::SceneDescription d;
    to_proto(scene, &d);
    ASSERT_TRUE(api.create_scene("s", d).ok());
    SceneOptions opt;
    opt.occlusion_buffer = std::stoi(width);
    std::unique_ptr<Scene> engine;
    ASSERT_TRUE(Scene::create(scene, opt, &engine).ok);
    Scratch scratch;
    const ViewerId in_process_viewer = engine->add_viewer();
    ViewStream view(api, "s");
    Rng rng(0x3e7e);
    int seen = 0;  // Frames that see something: the comparison is not of empty sets only.
    const int n = std::max(10, static_cast<int>(40 * test::test_scale()));
    for (int i = 0; i < n; ++i) {
      const Camera cam = test::extreme_camera(rng, scene);
      const std::string label = std::string("buffer ") + width + ", camera " + std::to_string(i) + ": " + text(cam);
      FrameResult expected;
      {
        const ViewerId v = engine->add_viewer();
        ASSERT_TRUE(engine->frame(v, cam, 0.0, scratch, &expected).ok) << label;
        engine->remove_viewer(v);
      }
      v1::GetPvsResponse r;
      const grpc::Status s = api.get_pvs("s", 0.0, cam, &r);
      ASSERT_TRUE(s.ok()) << label << ": " << show(s);
      EXPECT_EQ(ids_of(r.pvs()), expected.pvs) << label;
      seen += !expected.pvs.empty();
      FrameResult streamed;
      ASSERT_TRUE(engine->frame(in_process_viewer, cam, 0.0, scratch, &streamed).ok) << label;
      v1::ViewResponse vr;
      ASSERT_TRUE(view.frame(static_cast<std::uint64_t>(i + 1), 0.0, cam, &vr)) << label;
      EXPECT_EQ(ids_of(vr.pvs()), streamed.pvs) << label;
    }
    EXPECT_TRUE(view.finish().ok());
    EXPECT_GT(seen, n / 4);
    EXPECT_EQ(server.terminate(), 0) << server.log();
  }
}

TEST(Cameras, CamerasBeyondTheBoundsAreRefusedNamingTheFieldAndNothingElseStops) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  ASSERT_TRUE(api.create_scene_json("w", wall_scene_json()).ok());
  struct Bad {
    Camera camera;
    std::string field;
  };
  std::vector<Bad> bad;
  for (double fov : {kDenormal, 1e-322, 1e-300, 1e-7, 0.0, -0.0, 180.0}) {
    Camera c = wall_camera();
    c.fov_y_deg = fov;
    bad.push_back({c, "camera.fov_y_deg"});
  }
  for (double aspect : {1e-300, 1e-4, 1e4, 1e300}) {
    Camera c = wall_camera();
    c.aspect = aspect;
    bad.push_back({c, "camera.aspect"});
  }
  {
    Camera c = wall_camera();
    c.eye = Vec3(1e13, 0, 0);
    bad.push_back({c, "camera.eye"});
  }
  // A viewer beside the refused ones keeps its stream.
  ViewStream keeps(api, "w");
  v1::ViewResponse kr;
  std::uint64_t frame = 0;
  ASSERT_TRUE(keeps.frame(++frame, 0.0, wall_camera(), &kr));
  for (const Bad& b : bad) {
    v1::GetPvsResponse r;
    const grpc::Status s = api.get_pvs("w", 0.0, b.camera, &r);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << text(b.camera) << ": " << show(s);
    EXPECT_THAT(s.error_message(), HasSubstr(b.field)) << text(b.camera);
    ViewStream view(api, "w");
    v1::ViewResponse vr;
    EXPECT_FALSE(view.frame(1, 0.0, b.camera, &vr));
    const grpc::Status vs = view.finish();
    EXPECT_EQ(vs.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << text(b.camera) << ": " << show(vs);
    EXPECT_THAT(vs.error_message(), HasSubstr(b.field)) << text(b.camera);
    ASSERT_TRUE(keeps.frame(++frame, 0.0, wall_camera(), &kr)) << "after " << text(b.camera);
    EXPECT_EQ(ids_of(kr.pvs()), (std::vector<ObjectId>{1, 3}));
  }
  EXPECT_TRUE(keeps.finish().ok());
  EXPECT_TRUE(server.running());
  EXPECT_EQ(server.terminate(), 0);
}

}  // namespace
}  // namespace voxvis::servertest
