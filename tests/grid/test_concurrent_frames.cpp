// Frames of different viewers of one scene run in parallel (Scene::frame
// traverses under a shared lock and defers the TBVs it reaches). Each round
// here moves the objects, then computes every viewer's frame on its own
// thread at once; every result must still contain every visible object.
// A second test runs moves concurrently with frames, for the sanitizers.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <thread>
#include <vector>

#include "engine_check.h"
#include "scenes.h"
#include "voxvis/scene.h"

namespace voxvis {
namespace {

TEST(ConcurrentFrames, ParallelViewersStayConservative) {
  constexpr int kViewers = 4;
  const int scenes = test::scaled(6);
  int tbv_events = 0;
  for (int k = 0; k < scenes; ++k) {
    const std::uint64_t seed = 9100 + static_cast<std::uint64_t>(k);
    test::RandomSceneParams params = test::random_scene_params(seed);
    params.dynamic_fraction = 0.5;
    const SceneDesc desc = test::random_scene(params, seed);
    const std::string label = test::describe_scene(desc, seed);
    std::unique_ptr<Scene> scene;
    ASSERT_TRUE(Scene::create(desc, SceneOptions{}, &scene)) << label;
    std::vector<ViewerId> viewers;
    std::vector<std::vector<Camera>> paths;
    for (int v = 0; v < kViewers; ++v) {
      viewers.push_back(scene->add_viewer());
      paths.push_back(test::random_camera_path(desc, test::mix_seed(seed, 10 + v)));
    }
    test::Mover mover(desc, test::mix_seed(seed, 1));
    std::vector<ObjectDesc> objects = desc.objects;
    std::vector<Scratch> scratch(kViewers);
    test::RaySampling sampling;
    sampling.cols = sampling.rows = 48;
    double t = 0.0;
    for (std::size_t round = 0; round < paths[0].size(); ++round) {
      t += 0.2;
      const std::vector<Move> moves = mover.step(0.2);
      ASSERT_TRUE(scene->apply_moves(t, moves));
      test::apply_moves_to(&objects, moves);
      std::vector<FrameResult> results(kViewers);
      std::vector<Status> status(kViewers);
      std::vector<std::thread> threads;
      for (int v = 0; v < kViewers; ++v)
        threads.emplace_back([&, v] {
          status[v] = scene->frame(viewers[v], paths[v][round], t, scratch[v], &results[v]);
        });
      for (std::thread& th : threads) th.join();
      for (int v = 0; v < kViewers; ++v) {
        ASSERT_TRUE(status[v]) << status[v].str();
        tbv_events += static_cast<int>(results[v].stats.tbvs_created + results[v].stats.tbvs_revealed);
        const std::string err = test::check_frame(label + " viewer " + std::to_string(v),
                                                  static_cast<int>(round), objects,
                                                  paths[v][round], results[v], sampling);
        ASSERT_EQ(err, "");
      }
    }
  }
  EXPECT_GT(tbv_events, 0);  // The rounds exercise TBVs, not only static culling.
}

TEST(ConcurrentFrames, MovesAndViewerChangesDuringFrames) {
  const std::uint64_t seed = 9200;
  test::RandomSceneParams params = test::random_scene_params(seed);
  params.dynamic_fraction = 0.6;
  const SceneDesc desc = test::random_scene(params, seed);
  std::unique_ptr<Scene> scene;
  ASSERT_TRUE(Scene::create(desc, SceneOptions{}, &scene));
  std::atomic<double> clock{0.0};
  std::atomic<bool> stop{false};
  std::atomic<int> frames{0};
  const auto viewer_loop = [&](std::uint64_t s) {
    Scratch scratch;
    const ViewerId v = scene->add_viewer();
    const std::vector<Camera> path = test::random_camera_path(desc, s);
    for (std::size_t i = 0; !stop.load(); i = (i + 1) % path.size()) {
      FrameResult r;
      // Other threads move the clock on between reading it and the frame:
      // Clock::Latest takes the scene's time then, atomically.
      const double asked = clock.load();
      const Status st = scene->frame(v, path[i], asked, scratch, &r, Scene::Clock::Latest);
      ASSERT_TRUE(st) << st.str();
      EXPECT_GE(r.t, asked);
      // (check_stats assumes one move batch per frame; here many land
      // between a viewer's frames, so only the result's shape is checked.)
      EXPECT_TRUE(std::is_sorted(r.pvs.begin(), r.pvs.end()));
      EXPECT_TRUE(std::adjacent_find(r.pvs.begin(), r.pvs.end()) == r.pvs.end());
      EXPECT_EQ(r.stats.pvs_size, r.pvs.size());
      EXPECT_TRUE(std::isfinite(r.stats.time_us));
      frames.fetch_add(1);
    }
    scene->remove_viewer(v);
  };
  std::vector<std::thread> threads;
  for (int v = 0; v < 3; ++v) threads.emplace_back(viewer_loop, test::mix_seed(seed, v));
  test::Mover mover(desc, test::mix_seed(seed, 99));
  double t = 0.0;
  for (int step = 0; step < test::scaled(200); ++step) {
    t += 0.05;
    clock.store(t);
    MoveReport report;
    ASSERT_TRUE(scene->apply_moves(t, mover.step(0.05), &report, Scene::Clock::Latest));
    EXPECT_GE(report.t, t);
    if (step % 20 == 0) scene->remove_viewer(scene->add_viewer());
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  stop.store(true);
  for (std::thread& th : threads) th.join();
  EXPECT_GT(frames.load(), 0);
  // With every viewer gone, every dynamic object ends up unclaimed: one more
  // viewer's frame looking nowhere near puts them under TBVs eventually, and
  // nothing is left claimed by the departed viewers.
  const std::vector<ObjectId> wake = scene->wake_set();
  EXPECT_LE(wake.size(), scene->dynamic_count());
}

TEST(SceneClock, StrictRefusesAndLatestTakesTheSceneTime) {
  SceneDesc desc;
  desc.bounds_max = Vec3(10.0);
  desc.objects = {test::dynamic(test::sphere(1, Vec3(5.0), 0.5), 1.0)};
  std::unique_ptr<Scene> scene;
  ASSERT_TRUE(Scene::create(desc, SceneOptions{}, &scene));
  const ViewerId v = scene->add_viewer();
  Scratch scratch;
  Camera cam;
  cam.eye = Vec3(5.0, 5.0, 9.5);
  FrameResult r;
  ASSERT_TRUE(scene->frame(v, cam, 2.0, scratch, &r));
  EXPECT_EQ(r.t, 2.0);
  EXPECT_EQ(scene->frame(v, cam, 1.0, scratch, &r).field, "t");
  ASSERT_TRUE(scene->frame(v, cam, 1.0, scratch, &r, Scene::Clock::Latest));
  EXPECT_EQ(r.t, 2.0);
  const std::vector<Move> moves = {{1, Vec3(5.0, 5.0, 5.5)}};
  EXPECT_EQ(scene->apply_moves(1.5, moves).field, "t");
  MoveReport report;
  ASSERT_TRUE(scene->apply_moves(1.5, moves, &report, Scene::Clock::Latest));
  EXPECT_EQ(report.t, 2.0);
  EXPECT_EQ(report.applied, 1u);
  ASSERT_TRUE(scene->apply_moves(3.0, moves, &report, Scene::Clock::Latest));
  EXPECT_EQ(report.t, 3.0);
  EXPECT_EQ(scene->time(), 3.0);
}

}  // namespace
}  // namespace voxvis
