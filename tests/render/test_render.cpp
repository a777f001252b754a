// The headless renderer (render/): a context on this machine's EGL, and
// visible sets that agree with the CPU ray caster of the tests at the same
// pixel centres (docs/verify.md, "Agreement with the ray caster").
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "raycast.h"
#include "render_check.h"
#include "scenes.h"
#include "voxvis/render.h"

namespace voxvis::test {
namespace {

using render::Method;
using render::Renderer;
using render::VisibleOptions;
using render::VisibleStats;

/// The ray caster's first hits at every pixel centre of a w x h image, row 0
/// at the bottom, as the renderer samples them.
std::vector<std::vector<ObjectId>> cast_pixels(const std::vector<ObjectDesc>& objects, const Camera& cam, int w,
                                               int h) {
  std::vector<std::vector<ObjectId>> hits(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i)
      hits[static_cast<std::size_t>(j) * static_cast<std::size_t>(w) + static_cast<std::size_t>(i)] =
          first_hit(objects, cam, -1.0 + (2.0 * i + 1.0) / w, -1.0 + (2.0 * j + 1.0) / h);
  return hits;
}

struct Agreement {
  int pixels = 0;
  int differ = 0;                       ///< Pixels whose GPU id is not among the caster's first hits.
  std::map<ObjectId, int> gpu_only;      ///< Objects only the GPU sees, with their GPU pixel counts.
  /// Objects only the caster sees, with the pixels where the caster hits
  /// them and the GPU does not agree or they are the caster's only hit.
  std::map<ObjectId, int> caster_only;
};

Agreement compare(const std::vector<ObjectId>& gpu, const std::vector<std::vector<ObjectId>>& cpu) {
  Agreement a;
  std::map<ObjectId, int> gpu_px, cpu_px;
  for (std::size_t p = 0; p < gpu.size(); ++p) {
    ++a.pixels;
    const auto& hits = cpu[p];
    const bool ok = gpu[p] == 0 ? hits.empty() : std::find(hits.begin(), hits.end(), gpu[p]) != hits.end();
    if (!ok) ++a.differ;
    if (gpu[p] != 0) ++gpu_px[gpu[p]];
    // An object tied with the GPU's choice is not counted against the GPU:
    // the id buffer keeps one object of a tie.
    for (ObjectId id : hits)
      if (hits.size() == 1 || !ok) ++cpu_px[id];
    if (ok && hits.size() > 1)
      for (ObjectId id : hits) cpu_px.try_emplace(id, 0);
  }
  for (const auto& [id, n] : gpu_px)
    if (!cpu_px.count(id)) a.gpu_only[id] = n;
  for (const auto& [id, n] : cpu_px)
    if (!gpu_px.count(id) && n > 0) a.caster_only[id] = n;
  return a;
}

TEST(Render, HeadlessContextOffersOpenGL4Core) {
  VOXVIS_RENDERER_OR_SKIP(r, render::Platform::Auto);
  const render::ContextInfo& info = r->info();
  EXPECT_NE(info.platform, render::Platform::Auto);
  EXPECT_EQ(info.gl_version.rfind("4.", 0), 0u) << info.summary();
  EXPECT_GE(info.max_size, 2048) << info.summary();
  // It says which platform and device it took, and why.
  EXPECT_FALSE(info.why.empty()) << info.summary();
  EXPECT_NE(info.summary().find(" (" + info.why + ")"), std::string::npos) << info.summary();
}

TEST(Render, DeviceAndSurfacelessPlatformsRenderTheSameSet) {
  VOXVIS_RENDERER_OR_SKIP(device, render::Platform::Device);
  render::ContextOptions o;
  o.platform = render::Platform::Surfaceless;
  std::string error;
  auto surfaceless = Renderer::create(o, &error);
  if (!surfaceless && error.find("EGL_MESA_platform_surfaceless") != std::string::npos)
    GTEST_SKIP() << "this EGL has no surfaceless platform: " << error;
  ASSERT_TRUE(surfaceless) << error;
  EXPECT_EQ(surfaceless->info().platform, render::Platform::Surfaceless);
  const SceneDesc scene = random_scene(random_scene_params(11), 11);
  const Camera cam = random_camera_path(scene, 12)[3];
  std::vector<ObjectId> a, b;
  VisibleStats st;
  ASSERT_TRUE(device->visible(scene.objects, cam, VisibleOptions{64, 48}, nullptr, &a, &st, &error)) << error;
  ASSERT_TRUE(surfaceless->visible(scene.objects, cam, VisibleOptions{64, 48}, nullptr, &b, &st, &error)) << error;
  EXPECT_EQ(a, b);
}

TEST(Render, AgreesWithTheRayCasterAtPixelCentres) {
  // Random scenes of balls and boxes (thin walls, flat boxes, objects outside
  // the bounds) under random cameras (eye on voxel planes, axis views,
  // extreme lenses): the GPU's first hit at every pixel centre is one of the
  // caster's, except where single-precision depths order near-ties or a
  // pixel centre grazes a silhouette. Those pixels are few, and an object
  // only one side sees covers at most a pixel or two.
  VOXVIS_RENDERER_OR_SKIP(r, render::Platform::Auto);
  constexpr int kW = 80, kH = 45;
  int pixels = 0, differ = 0, frames = 0;
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    const SceneDesc scene = random_scene(random_scene_params(seed), seed);
    const std::vector<Camera> path = random_camera_path(scene, seed + 100);
    for (std::size_t f = 0; f < path.size(); f += 6) {
      const Camera& cam = path[f];
      std::vector<ObjectId> vis;
      VisibleStats st;
      std::string error;
      ASSERT_TRUE(r->visible(scene.objects, cam, VisibleOptions{kW, kH}, nullptr, &vis, &st, &error)) << error;
      const Agreement a = compare(r->last_ids(), cast_pixels(scene.objects, cam, kW, kH));
      const std::string where = "seed " + std::to_string(seed) + " frame " + std::to_string(f) + ": " + describe(cam);
      for (const auto& [id, n] : a.gpu_only) {
        EXPECT_LE(n, 2) << where << ": object " << id << " only on the GPU";
      }
      for (const auto& [id, n] : a.caster_only) {
        EXPECT_LE(n, 2) << where << ": object " << id << " only in the caster";
      }
      EXPECT_LE(a.differ, std::max(2, a.pixels / 200)) << where;
      pixels += a.pixels;
      differ += a.differ;
      ++frames;
      // The set is the id image's ids.
      std::set<ObjectId> from_image(r->last_ids().begin(), r->last_ids().end());
      from_image.erase(0);
      EXPECT_EQ(vis, std::vector<ObjectId>(from_image.begin(), from_image.end())) << where;
    }
  }
  EXPECT_LE(differ, pixels / 1000) << differ << " of " << pixels << " pixels differ over " << frames << " frames";
}

TEST(Render, HugeAndTinyCoordinatesRenderTheSameImage) {
  // Coordinates go relative to the eye in double before they are rounded to
  // float, so a scene moved far from the origin, or shrunk or grown by many
  // orders of magnitude, renders as it does at home: the same id at (nearly)
  // every pixel.
  VOXVIS_RENDERER_OR_SKIP(r, render::Platform::Auto);
  constexpr int kW = 64, kH = 36;
  const SceneDesc scene = random_scene(random_scene_params(31), 31);
  const std::vector<Camera> path = random_camera_path(scene, 32);
  const std::pair<double, Vec3> transforms[] = {
      {1.0, Vec3(3e7, -2e7, 1e7)}, {1e-5, Vec3(0.25, -0.5, 0.125)}, {1e5, Vec3(-4e9, 1e9, 2e9)}};
  std::string error;
  VisibleStats st;
  std::vector<ObjectId> vis;
  for (std::size_t f = 0; f < path.size(); f += 8) {
    ASSERT_TRUE(r->visible(scene.objects, path[f], VisibleOptions{kW, kH}, nullptr, &vis, &st, &error)) << error;
    const std::vector<ObjectId> home = r->last_ids();
    for (const auto& [scale, offset] : transforms) {
      const SceneDesc moved = transform_scene(scene, scale, offset);
      ASSERT_TRUE(r->visible(moved.objects, transform_camera(path[f], scale, offset), VisibleOptions{kW, kH},
                             nullptr, &vis, &st, &error))
          << error;
      int differ = 0;
      for (std::size_t p = 0; p < home.size(); ++p) differ += home[p] != r->last_ids()[p] ? 1 : 0;
      EXPECT_LE(differ, kW * kH / 500) << "frame " << f << ", scale " << scale << ", offset " << offset.x;
    }
  }
}

TEST(Render, EyeInsideAnObjectSeesOnlyThatObject) {
  // The caster's convention: an object containing the eye is hit at depth
  // `near` on every ray, so it hides everything, also what lies inside it.
  VOXVIS_RENDERER_OR_SKIP(r, render::Platform::Auto);
  for (const ObjectDesc& outer : {box_between(1, Vec3(-5.0), Vec3(5.0)), sphere(1, Vec3(0.5, 0.0, 0.0), 4.0)}) {
    const std::vector<ObjectDesc> objects = {outer, sphere(2, Vec3(0.0, 0.0, -2.0), 0.5),
                                             box_between(3, Vec3(-1, -1, -20), Vec3(1, 1, -19))};
    std::vector<ObjectId> vis;
    VisibleStats st;
    std::string error;
    ASSERT_TRUE(r->visible(objects, camera_along(Vec3(0.0), Vec3(0, 0, -1)), VisibleOptions{32, 32}, nullptr, &vis,
                           &st, &error))
        << error;
    EXPECT_EQ(vis, std::vector<ObjectId>{1});
    EXPECT_EQ(std::count(r->last_ids().begin(), r->last_ids().end(), ObjectId{1}), 32 * 32);
  }
}

TEST(Render, OnlyThePartOfAnOccluderBeyondTheNearPlaneHides) {
  // Left: a wall wholly nearer than `near` is clipped away and hides
  // nothing. Right: a wall crossing the near plane keeps its part beyond it,
  // which (a solid) is hit at depth `near` and hides what lies behind.
  VOXVIS_RENDERER_OR_SKIP(r, render::Platform::Auto);
  const Camera cam = camera_along(Vec3(0.0), Vec3(0, 0, -1), 90.0, 1.0, 1.0, 100.0);
  const std::vector<ObjectDesc> objects = {box_between(1, Vec3(-10, -10, -0.8), Vec3(0, 10, -0.2)),
                                           box_between(2, Vec3(0, -10, -1.5), Vec3(10, 10, -0.5)),
                                           sphere(3, Vec3(-3, 0, -6), 1.0), sphere(4, Vec3(3, 0, -6), 1.0)};
  std::vector<ObjectId> vis;
  VisibleStats st;
  std::string error;
  ASSERT_TRUE(r->visible(objects, cam, VisibleOptions{64, 64}, nullptr, &vis, &st, &error)) << error;
  EXPECT_EQ(vis, (std::vector<ObjectId>{2, 3}));
  EXPECT_EQ(vis, visible_objects(objects, cam, RaySampling{64, 64, false, false}));
}

TEST(Render, QueriesSeeWhatTheIdBufferSeesAndTies) {
  // Both methods sample the same pixel centres; queries count every object
  // of a depth tie, the id buffer one of them, so ids <= queries, and the
  // queries' extra objects are ties: the caster hits them first too.
  VOXVIS_RENDERER_OR_SKIP(r, render::Platform::Auto);
  // Abutting unit blocks and a sphere touching a box: ties at shared faces.
  std::vector<ObjectDesc> objects;
  ObjectId id = 1;
  for (int x = 0; x < 6; ++x)
    for (int y = 0; y < 3; ++y) objects.push_back(box_between(id++, Vec3(x, y, -8), Vec3(x + 1, y + 1, -7)));
  objects.push_back(sphere(id++, Vec3(2.5, 1.5, -5.0), 0.7));
  const SceneDesc scene = random_scene(random_scene_params(5), 5);
  for (std::size_t f = 0; f < 2; ++f) {
    const bool blocks = f == 0;
    const std::vector<ObjectDesc>& objs = blocks ? objects : scene.objects;
    const Camera cam = blocks ? camera_along(Vec3(3.0, 1.5, 0.0), Vec3(0.0, 0.0, -1.0), 50.0, 1.5)
                              : random_camera_path(scene, 55)[7];
    std::vector<ObjectId> by_ids, by_queries;
    VisibleStats st_ids, st_q;
    std::string error;
    ASSERT_TRUE(r->visible(objs, cam, VisibleOptions{96, 64, Method::Ids}, nullptr, &by_ids, &st_ids, &error))
        << error;
    ASSERT_TRUE(r->visible(objs, cam, VisibleOptions{96, 64, Method::Queries}, nullptr, &by_queries, &st_q, &error))
        << error;
    EXPECT_EQ(st_q.queries, st_q.in_frustum);
    EXPECT_TRUE(std::includes(by_queries.begin(), by_queries.end(), by_ids.begin(), by_ids.end()));
    std::vector<ObjectId> extra;
    std::set_difference(by_queries.begin(), by_queries.end(), by_ids.begin(), by_ids.end(),
                        std::back_inserter(extra));
    const std::vector<ObjectId> cast = visible_objects(objs, cam, RaySampling{96, 64, false, false});
    for (ObjectId e : extra) {
      EXPECT_TRUE(std::binary_search(cast.begin(), cast.end(), e)) << "object " << e << " seen only by a query";
    }
    if (blocks) {
      EXPECT_FALSE(by_ids.empty());
    }
  }
}

TEST(Render, CandidatesLimitWhatIsReported) {
  VOXVIS_RENDERER_OR_SKIP(r, render::Platform::Auto);
  const SceneDesc scene = random_scene(random_scene_params(8), 8);
  const Camera cam = random_camera_path(scene, 9)[0];
  std::string error;
  VisibleStats st;
  for (Method method : {Method::Ids, Method::Queries}) {
    std::vector<ObjectId> all, some;
    ASSERT_TRUE(r->visible(scene.objects, cam, VisibleOptions{64, 36, method}, nullptr, &all, &st, &error)) << error;
    ASSERT_GE(all.size(), 2u);
    // Every other visible object, and ids that are not in view at all.
    std::vector<ObjectId> candidates;
    for (std::size_t i = 0; i < all.size(); i += 2) candidates.push_back(all[i]);
    for (const ObjectDesc& o : scene.objects)
      if (!std::binary_search(all.begin(), all.end(), o.id)) candidates.push_back(o.id);
    std::sort(candidates.begin(), candidates.end());
    ASSERT_TRUE(r->visible(scene.objects, cam, VisibleOptions{64, 36, method}, &candidates, &some, &st, &error))
        << error;
    std::vector<ObjectId> expect;
    for (std::size_t i = 0; i < all.size(); i += 2) expect.push_back(all[i]);
    EXPECT_EQ(some, expect) << render::method_name(method);
  }
}

TEST(Render, TheSetGatheredOnTheGpuIsTheImages) {
  // The two read-backs of Method::Ids (render.h, IdReadback): the flags a
  // compute pass marks and the whole image give the same set, candidates
  // applied the same way; the image behind the flags is read on demand and
  // is gone once the renderer draws again.
  std::unique_ptr<Renderer> by_set, by_image;
  for (auto [readback, out] : {std::pair{render::IdReadback::Set, &by_set},
                               std::pair{render::IdReadback::Image, &by_image}}) {
    render::ContextOptions o;
    o.id_readback = readback;
    std::string why;
    *out = Renderer::create(o, &why);
    if (!*out) GTEST_SKIP() << "no renderer on this machine: " << why;
  }
  EXPECT_FALSE(by_image->info().id_set_on_gpu);
  if (!by_set->info().id_set_on_gpu) GTEST_SKIP() << "no compute shaders: " << by_set->info().summary();
  int frames = 0;
  for (std::uint64_t seed = 31; seed <= 34; ++seed) {
    const SceneDesc scene = random_scene(random_scene_params(seed), seed);
    const std::vector<Camera> path = random_camera_path(scene, seed + 7);
    for (std::size_t f = 0; f < path.size(); f += 10, ++frames) {
      const std::string where = "seed " + std::to_string(seed) + " frame " + std::to_string(f);
      std::vector<ObjectId> a, b, some_a, some_b;
      VisibleStats st;
      std::string error;
      ASSERT_TRUE(by_set->visible(scene.objects, path[f], VisibleOptions{72, 40}, nullptr, &a, &st, &error)) << error;
      ASSERT_TRUE(by_image->visible(scene.objects, path[f], VisibleOptions{72, 40}, nullptr, &b, &st, &error))
          << error;
      EXPECT_EQ(a, b) << where;
      EXPECT_EQ(by_set->last_ids(), by_image->last_ids()) << where;
      std::vector<ObjectId> candidates;
      for (const ObjectDesc& o : scene.objects)
        if (o.id % 3 != 0) candidates.push_back(o.id);
      ASSERT_TRUE(by_set->visible(scene.objects, path[f], VisibleOptions{72, 40}, &candidates, &some_a, &st, &error))
          << error;
      ASSERT_TRUE(
          by_image->visible(scene.objects, path[f], VisibleOptions{72, 40}, &candidates, &some_b, &st, &error))
          << error;
      EXPECT_EQ(some_a, some_b) << where;
    }
  }
  EXPECT_GT(frames, 4);
  // A query pass draws again: the last id image is gone.
  const SceneDesc scene = random_scene(random_scene_params(31), 31);
  std::vector<ObjectId> vis;
  VisibleStats st;
  std::string error;
  const Camera cam = random_camera_path(scene, 38)[0];
  ASSERT_TRUE(by_set->visible(scene.objects, cam, VisibleOptions{72, 40}, nullptr, &vis, &st, &error)) << error;
  EXPECT_EQ(by_set->last_ids().size(), 72u * 40u);
  ASSERT_TRUE(by_set->visible(scene.objects, cam, VisibleOptions{72, 40, Method::Queries}, nullptr, &vis, &st,
                              &error))
      << error;
  EXPECT_TRUE(by_set->last_ids().empty());
}

TEST(Render, BadResolutionsAndCamerasAreErrors) {
  VOXVIS_RENDERER_OR_SKIP(r, render::Platform::Auto);
  const std::vector<ObjectDesc> objects = {sphere(1, Vec3(0, 0, -5), 1.0)};
  const Camera good = camera_along(Vec3(0.0), Vec3(0, 0, -1));
  std::vector<ObjectId> vis;
  VisibleStats st;
  const int max = r->info().max_size;
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{{0, 10}, {10, 0}, {-4, 10}, {max + 1, 8}, {8, max + 1}}) {
    std::string error;
    EXPECT_FALSE(r->visible(objects, good, VisibleOptions{w, h}, nullptr, &vis, &st, &error));
    EXPECT_NE(error.find("resolution " + std::to_string(w) + "x" + std::to_string(h)), std::string::npos) << error;
  }
  Camera bad = good;
  bad.dir = Vec3(0.0);
  std::string error;
  EXPECT_FALSE(r->visible(objects, bad, VisibleOptions{8, 8}, nullptr, &vis, &st, &error));
  EXPECT_NE(error.find("dir"), std::string::npos) << error;
  bad = good;
  bad.near = std::nan("");
  EXPECT_FALSE(r->visible(objects, bad, VisibleOptions{8, 8}, nullptr, &vis, &st, &error));
  EXPECT_NE(error.find("not finite"), std::string::npos) << error;
  // Still usable afterwards.
  EXPECT_TRUE(r->visible(objects, good, VisibleOptions{8, 8}, nullptr, &vis, &st, &error)) << error;
  EXPECT_EQ(vis, std::vector<ObjectId>{1});
}

