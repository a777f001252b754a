// Occlusion for regions (region_occlusion.h): a static occluder leaves out
// what it hides from every eye of the box, and nothing more. Each case is
// checked against the sampled region reference (raycast::region_visible)
// as well as by its expected answer: a wall hides from the whole box and
// not past its edge; two walls abutting hide together (the box halved);
// an object flush with the wall's face is a tie and stays; a wall nearer
// than the near plane hides nothing; a mover that can come out from behind
// within the horizon stays; hidden movers around a closed room stay hidden
// at no cost, frame for frame as for a point camera.
#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <string>
#include <vector>

#include "scenes.h"
#include "voxvis/raycast.h"
#include "voxvis/scene.h"

namespace voxvis::test {
namespace {

bool has(const std::vector<ObjectId>& v, ObjectId id) { return std::binary_search(v.begin(), v.end(), id); }

std::string ids(const std::vector<ObjectId>& v) {
  std::string s;
  for (ObjectId id : v) {
    if (!s.empty()) s += ',';
    s += std::to_string(id);
  }
  return s;
}

SceneOptions with_buffer(int width) {
  SceneOptions o;
  o.occlusion_buffer = width;
  return o;
}

/// One region frame on a fresh scene; fails the test when the reference
/// sees anything the answer lacks.
FrameResult checked_frame(const SceneDesc& d, const Camera& cam, const SceneOptions& options = {}) {
  std::unique_ptr<Scene> scene;
  const Status st = Scene::create(d, options, &scene);
  EXPECT_TRUE(st.ok) << st.message;
  Scratch scratch;
  FrameResult fr;
  EXPECT_TRUE(scene->frame(scene->add_viewer(), cam, 0.0, scratch, &fr).ok);
  raycast::RegionSampling sampling;
  sampling.rays = raycast::RaySampling{40, 40};
  for (ObjectId id : raycast::region_visible(d.objects, cam, sampling))
    EXPECT_TRUE(has(fr.pvs, id)) << "missed " << id << " of " << ids(fr.pvs);
  return fr;
}

/// A 100-unit world with a wall 4 thick across x = 40..44 (y in 20..60, z
/// in 20..80) and an omnidirectional region of eyes 10 wide about
/// (20, 50, 50).
SceneDesc walled() {
  SceneDesc d = unit_grid(100);
  d.objects.push_back(box_between(1, Vec3(40.0, 20.0, 20.0), Vec3(44.0, 60.0, 80.0)));
  return d;
}

Camera box_of_eyes(double half = 5.0) {
  Camera cam = camera_along(Vec3(20.0, 50.0, 50.0), Vec3(1.0, 0.0, 0.0), 60.0, 1.0, 0.05, 500.0);
  cam.eye_extent = Vec3(half);
  cam.omnidirectional = true;
  return cam;
}

TEST(RegionOcclusion, AWallHidesFromEveryEyeOfTheBoxAndNotPastItsEdge) {
  SceneDesc d = walled();
  d.objects.push_back(sphere(2, Vec3(70.0, 35.0, 50.0), 2.0));  // Behind the wall.
  d.objects.push_back(sphere(3, Vec3(70.0, 75.0, 50.0), 2.0));  // Seen past its edge.
  for (int width : {0, 128}) {
    const FrameResult fr = checked_frame(d, box_of_eyes(), with_buffer(width));
    EXPECT_TRUE(has(fr.pvs, 1) && has(fr.pvs, 3)) << ids(fr.pvs);
    EXPECT_FALSE(has(fr.pvs, 2)) << "buffer " << width << ": " << ids(fr.pvs);
    EXPECT_GE(fr.stats.ob_objects_culled, 1u);
  }
  // A box of eyes reaching past the wall's edge sees behind it.
  Camera wide = box_of_eyes();
  wide.eye_extent = Vec3(5.0, 35.0, 5.0);  // Up to y = 85.
  EXPECT_TRUE(has(checked_frame(d, wide).pvs, 2));
}

TEST(RegionOcclusion, TwoWallsHideTogetherWhatNeitherHidesAlone) {
  // A moving bar behind two walls at different depths, overlapping a
  // little along y: neither hides it whole, each hides one half of it (a
  // moving object's box is halved; a static one is tested whole). Buffer
  // off: no opaque voxel box joins them.
  SceneDesc d = unit_grid(100);
  d.objects.push_back(box_between(1, Vec3(40.0, 20.0, 20.0), Vec3(44.0, 52.0, 80.0)));
  d.objects.push_back(box_between(2, Vec3(50.0, 48.0, 20.0), Vec3(54.0, 80.0, 80.0)));
  d.objects.push_back(dynamic(box_between(3, Vec3(70.0, 30.0, 48.0), Vec3(72.0, 70.0, 52.0)), 1.0));
  const FrameResult fr = checked_frame(d, box_of_eyes(1.0), with_buffer(0));
  EXPECT_FALSE(has(fr.pvs, 3)) << ids(fr.pvs);
  EXPECT_TRUE(has(fr.pvs, 1) && has(fr.pvs, 2)) << ids(fr.pvs);
  // Walls meeting at a corner of a room hide from each half of the eyes
  // by another wall: the eyes' box is halved too.
  SceneDesc corner = unit_grid(100);
  corner.objects.push_back(box_between(1, Vec3(40.0, 20.0, 20.0), Vec3(42.0, 80.0, 80.0)));
  corner.objects.push_back(box_between(2, Vec3(20.0, 20.0, 20.0), Vec3(42.0, 80.0, 22.0)));
  corner.objects.push_back(dynamic(sphere(3, Vec3(60.0, 50.0, 5.0), 1.0), 1.0));
  Camera cam = box_of_eyes(2.0);
  cam.eye = Vec3(30.0, 50.0, 35.0);
  const FrameResult fc = checked_frame(corner, cam, with_buffer(0));
  EXPECT_FALSE(has(fc.pvs, 3)) << ids(fc.pvs);
}

TEST(RegionOcclusion, AnObjectFlushWithTheWallsFaceIsATieAndStays) {
  // A box sunk into the wall with its face in the wall's face: the rays
  // that meet that face hit both at once.
  SceneDesc d = walled();
  d.objects.push_back(box_between(2, Vec3(40.0, 45.0, 45.0), Vec3(42.0, 55.0, 55.0)));
  d.objects.push_back(box_between(3, Vec3(41.0, 45.0, 45.0), Vec3(43.0, 55.0, 55.0)));  // Wholly inside.
  for (int width : {0, 128}) {
    const FrameResult fr = checked_frame(d, box_of_eyes(), with_buffer(width));
    EXPECT_TRUE(has(fr.pvs, 2)) << "buffer " << width << ": " << ids(fr.pvs);
    EXPECT_FALSE(has(fr.pvs, 3)) << "buffer " << width << ": " << ids(fr.pvs);
  }
}

TEST(RegionOcclusion, AWallNearerThanTheNearPlaneHidesNothing) {
  // A thin wall 0.5 beyond the box's front face, the near plane 1 away:
  // from the front eyes the wall is clipped away, the ball behind shows.
  SceneDesc d = unit_grid(100);
  d.objects.push_back(box_between(1, Vec3(25.5, 20.0, 20.0), Vec3(25.9, 80.0, 80.0)));
  d.objects.push_back(sphere(2, Vec3(70.0, 50.0, 50.0), 2.0));
  for (bool omni : {false, true}) {
    Camera cam = box_of_eyes();
    cam.omnidirectional = omni;
    cam.near = 1.0;
    EXPECT_TRUE(has(checked_frame(d, cam).pvs, 2)) << "omnidirectional " << omni;
    cam.near = 0.05;
    EXPECT_FALSE(has(checked_frame(d, cam).pvs, 2)) << "omnidirectional " << omni << ", near 0.05";
  }
}

TEST(RegionOcclusion, AMoverThatCanComeOutWithinTheHorizonStays) {
  // A ball moving at 100 units/s behind the wall, 10 from its edge.
  SceneDesc d = walled();
  d.objects.push_back(dynamic(sphere(2, Vec3(70.0, 45.0, 50.0), 2.0), 100.0));
  Camera cam = box_of_eyes();
  EXPECT_FALSE(has(checked_frame(d, cam).pvs, 2));
  cam.horizon_s = 0.01;  // One unit: still behind.
  EXPECT_FALSE(has(checked_frame(d, cam).pvs, 2));
  cam.horizon_s = 0.2;  // 20 units: past the edge.
  EXPECT_TRUE(has(checked_frame(d, cam).pvs, 2));
}

TEST(RegionOcclusion, HiddenMoversAroundAClosedRoomCostWhatTheyCostAPoint) {
  // A closed room (walls 2 thick) with the box of eyes inside (4 wide),
  // 40 movers outside. Every direction, 100 ms ahead: none is revealed or woken
  // beyond what the point camera's frames wake (TBV renewals), frame for
  // frame, and none enters the PVS.
  SceneDesc d = unit_grid(100);
  const Vec3 lo(30.0), hi(70.0);
  ObjectId id = 1;
  for (int a = 0; a < 3; ++a) {
    Vec3 l = lo - Vec3(2.0), h = hi + Vec3(2.0);
    h[a] = lo[a];
    d.objects.push_back(box_between(id++, l, h));
    l[a] = hi[a];
    h[a] = hi[a] + 2.0;
    d.objects.push_back(box_between(id++, l, h));
  }
  const ObjectId first_mover = id;
  // Ten behind each side wall (not behind the room's edges, where two walls
  // would have to fuse across more halvings than a frame makes).
  for (int i = 0; i < 40; ++i) {
    const double along = 35.0 + 3.0 * (i / 4), z = 40.0 + (i % 7);
    const Vec3 at[4] = {Vec3(90.0, along, z), Vec3(10.0, along, z), Vec3(along, 90.0, z), Vec3(along, 10.0, z)};
    d.objects.push_back(dynamic(sphere(id++, at[i % 4], 1.0), 5.0));
  }
  std::unique_ptr<Scene> by_point, by_region;
  ASSERT_TRUE(Scene::create(d, SceneOptions{}, &by_point).ok);
  ASSERT_TRUE(Scene::create(d, SceneOptions{}, &by_region).ok);
  Scratch scratch;
  const ViewerId vp = by_point->add_viewer(), vr = by_region->add_viewer();
  const Camera point = camera_along(Vec3(50.0), Vec3(1.0, 0.0, 0.0), 60.0, 1.0, 0.05, 500.0);
  Camera region = point;
  region.eye_extent = Vec3(2.0);
  region.omnidirectional = true;
  region.horizon_s = 0.1;
  FrameResult fp, fr;
  for (int i = 0; i < 60; ++i) {
    ASSERT_TRUE(by_point->frame(vp, point, i / 30.0, scratch, &fp).ok);
    ASSERT_TRUE(by_region->frame(vr, region, i / 30.0, scratch, &fr).ok);
    if (i == 0) continue;  // The first frame finds every mover without a TBV.
    EXPECT_EQ(fr.stats.tbvs_revealed, 0u) << "frame " << i;
    EXPECT_EQ(fr.wake, fp.wake) << "frame " << i;
    for (ObjectId m : fr.pvs) EXPECT_LT(m, first_mover) << "frame " << i;
  }
  EXPECT_EQ(fr.pvs.size(), 6u) << ids(fr.pvs);
  EXPECT_GE(fr.stats.tbvs_active, 40u);
}

}  // namespace
}  // namespace voxvis::test
