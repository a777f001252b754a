// voxvis/inspect.h: the grid read row by row (static opacity, the objects
// each voxel holds) against expectations computed from the objects'
// geometry alone, and the frame's record (FrameTrace) of both traversals:
// a wall hides what lies behind it, every voxel a ray shows before its
// first hit is visited and never occluded, and recording changes nothing.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/vector_relational.hpp>

#include "raycast.h"
#include "scenes.h"
#include "voxvis/inspect.h"
#include "voxvis/scene.h"

namespace voxvis::test {
namespace {

/// The grid as inspect_grid reads it, a value per voxel (x fastest).
struct GridDump {
  glm::ivec3 res{0};
  std::vector<std::uint8_t> opaque;
  std::vector<std::uint32_t> objects;
  std::size_t at(int x, int y, int z) const {
    return static_cast<std::size_t>(x + res.x * (y + res.y * z));
  }
};

GridDump dump(const Scene& scene, const std::vector<ObjectId>* only = nullptr) {
  GridDump d;
  d.res = scene.grid().res;
  const auto n = static_cast<std::size_t>(scene.grid().voxel_count());
  d.opaque.assign(n, 0);
  d.objects.assign(n, 0);
  int rows = 0;
  inspect_grid(
      scene,
      [&](const GridRow& r) {
        EXPECT_EQ(r.opaque.size(), static_cast<std::size_t>(d.res.x));
        EXPECT_EQ(r.objects.size(), static_cast<std::size_t>(d.res.x));
        for (int x = 0; x < d.res.x; ++x) {
          d.opaque[d.at(x, r.y, r.z)] = r.opaque[static_cast<std::size_t>(x)];
          d.objects[d.at(x, r.y, r.z)] = r.objects[static_cast<std::size_t>(x)];
        }
        ++rows;
      },
      only);
  EXPECT_EQ(rows, d.res.y * d.res.z);
  return d;
}

std::unique_ptr<Scene> build(const SceneDesc& desc, const SceneOptions& options = {}) {
  std::unique_ptr<Scene> scene;
  const Status st = Scene::create(desc, options, &scene);
  EXPECT_TRUE(st.ok) << st.str();
  return scene;
}

/// Whether the closed world box [lo, hi] meets voxel (x, y, z)'s closed
/// cube on a grid of unit voxels from the origin.
bool box_touches(const Vec3& lo, const Vec3& hi, int x, int y, int z) {
  const Vec3 v(x, y, z);
  return lo.x <= v.x + 1 && hi.x >= v.x && lo.y <= v.y + 1 && hi.y >= v.y && lo.z <= v.z + 1 && hi.z >= v.z;
}

/// Distance from point c to voxel (x, y, z)'s closed cube (unit voxels).
double distance_to_voxel(const Vec3& c, int x, int y, int z) {
  const Vec3 v(x, y, z);
  const Vec3 q = glm::clamp(c, v, v + 1.0);
  return glm::length(q - c);
}

TEST(InspectGrid, CountsAndOpacityFollowTheObjectsGeometry) {
  // Unit voxels from the origin. A box off the voxel planes, a wall on
  // them (its faces touch the neighbouring layers, closed sets), a sphere,
  // a sphere over the whole grid (stored in the top cell, not per voxel)
  // and a box of many bricks (stored in coarse cells).
  SceneDesc desc;
  desc.bounds_min = Vec3(0.0);
  desc.bounds_max = Vec3(32.0);
  desc.grid = glm::ivec3(32);
  const Vec3 box_lo(2.5, 3.5, 4.5), box_hi(6.5, 5.5, 9.5);
  const Vec3 wall_lo(0.0, 0.0, 20.0), wall_hi(32.0, 32.0, 21.0);
  const Vec3 big_lo(8.25, 8.25, 8.25), big_hi(27.75, 19.75, 18.75);
  const Vec3 ball_c(12.3, 26.4, 3.7);
  const double ball_r = 2.2;
  desc.objects = {box_between(1, box_lo, box_hi), box_between(2, wall_lo, wall_hi), sphere(3, ball_c, ball_r),
                  sphere(4, Vec3(16.0), 200.0), box_between(5, big_lo, big_hi)};
  const auto scene = build(desc);
  ASSERT_NE(scene, nullptr);
  const GridDump d = dump(*scene);
  for (int z = 0; z < 32; ++z)
    for (int y = 0; y < 32; ++y)
      for (int x = 0; x < 32; ++x) {
        const double ball_gap = distance_to_voxel(ball_c, x, y, z) - ball_r;
        if (std::fabs(ball_gap) < 1e-9) continue;  // A tangent: either answer is right.
        const std::uint32_t want = 1u + box_touches(box_lo, box_hi, x, y, z) + box_touches(wall_lo, wall_hi, x, y, z) +
                                   box_touches(big_lo, big_hi, x, y, z) + (ball_gap < 0.0);
        ASSERT_EQ(d.objects[d.at(x, y, z)], want) << "voxel " << x << "," << y << "," << z;
        EXPECT_EQ(d.opaque[d.at(x, y, z)], 1) << "inside the ball over the grid: " << x << "," << y << "," << z;
      }
  // Without the ball over everything, a voxel is opaque when it lies in the
  // wall's layer, wholly inside a box, or wholly inside the small ball (no
  // two of them meet, so no union covers more).
  desc.objects.erase(desc.objects.begin() + 3);
  const auto plain = build(desc);
  ASSERT_NE(plain, nullptr);
  const GridDump p = dump(*plain);
  std::int64_t opaque = 0;
  for (int z = 0; z < 32; ++z)
    for (int y = 0; y < 32; ++y)
      for (int x = 0; x < 32; ++x) {
        const Vec3 v(x, y, z);
        const double far_corner = glm::length(glm::max(glm::abs(v - ball_c), glm::abs(v + 1.0 - ball_c)));
        if (std::fabs(far_corner - ball_r) < 1e-9) continue;
        const bool in_wall = z == 20;
        const bool in_box = x >= 3 && x <= 5 && y == 4 && z >= 5 && z <= 8;
        const bool in_big = x >= 9 && x <= 26 && y >= 9 && y <= 18 && z >= 9 && z <= 17;
        const bool in_ball = far_corner < ball_r;
        ASSERT_EQ(p.opaque[p.at(x, y, z)] != 0, in_wall || in_box || in_big || in_ball)
            << "voxel " << x << "," << y << "," << z;
        opaque += p.opaque[p.at(x, y, z)];
      }
  EXPECT_GT(opaque, 32 * 32);
}

TEST(InspectGrid, OnlyCountsTheGivenIdsAndDynamicObjectsWhereTheyAre) {
  SceneDesc desc;
  desc.bounds_min = Vec3(-8.0);
  desc.bounds_max = Vec3(8.0);
  desc.grid = glm::ivec3(16);
  const Vec3 crate_lo(-6.5, -6.5, -6.5), crate_hi(-4.5, -3.5, -2.5);
  desc.objects = {box_between(10, crate_lo, crate_hi), dynamic(box_around(11, Vec3(2.5), Vec3(0.75)), 10.0),
                  sphere(12, Vec3(0.0), 3.0)};
  for (int ob : {0, 160}) {
    SceneOptions options;
    options.occlusion_buffer = ob;
    const auto scene = build(desc, options);
    ASSERT_NE(scene, nullptr);
    const Vec3 moved(-3.5, 4.5, 5.5);
    const Move move{11, moved};
    ASSERT_TRUE(scene->apply_moves(0.1, std::span<const Move>(&move, 1)).ok);
    // Voxel (i, j, k) is the unit cube from (-8, -8, -8) + (i, j, k).
    auto touches = [](const Vec3& lo, const Vec3& hi, int x, int y, int z) {
      return box_touches(lo + 8.0, hi + 8.0, x, y, z);
    };
    const std::vector<ObjectId> only{11, 10, 99};
    const GridDump d = dump(*scene, &only);
    std::int64_t total = 0;
    for (int z = 0; z < 16; ++z)
      for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x) {
          const std::uint32_t want = touches(crate_lo, crate_hi, x, y, z) +
                                     touches(moved - 0.75, moved + 0.75, x, y, z);
          ASSERT_EQ(d.objects[d.at(x, y, z)], want) << "ob " << ob << " voxel " << x << "," << y << "," << z;
          total += d.objects[d.at(x, y, z)];
        }
    // 3 x 4 x 5 voxels for the crate (grid 1.5 to 3.5, 4.5, 5.5), 3 x 3 x 3
    // for the moved box.
    EXPECT_EQ(total, 3 * 4 * 5 + 27);
    const std::vector<ObjectId> none;
    const GridDump e = dump(*scene, &none);
    EXPECT_TRUE(std::all_of(e.objects.begin(), e.objects.end(), [](std::uint32_t n) { return n == 0; }));
  }
}

/// The trace as a value per voxel: 0 neither, 1 visited, 2 occluded. Fails
/// the test when a box leaves the grid or two boxes overlap.
std::vector<std::uint8_t> paint(const FrameTrace& trace, const glm::ivec3& res) {
  std::vector<std::uint8_t> v(static_cast<std::size_t>(res.x) * res.y * res.z, 0);
  for (const std::uint8_t kind : {std::uint8_t{1}, std::uint8_t{2}})
    for (const VoxelBox& b : kind == 1 ? trace.visited : trace.occluded) {
      EXPECT_FALSE(b.empty());
      EXPECT_TRUE(b.lo.x >= 0 && b.lo.y >= 0 && b.lo.z >= 0 && b.hi.x < res.x && b.hi.y < res.y && b.hi.z < res.z)
          << "box " << b.lo.x << "," << b.lo.y << "," << b.lo.z << " - " << b.hi.x << "," << b.hi.y << "," << b.hi.z;
      for (int z = std::max(b.lo.z, 0); z <= std::min(b.hi.z, res.z - 1); ++z)
        for (int y = std::max(b.lo.y, 0); y <= std::min(b.hi.y, res.y - 1); ++y)
          for (int x = std::max(b.lo.x, 0); x <= std::min(b.hi.x, res.x - 1); ++x) {
            std::uint8_t& c = v[static_cast<std::size_t>(x + res.x * (y + res.y * z))];
            EXPECT_EQ(c, 0) << "voxel " << x << "," << y << "," << z << " recorded twice";
            c = kind;
          }
    }
  return v;
}

/// A wall in the middle of the view, x and y in [5, 11], z in [6, 7]; the
/// camera before it looking along +z with a 90 degree field of view, so
/// that open space shows around the wall. Spheres behind it, static and
/// dynamic, and one before it. Unit voxels, 16^3.
SceneDesc wall_scene() {
  SceneDesc desc;
  desc.bounds_min = Vec3(0.0);
  desc.bounds_max = Vec3(16.0);
  desc.grid = glm::ivec3(16);
  desc.objects = {box_between(1, Vec3(5.0, 5.0, 6.0), Vec3(11.0, 11.0, 7.0)), sphere(2, Vec3(8.2, 8.3, 12.4), 1.5),
                  dynamic(sphere(3, Vec3(6.4, 9.1, 13.3), 1.0), 1.0), sphere(4, Vec3(9.6, 7.7, 3.8), 0.5)};
  return desc;
}

Camera wall_camera() { return camera_along(Vec3(8.1, 8.2, 0.6), Vec3(0.0, 0.0, 1.0), 90.0, 1.0, 0.05, 100.0); }

TEST(FrameTrace, WallHidesWhatLiesBehindIt) {
  const Camera cam = wall_camera();
  ViewBasis basis;
  ASSERT_TRUE(make_basis(cam, &basis));
  // The image of the wall's back face (z = 7), shrunk by a margin: a point
  // beyond z = 7 that projects inside it is hidden by the wall.
  double ilo[2] = {1.0, 1.0}, ihi[2] = {-1.0, -1.0};
  for (double x : {5.0, 11.0})
    for (double y : {5.0, 11.0}) {
      double p[2];
      ASSERT_TRUE(project(cam, Vec3(x, y, 7.0), &p[0], &p[1]));
      for (int a = 0; a < 2; ++a) ilo[a] = std::fmin(ilo[a], p[a] + 0.02), ihi[a] = std::fmax(ihi[a], p[a] - 0.02);
    }
  // Whether the box of voxels [lo, lo + n) lies behind the wall, in its shadow.
  auto shadowed = [&](const glm::ivec3& lo, int n) {
    if (lo.z < 7) return false;
    for (int c = 0; c < 8; ++c) {
      const Vec3 p = Vec3(lo) + Vec3(c & 1, c >> 1 & 1, c >> 2 & 1) * static_cast<double>(n);
      double q[2];
      if (!project(cam, p, &q[0], &q[1])) return false;
      for (int a = 0; a < 2; ++a)
        if (q[a] < ilo[a] || q[a] > ihi[a]) return false;
    }
    return true;
  };
  for (int ob : {0, 160}) {
    SCOPED_TRACE("occlusion_buffer " + std::to_string(ob));
    SceneOptions options;
    options.occlusion_buffer = ob;
    const auto scene = build(wall_scene(), options);
    ASSERT_NE(scene, nullptr);
    const ViewerId viewer = scene->add_viewer();
    Scratch scratch;
    FrameTrace trace;
    scratch.set_trace(&trace);
    FrameResult r;
    ASSERT_TRUE(scene->frame(viewer, cam, 0.0, scratch, &r).ok);
    EXPECT_EQ(trace.traversal, ob > 0 ? FrameTrace::Traversal::Cells : FrameTrace::Traversal::Voxels);
    EXPECT_EQ(r.pvs, (std::vector<ObjectId>{1, 4}));
    const std::vector<std::uint8_t> v = paint(trace, scene->grid().res);
    auto at = [&](int x, int y, int z) { return v[static_cast<std::size_t>(x + 16 * (y + 16 * z))]; };
    // The wall's near layer (z = 6) is visited. The voxel traversal proves
    // the column behind the wall hidden, shell by shell, from the layer just
    // behind it (open space shows around the wall, so it goes on); the rest
    // of the wall's shadow, which widens with depth, it proves hidden only
    // in part (its exits are whole voxels: design.md, "Which shells"). The
    // cell traversal records cells whole: the bricks wholly in the shadow
    // are occluded, skipped as hidden.
    int wall = 0, hidden = 0;
    for (int z = 0; z < 16; ++z)
      for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x) {
          if (z == 6 && x >= 5 && x <= 10 && y >= 5 && y <= 10) {
            EXPECT_EQ(at(x, y, z), 1) << "wall voxel " << x << "," << y;
            ++wall;
          }
          if (ob == 0 && z >= 7 && x >= 5 && x <= 10 && y >= 5 && y <= 10) {
            EXPECT_EQ(at(x, y, z), 2) << "voxel " << x << "," << y << "," << z << " behind the wall";
            ++hidden;
          }
          if (ob > 0 && shadowed(glm::ivec3(x, y, z) & ~3, 4)) {
            EXPECT_EQ(at(x, y, z), 2) << "voxel " << x << "," << y << "," << z << " in a brick behind the wall";
            ++hidden;
          }
        }
    EXPECT_EQ(wall, 36);
    EXPECT_GT(hidden, 0);
    // The dynamic sphere makes the cell traversal test empty cells too: then
    // every voxel wholly in the frustum is visited or occluded.
    if (ob > 0) {
      for (int z = 0; z < 16; ++z)
        for (int y = 0; y < 16; ++y)
          for (int x = 0; x < 16; ++x) {
            bool inside = true;
            for (int c = 0; c < 8 && inside; ++c) {
              const Vec3 p(x + (c & 1), y + (c >> 1 & 1), z + (c >> 2 & 1));
              double px = 0.0, py = 0.0;
              const double depth = glm::dot(p - basis.eye, basis.f);
              inside = project(cam, p, &px, &py) && std::fabs(px) < 0.999 && std::fabs(py) < 0.999 &&
                       depth > cam.near * 1.001 && depth < cam.far * 0.999;
            }
            if (inside) {
              EXPECT_NE(at(x, y, z), 0) << "voxel " << x << "," << y << "," << z << " in view";
            }
          }
    }
  }
}

