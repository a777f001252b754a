// Occlusion for regions (region_occlusion.h): a static occluder leaves out
// what it hides from every eye of the box, and nothing more. Each case is
// checked against the sampled region reference (raycast::region_visible)
// as well as by its expected answer: a wall hides from the whole box and
// not past its edge; two walls abutting hide together (the box halved);
// an object flush with the wall's face is a tie and stays; a wall nearer
// than the near plane hides nothing; a mover that can come out from behind
// within the horizon stays; hidden movers around a closed room, even
// diagonally behind its edges, stay hidden at no cost, frame for frame as
// for a point camera (the room's free space, region_cavity.h); a doorway
// lets the room see out, and movers far outside a closed room are never
// even tested (region_candidates.h).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "describe.h"
#include "scenes.h"
#include "voxvis/raycast.h"
#include "voxvis/scene.h"

namespace voxvis::test {
namespace {

bool has(const std::vector<ObjectId>& v, ObjectId id) { return std::binary_search(v.begin(), v.end(), id); }

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
    EXPECT_TRUE(has(fr.pvs, id)) << "missed " << id << " of " << describe_ids(fr.pvs);
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
    EXPECT_TRUE(has(fr.pvs, 1) && has(fr.pvs, 3)) << describe_ids(fr.pvs);
    EXPECT_FALSE(has(fr.pvs, 2)) << "buffer " << width << ": " << describe_ids(fr.pvs);
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
  EXPECT_FALSE(has(fr.pvs, 3)) << describe_ids(fr.pvs);
  EXPECT_TRUE(has(fr.pvs, 1) && has(fr.pvs, 2)) << describe_ids(fr.pvs);
  // Walls meeting at a corner of a room hide from each half of the eyes
  // by another wall: the eyes' box is halved too.
  SceneDesc corner = unit_grid(100);
  corner.objects.push_back(box_between(1, Vec3(40.0, 20.0, 20.0), Vec3(42.0, 80.0, 80.0)));
  corner.objects.push_back(box_between(2, Vec3(20.0, 20.0, 20.0), Vec3(42.0, 80.0, 22.0)));
  corner.objects.push_back(dynamic(sphere(3, Vec3(60.0, 50.0, 5.0), 1.0), 1.0));
  Camera cam = box_of_eyes(2.0);
  cam.eye = Vec3(30.0, 50.0, 35.0);
  const FrameResult fc = checked_frame(corner, cam, with_buffer(0));
  EXPECT_FALSE(has(fc.pvs, 3)) << describe_ids(fc.pvs);
}

TEST(RegionOcclusion, AnObjectFlushWithTheWallsFaceIsATieAndStays) {
  // A box sunk into the wall with its face in the wall's face: the rays
  // that meet that face hit both at once.
  SceneDesc d = walled();
  d.objects.push_back(box_between(2, Vec3(40.0, 45.0, 45.0), Vec3(42.0, 55.0, 55.0)));
  d.objects.push_back(box_between(3, Vec3(41.0, 45.0, 45.0), Vec3(43.0, 55.0, 55.0)));  // Wholly inside.
  for (int width : {0, 128}) {
    const FrameResult fr = checked_frame(d, box_of_eyes(), with_buffer(width));
    EXPECT_TRUE(has(fr.pvs, 2)) << "buffer " << width << ": " << describe_ids(fr.pvs);
    EXPECT_FALSE(has(fr.pvs, 3)) << "buffer " << width << ": " << describe_ids(fr.pvs);
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

/// A closed room [30, 70]^3 (walls 2 thick, overlapping at the edges), with
/// a doorway in its +x wall when `door`, in a 100-unit world.
SceneDesc room(bool door) {
  SceneDesc d = unit_grid(100);
  const Vec3 lo(30.0), hi(70.0);
  ObjectId id = 1;
  for (int a = 0; a < 3; ++a) {
    Vec3 l = lo - Vec3(2.0), h = hi + Vec3(2.0);
    h[a] = lo[a];
    d.objects.push_back(box_between(id++, l, h));
    l[a] = hi[a];
    h[a] = hi[a] + 2.0;
    if (a == 0 && door) {  // The +x wall in two, a doorway 8 wide at y in 46..54.
      d.objects.push_back(box_between(id++, l, Vec3(h.x, 46.0, h.z)));
      d.objects.push_back(box_between(id++, Vec3(l.x, 54.0, l.z), h));
    } else {
      d.objects.push_back(box_between(id++, l, h));
    }
  }
  return d;
}

TEST(RegionOcclusion, HiddenMoversAroundAClosedRoomCostWhatTheyCostAPoint) {
  // The box of eyes (8 wide) inside the closed room, 40 movers on a ring
  // outside it, many diagonally behind its edges (where no one wall hides
  // them: the room's free space does). Every direction, 100 ms ahead: none
  // is revealed, none enters the PVS, and a frame wakes only the TBVs that
  // expired in it, as the point camera's frames do. (Which expire differs:
  // the region records more space seen, so fewer of its TBVs start long;
  // scene_tbv.cpp, make_tbv.)
  SceneDesc d = room(false);
  const auto first_mover = static_cast<ObjectId>(d.objects.size() + 1);
  for (int i = 0; i < 40; ++i) {
    const double u = 0.157 * i;
    d.objects.push_back(dynamic(sphere(static_cast<ObjectId>(first_mover + i),
                                       Vec3(50.0 + 40.0 * std::cos(u), 50.0 + 40.0 * std::sin(u), 10.0 + i), 1.0),
                                1.0));
  }
  const Camera point = camera_along(Vec3(50.0), Vec3(1.0, 0.0, 0.0), 60.0, 1.0, 0.05, 500.0);
  Camera region = point;
  region.eye_extent = Vec3(4.0);
  region.omnidirectional = true;
  region.horizon_s = 0.1;
  FrameResult fr;
  ASSERT_EQ(frames_side_by_side(d, point, d, region, 60, 30.0,
                                [&](int i, const FrameResult& fp, const FrameResult& r) {
                                  fr = r;
                                  if (i == 0) return;  // The first frame finds every mover without a TBV.
                                  EXPECT_EQ(r.stats.tbvs_revealed, 0u) << "frame " << i;
                                  EXPECT_EQ(r.wake.size(), r.stats.tbvs_expired) << "frame " << i;
                                  EXPECT_EQ(fp.wake.size(), fp.stats.tbvs_expired) << "frame " << i;
                                  for (ObjectId m : r.pvs) EXPECT_LT(m, first_mover) << "frame " << i;
                                }),
            "");
  EXPECT_EQ(fr.pvs.size(), 6u) << describe_ids(fr.pvs);
  EXPECT_GE(fr.stats.tbvs_active, 40u);
  // The walls alone (no free space: a scene without movers builds none)
  // would not hide the movers behind the edges; the reference agrees with
  // the answer on a static copy.
  SceneDesc still = d;
  for (ObjectDesc& o : still.objects) o.dynamic = false;
  const FrameResult fs = checked_frame(still, region);
  EXPECT_GT(fs.pvs.size(), 6u) << "the umbra test alone hid the ring";
}

/// `n` movers (speed 1, radius 0.3) far from the room of room(): each in a
/// band 2..14 or 86..98 along one axis, at least 12 voxels beyond what a
/// frame of eyes in the room can reach within 100 ms (its free space, 30..70,
/// grown by a voxel and the reach, and a TBV's 8 voxels).
void add_far_movers(SceneDesc* d, int n, std::uint64_t seed) {
  Rng rng(seed);
  auto id = static_cast<ObjectId>(d->objects.size() + 1);
  for (int i = 0; i < n; ++i) {
    Vec3 c(rng.uniform(2.0, 98.0), rng.uniform(2.0, 98.0), rng.uniform(2.0, 98.0));
    c[rng.uniform_int(0, 2)] = rng.chance(0.5) ? rng.uniform(2.0, 14.0) : rng.uniform(86.0, 98.0);
    d->objects.push_back(dynamic(sphere(id++, c, 0.3), 1.0));
  }
}

TEST(RegionOcclusion, MoversFarOutsideAClosedRoomAreNeverTested) {
  // A region frame finds the movers through the cells its eyes' free space
  // can reach (region_candidates.h): 1,000 movers far outside the closed
  // room are neither tested nor kept, frame after frame, while the five
  // inside are kept; the same frames of a scene without the far movers give
  // the same answers.
  SceneDesc d = room(false);
  const auto inside = static_cast<ObjectId>(d.objects.size() + 1);
  for (int i = 0; i < 5; ++i)
    d.objects.push_back(dynamic(sphere(static_cast<ObjectId>(inside + i), Vec3(35.0 + 7.0 * i, 40.0, 60.0), 1.0), 1.0));
  SceneDesc crowded = d;
  add_far_movers(&crowded, 1000, 7);
  Camera cam = box_of_eyes(2.0);
  cam.eye = Vec3(50.0);
  cam.horizon_s = 0.1;
  FrameResult b;
  ASSERT_EQ(frames_side_by_side(d, cam, crowded, cam, 60, 30.0,
                                [&](int i, const FrameResult& a, const FrameResult& r) {
                                  b = r;
                                  EXPECT_EQ(r.pvs, a.pvs) << "frame " << i;
                                  if (i == 0) return;  // The first frame finds every mover without a TBV.
                                  EXPECT_EQ(r.stats.ob_objects_culled, a.stats.ob_objects_culled)
                                      << "frame " << i << ": far movers tested";
                                  EXPECT_EQ(r.stats.tbvs_revealed, 0u) << "frame " << i;
                                }),
            "");
  for (int i = 0; i < 5; ++i) EXPECT_TRUE(has(b.pvs, static_cast<ObjectId>(inside + i))) << describe_ids(b.pvs);
  EXPECT_EQ(b.pvs.size(), 11u) << describe_ids(b.pvs);
  EXPECT_GE(b.stats.tbvs_active, 1000u);
}

TEST(RegionOcclusion, HiddenMoversTbvsDoNotGrowIntoTheSpaceTheEyesSee) {
  // A wall 4 thick across the whole grid, movers 3 to 6 units behind it, a
  // box of eyes on the other side, every direction, 100 ms ahead, for 16 s
  // of frames: the movers' TBVs double to 8 units and would reach through
  // the wall into the eyes' space, to be revealed by the next frame; the
  // region frames record that space as seen (region_candidates.h), so the
  // TBVs stop short of it and none is ever revealed.
  SceneDesc d = unit_grid(100);
  d.objects.push_back(box_between(1, Vec3(40.0, -10.0, -10.0), Vec3(44.0, 110.0, 110.0)));
  for (int i = 0; i < 40; ++i)
    d.objects.push_back(dynamic(sphere(static_cast<ObjectId>(2 + i), Vec3(47.5 + 0.075 * i, 10.0 + 2.0 * i, 50.0), 0.5), 1.0));
  std::unique_ptr<Scene> scene;
  ASSERT_TRUE(Scene::create(d, SceneOptions{}, &scene).ok);
  Scratch scratch;
  const ViewerId v = scene->add_viewer();
  Camera cam = box_of_eyes(2.0);
  cam.horizon_s = 0.1;
  FrameResult fr;
  std::uint32_t revealed = 0;
  for (int i = 0; i < 160; ++i) {
    ASSERT_TRUE(scene->frame(v, cam, i / 10.0, scratch, &fr).ok);
    EXPECT_EQ(fr.pvs, (std::vector<ObjectId>{1})) << "frame " << i << ": " << describe_ids(fr.pvs);
    if (i > 0) revealed += fr.stats.tbvs_revealed;
  }
  EXPECT_EQ(revealed, 0u);
  EXPECT_EQ(fr.stats.tbvs_active, 40u);
}

TEST(RegionOcclusion, AMoverBeyondTheGridShowsThroughADoorwayOnly) {
  // A mover wholly beyond the grid box, in line with the doorway's opening,
  // among 1,000 far movers: kept when the room has the doorway (the eyes'
  // free space reaches the grid's boundary), left out when it is closed.
  for (const bool door : {true, false}) {
    SceneDesc d = room(door);
    const auto beyond = static_cast<ObjectId>(d.objects.size() + 1);
    d.objects.push_back(dynamic(sphere(beyond, Vec3(110.0, 50.0, 50.0), 2.0), 1.0));
    add_far_movers(&d, 1000, 11);
    Camera cam = box_of_eyes(2.0);
    cam.eye = Vec3(50.0);
    cam.horizon_s = 0.05;
    std::unique_ptr<Scene> scene;
    ASSERT_TRUE(Scene::create(d, SceneOptions{}, &scene).ok);
    Scratch scratch;
    FrameResult fr;
    ASSERT_TRUE(scene->frame(scene->add_viewer(), cam, 0.0, scratch, &fr).ok);
    EXPECT_EQ(has(fr.pvs, beyond), door) << (door ? "doorway" : "closed") << ": " << describe_ids(fr.pvs);
  }
  // The reference sees it through the doorway (the far movers left out:
  // they only slow the ray caster).
  SceneDesc d = room(true);
  d.objects.push_back(dynamic(sphere(static_cast<ObjectId>(d.objects.size() + 1), Vec3(110.0, 50.0, 50.0), 2.0), 1.0));
  Camera cam = box_of_eyes(2.0);
  cam.eye = Vec3(50.0);
  cam.horizon_s = 0.05;
  EXPECT_TRUE(has(checked_frame(d, cam).pvs, static_cast<ObjectId>(d.objects.size())));
}

TEST(RegionOcclusion, ADoorwayLetsTheRoomSeeOut) {
  // The same room with a doorway in its +x wall: the free space inside
  // reaches the whole world, so nothing is hidden by it; a mover in line
  // with the doorway shows, one behind a solid wall does not.
  SceneDesc d = room(true);
  const auto ahead = static_cast<ObjectId>(d.objects.size() + 1);
  d.objects.push_back(dynamic(sphere(ahead, Vec3(90.0, 50.0, 50.0), 1.0), 1.0));
  d.objects.push_back(dynamic(sphere(ahead + 1, Vec3(10.0, 50.0, 50.0), 1.0), 1.0));
  Camera cam = box_of_eyes(2.0);
  cam.eye = Vec3(50.0);
  cam.horizon_s = 0.05;
  const FrameResult fr = checked_frame(d, cam);
  EXPECT_TRUE(has(fr.pvs, ahead)) << describe_ids(fr.pvs);
  EXPECT_FALSE(has(fr.pvs, ahead + 1)) << describe_ids(fr.pvs);
}

}  // namespace
}  // namespace voxvis::test
