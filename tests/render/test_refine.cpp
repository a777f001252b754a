// Refinement levels (voxvis/refine.h) on this machine's EGL: each returns a
// subset of the engine's PVS that keeps every object visible at pixel level
// (adaptive:N drops only objects under N pixels), and the hierarchy finds
// exactly what one query per object finds.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "raycast.h"
#include "scenes.h"
#include "voxvis/refine.h"
#include "voxvis/render.h"
#include "voxvis/scene.h"

namespace voxvis::test {
namespace {

using render::Level;
using render::LevelKind;
using render::RefineStats;
using render::Renderer;

Level level(const std::string& text) {
  Level l;
  std::string message;
  EXPECT_TRUE(render::parse_level(text, &l, &message)) << message;
  return l;
}

TEST(Refine, LevelsKeepEveryVisibleObjectOfTheirInput) {
  std::string error;
  auto r = Renderer::create(render::ContextOptions{}, &error);
  ASSERT_TRUE(r) << error;
  constexpr int kW = 96, kH = 54;
  int frames = 0, tightened = 0, lazy_tightened = 0;
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    const SceneDesc scene = random_scene(random_scene_params(seed), seed);
    std::unique_ptr<Scene> engine;
    ASSERT_TRUE(Scene::create(scene, SceneOptions{}, &engine).ok);
    const ViewerId viewer = engine->add_viewer();
    Scratch scratch;
    const std::vector<Camera> path = random_camera_path(scene, seed + 50);
    for (std::size_t f = 0; f < path.size(); f += 5) {
      FrameResult fr;
      ASSERT_TRUE(engine->frame(viewer, path[f], static_cast<double>(f) / 60.0, scratch, &fr).ok);
      // The exact set at these pixels, and each object's pixels in it.
      std::vector<ObjectId> exact;
      render::VisibleStats vs;
      ASSERT_TRUE(r->visible(scene.objects, path[f], render::VisibleOptions{kW, kH}, nullptr, &exact, &vs, &error))
          << error;
      std::map<ObjectId, int> pixels;
      for (ObjectId id : r->last_ids()) ++pixels[id];
      const std::string where = "seed " + std::to_string(seed) + " frame " + std::to_string(f);
      std::vector<ObjectId> by_queries;
      for (const char* name : {"none", "queries", "hierarchical", "lazy-grid", "adaptive:4"}) {
        const Level l = level(name);
        std::vector<ObjectId> out;
        RefineStats st;
        ASSERT_TRUE(r->refine(l, scene.objects, path[f], kW, kH, fr.pvs, &out, &st, &error)) << error;
        EXPECT_TRUE(std::is_sorted(out.begin(), out.end()));
        EXPECT_TRUE(std::includes(fr.pvs.begin(), fr.pvs.end(), out.begin(), out.end())) << where << " " << name;
        for (ObjectId id : exact) {
          if (std::binary_search(out.begin(), out.end(), id)) continue;
          if (l.kind == LevelKind::Adaptive) {
            EXPECT_LT(pixels[id], 4) << where << ": adaptive:4 dropped object " << id << " of " << pixels[id]
                                     << " pixels";
          } else {
            ADD_FAILURE() << where << ": level " << name << " dropped visible object " << id;
          }
        }
        if (l.kind == LevelKind::None) {
          EXPECT_EQ(out, fr.pvs);
        }
        if (l.kind == LevelKind::Queries) {
          by_queries = out;
          EXPECT_EQ(st.levels, out.empty() && st.queries == 0 ? 0u : 1u);
          tightened += out.size() < fr.pvs.size() ? 1 : 0;
        }
        if (l.kind == LevelKind::Hierarchical) {
          EXPECT_EQ(out, by_queries) << where;
        }
        if (l.kind == LevelKind::LazyGrid) {
          // Coarser than a query per object: never tighter than it.
          EXPECT_TRUE(std::includes(out.begin(), out.end(), by_queries.begin(), by_queries.end())) << where;
          lazy_tightened += out.size() < fr.pvs.size() ? 1 : 0;
        }
        if (l.kind != LevelKind::None && l.kind != LevelKind::LazyGrid) {
          EXPECT_GE(st.draw_calls, st.queries);  // Each query draws its probe.
        }
      }
      ++frames;
    }
  }
  EXPECT_GT(tightened, frames / 4) << "queries tightened " << tightened << " of " << frames << " PVSs";
  EXPECT_GT(lazy_tightened, 0) << "the lazy grid tightened none of " << frames << " PVSs";
}

TEST(Refine, TheHierarchySkipsTheObjectsOfHiddenBoxes) {
  // A wall in front of a crowd: the crowd's boxes are hidden, so the
  // hierarchy drops them with a few queries where one per object needs 200.
  std::string error;
  auto r = Renderer::create(render::ContextOptions{}, &error);
  ASSERT_TRUE(r) << error;
  std::vector<ObjectDesc> objects = {box_between(1, Vec3(-50, -50, -11), Vec3(50, 50, -10))};
  std::vector<ObjectId> pvs = {1};
  for (int i = 0; i < 200; ++i) {
    objects.push_back(sphere(static_cast<ObjectId>(i + 2), Vec3(i % 20 - 10, i / 20 - 5, -20.0 - i % 7), 0.4));
    pvs.push_back(static_cast<ObjectId>(i + 2));
  }
  const Camera cam = camera_along(Vec3(0.0), Vec3(0, 0, -1), 60.0, 1.0);
  std::vector<ObjectId> flat, tree;
  RefineStats st_flat, st_tree;
  ASSERT_TRUE(r->refine(level("queries"), objects, cam, 64, 64, pvs, &flat, &st_flat, &error)) << error;
  ASSERT_TRUE(r->refine(level("hierarchical"), objects, cam, 64, 64, pvs, &tree, &st_tree, &error)) << error;
  EXPECT_EQ(flat, std::vector<ObjectId>{1});
  EXPECT_EQ(tree, flat);
  EXPECT_EQ(st_flat.queries, 201u);
  EXPECT_LT(st_tree.queries, 20u) << st_tree.queries << " queries in " << st_tree.levels << " rounds";
  // The lazy grid: the wall drawn first (nearest), then the crowd's boxes
  // found behind it after a few cells are read back.
  std::vector<ObjectId> lazy;
  RefineStats st_lazy;
  ASSERT_TRUE(r->refine(level("lazy-grid"), objects, cam, 64, 64, pvs, &lazy, &st_lazy, &error)) << error;
  EXPECT_EQ(lazy, flat);
  EXPECT_EQ(st_lazy.draw_calls, 1u);  // The wall alone.
  EXPECT_LE(st_lazy.queries, 16u) << "cells read back";
}

TEST(Refine, BadLevelsAndIdsAreErrors) {
  Level l;
  std::string message;
  for (const char* bad : {"", "query", "adaptive", "adaptive:", "adaptive:0", "adaptive:-3", "adaptive:x",
                          "adaptive:99999999"}) {
    EXPECT_FALSE(render::parse_level(bad, &l, &message)) << bad;
    EXPECT_NE(message.find(bad), std::string::npos) << message;
  }
  EXPECT_TRUE(render::parse_level("adaptive:25", &l, &message));
  EXPECT_EQ(l.min_pixels, 25u);
  EXPECT_EQ(render::level_name(l), "adaptive:25");
  EXPECT_TRUE(render::level_may_miss(l));
  EXPECT_FALSE(render::level_may_miss(level("hierarchical")));

  std::string error;
  auto r = Renderer::create(render::ContextOptions{}, &error);
  ASSERT_TRUE(r) << error;
  std::vector<ObjectId> out;
  RefineStats st;
  const std::vector<ObjectDesc> objects = {sphere(1, Vec3(0, 0, -5), 1.0)};
  EXPECT_FALSE(r->refine(level("queries"), objects, camera_along(Vec3(0.0), Vec3(0, 0, -1)), 16, 16, {1, 7}, &out,
                         &st, &error));
  EXPECT_NE(error.find("id 7"), std::string::npos) << error;
  EXPECT_FALSE(r->refine(level("queries"), objects, camera_along(Vec3(0.0), Vec3(0, 0, -1)), 0, 16, {1}, &out, &st,
                         &error));
  EXPECT_NE(error.find("resolution 0x16"), std::string::npos) << error;
}

}  // namespace
}  // namespace voxvis::test