/// Voxels (grid indices) the rays of `cam` pass through before their first
/// hit, from the near plane: visible space. Points within 1e-6 voxel of a
/// voxel's face are left out (either voxel may hold them).
std::vector<glm::ivec3> visible_voxels(const std::vector<ObjectDesc>& objects, const Camera& cam, const GridSpec& g,
                                       std::uint64_t seed) {
  ViewBasis b;
  std::vector<glm::ivec3> out;
  if (!make_basis(cam, &b)) return out;
  Rng rng(seed);
  for (int ray = 0; ray < 400; ++ray) {
    const Vec3 d = b.ray_dir(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0));
    double hit = b.far;  // d . f = 1: t is the depth.
    for (const ObjectDesc& o : objects) {
      double t0 = 0.0, t1 = 0.0;
      if (intersect(o, b.eye, d, &t0, &t1) && t1 >= b.near) hit = std::fmin(hit, std::fmax(t0, b.near));
    }
    for (int k = 1; k < 40; ++k) {
      const double t = b.near + (hit - b.near) * (k / 40.0);
      const Vec3 q = (b.eye + t * d - g.bounds_min) / g.voxel_size;
      const Vec3 f = glm::floor(q);
      if (glm::any(glm::lessThan(glm::min(q - f, f + 1.0 - q), Vec3(1e-6)))) continue;
      const glm::ivec3 v(f);
      if (glm::all(glm::greaterThanEqual(v, glm::ivec3(0))) && glm::all(glm::lessThan(v, g.res))) out.push_back(v);
    }
  }
  return out;
}

