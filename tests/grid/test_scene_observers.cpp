// The Scene observers the server relies on: wake_epoch() must change whenever
// wake_set() changes (the server recomputes and sends wake lists only then),
// and dynamic_centers() must report the positions the engine uses (the server
// saves them and restores them after a restart).
#include <gtest/gtest.h>

#include <algorithm>
#include <map>

#include "scenes.h"
#include "voxvis/scene.h"

namespace voxvis {
namespace {

TEST(SceneObservers, WakeEpochChangesWheneverWakeSetChanges) {
  int changes = 0;
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(test::scaled(8)); ++seed) {
    test::RandomSceneParams params = test::random_scene_params(seed);
    params.dynamic_fraction = 0.6;
    const SceneDesc desc = test::random_scene(params, seed);
    std::unique_ptr<Scene> scene;
    ASSERT_TRUE(Scene::create(desc, SceneOptions{}, &scene)) << test::describe_scene(desc, seed);
    const ViewerId a = scene->add_viewer();
    const ViewerId b = scene->add_viewer();
    test::Mover mover(desc, test::mix_seed(seed, 1));
    const std::vector<Camera> path = test::random_camera_path(desc, test::mix_seed(seed, 2));
    Scratch scratch;
    std::vector<ObjectId> last = scene->wake_set();
    std::uint64_t last_epoch = scene->wake_epoch();
    double t = 0.0;
    for (std::size_t i = 0; i < path.size(); ++i) {
      t += 0.25;
      // Checked after the moves (which only reveal) and after the frame
      // (which also creates TBVs), so that neither hides the other.
      const auto check = [&](const char* after) {
        const std::vector<ObjectId> now = scene->wake_set();
        if (now != last) {
          ++changes;
          EXPECT_NE(scene->wake_epoch(), last_epoch)
              << "wake set changed without an epoch change after the " << after << " of step "
              << i << ", " << test::describe_scene(desc, seed);
        }
        last = now;
        last_epoch = scene->wake_epoch();
      };
      ASSERT_TRUE(scene->apply_moves(t, mover.step(0.25)));
      check("moves");
      FrameResult r;
      ASSERT_TRUE(scene->frame(i % 3 == 2 ? b : a, path[i], t, scratch, &r));
      check("frame");
    }
  }
  // The scenes must exercise the property: TBVs come and go.
  EXPECT_GT(changes, 0);
}

TEST(SceneObservers, DynamicCentersAreTheMovedPositionsInIdOrder) {
  SceneDesc desc;
  desc.bounds_max = Vec3(10.0);
  desc.objects = {test::dynamic(test::sphere(9, Vec3(1.0), 0.5), 1.0),
                  test::sphere(4, Vec3(5.0), 0.5),
                  test::dynamic(test::box_around(2, Vec3(3.0), Vec3(0.5)), 1.0)};
  std::unique_ptr<Scene> scene;
  ASSERT_TRUE(Scene::create(desc, SceneOptions{}, &scene));
  std::vector<Move> c = scene->dynamic_centers();
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c[0].id, 2u);
  EXPECT_EQ(c[0].center, Vec3(3.0));
  EXPECT_EQ(c[1].id, 9u);
  EXPECT_EQ(c[1].center, Vec3(1.0));

  const std::vector<Move> moves = {{9, Vec3(1.5, 1.0, 1.0)}};
  ASSERT_TRUE(scene->apply_moves(1.0, moves));
  c = scene->dynamic_centers();
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c[1].id, 9u);
  EXPECT_EQ(c[1].center, Vec3(1.5, 1.0, 1.0));
  EXPECT_EQ(c[0].center, Vec3(3.0));
}

TEST(SceneObservers, PositionsEpochTellsWhetherAFrameSawTheCurrentPositions) {
  // A frame records the move epoch it ran under; dynamic_centers reports the
  // current one: equal exactly when no batch of moves landed in between.
  SceneDesc desc;
  desc.bounds_max = Vec3(10.0);
  desc.objects = {test::dynamic(test::sphere(9, Vec3(1.0), 0.5), 1.0), test::sphere(4, Vec3(5.0), 0.5)};
  std::unique_ptr<Scene> scene;
  ASSERT_TRUE(Scene::create(desc, SceneOptions{}, &scene));
  const ViewerId v = scene->add_viewer();
  Scratch scratch;
  FrameResult r;
  const Camera cam = test::camera_along(Vec3(5.0, 5.0, 9.5), Vec3(0.0, 0.0, -1.0));
  ASSERT_TRUE(scene->frame(v, cam, 0.5, scratch, &r));
  std::uint64_t epoch = 0;
  scene->dynamic_centers(nullptr, &epoch);
  EXPECT_EQ(epoch, r.positions_epoch);
  ASSERT_TRUE(scene->apply_moves(1.0, std::vector<Move>{{9, Vec3(1.2, 1.0, 1.0)}}));
  scene->dynamic_centers(nullptr, &epoch);
  EXPECT_NE(epoch, r.positions_epoch) << "a batch of moves landed after the frame";
  const std::uint64_t after_moves = epoch;
  ASSERT_TRUE(scene->apply_moves(1.5, std::vector<Move>{}));  // Only the clock: nobody moved.
  scene->dynamic_centers(nullptr, &epoch);
  EXPECT_EQ(epoch, after_moves);
  ASSERT_TRUE(scene->frame(v, cam, 1.5, scratch, &r));
  EXPECT_EQ(r.positions_epoch, epoch);
}

}  // namespace
}  // namespace voxvis
