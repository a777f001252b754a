// Property tests of the engine against the ray-cast ground truth: for random
// scenes, grids (generally non-cubic voxels), camera paths and dynamic objects
// moving at up to their max_speed, the PVS must contain every object the ray
// caster sees (zero misses). Also the invariants of the wake list, TBV
// bookkeeping, and several viewers sharing a scene and a Scratch.
//
// Counts scale with VOXVIS_TEST_SCALE (default 1; e.g. 0.2 under ASan).
// VOXVIS_PROPERTY_SEED=<n> runs just that seed of the random-scene tests;
// VOXVIS_PROPERTY_FIRST_SEED=<k> shifts the seed ranges by k (for soaks).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <memory>
#include <string>

#include "engine_check.h"
#include "raycast.h"
#include "scenes.h"
#include "voxvis/scene.h"

namespace voxvis::test {
namespace {

using Ids = std::vector<ObjectId>;
constexpr double kDt = 1.0 / 30.0;

bool sorted_unique(const Ids& v) {
  return std::adjacent_find(v.begin(), v.end(), [](ObjectId a, ObjectId b) { return a >= b; }) ==
         v.end();
}

/// Seeds to run: [first, first + count), or the one in VOXVIS_PROPERTY_SEED.
std::vector<std::uint64_t> seeds(std::uint64_t first, int count) {
  if (const char* s = std::getenv("VOXVIS_PROPERTY_SEED"); s != nullptr && *s != '\0') {
    return {std::strtoull(s, nullptr, 10)};
  }
  if (const char* s = std::getenv("VOXVIS_PROPERTY_FIRST_SEED"); s != nullptr && *s != '\0') {
    first += std::strtoull(s, nullptr, 10);  // shift every seed range (soak runs)
  }
  std::vector<std::uint64_t> out;
  for (int i = 0; i < count; ++i) out.push_back(first + static_cast<std::uint64_t>(i));
  return out;
}

Ids dynamic_ids_of(const SceneDesc& scene) {
  Ids out;
  for (const ObjectDesc& o : scene.objects) {
    if (o.dynamic) out.push_back(o.id);
  }
  std::sort(out.begin(), out.end());
  return out;
}

/// Per-seed TBV options: automatic periods, short ones (frequent expiry),
/// long ones, or a different voxel allowance.
SceneOptions random_options(std::uint64_t seed) {
  Rng rng(mix_seed(seed, 0x0971));
  SceneOptions opt;
  switch (rng.uniform_int(0, 3)) {
    case 0: break;
    case 1: opt.tbv_period = rng.uniform(0.01, 0.2); break;
    case 2: opt.tbv_period = rng.uniform(1.0, 30.0); break;
    default: opt.tbv_voxels = rng.uniform(0.5, 8.0); break;
  }
  // The occlusion buffer off, at the default width, coarser and finer.
  const int widths[] = {0, 128, 48, 256};
  opt.occlusion_buffer = widths[rng.uniform_int(0, 3)];
  // Deep shells (used with the buffer off) on half the seeds.
  opt.deep_shells = rng.uniform_int(0, 1) == 1;
  return opt;
}

std::string label_of(const SceneDesc& scene, std::uint64_t seed) {
  return describe_scene(scene, seed) + " (rerun: VOXVIS_PROPERTY_SEED=" + std::to_string(seed) + ")";
}

struct RunStats {
  int frames = 0;
  double pvs_total = 0;
  double visible_total = 0;
  double objects_total = 0;
  std::uint32_t max_tbvs = 0;
};

/// One random scene, one viewer, a camera path, moving objects.
void run_random_scene(std::uint64_t seed, int frames, RunStats* rs) {
  const SceneDesc scene = random_scene(random_scene_params(seed), seed);
  const std::string label = label_of(scene, seed);
  EngineHarness h(scene, random_options(seed), label);
  ASSERT_TRUE(h.status().ok) << label << ": " << h.status().str();
  ASSERT_EQ(h.scene().object_count(), scene.objects.size());
  ASSERT_EQ(h.scene().dynamic_count(), dynamic_ids_of(scene).size());
  const std::vector<Camera> path = random_camera_path(scene, seed, {.frames = frames});
  Mover mover(scene, seed);
  for (int f = 0; f < frames; ++f) {
    const double t = f * kDt;
    if (f > 0) {
      const std::vector<Move> moves = mover.step(kDt);
      MoveReport report;
      const Status ms = h.move(t, moves, &report);
      ASSERT_TRUE(ms.ok) << label << " frame " << f << ": " << ms.str();
      EXPECT_EQ(report.applied, moves.size()) << label << " frame " << f;
      EXPECT_TRUE(report.too_fast.empty()) << label << " frame " << f
                                           << ": moves within max_speed flagged too fast "
                                           << describe_ids(report.too_fast);
    }
    const Camera& cam = path[static_cast<std::size_t>(f)];
    const std::string err = h.frame(cam, t);
    ASSERT_TRUE(err.empty()) << err;
    rs->frames += 1;
    rs->pvs_total += static_cast<double>(h.last().pvs.size());
    rs->visible_total += static_cast<double>(visible_objects(h.objects(), cam, {.cols = 32, .rows = 32}).size());
    rs->objects_total += static_cast<double>(scene.objects.size());
    rs->max_tbvs = std::max(rs->max_tbvs, h.last().stats.tbvs_active);
  }
}

TEST(VisibilityProperty, RandomScenesHaveZeroMisses) {
  RunStats rs;
  for (std::uint64_t seed : seeds(1, scaled(40))) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    run_random_scene(seed, std::max(2, scaled(25)), &rs);
    if (HasFatalFailure()) return;
  }
  // Not a correctness property: shows how much the engine culled, so that a
  // PVS of "everything" would be noticed.
  if (rs.frames > 0) {
    std::printf("[ stats    ] frames=%d mean objects=%.1f pvs=%.1f visible(32x32)=%.1f max tbvs_active=%u\n",
                rs.frames, rs.objects_total / rs.frames, rs.pvs_total / rs.frames,
                rs.visible_total / rs.frames, rs.max_tbvs);
  }
}

TEST(VisibilityProperty, LargeNearPlanesHaveZeroMisses) {
  // Near planes of 2% .. 40% of the scene: objects (or parts) before the near
  // plane are clipped away and must not hide what is behind them.
  for (std::uint64_t seed : seeds(500, scaled(12))) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const SceneDesc scene = random_scene(random_scene_params(seed), seed);
    const std::string label = label_of(scene, seed) + " (large near)";
    EngineHarness h(scene, random_options(seed), label);
    ASSERT_TRUE(h.status().ok) << h.status().str();
    const int frames = std::max(2, scaled(15));
    CameraPathParams cp;
    cp.frames = frames;
    cp.near_min = 0.02;
    cp.near_max = 0.4;
    const std::vector<Camera> path = random_camera_path(scene, seed, cp);
    Mover mover(scene, seed);
    for (int f = 0; f < frames; ++f) {
      const double t = f * kDt;
      if (f > 0) {
        ASSERT_TRUE(h.move(t, mover.step(kDt)).ok);
      }
      const std::string err = h.frame(path[static_cast<std::size_t>(f)], t);
      ASSERT_TRUE(err.empty()) << err;
    }
  }
}