TEST(FrameTrace, VisibleVoxelsAreVisitedAndRecordingChangesNothing) {
  // Random scenes with moving objects, their camera paths, both
  // traversals: twin scenes run the same frames, one recording; the answers
  // (PVS, wake, counters) must be equal, and every voxel a ray shows before
  // its first hit must be visited (the scenes have dynamic objects, so the
  // cell traversal tests empty cells too), never occluded.
  std::size_t checked = 0;
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(scaled(6)); ++seed)
    for (int ob : {0, 160}) {
      const std::string label = "seed " + std::to_string(seed) + " ob " + std::to_string(ob);
      SCOPED_TRACE(label);
      RandomSceneParams params = random_scene_params(seed);
      params.dynamic_fraction = std::max(params.dynamic_fraction, 0.2);
      const SceneDesc desc = random_scene(params, seed);
      SceneOptions options;
      options.occlusion_buffer = ob;
      const auto plain = build(desc, options), traced = build(desc, options);
      ASSERT_NE(plain, nullptr);
      ASSERT_NE(traced, nullptr);
      const ViewerId vp = plain->add_viewer(), vt = traced->add_viewer();
      Scratch sp, st;
      FrameTrace trace;
      st.set_trace(&trace);
      Mover mover(desc, mix_seed(seed, 7));
      CameraPathParams path;
      path.frames = 8;
      const std::vector<Camera> cams = random_camera_path(desc, mix_seed(seed, 3), path);
      for (std::size_t i = 0; i < cams.size(); ++i) {
        const double t = 0.05 * static_cast<double>(i);
        const std::vector<Move> moves = i == 0 ? std::vector<Move>{} : mover.step(0.05);
        ASSERT_TRUE(plain->apply_moves(t, moves).ok);
        ASSERT_TRUE(traced->apply_moves(t, moves).ok);
        FrameResult a, b;
        ASSERT_TRUE(plain->frame(vp, cams[i], t, sp, &a).ok);
        ASSERT_TRUE(traced->frame(vt, cams[i], t, st, &b).ok);
        EXPECT_EQ(a.pvs, b.pvs) << "frame " << i;
        EXPECT_EQ(a.wake, b.wake) << "frame " << i;
        const FrameStats& x = a.stats;
        const FrameStats& y = b.stats;
        EXPECT_TRUE(x.voxels_visited == y.voxels_visited && x.cells_visited == y.cells_visited &&
                    x.cells_hidden == y.cells_hidden && x.cells_whole == y.cells_whole &&
                    x.ob_voxels_culled == y.ob_voxels_culled && x.front_voxels_culled == y.front_voxels_culled &&
                    x.tbvs_created == y.tbvs_created && x.tbvs_revealed == y.tbvs_revealed &&
                    x.early_exit == y.early_exit && x.shells == y.shells)
            << "frame " << i << ": counters differ";
        const GridSpec& g = traced->grid();
        const std::vector<std::uint8_t> v = paint(trace, g.res);
        if (trace.traversal == FrameTrace::Traversal::None) continue;
        // Without dynamic objects the cell traversal does not test empty
        // cells: a visible voxel there may be neither, never occluded.
        const bool all_tested = ob == 0 || traced->dynamic_count() > 0;
        for (const glm::ivec3& p : visible_voxels(mover.objects(), cams[i], g, mix_seed(seed, i))) {
          const std::uint8_t c = v[static_cast<std::size_t>(p.x + g.res.x * (p.y + g.res.y * p.z))];
          ASSERT_TRUE(c == 1 || (c == 0 && !all_tested))
              << "frame " << i << ": visible voxel " << p.x << "," << p.y << "," << p.z
              << (c == 2 ? " occluded" : " not visited");
          ++checked;
        }
      }
    }
  EXPECT_GT(checked, 1000u);  // The rays did show space.
}

