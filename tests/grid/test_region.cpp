// Region cameras (Camera::eye_extent, omnidirectional, horizon_s): the
// answer holds every object the sampled region sees (raycast::region_visible:
// eyes at the box's centre, corners and random points, six cube faces when
// omnidirectional, the moving objects placed anywhere their speed reaches
// within the horizon), on random scenes and the hard cases; it leaves out
// what the region cannot reach; many movers, found through the cells near
// the eyes, are missed no more; TBVs out of reach stay hidden at no cost;
// bad fields are errors naming them; the frames format carries the fields.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "describe.h"
#include "scenes.h"
#include "voxvis/format.h"
#include "voxvis/raycast.h"
#include "voxvis/rng.h"
#include "voxvis/scene.h"

namespace voxvis::test {
namespace {

bool has(const std::vector<ObjectId>& v, ObjectId id) { return std::binary_search(v.begin(), v.end(), id); }

/// One frame of a region camera on a fresh scene at time 0.
FrameResult region_frame(const SceneDesc& desc, const Camera& cam, SceneOptions options = {}) {
  std::unique_ptr<Scene> scene;
  const Status st = Scene::create(desc, options, &scene);
  EXPECT_TRUE(st.ok) << st.message;
  Scratch scratch;
  FrameResult fr;
  const ViewerId v = scene->add_viewer();
  const Status fs = scene->frame(v, cam, 0.0, scratch, &fr);
  EXPECT_TRUE(fs.ok) << fs.field << ": " << fs.message;
  return fr;
}

TEST(Region, RandomScenesAndRegionsMissNothingTheSampledRegionSees) {
  int checked = 0, wider = 0, occluded = 0;
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(scaled(12)); ++seed) {
    const SceneDesc desc = random_scene(random_scene_params(seed), seed);
    const std::vector<Camera> path = random_camera_path(desc, seed + 300);
    Rng rng(seed * 77);
    for (std::size_t f = 0; f < path.size(); f += 6) {
      Camera cam = path[f];
      const double size = glm::length(desc.bounds_max - desc.bounds_min);
      const double s = size * rng.log_uniform(1e-4, 0.05);
      cam.eye_extent = Vec3(s * rng.uniform(), s * rng.uniform(), s * rng.uniform());
      cam.omnidirectional = rng.chance(0.4);
      cam.horizon_s = rng.chance(0.5) ? rng.uniform(0.0, 0.3) : 0.0;
      {
        const SceneOptions options;
        const FrameResult fr = region_frame(desc, cam, options);
        EXPECT_TRUE(fr.stats.region);
        occluded += fr.stats.ob_objects_culled > 0 ? 1 : 0;
        raycast::RegionSampling sampling;
        sampling.seed = seed * 1000 + f;
        sampling.rays = raycast::RaySampling{32, 32};
        const std::vector<ObjectId> seen = raycast::region_visible(desc.objects, cam, sampling);
        const std::vector<ObjectId> lost = missing_ids(fr.pvs, seen);
        EXPECT_TRUE(lost.empty()) << describe_scene(desc, seed) << " frame " << f << " " << describe(cam)
                                  << " extent " << cam.eye_extent.x << "," << cam.eye_extent.y << ","
                                  << cam.eye_extent.z << " omni " << cam.omnidirectional << " horizon "
                                  << cam.horizon_s << ": missed " << describe_ids(lost);
        // Wider than the point camera's answer (the point answer keeps
        // objects of voxels the frustum touches, so it need not be a subset).
        Camera point = cam;
        point.eye_extent = Vec3(0.0);
        point.omnidirectional = false;
        point.horizon_s = 0.0;
        const FrameResult pf = region_frame(desc, point, options);
        wider += fr.pvs.size() > pf.pvs.size() ? 1 : 0;
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, scaled(20));
  EXPECT_GT(wider, checked / 4) << "regions are hardly ever wider than their point";
  // Static occluders hide something from the region in some frames.
  EXPECT_GT(occluded, checked / 10) << occluded << " of " << checked;
}

TEST(Region, ManyMoversAreFoundThroughTheCellsAndNoneIsMissed) {
  // Random scenes with 150 small movers more (inside the bounds and beyond
  // them), so that a region frame reads the cells near its eyes for movers
  // rather than their list (region_candidates.h); the second frame of each
  // camera, after the first has put the hidden movers under TBVs. Regions
  // of every size (some reaching far past the grid), horizons up to 1e6:
  // nothing the sampled region sees is missing.
  int checked = 0, through_cells = 0;
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(scaled(6)); ++seed) {
    const RandomSceneParams params = random_scene_params(seed);
    SceneDesc desc = random_scene(params, seed);
    Rng rng(seed * 131);
    const Vec3 lo = desc.bounds_min, hi = desc.bounds_max, size = hi - lo;
    const double voxel = std::min({size.x / params.grid.x, size.y / params.grid.y, size.z / params.grid.z});
    ObjectId id = 1;
    for (const ObjectDesc& o : desc.objects) id = std::max(id, o.id + 1);
    for (int i = 0; i < 150; ++i)
      desc.objects.push_back(dynamic(sphere(id++, rng.in_box(lo - 0.1 * size, hi + 0.1 * size), 0.3 * voxel),
                                     params.max_speed));
    const std::vector<Camera> path = random_camera_path(desc, seed + 500);
    for (std::size_t f = 0; f < path.size(); f += 8) {
      Camera cam = path[f];
      const double s = glm::length(size) * (rng.chance(0.15) ? 3.0 : rng.log_uniform(1e-4, 0.05));
      cam.eye_extent = Vec3(s * rng.uniform(), s * rng.uniform(), s * rng.uniform());
      cam.omnidirectional = rng.chance(0.4);
      cam.horizon_s = rng.chance(0.1) ? 1e6 : rng.chance(0.6) ? rng.uniform(0.0, 0.3) : 0.0;
      std::unique_ptr<Scene> scene;
      ASSERT_TRUE(Scene::create(desc, SceneOptions{}, &scene).ok);
      Scratch scratch;
      const ViewerId v = scene->add_viewer();
      FrameResult fr;
      ASSERT_TRUE(scene->frame(v, cam, 0.0, scratch, &fr).ok);
      ASSERT_TRUE(scene->frame(v, cam, 0.0, scratch, &fr).ok);
      through_cells += fr.stats.cells_visited > 0 ? 1 : 0;
      raycast::RegionSampling sampling;
      sampling.seed = seed * 1000 + f;
      sampling.rays = raycast::RaySampling{32, 32};
      const std::vector<ObjectId> lost = missing_ids(fr.pvs, raycast::region_visible(desc.objects, cam, sampling));
      EXPECT_TRUE(lost.empty()) << describe_scene(desc, seed) << " frame " << f << " " << describe(cam) << " extent "
                                << cam.eye_extent.x << "," << cam.eye_extent.y << "," << cam.eye_extent.z << " omni "
                                << cam.omnidirectional << " horizon " << cam.horizon_s << ": missed "
                                << describe_ids(lost);
      ++checked;
    }
  }
  EXPECT_GT(checked, scaled(10));
  EXPECT_GT(through_cells, checked / 3) << "the cells were read in " << through_cells << " of " << checked;
}

TEST(Region, AnEyeBoxAcrossAThinWallSeesBothSides) {
  // A wall 0.1 thick at z = 0 from x = 0 to 40; a ball on each side, in
  // front of the eye along +x. The eye box straddles the wall.
  SceneDesc d = unit_grid(40);
  d.objects.push_back(box_between(1, Vec3(0.0, 0.0, 19.95), Vec3(40.0, 40.0, 20.05)));
  d.objects.push_back(sphere(2, Vec3(30.0, 20.0, 16.0), 1.0));
  d.objects.push_back(sphere(3, Vec3(30.0, 20.0, 24.0), 1.0));
  Camera cam = camera_along(Vec3(5.0, 20.0, 20.0), Vec3(1.0, 0.0, 0.0), 60.0, 1.0);
  cam.eye_extent = Vec3(0.0, 0.0, 1.0);
  const std::vector<ObjectId> seen = raycast::region_visible(d.objects, cam);
  EXPECT_TRUE(has(seen, 2) && has(seen, 3)) << describe_ids(seen);
  const FrameResult fr = region_frame(d, cam);
  EXPECT_TRUE(has(fr.pvs, 2) && has(fr.pvs, 3)) << describe_ids(fr.pvs);
}

TEST(Region, WhatTheRegionCannotReachIsLeftOut) {
  // Balls behind the eye (beyond the box) and beyond far (plus the box) are
  // out; one just within the box's reach of the frustum is in.
  SceneDesc d = unit_grid(100);
  d.objects.push_back(sphere(1, Vec3(50.0, 50.0, 80.0), 1.0));   // Ahead.
  d.objects.push_back(sphere(2, Vec3(50.0, 50.0, 10.0), 1.0));   // 40 behind.
  d.objects.push_back(sphere(3, Vec3(50.0, 50.0, 99.0), 0.5));   // Beyond far (45) + 2.
  d.objects.push_back(sphere(4, Vec3(50.0, 50.0, 47.5), 1.0));   // Behind the centre, ahead of the box's back.
  d.objects.push_back(sphere(5, Vec3(80.0, 80.0, 80.0), 0.5));   // Diagonal, 47 from the nearest eye.
  Camera cam = camera_along(Vec3(50.0, 50.0, 50.0), Vec3(0.0, 0.0, 1.0), 60.0, 1.0, 0.05, 45.0);
  cam.eye_extent = Vec3(2.0, 2.0, 3.0);
  FrameResult fr = region_frame(d, cam);
  EXPECT_EQ(fr.pvs, (std::vector<ObjectId>{1, 4})) << describe_ids(fr.pvs);
  // Omnidirectional: behind counts too, within far of some eye of the box;
  // far bounds distance, so the diagonal ball (within a cube face's far
  // plane, beyond far) is out, for the engine and the sampled reference.
  cam.omnidirectional = true;
  fr = region_frame(d, cam);
  EXPECT_EQ(fr.pvs, (std::vector<ObjectId>{1, 2, 4})) << describe_ids(fr.pvs);
  const std::vector<ObjectId> sampled = raycast::region_visible(d.objects, cam);
  EXPECT_FALSE(has(sampled, 5)) << describe_ids(sampled);
  EXPECT_TRUE(has(sampled, 2)) << describe_ids(sampled);
  EXPECT_TRUE(missing_ids(fr.pvs, sampled).empty()) << describe_ids(sampled);
  // A horizon lets a moving ball come within reach: its near side is 0.5
  // beyond the farthest eye's far plane (z 98); at 1 unit/s, 0.6 s will do,
  // 0.4 s will not.
  d.objects[2] = dynamic(sphere(3, Vec3(50.0, 50.0, 99.0), 0.5), 1.0);
  cam.omnidirectional = false;
  cam.horizon_s = 0.4;
  fr = region_frame(d, cam);
  EXPECT_FALSE(has(fr.pvs, 3)) << describe_ids(fr.pvs);
  cam.horizon_s = 0.6;
  fr = region_frame(d, cam);
  EXPECT_TRUE(has(fr.pvs, 3)) << describe_ids(fr.pvs);
}

TEST(Region, HardCasesAreConservativeAndFinite) {
  const SceneDesc base = random_scene(random_scene_params(5), 5);
  const Camera start = random_camera_path(base, 9)[2];
  struct Case {
    const char* name;
    Vec3 extent;
    bool omni;
    double horizon;
    double near;
  };
  const double big = 0.5 * glm::length(base.bounds_max - base.bounds_min);
  const Case cases[] = {
      {"eye box inside an object", Vec3(0.2), false, 0.0, 0.05},
      {"box past the grid's bounds", Vec3(3.0 * big), true, 0.0, 0.05},
      {"huge box", Vec3(kMaxCoordinate), false, 0.0, 0.05},
      {"horizon 1e6", Vec3(0.0), false, 1e6, 0.05},
      {"near plane inside the box", Vec3(4.0), false, 0.0, 3.0},
      {"everything at once", Vec3(1e9), true, kMaxHorizon, 0.05},
      {"a flat box", Vec3(5.0, 0.0, 0.0), false, 0.0, 0.05},
  };
  for (const Case& c : cases) {
    SceneDesc d = base;
    Camera cam = start;
    if (std::string(c.name) == "eye box inside an object") cam.eye = d.objects[0].center;
    cam.eye_extent = c.extent;
    cam.omnidirectional = c.omni;
    cam.horizon_s = c.horizon;
    cam.near = c.near;
    const FrameResult fr = region_frame(d, cam);
    raycast::RegionSampling sampling;
    sampling.rays = raycast::RaySampling{24, 24};
    const std::vector<ObjectId> lost = missing_ids(fr.pvs, raycast::region_visible(d.objects, cam, sampling));
    EXPECT_TRUE(lost.empty()) << c.name << ": missed " << describe_ids(lost);
    EXPECT_TRUE(std::isfinite(fr.stats.time_us)) << c.name;
  }
  // With a huge box or an unbounded horizon, everything within reach: all.
  Camera cam = start;
  cam.eye_extent = Vec3(kMaxCoordinate);
  cam.far = 1e13;
  EXPECT_EQ(region_frame(base, cam).pvs.size(), base.objects.size());
}

TEST(Region, HiddenMoversOutOfReachStayHiddenAtNoCost) {
  // A ball moving at 1 unit/s far behind the eye: hidden from the first
  // frame on, it gets a TBV. A frustum region looking away costs it what
  // the point camera does (no reveal; wakes only when its TBV expires, as
  // for the point), frame for frame; an omnidirectional region reaching
  // it reveals it and wakes it.
  SceneDesc d = unit_grid(100);
  d.objects.push_back(sphere(1, Vec3(50.0, 50.0, 90.0), 1.0));
  d.objects.push_back(dynamic(sphere(2, Vec3(50.0, 50.0, 5.0), 1.0), 1.0));
  std::unique_ptr<Scene> by_point, by_region;
  ASSERT_TRUE(Scene::create(d, SceneOptions{}, &by_point).ok);
  ASSERT_TRUE(Scene::create(d, SceneOptions{}, &by_region).ok);
  Scratch scratch;
  const ViewerId vp = by_point->add_viewer(), vr = by_region->add_viewer();
  const Camera point = camera_along(Vec3(50.0, 50.0, 50.0), Vec3(0.0, 0.0, 1.0), 60.0, 1.0, 0.05, 200.0);
  Camera region = point;
  region.eye_extent = Vec3(2.0);
  region.horizon_s = 0.15;
  FrameResult fp, fr;
  for (int i = 0; i < 60; ++i) {
    ASSERT_TRUE(by_point->frame(vp, point, i / 30.0, scratch, &fp).ok);
    ASSERT_TRUE(by_region->frame(vr, region, i / 30.0, scratch, &fr).ok);
    EXPECT_FALSE(has(fr.pvs, 2)) << "frame " << i;
    EXPECT_EQ(fr.wake, fp.wake) << "frame " << i;
    EXPECT_EQ(fr.stats.tbvs_revealed, 0u) << "frame " << i;
  }
  EXPECT_GE(fr.stats.tbvs_active, 1u);
  region.omnidirectional = true;
  ASSERT_TRUE(by_region->frame(vr, region, 2.0, scratch, &fr).ok);
  EXPECT_TRUE(has(fr.wake, 2)) << "the omnidirectional region reaches it: " << describe_ids(fr.wake);
  EXPECT_TRUE(has(fr.pvs, 2) || fr.stats.tbvs_revealed > 0);
}

TEST(Region, BadFieldsAreErrorsNamingThem) {
  const Camera good = camera_along(Vec3(1.0), Vec3(0.0, 0.0, 1.0));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  struct Bad {
    Vec3 extent;
    double horizon;
    const char* field;
  };
  for (const Bad& b : {Bad{Vec3(-1.0, 0.0, 0.0), 0.0, "eye_extent"}, Bad{Vec3(0.0, nan, 0.0), 0.0, "eye_extent"},
                       Bad{Vec3(0.0, 0.0, 2e12), 0.0, "eye_extent"},
                       Bad{Vec3(0.0, 0.0, std::numeric_limits<double>::infinity()), 0.0, "eye_extent"},
                       Bad{Vec3(0.0), -0.1, "horizon_s"}, Bad{Vec3(0.0), nan, "horizon_s"},
                       Bad{Vec3(0.0), 2e9, "horizon_s"}}) {
    Camera c = good;
    c.eye_extent = b.extent;
    c.horizon_s = b.horizon;
    const Status st = validate_camera(c);
    EXPECT_FALSE(st.ok);
    EXPECT_EQ(st.field, b.field) << st.message;
  }
  // Omnidirectional still validates the frustum's fields.
  Camera c = good;
  c.omnidirectional = true;
  c.up = c.dir;
  EXPECT_EQ(validate_camera(c).field, "up");
}

TEST(Region, FramesFilesCarryTheFieldsAndPointLinesAreUnchanged) {
  FrameInput f;
  f.t = 0.5;
  f.camera = camera_along(Vec3(1.0, 2.0, 3.0), Vec3(0.0, 0.0, 1.0));
  const std::string point = frame_to_json(f);
  EXPECT_EQ(point.find("eye_extent"), std::string::npos);
  EXPECT_EQ(point.find("omnidirectional"), std::string::npos);
  EXPECT_EQ(point.find("horizon_s"), std::string::npos);
  f.camera.eye_extent = Vec3(16.0, 0.0, 16.0);
  f.camera.omnidirectional = true;
  f.camera.horizon_s = 0.1;
  FrameInput back;
  FormatError error;
  ASSERT_TRUE(parse_frame_line(frame_to_json(f), "f.jsonl", 1, &back, &error)) << error.str();
  EXPECT_EQ(back.camera.eye_extent, f.camera.eye_extent);
  EXPECT_TRUE(back.camera.omnidirectional);
  EXPECT_EQ(back.camera.horizon_s, 0.1);
  struct Bad {
    std::string key, value, field;
  };
  const std::string head = R"({"t": 0, "eye": [0,0,0], "dir": [0,0,1], "up": [0,1,0], "fov_y_deg": 60, "aspect": 1, )"
                           R"("near": 0.1, "far": 100, )";
  for (const Bad& b : {Bad{"eye_extent", "[1, -2, 0]", "eye_extent"}, Bad{"eye_extent", "[1, 2]", "eye_extent"},
                       Bad{"eye_extent", "[1, 2, 1e13]", "eye_extent[2]"}, Bad{"horizon_s", "-1", "horizon_s"},
                       Bad{"horizon_s", "\"soon\"", "horizon_s"}, Bad{"omnidirectional", "1", "omnidirectional"}}) {
    const std::string line = head + "\"" + b.key + "\": " + b.value + "}";
    EXPECT_FALSE(parse_frame_line(line, "f.jsonl", 7, &back, &error)) << line;
    EXPECT_EQ(error.field, b.field) << error.str();
    EXPECT_EQ(error.line, 7);
  }
}

}  // namespace
}  // namespace voxvis::test
