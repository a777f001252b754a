// Scene builds against careless and hostile admins: a scene's cost is counted
// from its objects' footprints before anything is built, a build runs on its
// own thread (viewers of other scenes keep their answers), and a build whose
// client has gone or whose deadline has passed stops.
//
// Before: the budget counted the grid only (1,000 spheres each covering the
// whole grid were estimated at 8 MB and took 1.3 GB); a create of 100,000
// such spheres never finished, kept a core busy long after its client's
// deadline, and two of them left another scene's viewer unanswered for 39 s.
#include <algorithm>
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

namespace voxvis::servertest {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using Clock = std::chrono::steady_clock;

v1::SceneDescription huge_spheres(int count) {
  v1::SceneDescription out;
  to_proto(huge_footprint_scene(count), &out);
  return out;
}

// The figure that refuses is the objects' footprints, not the grid: the
// grid alone fits the budget many times over.
TEST(Builds, FootprintsCountInTheMemoryBudget) {
  ServerProcess server({"--memory-budget-mib", "24"});
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  const auto t0 = Clock::now();
  const grpc::Status s = api.create_scene("spheres", huge_spheres(1000));
  const double seconds = Seconds(Clock::now() - t0).count();
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << show(s);
  EXPECT_THAT(s.error_message(), HasSubstr("id-list entries"));
  EXPECT_THAT(s.error_message(), HasSubstr("memory budget 24 MiB"));
  std::printf("1,000 grid-covering spheres under a 24 MiB budget: refused in %.2f s: %s\n", seconds,
              s.error_message().c_str());
  // The same grid with few objects fits.
  const grpc::Status few = api.create_scene("few", huge_spheres(3));
  EXPECT_TRUE(few.ok()) << show(few);
  EXPECT_EQ(server.terminate(), 0);
}

// A build whose deadline passes stops: the client hears DEADLINE_EXCEEDED,
// the server's CPU goes quiet, nothing is left registered or reserved.
TEST(Builds, ABuildStopsWhenItsDeadlinePasses) {
  ServerProcess server({"--metrics", "127.0.0.1:0"});
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  const v1::SceneDescription big = huge_spheres(100000);
  const grpc::Status s = create_with_deadline(api, "big", big, Seconds(1.5));
  EXPECT_EQ(s.error_code(), grpc::StatusCode::DEADLINE_EXCEEDED) << show(s);
  // The build polls its control every few milliseconds of work.
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  const double cpu0 = server.cpu_seconds();
  std::this_thread::sleep_for(std::chrono::seconds(2));
  const double cpu = server.cpu_seconds() - cpu0;
  std::printf("server CPU in the 2 s after the deadline: %.2f s\n", cpu);
  EXPECT_LT(cpu, 0.5) << "the build went on after its client's deadline";
  // The build's worker runs at a lower priority: on a busy machine its log
  // line may come a little after the work stopped.
  EXPECT_TRUE(wait_until([&] { return server.log().find("build of scene 'big' stopped") != std::string::npos; },
                         Seconds(20)))
      << server.log();
  v1::SceneInfo info;
  EXPECT_EQ(api.stats("big", &info).error_code(), grpc::StatusCode::NOT_FOUND);
  // The id and the bytes it had reserved are free again.
  const grpc::Status again = api.create_scene("big", huge_spheres(3));
  EXPECT_TRUE(again.ok()) << show(again);
  EXPECT_EQ(server.terminate(), 0);
}

// Two long builds at once: a viewer of another scene keeps its answers.
TEST(Builds, LongBuildsDoNotDelayViewersOfOtherScenes) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  ASSERT_TRUE(api.create_scene_json("w", wall_scene_json()).ok());
  std::vector<std::thread> builders;
  std::atomic<int> builds_done{0};
  for (int i = 0; i < 2; ++i) {
    builders.emplace_back([&, i] {
      const Api admin = server.api();
      create_with_deadline(admin, "big" + std::to_string(i), huge_spheres(100000), Seconds(6));
      builds_done.fetch_add(1);
    });
  }
  // Let both builds start before the viewer measures.
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const Api viewer = server.api();
  double worst = 0.0;
  int frames = 0;
  auto last = Clock::now();
  const auto end = last + std::chrono::seconds(4);
  while (Clock::now() < end) {
    v1::GetPvsResponse r;
    const grpc::Status st = viewer.get_pvs("w", 0.0, wall_camera(), &r);
    const auto now = Clock::now();
    if (!st.ok()) {
      ADD_FAILURE() << "the viewer's frame: " << show(st);  // The builders are still joined.
      worst = std::max(worst, Seconds(now - last).count());
      break;
    }
    worst = std::max(worst, Seconds(now - last).count());
    last = now;
    ++frames;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  for (auto& t : builders) t.join();
  EXPECT_EQ(builds_done.load(), 2);
  std::printf("viewer beside two 100,000-sphere builds: %d frames in 4 s, worst gap %.3f s\n", frames, worst);
  // A liveness bound, not a timing target (the figure is printed above and
  // in docs/server.md): before, the viewer got no answer within 30 s.
  EXPECT_LT(worst, 5.0);
}

// An exception in a frame or a move batch (here injected) is answered
// INTERNAL for that call and counted; the server and other scenes go on.
TEST(Faults, AFrameThatThrowsIsAnsweredInternalAndTheServerGoesOn) {
  ServerProcess server({"--metrics", "127.0.0.1:0"});
  server.extra_env() = {"VOXVIS_TEST_FAIL_SCENE=boom"};
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  ASSERT_TRUE(api.create_scene_json("boom", wall_scene_json()).ok());
  ASSERT_TRUE(api.create_scene_json("ok", wall_scene_json()).ok());
  for (int i = 0; i < 3; ++i) {
    v1::GetPvsResponse r;
    const grpc::Status s = api.get_pvs("boom", 0.0, wall_camera(), &r);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INTERNAL) << show(s);
    EXPECT_THAT(s.error_message(), HasSubstr("internal error in the frame"));
  }
  {
    ViewStream view(api, "boom");
    v1::ViewResponse r;
    EXPECT_FALSE(view.frame(1, 0.0, wall_camera(), &r));
    const grpc::Status s = view.finish();
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INTERNAL) << show(s);
  }
  {
    SimStream sim(api, "boom");
    v1::MoveAck ack;
    EXPECT_FALSE(sim.move(1, 0.1, {Move{2, Vec3(10, 10, 15.1)}}, &ack));
    const grpc::Status s = sim.finish();
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INTERNAL) << show(s);
    EXPECT_THAT(s.error_message(), HasSubstr("internal error in the move batch"));
  }
  // Everything else is served as before.
  v1::GetPvsResponse r;
  ASSERT_TRUE(api.get_pvs("ok", 0.0, wall_camera(), &r).ok());
  EXPECT_EQ(ids_of(r.pvs()), (std::vector<ObjectId>{1, 3}));
  EXPECT_TRUE(server.running());
  ASSERT_GT(server.metrics_port(), 0) << server.log();
  const std::string text = http_get(server.metrics_port(), "/metrics");
  EXPECT_THAT(text, HasSubstr("voxvis_errors_total{code=\"INTERNAL\",method=\"GetPvs\"} 3"));
  EXPECT_THAT(text, HasSubstr("voxvis_errors_total{code=\"INTERNAL\",method=\"View\"} 1"));
  EXPECT_THAT(text, HasSubstr("voxvis_errors_total{code=\"INTERNAL\",method=\"Simulate\"} 1"));
  EXPECT_THAT(server.log(), HasSubstr("internal error in a frame of scene 'boom'"));
  EXPECT_EQ(server.terminate(), 0);
}

