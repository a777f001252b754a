// Every accepted camera answers, conservatively: extreme lenses (fov at its
// lower bound and just below 180 degrees, aspect at both limits), directions
// of any magnitude (1e308 and denormal components, signed zeros), eyes on the
// grid's bounds, voxel corners and far outside, near planes of 1e-300 and far
// planes of 1e300 or a hair beyond near, at every width of the occlusion
// buffer from off to 4096 pixels, in scenes at home, shrunk to 1e-90 and
// offset to 1e11. Each frame must return ok, keep its statistics finite and
// miss nothing the ray caster sees; cameras beyond the documented bounds
// (a denormal fov, one below kMinFovDeg) are refused naming the field.
//
// Before these rules a denormal fov (half the angle's tangent is zero) made
// the buffer's height NaN and aborted the process (std::length_error).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "engine_check.h"
#include "extreme_cameras.h"
#include "raycast.h"
#include "scenes.h"
#include "voxvis/rng.h"
#include "voxvis/scene.h"

namespace voxvis::test {
namespace {

struct Case {
  std::string name;
  SceneDesc scene;
};

std::vector<Case> scenes() {
  RandomSceneParams p;
  p.grid = glm::ivec3(20, 12, 20);
  p.spheres = 40;
  p.boxes = 25;
  p.occluders = 6;
  p.walls = 6;
  SceneDesc home = random_scene(p, 0xca3e);
  std::vector<Case> out;
  out.push_back({"home", home});
  out.push_back({"shrunk to 1e-90", transform_scene(home, 1e-90, Vec3(3e-89, -1e-88, 0.0))});
  out.push_back({"offset to 1e11", transform_scene(home, 1e3, Vec3(1e11, -1e11, 5e10))});
  return out;
}

TEST(ExtremeCameras, EveryAcceptedCameraAnswersWithoutAMissAtEveryBufferWidth) {
  // Off, the narrowest, one not a multiple of the 8-pixel tiles, the
  // default, and the widest (fewer frames: a 4096-pixel buffer is 64 MB).
  const int widths[] = {0, 8, 13, 128, 4096};
  RaySampling sampling;  // Jittered cells only: rays of positive measure.
  sampling.cols = sampling.rows = 48;
  for (const Case& c : scenes()) {
    for (int width : widths) {
      SceneOptions opt;
      opt.occlusion_buffer = width;
      const std::string label = c.name + ", buffer " + std::to_string(width);
      EngineHarness h(c.scene, opt, label);
      ASSERT_TRUE(h.status().ok) << label << ": " << h.status().str();
      Rng rng(mix_seed(0xe7e3, static_cast<std::uint64_t>(width)));
      const int n = width == 4096 ? scaled(6) : scaled(60);
      for (int i = 0; i < n; ++i) {
        const Camera cam = extreme_camera(rng, c.scene);
        ASSERT_TRUE(validate_camera(cam).ok) << validate_camera(cam).str();
        sampling.seed = mix_seed(0x5a3, static_cast<std::uint64_t>(i));
        const std::string err = h.frame(cam, 0.01 * i, &sampling);
        ASSERT_EQ(err, "") << label << ", camera " << i;
        ASSERT_EQ(check_stats(h.last().stats, c.scene.objects.size()), "") << label << ", camera " << i;
      }
    }
  }
}

TEST(ExtremeCameras, TheRayCasterAcceptsEveryCameraTheEngineAccepts) {
  // A caster that refused a camera would return nothing visible, and the
  // test above would pass without checking anything.
  const SceneDesc scene = scenes().front().scene;
  Rng rng(0x0bad);
  for (int i = 0; i < 400; ++i) {
    const Camera cam = extreme_camera(rng, scene);
    raycast::ViewBasis b;
    ASSERT_TRUE(raycast::make_basis(cam, &b)) << "camera " << i;
    EXPECT_TRUE(std::isfinite(b.tanx) && b.tanx > 0 && std::isfinite(b.tany) && b.tany > 0) << "camera " << i;
  }
  // And it sees what is straight ahead through the narrowest lens, with a
  // direction written at 1e308.
  Camera c = camera_along(Vec3(50, 30, -10), Vec3(0, 0, 1e308), kMinFovDeg, kMaxAspect);
  const std::vector<ObjectDesc> ball = {sphere(7, Vec3(50, 30, 50), 1.0)};
  EXPECT_EQ(raycast::visible_objects(ball, c), std::vector<ObjectId>{7});
}

TEST(ExtremeCameras, AThinLensStillSeesAndHidesWhatIsAhead) {
  // The same answers as a normal lens where they must agree: a ball straight
  // ahead is in the PVS, one beside the axis is not, through fov 1e-6 and
  // the direction written with 1e308 and with a denormal component.
  SceneDesc d;
  d.bounds_min = Vec3(0.0);
  d.bounds_max = Vec3(100.0);
  d.grid = glm::ivec3(32);
  d.objects = {sphere(1, Vec3(50, 50, 50), 5.0), sphere(2, Vec3(80, 50, 50), 5.0)};
  for (int width : {0, 128}) {
    for (const Vec3& dir : {Vec3(0, 0, 1e308), Vec3(0, -0.0, kDenormal), Vec3(0, 0, 1e-300)}) {
      SceneOptions opt;
      opt.occlusion_buffer = width;
      EngineHarness h(d, opt, "thin lens");
      ASSERT_TRUE(h.status().ok);
      Camera cam = camera_along(Vec3(50, 50, -20), dir, kMinFovDeg, 1.5, 0.1, 1000.0);
      ASSERT_EQ(h.frame(cam, 0.0), "");
      EXPECT_EQ(h.last().pvs, std::vector<ObjectId>{1}) << "width " << width;
      EXPECT_FALSE(h.last().stats.frustum_fallback);
    }
  }
}

TEST(ExtremeCameras, LensesBeyondTheBoundsAreRefusedNamingTheField) {
  Camera c = camera_along(Vec3(50, 50, -20), Vec3(0, 0, 1));
  for (double fov : {kDenormal, 1e-322, 1e-300, 1e-7, std::nextafter(kMinFovDeg, 0.0), 0.0, -0.0, 180.0,
                     std::numeric_limits<double>::quiet_NaN()}) {
    c.fov_y_deg = fov;
    const Status s = validate_camera(c);
    EXPECT_FALSE(s.ok) << fov;
    EXPECT_EQ(s.field, "fov_y_deg") << fov;
    EXPECT_NE(s.message.find("[1e-06, 180)"), std::string::npos) << s.message;
  }
  c.fov_y_deg = 60.0;
  for (double aspect : {std::nextafter(1.0 / kMaxAspect, 0.0), std::nextafter(kMaxAspect, 2e3), 0.0}) {
    c.aspect = aspect;
    EXPECT_EQ(validate_camera(c).field, "aspect") << aspect;
  }
  c.aspect = 1.0;
  // Directions of any finite magnitude are directions; only zero is not.
  for (const Vec3& dir : {Vec3(1e308, 0, 1), Vec3(kDenormal, 0, 0), Vec3(-1e308, -1e308, 1e308)}) {
    c.dir = dir;
    EXPECT_TRUE(validate_camera(c).ok) << validate_camera(c).str();
  }
  for (const Vec3& dir : {Vec3(0.0), Vec3(-0.0, 0.0, -0.0)}) {
    c.dir = dir;
    EXPECT_EQ(validate_camera(c).field, "dir");
    EXPECT_EQ(validate_camera(c).message, "must not be the zero vector");
  }
  c.dir = Vec3(0, 1e308, 0);
  c.up = Vec3(0, 5e-324, 0);
  EXPECT_EQ(validate_camera(c).field, "up");
  EXPECT_EQ(validate_camera(c).message, "must not be parallel to dir");
}

TEST(ExtremeCameras, TheCrashingCameraOfTheReportAnswers) {
  // The report's reproduction: a 32^3 scene, eye (50,50,-20) looking +z, the
  // default buffer; fov 5e-324 took the process down. The nearest accepted
  // lens answers at every buffer width.
  SceneDesc d;
  d.bounds_min = Vec3(0.0);
  d.bounds_max = Vec3(100.0);
  d.grid = glm::ivec3(32);
  d.objects = {sphere(1, Vec3(50, 50, 50), 5.0)};
  Camera cam = camera_along(Vec3(50, 50, -20), Vec3(0, 0, 1), kDenormal, 1.5, 0.1, 1000.0);
  for (int width : {0, 8, 128, 4096}) {
    SceneOptions opt;
    opt.occlusion_buffer = width;
    std::unique_ptr<Scene> s;
    ASSERT_TRUE(Scene::create(d, opt, &s).ok);
    const ViewerId v = s->add_viewer();
    Scratch scratch;
    FrameResult r;
    cam.fov_y_deg = kDenormal;
    const Status refused = s->frame(v, cam, 0.0, scratch, &r);
    EXPECT_EQ(refused.field, "fov_y_deg");
    cam.fov_y_deg = kMinFovDeg;
    ASSERT_TRUE(s->frame(v, cam, 0.0, scratch, &r).ok);
    EXPECT_EQ(r.pvs, std::vector<ObjectId>{1});
  }
}

TEST(ExtremeCameras, AnEyeBeyondTheShellArithmeticFallsBackToFrustumCullingAndSaysSo) {
  // Voxels of ten micrometres seen from fifty thousand kilometres: over
  // 2^40 voxels away, where shell indices lose the precision the occlusion
  // tests need.
  SceneDesc d;
  d.bounds_min = Vec3(0.0);
  d.bounds_max = Vec3(1.0, 1.0, 0.01);
  d.grid = glm::ivec3(10, 10, 1000);
  d.objects = {box_between(1, Vec3(0.2, 0.2, 0.004), Vec3(0.8, 0.8, 0.0045)),  // A wall in front of
               sphere(2, Vec3(0.5, 0.5, 0.008), 0.001),                         // a ball.
               sphere(3, Vec3(50.0, 0.5, 0.005), 0.05)};                        // One outside the view.
  for (int width : {0, 128}) {
    SceneOptions opt;
    opt.occlusion_buffer = width;
    EngineHarness h(d, opt, "far eye");
    ASSERT_TRUE(h.status().ok) << h.status().str();
    ASSERT_EQ(h.frame(camera_along(Vec3(0.5, 0.5, -5e7), Vec3(0, 0, 1), 1e-5, 1.0, 1.0, 1e8), 0.0), "");
    EXPECT_TRUE(h.last().stats.frustum_fallback);
    EXPECT_EQ(h.last().stats.ob_width, 0u);
    EXPECT_EQ(h.last().pvs, (std::vector<ObjectId>{1, 2}));  // Frustum culling: the ball is kept.
    // From nearby the same wall hides the ball, and nothing falls back.
    ASSERT_EQ(h.frame(camera_along(Vec3(0.5, 0.5, 0.0005), Vec3(0, 0, 1), 30.0, 1.0, 1e-4, 10.0), 1.0), "");
    EXPECT_FALSE(h.last().stats.frustum_fallback);
    EXPECT_EQ(h.last().pvs, std::vector<ObjectId>{1});
  }
}

}  // namespace
}  // namespace voxvis::test