TEST(FrameTrace, ClearedEachFrameAndOffWhenUnset) {
  const auto scene = build(wall_scene());
  ASSERT_NE(scene, nullptr);
  const ViewerId viewer = scene->add_viewer();
  Scratch scratch;
  FrameTrace trace;
  trace.visited.push_back(VoxelBox{glm::ivec3(0), glm::ivec3(0)});
  scratch.set_trace(&trace);
  FrameResult r;
  // Looking away from the grid: no traversal, nothing recorded.
  ASSERT_TRUE(scene->frame(viewer, camera_along(Vec3(8.0, 8.0, -1.0), Vec3(0.0, 0.0, -1.0)), 0.0, scratch, &r).ok);
  EXPECT_EQ(trace.traversal, FrameTrace::Traversal::None);
  EXPECT_TRUE(trace.visited.empty() && trace.occluded.empty());
  ASSERT_TRUE(scene->frame(viewer, wall_camera(), 0.1, scratch, &r).ok);
  EXPECT_EQ(trace.traversal, FrameTrace::Traversal::Cells);
  const std::size_t recorded = trace.visited.size() + trace.occluded.size();
  EXPECT_GT(recorded, 0u);
  scratch.set_trace(nullptr);
  ASSERT_TRUE(scene->frame(viewer, wall_camera(), 0.2, scratch, &r).ok);
  EXPECT_EQ(trace.visited.size() + trace.occluded.size(), recorded);
}

}  // namespace
}  // namespace voxvis::test