TEST(Render, ContextsOnSeveralThreadsAndTeardownInAnyOrder) {
  // One renderer per thread, rendering at once; destroying one leaves the
  // others working (they share the process's EGL display).
  const SceneDesc scene = random_scene(random_scene_params(21), 21);
  const std::vector<Camera> path = random_camera_path(scene, 22);
  VOXVIS_RENDERER_OR_SKIP(reference, render::Platform::Auto);
  std::vector<std::vector<ObjectId>> expect(4);
  std::string error;
  VisibleStats st;
  for (std::size_t k = 0; k < expect.size(); ++k)
    ASSERT_TRUE(reference->visible(scene.objects, path[k], VisibleOptions{48, 32}, nullptr, &expect[k], &st, &error))
        << error;
  std::vector<std::vector<ObjectId>> got(expect.size());
  std::vector<std::string> errors(expect.size());
  std::vector<std::thread> threads;
  for (std::size_t k = 0; k < expect.size(); ++k)
    threads.emplace_back([&, k] {
      render::ContextOptions o;
      auto r = Renderer::create(o, &errors[k]);
      if (!r) return;
      VisibleStats s;
      if (!r->visible(scene.objects, path[k], VisibleOptions{48, 32}, nullptr, &got[k], &s, &errors[k])) return;
    });
  for (auto& t : threads) t.join();
  for (std::size_t k = 0; k < expect.size(); ++k) {
    EXPECT_TRUE(errors[k].empty()) << errors[k];
    EXPECT_EQ(got[k], expect[k]) << "thread " << k;
  }
  // The reference renderer outlived the others' teardown.
  std::vector<ObjectId> again;
  ASSERT_TRUE(reference->visible(scene.objects, path[0], VisibleOptions{48, 32}, nullptr, &again, &st, &error)) << error;
  EXPECT_EQ(again, expect[0]);
}

}  // namespace
}  // namespace voxvis::test