TEST(VisibilityProperty, SeveralViewersShareASceneAndAScratch) {
  for (std::uint64_t seed : seeds(1000, scaled(8))) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const SceneDesc scene = random_scene(random_scene_params(seed), seed);
    const std::string label = label_of(scene, seed);
    EngineHarness h(scene, random_options(seed), label);
    ASSERT_TRUE(h.status().ok) << h.status().str();
    const Ids dyn = dynamic_ids_of(scene);
    constexpr std::size_t kViewers = 3;
    const int frames = std::max(2, scaled(20));
    std::vector<ViewerId> viewers = {h.viewer()};
    while (viewers.size() < kViewers) viewers.push_back(h.scene().add_viewer());
    for (std::size_t v = 0; v < kViewers; ++v) {
      for (std::size_t w = 0; w < v; ++w) ASSERT_NE(viewers[v], viewers[w]);
    }
    std::vector<std::vector<Camera>> paths;
    for (std::size_t v = 0; v < kViewers; ++v) {
      paths.push_back(random_camera_path(scene, mix_seed(seed, 77 + v), {.frames = frames}));
    }
    Mover mover(scene, seed);
    for (int f = 0; f < frames; ++f) {
      const double t = f * kDt;
      if (f > 0) {
      ASSERT_TRUE(h.move(t, mover.step(kDt)).ok);
    }
      // Interleaved: the order of the viewers rotates with the frame.
      for (std::size_t k = 0; k < kViewers; ++k) {
        const std::size_t v = (static_cast<std::size_t>(f) + k) % kViewers;
        const std::string err =
            h.frame_viewer(viewers[v], paths[v][static_cast<std::size_t>(f)], t);
        ASSERT_TRUE(err.empty()) << "viewer " << viewers[v] << ": " << err;
      }
      const Ids ws = h.scene().wake_set();
      EXPECT_TRUE(sorted_unique(ws)) << label << " frame " << f;
      EXPECT_TRUE(missing_ids(dyn, ws).empty()) << label << " frame " << f << ": wake_set holds non-dynamic ids";
    }
    // Removing a viewer keeps the others working.
    h.scene().remove_viewer(viewers[0]);
    const std::string err = h.frame_viewer(viewers[1], paths[1].back(), frames * kDt);
    ASSERT_TRUE(err.empty()) << err;
  }
}

