// The cell pyramid (grid/src/cells.h) and what it bounds: objects stored
// once per cell they wholly touch cost about their surface, not their
// volume; Scene::estimate counts exactly what Scene::create stores and
// refuses over a limit before building; builds and estimates can be
// cancelled.
//
// Before the pyramid, 1,000 spheres covering an 84^3 grid cost 682 MB and
// 5.4 s to build (each stored in every voxel it touches), and nothing
// refused them.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <string>
#include <thread>
#include <vector>

#include "engine_check.h"
#include "scene_impl.h"
#include "scenes.h"
#include "voxvis/generate.h"
#include "voxvis/rng.h"
#include "voxvis/scene.h"

namespace voxvis::test {
namespace {

/// How many times object `slot` is stored along voxel (x, y, z)'s chain of
/// cells (its own list and the coarser cells holding it).
int stored(const Scene::Impl& s, std::uint32_t slot, int x, int y, int z) {
  int n = 0;
  for (int l = 0; l < s.pyr.levels; ++l) {
    const detail::IdLists& lists = s.static_lists[static_cast<std::size_t>(l)];
    if (lists.offsets.empty()) continue;
    const int sh = detail::kCellShift * l;
    const std::size_t c = s.pyr.index(l, glm::ivec3(x >> sh, y >> sh, z >> sh));
    n += static_cast<int>(std::count(lists.begin(c), lists.end(c), slot));
  }
  return n;
}

std::uint64_t static_entries(const Scene::Impl& s) {
  std::uint64_t n = 0;
  for (int l = 0; l < s.pyr.levels; ++l) n += s.static_lists[static_cast<std::size_t>(l)].ids.size();
  return n;
}

TEST(Cells, PyramidLevelsEndInOneCell) {
  for (const glm::ivec3& r : {glm::ivec3(1), glm::ivec3(4), glm::ivec3(5, 1, 17), glm::ivec3(100, 60, 100),
                              glm::ivec3(8192, 1, 3)}) {
    const detail::Pyramid p = detail::Pyramid::make(r);
    EXPECT_EQ(p.res[static_cast<std::size_t>(p.levels - 1)], glm::ivec3(1));
    EXPECT_LE(p.levels, detail::kMaxLevels);
    for (int l = 1; l < p.levels; ++l)
      EXPECT_EQ(p.res[static_cast<std::size_t>(l)], (p.res[static_cast<std::size_t>(l - 1)] + 3) / 4);
  }
}

TEST(Cells, EveryTouchedVoxelHoldsItsObjectExactlyOnceAndNoOtherDoes) {
  // Random balls and boxes of every size on random non-cubic grids: along
  // each voxel's chain of cells an object is stored once when it touches
  // the voxel and never when it is clearly away (rounding may add a voxel
  // the object touches within an ulp; none is ever missing).
  Rng rng(0xce115);
  const int cases = scaled(60);
  for (int k = 0; k < cases; ++k) {
    SceneDesc d;
    d.bounds_min = Vec3(rng.uniform(-50, 50), rng.uniform(-50, 50), rng.uniform(-50, 50));
    d.bounds_max = d.bounds_min + Vec3(rng.uniform(10, 100), rng.uniform(10, 100), rng.uniform(10, 100));
    d.grid = glm::ivec3(rng.uniform_int(1, 40), rng.uniform_int(1, 40), rng.uniform_int(1, 40));
    const Vec3 ext = d.bounds_max - d.bounds_min;
    const double size = std::exp(rng.uniform(std::log(0.01), std::log(1.5))) * std::fmax(ext.x, std::fmax(ext.y, ext.z));
    const Vec3 c = d.bounds_min + Vec3(rng.uniform(-0.3, 1.3), rng.uniform(-0.3, 1.3), rng.uniform(-0.3, 1.3)) * ext;
    d.objects.push_back(rng.uniform_int(0, 1) ? sphere(1, c, 0.5 * size)
                                               : box_around(1, c, Vec3(rng.uniform(0.05, 0.5), rng.uniform(0.05, 0.5),
                                                                       rng.uniform(0.05, 0.5)) * size));
    std::unique_ptr<Scene> scene;
    ASSERT_TRUE(Scene::create(d, buffer_off(), &scene).ok);
    const Scene::Impl& s = scene->impl();
    const detail::Obj& o = s.objs[0];
    for (int z = 0; z < s.res.z; ++z)
      for (int y = 0; y < s.res.y; ++y)
        for (int x = 0; x < s.res.x; ++x) {
          const int n = stored(s, 0, x, y, z);
          if (s.touches(o, o.center, x, y, z)) {
            ASSERT_EQ(n, 1) << "case " << k << " voxel " << x << "," << y << "," << z;
          } else {
            ASSERT_LE(n, 1) << "case " << k;
            if (n == 1) {
              // Only where the object is within a rounding of the voxel.
              detail::Obj grown = o;
              grown.radius *= 1.0 + 1e-9;
              grown.half *= 1.0 + 1e-9;
              EXPECT_TRUE(s.touches(grown, grown.center, x, y, z)) << "case " << k << " voxel " << x << "," << y << "," << z;
            }
          }
        }
  }
}

/// `n` spheres of radius 1e12 in bounds of +-1e12 (each reaches over most
/// of the automatic 84^3 grid): the report's scene.
SceneDesc huge_spheres(int n, std::uint64_t seed, bool dynamic = false) {
  Rng rng(seed);
  SceneDesc d;
  d.bounds_min = Vec3(-1e12);
  d.bounds_max = Vec3(1e12);
  for (int i = 0; i < n; ++i) {
    ObjectDesc o = sphere(static_cast<ObjectId>(i + 1), rng.in_box(Vec3(-1e12), Vec3(1e12)), 1e12);
    if (dynamic) o = test::dynamic(o, 1e9);
    d.objects.push_back(o);
  }
  return d;
}

TEST(Cells, ObjectsCoveringTheGridCostTheirSurfaceAndTheEstimateIsExact) {
  const SceneDesc d = huge_spheres(scaled(100), 11);
  SceneCost cost;
  ASSERT_TRUE(Scene::estimate(d, {}, &cost).ok);
  std::unique_ptr<Scene> scene;
  ASSERT_TRUE(Scene::create(d, {}, &scene).ok);
  const Scene::Impl& s = scene->impl();
  EXPECT_EQ(cost.res, s.res);
  EXPECT_EQ(cost.id_entries, static_entries(s));
  // Per voxel storage would be (objects x voxels touched), over 300,000 an
  // object here; the pyramid stores about the surface the grid holds.
  std::uint64_t touched = 0;
  for (int z = 0; z < s.res.z; z += 7)
    for (int y = 0; y < s.res.y; y += 7)
      for (int x = 0; x < s.res.x; x += 7)
        for (std::uint32_t slot = 0; slot < 5; ++slot) touched += s.touches(s.objs[slot], s.objs[slot].center, x, y, z);
  const double per_object_volume = static_cast<double>(touched) / 5.0 * 343.0;
  const double per_object_stored = static_cast<double>(cost.id_entries) / static_cast<double>(d.objects.size());
  EXPECT_LT(per_object_stored, 0.15 * per_object_volume) << per_object_stored << " vs " << per_object_volume;
  EXPECT_LT(cost.bytes, std::uint64_t{64} << 20);
  // And the scene answers, conservatively.
  EngineHarness h(d, {}, "huge spheres");
  ASSERT_TRUE(h.status().ok);
  ASSERT_EQ(h.frame(camera_along(Vec3(0, 0, -9.9e11), Vec3(0, 0, 1), 60.0, 1.5, 1.0, 1e13), 0.0), "");
  ASSERT_EQ(h.frame(camera_along(Vec3(3e11, -2e11, 1e11), Vec3(-1, 0.2, 0.5), 90.0, 1.0, 1.0, 1e13), 0.1), "");
}

TEST(Cells, TheEstimateMatchesWhatCreateStoresOnEveryKindOfScene) {
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(scaled(12)); ++seed) {
    const SceneDesc d = random_scene(random_scene_params(seed), seed);
    SceneCost cost;
    ASSERT_TRUE(Scene::estimate(d, {}, &cost).ok);
    std::unique_ptr<Scene> scene;
    ASSERT_TRUE(Scene::create(d, {}, &scene).ok);
    std::uint64_t dyn = 0;
    for (const ObjectDesc& o : d.objects) dyn += o.dynamic;
    if (dyn == 0) {
      EXPECT_EQ(cost.id_entries, static_entries(scene->impl())) << "seed " << seed;
    }
    EXPECT_GE(cost.id_entries, static_entries(scene->impl())) << "seed " << seed;
  }
}

TEST(Cells, AScenePastTheLimitIsRefusedBeforeItIsBuiltNamingTheFigures) {
  const SceneDesc d = huge_spheres(scaled(200), 12);
  SceneCost cost;
  ASSERT_TRUE(Scene::estimate(d, {}, &cost).ok);
  BuildControl limit;
  limit.max_bytes = cost.bytes / 2;
  for (const bool build : {false, true}) {
    std::unique_ptr<Scene> scene;
    SceneCost c2;
    const Status st = build ? Scene::create(d, {}, &scene, &limit) : Scene::estimate(d, {}, &c2, &limit);
    EXPECT_EQ(st.code, Status::Code::ResourceExhausted);
    EXPECT_EQ(st.field, "memory");
    // It stopped counting once past the limit, and says how far it got.
    EXPECT_NE(st.message.find("the scene needs at least "), std::string::npos) << st.message;
    EXPECT_NE(st.message.find(" of " + std::to_string(d.objects.size()) + " objects, grid 84x84x84)"), std::string::npos)
        << st.message;
    EXPECT_NE(st.message.find("over the limit of "), std::string::npos) << st.message;
    EXPECT_EQ(scene, nullptr);
  }
  // A grid alone over the limit is refused before any object is counted.
  SceneDesc big;
  big.bounds_max = Vec3(1.0);
  big.grid = glm::ivec3(512);
  big.objects = {sphere(1, Vec3(0.5), 0.1)};
  limit.max_bytes = 1 << 20;
  SceneCost c3;
  const Status st = Scene::estimate(big, {}, &c3, &limit);
  EXPECT_EQ(st.code, Status::Code::ResourceExhausted);
  EXPECT_NE(st.message.find("the grid 512x512x512 alone needs about "), std::string::npos) << st.message;
  // Within the limit (the scene and its build's temporaries): built.
  limit.max_bytes = cost.bytes + cost.build_bytes;
  std::unique_ptr<Scene> scene;
  EXPECT_TRUE(Scene::create(d, {}, &scene, &limit).ok);
}

TEST(Cells, BuildsAndEstimatesStopWhenCancelled) {
  const SceneDesc d = huge_spheres(scaled(300), 13);
  // Cancelled from the start, after a few polls, and from another thread.
  for (int after : {0, 3}) {
    int polls = 0;
    BuildControl control;
    control.cancelled = [&] { return polls++ >= after; };
    std::unique_ptr<Scene> scene;
    const Status st = Scene::create(d, {}, &scene, &control);
    EXPECT_EQ(st.code, Status::Code::Cancelled) << st.str();
    EXPECT_EQ(scene, nullptr);
    polls = 0;
    SceneCost cost;
    EXPECT_EQ(Scene::estimate(d, {}, &cost, &control).code, Status::Code::Cancelled);
  }
  std::atomic<bool> stop{false};
  BuildControl control;
  control.cancelled = [&] { return stop.load(); };
  std::thread canceller([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    stop = true;
  });
  std::unique_ptr<Scene> scene;
  const Status st = Scene::create(huge_spheres(scaled(3000), 14), {}, &scene, &control);
  canceller.join();
  EXPECT_EQ(st.code, Status::Code::Cancelled) << st.str();
}

TEST(Cells, HugeDynamicObjectsMoveAtTheCostOfTheirSurface) {
  // Dynamic balls over the whole grid: their entries go to the coarsest
  // cells inside their range of bricks, they add no dynamic opacity (a move
  // would otherwise test every voxel they cover), and frames stay
  // conservative while they move, hide and come back.
  SceneDesc d = huge_spheres(scaled(40), 15, true);
  d.objects.push_back(dynamic(sphere(100000, Vec3(1e11, 0, 0), 3e10), 1e9));  // Small: opacity as usual.
  EngineHarness h(d, buffer_off(), "huge dynamic");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  const Scene::Impl& s = h.scene().impl();
  std::uint64_t entries = 0;
  for (const detail::Brick& b : s.bricks) entries += b.live;
  for (const auto& level : s.coarse_dyn)
    for (const detail::Brick& b : level) entries += b.live;
  EXPECT_LT(entries, 1200u * d.objects.size()) << "entries " << entries;  // 84^3 has 9,261 bricks.
  for (std::size_t i = 0; i + 1 < s.objs.size(); ++i) EXPECT_TRUE(s.objs[i].no_opacity);
  EXPECT_FALSE(s.objs.back().no_opacity);
  Mover mover(d, 16);
  const Camera cam = camera_along(Vec3(0, 0, -9.9e11), Vec3(0, 0, 1), 60.0, 1.5, 1.0, 1e13);
  double t = 0.0;
  for (int f = 0; f < 6; ++f) {
    t += 1.0;
    ASSERT_TRUE(h.move(t, mover.step(1.0)).ok);
    ASSERT_EQ(h.frame(f % 2 ? cam : camera_along(Vec3(9e11, 9e11, 9e11), Vec3(1, 1, 1), 10.0, 1.0, 1.0, 1e13), t), "");
  }
}

/// Checks the cell traversal's masks against the cells' content, counted
/// afresh: a static bit set iff the child (or a cell below it) holds static
/// content, a dynamic count equal to the live entries in the cell and below
/// it, a dynamic bit set iff the child's count is not 0. "" when they agree.
std::string check_masks(const Scene::Impl& s) {
  const int levels = s.pyr.levels;
  std::vector<std::vector<std::uint64_t>> live(static_cast<std::size_t>(levels));
  std::vector<std::vector<char>> stat(static_cast<std::size_t>(levels));
  for (int l = 0; l < levels; ++l) {
    live[static_cast<std::size_t>(l)].assign(s.pyr.cells(l), 0);
    stat[static_cast<std::size_t>(l)].assign(s.pyr.cells(l), 0);
  }
  for (int z = 0; z < s.res.z; ++z)
    for (int y = 0; y < s.res.y; ++y)
      for (int x = 0; x < s.res.x; ++x) {
        const auto i = static_cast<std::size_t>(s.index(x, y, z));
        if (s.vflags[i] & (Scene::Impl::kStaticIds | Scene::Impl::kStaticOpaque)) stat[0][i] = 1;
      }
  for (int l = 1; l < levels; ++l) {
    const detail::IdLists& lists = s.static_lists[static_cast<std::size_t>(l)];
    for (std::size_t c = 0; c < s.pyr.cells(l); ++c) {
      if (lists.any() && lists.end(c) != lists.begin(c)) stat[static_cast<std::size_t>(l)][c] = 1;
      if (!s.bricks.empty()) {
        const detail::Brick& b = l == 1 ? s.bricks[c] : s.coarse_dyn[static_cast<std::size_t>(l)][c];
        live[static_cast<std::size_t>(l)][c] = b.live;
      }
    }
  }
  // Children into parents, bottom up, checking each parent's bits.
  for (int l = 0; l + 1 < levels; ++l) {
    const glm::ivec3 r = s.pyr.res[static_cast<std::size_t>(l)];
    std::vector<std::uint64_t> sbits(s.pyr.cells(l + 1), 0), dbits(s.pyr.cells(l + 1), 0);
    for (int z = 0; z < r.z; ++z)
      for (int y = 0; y < r.y; ++y)
        for (int x = 0; x < r.x; ++x) {
          const glm::ivec3 c(x, y, z);
          const std::size_t i = s.pyr.index(l, c), p = s.pyr.index(l + 1, c >> detail::kCellShift);
          const std::uint64_t bit = std::uint64_t{1} << ((x & 3) | (y & 3) << 2 | (z & 3) << 4);
          if (stat[static_cast<std::size_t>(l)][i]) {
            sbits[p] |= bit;
            stat[static_cast<std::size_t>(l) + 1][p] = 1;
          }
          if (l >= 1 && live[static_cast<std::size_t>(l)][i] > 0) dbits[p] |= bit;
          // A count is the cell's own live entries plus its non-empty children.
          if (l >= 1 && live[static_cast<std::size_t>(l)][i] > 0) ++live[static_cast<std::size_t>(l) + 1][p];
        }
    for (std::size_t p = 0; p < s.pyr.cells(l + 1); ++p) {
      const std::string at = "level " + std::to_string(l + 1) + " cell " + std::to_string(p);
      if (s.static_mask[static_cast<std::size_t>(l) + 1][p] != sbits[p]) return "static mask differs at " + at;
      if (s.bricks.empty()) continue;
      if (l >= 1 && s.dyn_mask[static_cast<std::size_t>(l) + 1][p] != dbits[p]) return "dynamic mask differs at " + at;
      if (s.dyn_count[static_cast<std::size_t>(l) + 1][p] != live[static_cast<std::size_t>(l) + 1][p])
        return "dynamic count " + std::to_string(s.dyn_count[static_cast<std::size_t>(l) + 1][p]) + " != " +
               std::to_string(live[static_cast<std::size_t>(l) + 1][p]) + " at " + at;
    }
  }
  return "";
}

TEST(Cells, MasksFollowMovesRevealsAndTbvs) {
  // The masks the cell traversal skips empty space by are kept up to date
  // incrementally; after every move batch and frame (objects moving,
  // hidden under TBVs, revealed, some huge) they equal a recount.
  PaperSceneParams pp;
  pp.objects = 400;
  pp.dynamic = 150;
  pp.clusters = 12;
  pp.max_speed = 6.0;
  pp.bounds_max = Vec3(40.0, 24.0, 40.0);
  pp.seed = 3;
  SceneDesc d = make_paper_scene(pp);
  d.objects.push_back(dynamic(sphere(100000, Vec3(20.0, 12.0, 20.0), 30.0), 1.0));  // Covers the grid.
  EngineHarness h(d, {}, "masks");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  ASSERT_EQ(check_masks(h.scene().impl()), "");
  Mover mover(d, 5);
  double t = 0.0;
  for (int f = 0; f < 40; ++f) {
    t += 0.1;
    ASSERT_TRUE(h.move(t, mover.step(0.1)).ok);
    ASSERT_EQ(check_masks(h.scene().impl()), "") << "after the moves of frame " << f;
    const double a = 0.3 * f;
    const std::string err = h.frame(camera_along(Vec3(20.0 + 18.0 * std::cos(a), 12.0, 20.0 + 18.0 * std::sin(a)),
                                                 Vec3(-std::cos(a), -0.1, -std::sin(a)), 50.0, 1.5, 0.05, 200.0),
                                    t);
    ASSERT_EQ(err, "");
    ASSERT_EQ(check_masks(h.scene().impl()), "") << "after frame " << f;
  }
  EXPECT_GT(h.scene().impl().tbv_count, 0u) << "some objects were hidden under TBVs";
}

TEST(Cells, WithTheBufferOnDynamicObjectsAddNoOpacity) {
  // The cell traversal reads no voxel's opacity: with the buffer on, a
  // moving object costs its cells, not a cover test of every voxel it
  // touches; with it off, the shells need that opacity.
  SceneDesc d;
  d.bounds_min = Vec3(0.0);
  d.bounds_max = Vec3(32.0);
  d.grid = glm::ivec3(32);
  d.objects = {dynamic(box_between(1, Vec3(4.0), Vec3(12.0)), 1.0), box_between(2, Vec3(20.0), Vec3(28.0))};
  for (int ob : {0, 128}) {
    SceneOptions o;
    o.occlusion_buffer = ob;
    EngineHarness h(d, o, "opacity ob=" + std::to_string(ob));
    ASSERT_TRUE(h.status().ok);
    ASSERT_TRUE(h.move(0.1, {Move{1, Vec3(8.5, 8.0, 8.0)}}).ok);
    ASSERT_EQ(h.frame(camera_along(Vec3(16.0, 16.0, -10.0), Vec3(0.0, 0.0, 1.0)), 0.1), "");
    const Scene::Impl& s = h.scene().impl();
    const std::size_t dyn_opaque = static_cast<std::size_t>(
        std::count_if(s.vflags.begin(), s.vflags.end(), [](std::uint8_t f) { return (f & Scene::Impl::kDynOpaque) != 0; }));
    const std::size_t static_opaque = static_cast<std::size_t>(std::count_if(
        s.vflags.begin(), s.vflags.end(), [](std::uint8_t f) { return (f & Scene::Impl::kStaticOpaque) != 0; }));
    EXPECT_EQ(static_opaque, 512u) << "ob=" << ob;
    if (ob == 0) {
      EXPECT_GT(dyn_opaque, 0u);
    } else {
      EXPECT_EQ(dyn_opaque, 0u);
    }
    // The cell traversal's summaries exist for it alone.
    EXPECT_EQ(s.static_mask[1].empty(), ob == 0) << "ob=" << ob;
    EXPECT_EQ(s.dyn_count[1].empty(), ob == 0) << "ob=" << ob;
  }
}

TEST(Cells, GridsOfOneVoxelAnswer) {
  // The pyramid's top is a cell even when the grid is one voxel (a top at
  // level 0 read the masks of a level that has none: a crash with the
  // buffer on). Grids of 1 to 3 voxels, static and moving objects, the eye
  // inside and outside, buffer off and on: zero misses.
  int seed = 0;
  for (const glm::ivec3 g : {glm::ivec3(1), glm::ivec3(1, 1, 2), glm::ivec3(3, 1, 1), glm::ivec3(1, 2, 1)}) {
    SceneDesc d;
    d.bounds_min = Vec3(0.0);
    d.bounds_max = Vec3(4.0);
    d.grid = g;
    d.objects = {sphere(1, Vec3(2.0, 2.0, 2.0), 0.5), box_between(2, Vec3(0.0, 0.0, 3.0), Vec3(4.0, 4.0, 4.0)),
                 dynamic(sphere(3, Vec3(1.0, 1.0, 1.0), 0.3), 1.0), sphere(4, Vec3(2.0, 2.0, 6.0), 1.0)};
    for (int ob : {0, 128}) {
      SceneOptions o;
      o.occlusion_buffer = ob;
      EngineHarness h(d, o, "grid " + std::to_string(g.x) + "x" + std::to_string(g.y) + "x" + std::to_string(g.z) +
                                " ob=" + std::to_string(ob));
      ASSERT_TRUE(h.status().ok) << h.status().str();
      Mover mover(d, static_cast<std::uint64_t>(++seed));
      double t = 0.0;
      for (const Vec3 eye : {Vec3(2.0, 2.0, -5.0), Vec3(2.1, 1.9, 1.2), Vec3(8.0, 6.0, 9.0)}) {
        t += 0.5;
        ASSERT_TRUE(h.move(t, mover.step(0.5)).ok);
        ASSERT_EQ(h.frame(camera_along(eye, Vec3(2.0, 2.0, 3.0) - eye, 70.0, 1.0, 0.01, 100.0), t), "");
      }
    }
  }
}

}  // namespace
}  // namespace voxvis::test
