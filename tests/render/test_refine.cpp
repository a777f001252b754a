// Refinement levels (voxvis/refine.h) on this machine's EGL: each returns a
// subset of the engine's PVS that keeps every object visible at pixel level
// (adaptive:N drops only objects under N pixels), and the hierarchy finds
// exactly what one query per object finds.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

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
  if (!r) GTEST_SKIP() << "no renderer on this machine: " << error;
  constexpr int kW = 96, kH = 54;
  int frames = 0, tightened = 0, lazy_tightened = 0, ternary_tightened = 0;
  // A model of this machine (measured into a scratch file, not the user's).
  render::CostModel model;
  std::string note;
  ASSERT_TRUE(r->cost_model(::testing::TempDir() + "refine-cost-model.json", &model, &note, &error)) << error;
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    r->reset_refinement();  // A new scene: ternary's tree and near-optimal's states start afresh.
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
      for (const char* name : {"none", "queries", "hierarchical", "lazy-grid", "ternary", "near-optimal", "adaptive:4"}) {
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
        if (l.kind == LevelKind::Ternary || l.kind == LevelKind::NearOptimal) {
          // Fewer occluders (ternary: those drawn so far) or fewer queries
          // (near-optimal): never tighter than a query per object.
          EXPECT_TRUE(std::includes(out.begin(), out.end(), by_queries.begin(), by_queries.end())) << where << name;
          if (l.kind == LevelKind::Ternary) ternary_tightened += out.size() < fr.pvs.size() ? 1 : 0;
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
  EXPECT_GT(ternary_tightened, 0) << "the ternary tree tightened none of " << frames << " PVSs";
}

TEST(Refine, QueryResultsReadARoundAtOnceChangeNoAnswer) {
  // The levels that query, and Method::Queries, with the results of a round
  // read through a query buffer and one by one: the same sets and the same
  // counts of queries and pixels, frame after frame (near-optimal's state
  // carried over), under one cost model.
  std::unique_ptr<Renderer> batched, each;
  for (auto [batch, out] : {std::pair{true, &batched}, std::pair{false, &each}}) {
    render::ContextOptions o;
    o.batch_queries = batch;
    std::string why;
    *out = Renderer::create(o, &why);
    if (!*out) GTEST_SKIP() << "no renderer on this machine: " << why;
  }
  EXPECT_FALSE(each->info().query_buffer);
  if (!batched->info().query_buffer) GTEST_SKIP() << "no query buffer objects: " << batched->info().summary();
  render::CostModel even;  // Queries worth it for boxes of a few objects.
  even.query_setup_us = 5.0;
  even.render_setup_us = 2.0;
  even.render_triangle_ns = 50.0;
  batched->set_cost_model(even);
  each->set_cost_model(even);
  constexpr int kW = 96, kH = 54;
  int frames = 0, queried = 0;
  for (std::uint64_t seed = 5; seed <= 7; ++seed) {
    batched->reset_refinement();
    each->reset_refinement();
    const SceneDesc scene = random_scene(random_scene_params(seed), seed);
    std::unique_ptr<Scene> engine;
    ASSERT_TRUE(Scene::create(scene, SceneOptions{}, &engine).ok);
    const ViewerId viewer = engine->add_viewer();
    Scratch scratch;
    const std::vector<Camera> path = random_camera_path(scene, seed + 70);
    for (std::size_t f = 0; f < path.size(); f += 6, ++frames) {
      FrameResult fr;
      ASSERT_TRUE(engine->frame(viewer, path[f], static_cast<double>(f) / 60.0, scratch, &fr).ok);
      const std::string where = "seed " + std::to_string(seed) + " frame " + std::to_string(f);
      std::string error;
      for (const char* name : {"queries", "hierarchical", "near-optimal"}) {
        std::vector<ObjectId> a, b;
        RefineStats sa, sb;
        ASSERT_TRUE(batched->refine(level(name), scene.objects, path[f], kW, kH, fr.pvs, &a, &sa, &error)) << error;
        ASSERT_TRUE(each->refine(level(name), scene.objects, path[f], kW, kH, fr.pvs, &b, &sb, &error)) << error;
        EXPECT_EQ(a, b) << where << " " << name;
        EXPECT_EQ(sa.queries, sb.queries) << where << " " << name;
        EXPECT_EQ(sa.pixels, sb.pixels) << where << " " << name;
        queried += static_cast<int>(sa.queries);
      }
      std::vector<ObjectId> a, b;
      render::VisibleStats va, vb;
      const render::VisibleOptions full{kW, kH, render::Method::Queries};
      ASSERT_TRUE(batched->visible(scene.objects, path[f], full, nullptr, &a, &va, &error)) << error;
      ASSERT_TRUE(each->visible(scene.objects, path[f], full, nullptr, &b, &vb, &error)) << error;
      EXPECT_EQ(a, b) << where;
    }
  }
  EXPECT_GT(frames, 6);
  EXPECT_GT(queried, frames * 10) << "too few queries to compare";
}

/// A wall at z = -10 in front of a crowd of 200 small balls (ids 2..201),
/// seen from the origin down -z.
struct WallAndCrowd {
  std::vector<ObjectDesc> objects = {box_between(1, Vec3(-50, -50, -11), Vec3(50, 50, -10))};
  std::vector<ObjectId> pvs = {1};
  std::vector<ObjectId> crowd;
  Camera cam = camera_along(Vec3(0.0), Vec3(0, 0, -1), 60.0, 1.0);
  WallAndCrowd() {
    for (int i = 0; i < 200; ++i) {
      const auto id = static_cast<ObjectId>(i + 2);
      objects.push_back(sphere(id, Vec3(i % 20 - 10, i / 20 - 5, -20.0 - i % 7), 0.4));
      pvs.push_back(id);
      crowd.push_back(id);
    }
  }
};

TEST(Refine, TheTernaryTreeDrawsWhatShowsAndAdaptsToWhatIsHidden) {
  std::string error;
  auto r = Renderer::create(render::ContextOptions{}, &error);
  if (!r) GTEST_SKIP() << "no renderer on this machine: " << error;
  WallAndCrowd s;
  // A dense cluster of 40 small balls in front of the crowd, ids 300..339.
  std::vector<ObjectId> with_cluster = s.crowd;
  for (int i = 0; i < 40; ++i) {
    const auto id = static_cast<ObjectId>(300 + i);
    s.objects.push_back(sphere(id, Vec3(5.2 + 0.2 * (i % 4), 2.2 + 0.2 * (i / 4 % 5), -15.0 - 0.3 * (i / 20)), 0.1));
    with_cluster.push_back(id);
  }
  // The crowd alone, in full view: the first tree, leaves under 12 objects.
  std::vector<ObjectId> out, flat;
  RefineStats first, st;
  ASSERT_TRUE(r->refine(level("ternary"), s.objects, s.cam, 64, 64, s.crowd, &out, &first, &error)) << error;
  ASSERT_TRUE(r->refine(level("queries"), s.objects, s.cam, 64, 64, s.crowd, &flat, &st, &error)) << error;
  EXPECT_EQ(out, flat);
  EXPECT_GT(first.levels, 0u) << "no query waited for a nearer overlapping one";
  // The cluster joins: its leaf shows (ratio >= 0.25) with >= 12 objects and
  // splits, a level a frame.
  RefineStats grown;
  for (int frame = 0; frame < 3; ++frame) {
    ASSERT_TRUE(r->refine(level("ternary"), s.objects, s.cam, 64, 64, with_cluster, &out, &grown, &error)) << error;
    ASSERT_TRUE(r->refine(level("queries"), s.objects, s.cam, 64, 64, with_cluster, &flat, &st, &error)) << error;
    EXPECT_TRUE(std::includes(out.begin(), out.end(), flat.begin(), flat.end())) << "frame " << frame;
  }
  EXPECT_GT(grown.tree_nodes, first.tree_nodes);
  // It leaves: the emptied leaves (<= 5 objects, not shown) merge.
  RefineStats shrunk;
  for (int frame = 0; frame < 3; ++frame)
    ASSERT_TRUE(r->refine(level("ternary"), s.objects, s.cam, 64, 64, s.crowd, &out, &shrunk, &error)) << error;
  EXPECT_LT(shrunk.tree_nodes, grown.tree_nodes);
  // Frame after frame the same view gives the same answer, and what the
  // level keeps between frames does not grow.
  RefineStats steady;
  for (int frame = 0; frame < 40; ++frame) {
    ASSERT_TRUE(r->refine(level("ternary"), s.objects, s.cam, 64, 64, s.crowd, &out, &steady, &error)) << error;
    ASSERT_TRUE(r->refine(level("queries"), s.objects, s.cam, 64, 64, s.crowd, &flat, &st, &error)) << error;
    EXPECT_TRUE(std::includes(out.begin(), out.end(), flat.begin(), flat.end())) << "frame " << frame;
  }
  EXPECT_EQ(steady.tree_nodes, shrunk.tree_nodes);
  // The wall drawn first hides the crowd's boxes: the crowd goes with few
  // queries.
  for (int frame = 0; frame < 2; ++frame) {
    ASSERT_TRUE(r->refine(level("ternary"), s.objects, s.cam, 64, 64, s.pvs, &out, &st, &error)) << error;
    EXPECT_EQ(out, std::vector<ObjectId>{1});
    EXPECT_LT(st.queries, 40u) << "frame " << frame;
  }
}

TEST(Refine, NearOptimalQueriesWhereTheModelSaysItPays) {
  std::string error;
  auto r = Renderer::create(render::ContextOptions{}, &error);
  if (!r) GTEST_SKIP() << "no renderer on this machine: " << error;
  const WallAndCrowd s;
  std::vector<ObjectId> out;
  RefineStats st;
  // Queries dear, drawing cheap: nothing is worth a query, everything kept.
  render::CostModel dear;
  dear.query_setup_us = 1e6;
  dear.render_setup_us = 1.0;
  r->set_cost_model(dear);
  ASSERT_TRUE(r->refine(level("near-optimal"), s.objects, s.cam, 64, 64, s.pvs, &out, &st, &error)) << error;
  EXPECT_EQ(out, s.pvs);
  EXPECT_EQ(st.queries, 0u);
  EXPECT_EQ(st.kept_unqueried, 201u);

  // Queries cheap, drawing dear: what lies behind the wall is queried (as
  // boxes of the hierarchy, not ball by ball) and dropped; the wall, with
  // nothing in front of it, is kept without a query.
  render::CostModel cheap;
  cheap.query_setup_us = 0.01;
  cheap.render_setup_us = 100.0;
  r->set_cost_model(cheap);
  r->reset_refinement();
  for (int frame = 0; frame < 3; ++frame) {
    ASSERT_TRUE(r->refine(level("near-optimal"), s.objects, s.cam, 64, 64, s.pvs, &out, &st, &error)) << error;
    EXPECT_EQ(out, std::vector<ObjectId>{1}) << "frame " << frame;
    EXPECT_GT(st.queries, 0u);
    EXPECT_EQ(st.kept_unqueried, 1u);
    // Nothing known of the first frame: every box the crowd's is walked at
    // once. Hidden since, a box's children wait for its answer.
    if (frame > 0) {
      EXPECT_LT(st.queries, 40u) << "frame " << frame;
    }
  }
  // The triangle count prices drawing: at 1 triangle an object only boxes
  // of many objects are worth a query; at 100,000 every ball is too.
  render::CostModel even;
  even.query_setup_us = 10.0;
  even.render_setup_us = 1.0;
  even.render_triangle_ns = 1000.0;  // 1 us a triangle.
  r->set_cost_model(even);
  RefineStats few, many;
  r->reset_refinement();
  ASSERT_TRUE(r->refine(level("near-optimal:1"), s.objects, s.cam, 64, 64, s.pvs, &out, &few, &error)) << error;
  r->reset_refinement();
  ASSERT_TRUE(r->refine(level("near-optimal:100000"), s.objects, s.cam, 64, 64, s.pvs, &out, &many, &error)) << error;
  EXPECT_LT(few.queries, many.queries);
  EXPECT_GT(few.kept_unqueried, many.kept_unqueried);
  EXPECT_EQ(out, std::vector<ObjectId>{1});
}

TEST(Refine, TheCostModelIsMeasuredOnceAndKeptPerDevice) {
  const std::string path = ::testing::TempDir() + "voxvis-cost-model-test/model.json";
  std::remove(path.c_str());
  std::string error, note;
  render::CostModel a, b;
  {
    auto r = Renderer::create(render::ContextOptions{}, &error);
    if (!r) GTEST_SKIP() << "no renderer on this machine: " << error;
    ASSERT_TRUE(r->cost_model(path, &a, &note, &error)) << error;
    EXPECT_NE(note.find("measured in"), std::string::npos) << note;
    EXPECT_NE(note.find("saved to " + path), std::string::npos) << note;
    EXPECT_EQ(a.device, r->info().gl_renderer + " | " + r->info().gl_version +
                            (r->info().query_buffer ? " | query buffer" : ""));
    for (double v : {a.render_setup_us, a.query_setup_us, a.query_latency_us, a.calibration_ms}) {
      EXPECT_TRUE(std::isfinite(v));
      EXPECT_GT(v, 0.0);
    }
    for (double v : {a.render_triangle_ns, a.render_fragment_ns, a.query_fragment_ns, a.query_overhead_us}) {
      EXPECT_TRUE(std::isfinite(v));
      EXPECT_GE(v, 0.0);
    }
  }
  {
    // Another process (here: renderer) on the same device loads it.
    auto r = Renderer::create(render::ContextOptions{}, &error);
    if (!r) GTEST_SKIP() << "no renderer on this machine: " << error;
    ASSERT_TRUE(r->cost_model(path, &b, &note, &error)) << error;
    EXPECT_EQ(note, "cost model loaded from " + path);
    EXPECT_EQ(b.query_setup_us, a.query_setup_us);
    EXPECT_EQ(b.render_fragment_ns, a.render_fragment_ns);
  }
  // Another device's model in the file is kept when this one's is measured
  // anew; a broken file is measured over, and said so.
  {
    std::ofstream f(path, std::ios::trunc);
    f << R"({"format": "voxvis-cost-model", "version": 1, "models": [{"device": "elsewhere", "render_setup_us": 1,
      "render_triangle_ns": 1, "render_fragment_ns": 1, "query_setup_us": 1, "query_fragment_ns": 1,
      "query_latency_us": 1, "query_overhead_us": 1, "calibration_ms": 1}]})";
  }
  {
    auto r = Renderer::create(render::ContextOptions{}, &error);
    if (!r) GTEST_SKIP() << "no renderer on this machine: " << error;
    ASSERT_TRUE(r->cost_model(path, &b, &note, &error)) << error;
    EXPECT_NE(note.find("measured in"), std::string::npos) << note;
    std::ifstream f(path);
    const std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("\"elsewhere\""), std::string::npos) << text;
    EXPECT_NE(text.find(r->info().gl_renderer), std::string::npos) << text;
  }
  {
    std::ofstream f(path, std::ios::trunc);
    f << "{ not json";
  }
  {
    auto r = Renderer::create(render::ContextOptions{}, &error);
    if (!r) GTEST_SKIP() << "no renderer on this machine: " << error;
    ASSERT_TRUE(r->cost_model(path, &b, &note, &error)) << error;
    EXPECT_NE(note.find("is not valid JSON"), std::string::npos) << note;
    EXPECT_NE(note.find("saved to"), std::string::npos) << note;
  }
  // No place to keep it: measured, and said so.
  {
    auto r = Renderer::create(render::ContextOptions{}, &error);
    if (!r) GTEST_SKIP() << "no renderer on this machine: " << error;
    ASSERT_TRUE(r->cost_model("/proc/voxvis-no/model.json", &b, &note, &error)) << error;
    EXPECT_NE(note.find("not saved"), std::string::npos) << note;
  }
}