// A build that throws after its grid is built: the call ends INTERNAL, and
// the id, the budget and the data directory are as if it never ran.
TEST(Faults, ABuildThatThrowsGivesItsIdAndBudgetBack) {
  ServerProcess server({"--memory-budget-mib", "64"});
  server.extra_env() = {"VOXVIS_TEST_FAIL_BUILD=boom"};
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  // Each build reserves most of the budget: one leaked reservation would
  // refuse the next.
  v1::SceneDescription d;
  to_proto(lattice_scene(200, 160, 3), &d);
  for (int i = 0; i < 3; ++i) {
    const grpc::Status s = api.create_scene("boom", d);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INTERNAL) << show(s);
    EXPECT_THAT(s.error_message(), HasSubstr("internal error creating the scene"));
  }
  std::vector<std::string> ids;
  ASSERT_TRUE(api.list_scenes(&ids).ok());
  EXPECT_TRUE(ids.empty());
  EXPECT_FALSE(std::filesystem::exists(server.data_dir() + "/scenes/boom.json"));
  v1::SceneInfo info;
  const grpc::Status ok = api.create_scene("fine", d, &info);
  EXPECT_TRUE(ok.ok()) << show(ok);
  EXPECT_GT(info.memory_bytes(), 32u << 20) << "the scene must need more than half the budget";
  EXPECT_TRUE(server.running());
  EXPECT_EQ(server.terminate(), 0);
}

}  // namespace
}  // namespace voxvis::servertest
