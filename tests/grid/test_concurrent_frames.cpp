// Frames of different viewers of one scene run in parallel (Scene::frame
// traverses under a shared lock and defers the TBVs it reaches). Each round
// here moves the objects, then computes every viewer's frame on its own
// thread at once; every result must still contain every visible object.
// A second test runs moves concurrently with frames, for the sanitizers; a
// third shows that the grid lock lets a waiting writer in before new readers.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <future>
#include <mutex>
#include <shared_mutex>
#include <thread>
#include <vector>

#include "engine_check.h"
#include "scene_impl.h"
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

TEST(ConcurrentFrames, AFrameDoesNotWaitForAnotherTraversal) {
  // Frames change the grid (reveals, new TBVs) only under the scene's lock
  // held exclusive, which waits for every traversal in progress; they queue
  // those changes instead, so a frame with nothing due runs beside another
  // viewer's traversal. Here the test holds the lock shared, as a traversal
  // does, while a frame turns round and reveals TBVs behind a wall.
  SceneDesc desc;
  desc.bounds_max = Vec3(32.0);
  desc.grid = glm::ivec3(32);
  desc.objects.push_back(test::box_between(1, Vec3(10.0, 0.0, 0.0), Vec3(12.0, 32.0, 32.0)));
  std::vector<ObjectDesc> hidden;
  for (int i = 0; i < 4; ++i)
    hidden.push_back(test::dynamic(test::sphere(static_cast<ObjectId>(2 + i), Vec3(20.5, 12.5 + 2.5 * i, 16.5), 0.4), 1.0));
  desc.objects.insert(desc.objects.end(), hidden.begin(), hidden.end());
  SceneOptions opt;
  opt.tbv_period = 1000.0;  // Nothing expires in this test.
  std::unique_ptr<Scene> scene;
  ASSERT_TRUE(Scene::create(desc, opt, &scene));
  Scene::Impl& s = scene->impl();
  const ViewerId front = scene->add_viewer(), back = scene->add_viewer();
  Scratch scratch;
  const Camera cam = test::camera_along(Vec3(3.3, 16.2, 16.1), Vec3(1.0, 0.0, 0.0), 70.0, 1.0, 0.05, 100.0);
  // Both viewers in front of the wall: every sphere is hidden, unclaimed,
  // and put under a TBV by the frames (nothing holds the lock yet).
  FrameResult r;
  ASSERT_TRUE(scene->frame(front, cam, 0.0, scratch, &r));
  ASSERT_TRUE(scene->frame(back, cam, 0.0, scratch, &r));
  EXPECT_TRUE(r.pvs == std::vector<ObjectId>{1});
  EXPECT_TRUE(scene->wake_set().empty());
  for (std::uint32_t slot = 1; slot < 5; ++slot) ASSERT_TRUE(s.objs[slot].under_tbv);
  const std::uint64_t epoch = scene->wake_epoch();

  // A traversal in progress (the lock held shared): the back viewer turns
  // round behind the wall, reaches the TBVs, and its frame still completes.
  Camera behind = cam;
  behind.eye = Vec3(30.2, 16.2, 16.1);
  behind.dir = Vec3(-1.0, 0.0, 0.0);
  std::shared_lock<detail::GridMutex> traversal(s.mu);
  auto done = std::async(std::launch::async, [&] {
    Scratch own;
    FrameResult out;
    const Status st = scene->frame(back, behind, 1.0, own, &out);
    return std::make_pair(st, out);
  });
  const bool finished = done.wait_for(std::chrono::seconds(20)) == std::future_status::ready;
  if (!finished) traversal.unlock();  // Let it end rather than hang.
  ASSERT_TRUE(finished) << "a frame waited for another viewer's traversal";
  const auto [st, out] = done.get();
  ASSERT_TRUE(st) << st.str();
  // The TBVs it reached put their objects in the PVS and on the wake list
  // at once, and the wake set says so, though the grid still holds the TBVs
  // until the lock is free.
  std::vector<ObjectId> spheres{2, 3, 4, 5};
  for (ObjectId id : spheres) {
    EXPECT_TRUE(std::binary_search(out.pvs.begin(), out.pvs.end(), id)) << id;
    EXPECT_TRUE(std::binary_search(out.wake.begin(), out.wake.end(), id)) << id;
  }
  EXPECT_EQ(out.stats.tbvs_revealed, 4u);
  EXPECT_NE(scene->wake_epoch(), epoch);
  EXPECT_TRUE(scene->wake_set() == spheres);
  {
    std::lock_guard<std::mutex> book(s.book);
    EXPECT_EQ(s.queued_reveals.size(), 4u);
    for (std::uint32_t slot = 1; slot < 5; ++slot) EXPECT_TRUE(s.objs[slot].under_tbv);
  }
  traversal.unlock();

  // The next frame applies the queue: the spheres are in the grid again,
  // claimed by the back viewer, and it sees them through their voxels.
  ASSERT_TRUE(scene->frame(back, behind, 2.0, scratch, &r));
  {
    std::lock_guard<std::mutex> book(s.book);
    EXPECT_TRUE(s.queued_reveals.empty());
    for (std::uint32_t slot = 1; slot < 5; ++slot) EXPECT_FALSE(s.objs[slot].under_tbv);
  }
  EXPECT_EQ(r.stats.tbvs_revealed, 0u);
  EXPECT_EQ(r.stats.tbvs_created, 0u);
  for (ObjectId id : spheres) EXPECT_TRUE(std::binary_search(r.pvs.begin(), r.pvs.end(), id)) << id;
  EXPECT_TRUE(scene->wake_set() == spheres);
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

TEST(ConcurrentFrames, AWriterIsNotStarvedByOverlappingReaders) {
  // Three "traversals" hold the grid lock shared in turns that overlap, so
  // that at every moment one of them holds it, as busy viewers' frames do.
  // A move batch (the lock exclusive) must still get in: with a lock that
  // lets new readers overtake a waiting writer it would wait until the
  // readers stop, which this test does only after 10 s, as a failure.
  detail::GridMutex mu;
  std::atomic<bool> stop{false};
  const auto reader = [&](int phase) {
    std::this_thread::sleep_for(std::chrono::milliseconds(phase));
    while (!stop.load()) {
      std::shared_lock<detail::GridMutex> hold(mu);
      std::this_thread::sleep_for(std::chrono::milliseconds(4));
    }
  };
  std::thread a(reader, 0), b(reader, 1), c(reader, 2);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  std::promise<void> got;
  std::future<void> got_future = got.get_future();
  std::thread writer([&] {
    std::unique_lock<detail::GridMutex> lock(mu);
    got.set_value();
  });
  const bool in_time = got_future.wait_for(std::chrono::seconds(10)) == std::future_status::ready;
  stop.store(true);
  writer.join();
  a.join();
  b.join();
  c.join();
  EXPECT_TRUE(in_time) << "the exclusive locker waited for 10 s behind overlapping shared holders";
}

}  // namespace
}  // namespace voxvis