TEST(Refine, TheHierarchySkipsTheObjectsOfHiddenBoxes) {
  // A wall in front of a crowd: the crowd's boxes are hidden, so the
  // hierarchy drops them with a few queries where one per object needs 200.
  std::string error;
  auto r = Renderer::create(render::ContextOptions{}, &error);
  if (!r) GTEST_SKIP() << "no renderer on this machine: " << error;
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

TEST(Refine, EmptyAndDegenerateInputs) {
  std::string error;
  auto r = Renderer::create(render::ContextOptions{}, &error);
  if (!r) GTEST_SKIP() << "no renderer on this machine: " << error;
  render::CostModel model;
  model.query_setup_us = 1.0;
  model.render_setup_us = 10.0;
  r->set_cost_model(model);
  const Camera cam = camera_along(Vec3(0.0), Vec3(0, 0, -1), 60.0, 1.0);
  // 30 balls at one point (every split of the ternary tree puts them all on
  // one side) and a ball behind the eye.
  std::vector<ObjectDesc> objects;
  std::vector<ObjectId> pvs;
  for (int i = 0; i < 30; ++i) {
    objects.push_back(sphere(static_cast<ObjectId>(i + 1), Vec3(1.0, 0.5, -8.0), 0.5));
    pvs.push_back(static_cast<ObjectId>(i + 1));
  }
  objects.push_back(sphere(31, Vec3(0.0, 0.0, 8.0), 0.5));
  pvs.push_back(31);
  const std::vector<ObjectId> all_at_one_point(pvs.begin(), pvs.end() - 1);
  for (const char* name : {"none", "queries", "hierarchical", "lazy-grid", "ternary", "near-optimal", "adaptive:4"}) {
    std::vector<ObjectId> out = {99};
    RefineStats st;
    // An empty PVS stays empty.
    ASSERT_TRUE(r->refine(level(name), objects, cam, 32, 32, {}, &out, &st, &error)) << name << ": " << error;
    EXPECT_TRUE(out.empty()) << name;
    // Tied objects all show (the depth test passes on equal depths); the
    // one behind the eye goes with every level but none.
    r->reset_refinement();
    for (int frame = 0; frame < 3; ++frame) {
      ASSERT_TRUE(r->refine(level(name), objects, cam, 32, 32, pvs, &out, &st, &error)) << name << ": " << error;
      EXPECT_EQ(out, std::string(name) == "none" ? pvs : all_at_one_point) << name << " frame " << frame;
    }
  }
}

TEST(Refine, BadLevelsAndIdsAreErrors) {
  Level l;
  std::string message;
  for (const char* bad : {"", "query", "adaptive", "adaptive:", "adaptive:0", "adaptive:-3", "adaptive:x",
                          "adaptive:99999999", "near-optimal:", "near-optimal:0", "near-optimal:1e3",
                          "near-optimal:99999999", "ternary:2"}) {
    EXPECT_FALSE(render::parse_level(bad, &l, &message)) << bad;
    EXPECT_NE(message.find(bad), std::string::npos) << message;
  }
  EXPECT_TRUE(render::parse_level("adaptive:25", &l, &message));
  EXPECT_EQ(l.min_pixels, 25u);
  EXPECT_EQ(render::level_name(l), "adaptive:25");
  EXPECT_TRUE(render::level_may_miss(l));
  EXPECT_FALSE(render::level_may_miss(level("hierarchical")));
  EXPECT_EQ(level("near-optimal").triangles, 1000u);
  EXPECT_EQ(level("near-optimal:250").triangles, 250u);
  EXPECT_EQ(render::level_name(level("near-optimal:250")), "near-optimal:250");
  EXPECT_EQ(render::level_name(level("near-optimal")), "near-optimal");
  EXPECT_FALSE(render::level_may_miss(level("near-optimal")));
  EXPECT_FALSE(render::level_may_miss(level("ternary")));

  std::string error;
  auto r = Renderer::create(render::ContextOptions{}, &error);
  if (!r) GTEST_SKIP() << "no renderer on this machine: " << error;
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