TEST(VisibilityProperty, ScratchIsReusedAcrossScenes) {
  // One Scratch serving scenes of different sizes in turn.
  Scratch scratch;
  std::vector<std::unique_ptr<Scene>> scenes;
  std::vector<SceneDesc> descs;
  std::vector<ViewerId> viewers;
  const std::uint64_t first = 3001;
  for (std::uint64_t seed = first; seed < first + 3; ++seed) {
    descs.push_back(random_scene(random_scene_params(seed), seed));
    std::unique_ptr<Scene> sc;
    ASSERT_TRUE(Scene::create(descs.back(), {}, &sc).ok);
    viewers.push_back(sc->add_viewer());
    scenes.push_back(std::move(sc));
  }
  for (int f = 0; f < 6; ++f) {
    for (std::size_t i = 0; i < scenes.size(); ++i) {
      const std::uint64_t seed = first + i;
      const Camera cam = random_camera_path(descs[i], seed, {.frames = 6})[static_cast<std::size_t>(f)];
      FrameResult r;
      ASSERT_TRUE(scenes[i]->frame(viewers[i], cam, f * kDt, scratch, &r).ok);
      RaySampling s;
      s.corners = true;
      const std::string err = check_frame(label_of(descs[i], seed), f, descs[i].objects, cam, r, s);
      ASSERT_TRUE(err.empty()) << err;
    }
  }
}

TEST(VisibilityProperty, StaticSceneCreatesNoTbvs) {
  for (std::uint64_t seed : seeds(2000, scaled(6))) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    RandomSceneParams p = random_scene_params(seed);
    p.dynamic_fraction = 0.0;
    const SceneDesc scene = random_scene(p, seed);
    EngineHarness h(scene, {}, label_of(scene, seed));
    ASSERT_TRUE(h.status().ok) << h.status().str();
    ASSERT_EQ(h.scene().dynamic_count(), 0u);
    const int frames = 15;
    const std::vector<Camera> path = random_camera_path(scene, seed, {.frames = frames});
    for (int f = 0; f < frames; ++f) {
      const std::string err = h.frame(path[static_cast<std::size_t>(f)], f * kDt);
      ASSERT_TRUE(err.empty()) << err;
      const FrameStats& st = h.last().stats;
      EXPECT_EQ(st.tbvs_created, 0u) << "frame " << f;
      EXPECT_EQ(st.tbvs_active, 0u) << "frame " << f;
      EXPECT_EQ(st.tbvs_revealed, 0u) << "frame " << f;
      EXPECT_EQ(st.tbvs_expired, 0u) << "frame " << f;
      EXPECT_EQ(st.objects_discretized, 0u) << "frame " << f;
      EXPECT_TRUE(h.last().wake.empty()) << "frame " << f;
    }
    EXPECT_TRUE(h.scene().wake_set().empty());
  }
}

/// A 100^3 scene on a 20^3 grid (5-unit voxels) with a wall filling z in
/// [32.5, 47.5] and reaching beyond the bounds in x and y, so that the voxel
/// layers z in [35, 45] lie strictly inside it (the engine may treat voxels
/// that merely share a face with an object as not covered); the camera at z = 90 looks down -z at a few static
/// objects in front of the wall; `hidden` small dynamic spheres (max_speed 1)
/// are behind it.
struct WallScene {
  SceneDesc desc;
  Camera cam;
  Ids hidden;
};

