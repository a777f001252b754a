// The engine's time model: scene times are finite seconds within
// ±kMaxSceneTime, refused with the field named outside it (before anything
// changes), and TBV renewals always move forward in time, so no frame can spin
// on renewals that round back to the frame's own time.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <vector>

#include "scenes.h"
#include "voxvis/scene.h"

namespace voxvis::test {
namespace {

Camera looking_at_wall() {
  Camera c;
  c.eye = Vec3(10, 10, 1);
  c.dir = Vec3(0, 0, 1);
  c.fov_y_deg = 60.0;
  c.near = 0.05;
  c.far = 100.0;
  return c;
}

/// A 20-unit cube of 1-unit voxels, a wall across it at z in [8.5, 11.5], and
/// `hidden` fast dynamic spheres behind the wall (max_speed 1e4 units/s: the
/// shortest TBV periods the engine makes).
std::unique_ptr<Scene> walled_scene(int hidden) {
  SceneDesc d;
  d.bounds_min = Vec3(0.0);
  d.bounds_max = Vec3(20.0);
  d.grid = glm::ivec3(20);
  d.objects.push_back(box_between(1, Vec3(0, 0, 8.5), Vec3(20, 20, 11.5)));
  for (int i = 0; i < hidden; ++i) {
    const double x = 2.0 + (i % 8) * 2.0, y = 2.0 + (i / 8 % 8) * 2.0;
    d.objects.push_back(dynamic(sphere(ObjectId(100 + i), Vec3(x, y, 16.0), 0.4), 1e4));
  }
  std::unique_ptr<Scene> s;
  EXPECT_TRUE(Scene::create(d, SceneOptions{}, &s).ok);
  return s;
}

TEST(TimeModel, ValidateTimeBounds) {
  EXPECT_TRUE(validate_time("t", 0.0).ok);
  EXPECT_TRUE(validate_time("t", kMaxSceneTime).ok);
  EXPECT_TRUE(validate_time("t", -kMaxSceneTime).ok);
  EXPECT_TRUE(validate_time("t", 1.7e9).ok);  // Seconds since 1970 fit.
  for (double bad : {std::nextafter(kMaxSceneTime, 2e10), -std::nextafter(kMaxSceneTime, 2e10),
                     1.7e12, 1.7e15, 1e300, -1e300, std::numeric_limits<double>::infinity(),
                     std::numeric_limits<double>::quiet_NaN()}) {
    const Status s = validate_time("batch.t", bad);
    EXPECT_FALSE(s.ok) << bad;
    EXPECT_EQ(s.field, "batch.t");
    EXPECT_NE(s.message.find("within"), std::string::npos) << s.message;
  }
}

TEST(TimeModel, OutOfRangeTimesAreRefusedBeforeAnythingChanges) {
  auto scene = walled_scene(4);
  ASSERT_TRUE(scene);
  Scratch scratch;
  const ViewerId v = scene->add_viewer();
  FrameResult r;
  ASSERT_TRUE(scene->frame(v, looking_at_wall(), 5.0, scratch, &r).ok);
  for (double bad : {1e14, -1e14, 1e300, 1.7e15}) {
    for (Scene::Clock clock : {Scene::Clock::Strict, Scene::Clock::Latest}) {
      FrameResult fr;
      const Status f = scene->frame(v, looking_at_wall(), bad, scratch, &fr, clock);
      EXPECT_FALSE(f.ok) << bad;
      EXPECT_EQ(f.field, "t");
      const std::vector<Move> moves = {{100, Vec3(2, 2, 16)}};
      MoveReport rep;
      const Status m = scene->apply_moves(bad, moves, &rep, clock);
      EXPECT_FALSE(m.ok) << bad;
      EXPECT_EQ(m.field, "t");
      EXPECT_EQ(scene->time(), 5.0) << "a refused time must not move the clock";
    }
  }
}

// Frames at the far end of the range, with the shortest TBV periods, each
// expire every TBV at most once and finish: before the range existed, frames
// at t = 1e14 renewed TBVs to now + period == now and never returned.
TEST(TimeModel, RenewalsAtTheEdgeOfTheRangeTerminate) {
  constexpr int kHidden = 64;
  Scratch scratch;
  for (double t0 : {kMaxSceneTime - 1.0, -kMaxSceneTime}) {
    // Both clocks run forwards from t0 in frames of 1/30 s.
    auto fresh = walled_scene(kHidden);
    ASSERT_TRUE(fresh);
    const ViewerId fv = fresh->add_viewer();
    int expired = 0;
    for (int i = 0; i < 30; ++i) {
      FrameResult r;
      const double t = t0 + i / 30.0;
      ASSERT_TRUE(fresh->frame(fv, looking_at_wall(), t, scratch, &r).ok) << t;
      EXPECT_LE(r.stats.tbvs_expired, std::uint32_t{kHidden}) << "frame at " << t;
      EXPECT_LE(r.wake.size(), std::size_t{kHidden}) << "frame at " << t;
      expired += static_cast<int>(r.stats.tbvs_expired);
    }
    // Periods are about 1e-4 s, so TBVs do expire and renew along the way.
    EXPECT_GT(expired, 0) << "t0 = " << t0;
  }
}

TEST(TimeModel, TbvPeriodOptionBelowOneMillisecondIsRefused) {
  SceneDesc d;
  d.objects.push_back(dynamic(sphere(1, Vec3(0.5), 0.1), 1.0));
  for (double p : {1e-300, 1e-4, -1.0, std::numeric_limits<double>::quiet_NaN()}) {
    SceneOptions o;
    o.tbv_period = p;
    std::unique_ptr<Scene> s;
    const Status st = Scene::create(d, o, &s);
    EXPECT_FALSE(st.ok) << p;
    EXPECT_EQ(st.field, "tbv_period");
  }
  for (double p : {0.0, 1e-3, 2.5}) {
    SceneOptions o;
    o.tbv_period = p;
    std::unique_ptr<Scene> s;
    EXPECT_TRUE(Scene::create(d, o, &s).ok) << p;
  }
}

}  // namespace
}  // namespace voxvis::test
