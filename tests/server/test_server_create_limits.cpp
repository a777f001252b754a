// What a create may cost the server: a refused one is cheap and holds no
// other client's create, and an accepted one keeps within the memory budget
// while it builds (docs/server.md, "Memory budget").
#include <chrono>
#include <cmath>
#include <future>
#include <thread>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "scenes.h"
#include "server_process.h"

namespace voxvis::servertest {
namespace {

using ::testing::HasSubstr;

/// CreateScene with its own deadline.
grpc::Status create(const Api& api, const std::string& id, const v1::SceneDescription& d, Seconds timeout) {
  grpc::ClientContext ctx;
  api.prepare(&ctx, timeout);
  v1::CreateSceneRequest req;
  req.set_scene_id(id);
  *req.mutable_description() = d;
  v1::SceneInfo info;
  return api.stub().CreateScene(&ctx, req, &info);
}

/// A 5,000-triangle mesh placed `copies` times: a small message whose
/// saved file (each placement writing the mesh inline) is huge.
v1::SceneDescription instanced(int copies) {
  v1::SceneDescription d;
  d.mutable_bounds_min()->set_x(0);
  d.mutable_bounds_min()->set_y(0);
  d.mutable_bounds_min()->set_z(0);
  d.mutable_bounds_max()->set_x(1000);
  d.mutable_bounds_max()->set_y(1000);
  d.mutable_bounds_max()->set_z(1000);
  v1::Mesh* m = d.add_meshes();
  for (int i = 0; i < 2600; ++i) {
    m->add_vertices(3.0 * std::cos(i));
    m->add_vertices(3.0 * std::sin(i));
    m->add_vertices(0.1 * (i % 50));
  }
  for (int i = 0; i < 5000; ++i) {
    m->add_triangles(static_cast<std::uint32_t>(i % 2600));
    m->add_triangles(static_cast<std::uint32_t>((i + 1) % 2600));
    m->add_triangles(static_cast<std::uint32_t>((i + 7) % 2600));
  }
  for (int i = 0; i < copies; ++i) {
    v1::Object* o = d.add_objects();
    o->set_id(static_cast<std::uint32_t>(i));
    v1::MeshInstance* p = o->mutable_mesh();
    p->mutable_center()->set_x(5.0 + (i % 100) * 9.9);
    p->mutable_center()->set_y(5.0 + (i / 100 % 100) * 9.9);
    p->mutable_center()->set_z(500.0 + (i / 10000) * 9.9);
  }
  return d;
}

// Before: a 3.8 MB description placing one 5,000-triangle mesh 100,000
// times was validated vertex by vertex for every placement (about a minute
// of CPU) before its saved file (13 GB) was found too large; the client's
// 5 s deadline passed long before, and every other create waited behind it.
TEST(CreateLimits, ARefusedInstancingCreateIsCheapAndHoldsNoOtherCreate) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  const v1::SceneDescription big = instanced(100000);
  ASSERT_GT(big.ByteSizeLong(), std::size_t{3'000'000});
  const auto start = std::chrono::steady_clock::now();
  std::future<grpc::Status> refused =
      std::async(std::launch::async, [&] { return create(api, "big", big, Seconds(60)); });
  // Another client's tiny create, sent while the big one is being looked at.
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const Api other = server.api();
  const grpc::Status tiny = other.create_scene_json("tiny", wall_scene_json());
  const double tiny_done = Seconds(std::chrono::steady_clock::now() - start).count();
  const grpc::Status s = refused.get();
  const double refused_done = Seconds(std::chrono::steady_clock::now() - start).count();
  EXPECT_TRUE(tiny.ok()) << show(tiny);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << show(s);
  EXPECT_THAT(s.error_message(), HasSubstr("each of its 100000 mesh objects writes inline"));
  // Seconds, not the minute it took: generous bounds for sanitizer builds
  // on a loaded machine (measured: docs/performance.md).
  EXPECT_LT(refused_done, 20.0);
  EXPECT_LT(tiny_done, 20.0);
  EXPECT_EQ(server.terminate(), 0);
}

}  // namespace
}  // namespace voxvis::servertest