WallScene make_wall_scene(int hidden, std::uint64_t seed) {
  WallScene w;
  w.desc.bounds_min = Vec3(0.0);
  w.desc.bounds_max = Vec3(100.0);
  w.desc.grid = glm::ivec3(20);
  ObjectDesc wall;
  wall.id = 1;
  wall.shape = Shape::Box;
  wall.center = Vec3(50.0, 50.0, 40.0);
  wall.half_extent = Vec3(60.0, 60.0, 7.5);
  w.desc.objects.push_back(wall);
  Rng rng(seed);
  for (int i = 0; i < 5; ++i) {
    ObjectDesc o;
    o.id = 10 + static_cast<ObjectId>(i);
    o.shape = Shape::Sphere;
    o.radius = 2.0;
    o.center = rng.in_box(Vec3(35, 35, 55), Vec3(65, 65, 75));
    w.desc.objects.push_back(o);
  }
  for (int i = 0; i < hidden; ++i) {
    ObjectDesc o;
    o.id = 100 + static_cast<ObjectId>(i);
    o.shape = Shape::Sphere;
    o.radius = 1.0;
    o.center = rng.in_box(Vec3(20, 20, 5), Vec3(80, 80, 28));
    o.dynamic = true;
    o.max_speed = 1.0;
    w.desc.objects.push_back(o);
    w.hidden.push_back(o.id);
  }
  w.cam.eye = Vec3(50.0, 50.0, 90.0);
  w.cam.dir = Vec3(0.0, 0.0, -1.0);
  w.cam.up = Vec3(0.0, 1.0, 0.0);
  w.cam.fov_y_deg = 60.0;
  w.cam.aspect = 1.0;
  w.cam.near = 0.1;
  w.cam.far = 500.0;
  return w;
}

TEST(VisibilityProperty, HiddenDynamicObjectsGetTbvs) {
  const WallScene w = make_wall_scene(20, 11);
  EngineHarness h(w.desc, {}, "wall scene seed=11");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  Mover mover(w.desc, 11, 0.0);
  std::uint32_t max_active = 0;
  std::uint32_t created = 0;
  std::size_t min_hidden_in_pvs = w.hidden.size();
  for (int f = 0; f < 60; ++f) {
    const double t = f * kDt;
    if (f > 0) {
      ASSERT_TRUE(h.move(t, mover.step(kDt)).ok);
    }
    const std::string err = h.frame(w.cam, t);
    ASSERT_TRUE(err.empty()) << err;
    max_active = std::max(max_active, h.last().stats.tbvs_active);
    created += h.last().stats.tbvs_created;
    Ids hidden_in_pvs;
    std::set_intersection(h.last().pvs.begin(), h.last().pvs.end(), w.hidden.begin(),
                          w.hidden.end(), std::back_inserter(hidden_in_pvs));
    if (f > 0) min_hidden_in_pvs = std::min(min_hidden_in_pvs, hidden_in_pvs.size());
    // The wall hides them: the ground truth sees none of them.
    const Ids vis = visible_objects(h.objects(), w.cam);
    Ids hidden_seen;
    std::set_intersection(vis.begin(), vis.end(), w.hidden.begin(), w.hidden.end(),
                          std::back_inserter(hidden_seen));
    ASSERT_TRUE(hidden_seen.empty()) << "test scene broken: " << describe_ids(hidden_seen);
  }
  EXPECT_GT(max_active, 0u);
  EXPECT_GT(created, 0u);
  // The engine culls them (two whole voxel layers of the wall are opaque).
  EXPECT_LT(min_hidden_in_pvs, w.hidden.size());
  std::printf("[ stats    ] hidden=%zu max tbvs_active=%u created=%u least hidden in pvs=%zu\n",
              w.hidden.size(), max_active, created, min_hidden_in_pvs);
}

TEST(VisibilityProperty, WallSceneWithTbvExpiryAndReveal) {
  // Short TBV periods (frequent expiry) and a camera that eventually rises
  // over the wall, revealing everything: zero misses throughout.
  const WallScene w = make_wall_scene(30, 12);
  SceneOptions opt;
  opt.tbv_period = 0.1;
  EngineHarness h(w.desc, opt, "wall scene seed=12 tbv_period=0.1");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  Mover mover(w.desc, 12, 0.0);
  std::uint32_t expired = 0;
  for (int f = 0; f < 90; ++f) {
    const double t = f * kDt;
    if (f > 0) {
      ASSERT_TRUE(h.move(t, mover.step(kDt)).ok);
    }
    Camera cam = w.cam;
    if (f >= 45) {
      const double s = (f - 45) / 44.0;
      cam.eye = Vec3(50.0, 50.0 + 80.0 * s, 90.0 - 30.0 * s);
      cam.dir = Vec3(0.0, -0.3 - 1.2 * s, -1.0);
    }
    const std::string err = h.frame(cam, t);
    ASSERT_TRUE(err.empty()) << err;
    expired += h.last().stats.tbvs_expired;
  }
  EXPECT_GT(expired, 0u);
}

}  // namespace
}  // namespace voxvis::test
