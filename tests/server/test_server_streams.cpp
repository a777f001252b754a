// The streams' incremental encodings against the engine: PVS deltas
// reassemble to the full PVS, and the Simulate stream's wake list follows the
// engine's wake_set() step by step, with View answers equal to an in-process
// Scene driven by the same moves and frames at the same times.
#include <algorithm>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "scenes.h"
#include "server_process.h"
#include "voxvis/format.h"
#include "voxvis/scene.h"

namespace voxvis::servertest {
namespace {

std::string show(const std::vector<ObjectId>& ids) {
  std::ostringstream o;
  o << "[";
  for (std::size_t i = 0; i < ids.size(); ++i) o << (i ? "," : "") << ids[i];
  o << "]";
  return o.str();
}

test::RandomSceneParams stream_scene_params() {
  test::RandomSceneParams p;
  p.dynamic_fraction = 0.4;
  p.max_speed = 10.0;
  return p;
}

// ---------------------------------------------------------------------------

TEST(ServerStreams, DeltasReassembleToFullPvs) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  for (std::uint64_t seed : {11u, 12u, 13u}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const SceneDesc desc = test::random_scene(stream_scene_params(), seed);
    const std::string json = scene_to_json(desc);
    // Two copies: viewers of one scene share its TBVs, so each stream gets
    // its own scene to see exactly what the other sees.
    const std::string full_id = "full-" + std::to_string(seed);
    const std::string delta_id = "delta-" + std::to_string(seed);
    ASSERT_TRUE(api.create_scene_json(full_id, json).ok());
    ASSERT_TRUE(api.create_scene_json(delta_id, json).ok());

    test::CameraPathParams cp;
    cp.frames = 60;
    const std::vector<Camera> path = test::random_camera_path(desc, seed, cp);
    ViewStream full(api, full_id, v1::PVS_FULL);
    ViewStream delta(api, delta_id, v1::PVS_DELTA);
    std::vector<ObjectId> assembled;
    std::size_t delta_ids = 0, full_ids = 0, changes = 0;
    for (std::size_t i = 0; i < path.size(); ++i) {
      SCOPED_TRACE("frame " + std::to_string(i));
      const double t = static_cast<double>(i) / 30.0;
      v1::ViewResponse f, d;
      ASSERT_TRUE(full.frame(i + 1, t, path[i], &f)) << full.finish().error_message();
      ASSERT_TRUE(delta.frame(i + 1, t, path[i], &d)) << delta.finish().error_message();
      ASSERT_EQ(f.frame(), i + 1);
      ASSERT_EQ(d.frame(), i + 1);
      EXPECT_EQ(f.encoding(), v1::PVS_FULL);
      EXPECT_EQ(d.encoding(), v1::PVS_DELTA);
      EXPECT_TRUE(f.added().empty() && f.removed().empty());
      EXPECT_TRUE(d.pvs().empty());

      const std::vector<ObjectId> added = ids_of(d.added()), removed = ids_of(d.removed());
      ASSERT_TRUE(std::is_sorted(added.begin(), added.end()));
      ASSERT_TRUE(std::is_sorted(removed.begin(), removed.end()));
      std::vector<ObjectId> next;
      // removed must be in the previous PVS, added must not.
      std::vector<ObjectId> kept;
      std::set_difference(assembled.begin(), assembled.end(), removed.begin(), removed.end(),
                          std::back_inserter(kept));
      ASSERT_EQ(kept.size() + removed.size(), assembled.size())
          << "removed ids not in the previous PVS: " << show(removed);
      std::set_union(kept.begin(), kept.end(), added.begin(), added.end(),
                     std::back_inserter(next));
      ASSERT_EQ(next.size(), kept.size() + added.size())
          << "added ids already in the previous PVS: " << show(added);
      assembled = next;

      EXPECT_EQ(assembled, ids_of(f.pvs()));
      EXPECT_EQ(ids_of(d.wake()), ids_of(f.wake()));
      EXPECT_EQ(counters(d.stats()), counters(f.stats()));
      delta_ids += added.size() + removed.size();
      full_ids += static_cast<std::size_t>(f.pvs_size());
      if (i > 0 && !(added.empty() && removed.empty())) ++changes;
    }
    EXPECT_TRUE(full.finish().ok());
    EXPECT_TRUE(delta.finish().ok());
    // The path must make the PVS change, and deltas must be smaller than
    // whole sets (or this test checks nothing).
    EXPECT_GT(changes, 5u);
    EXPECT_LT(delta_ids, full_ids);
  }
}

// ---------------------------------------------------------------------------

/// Follows the wake lists a Simulate stream reassembles against the engine's
/// wake_set() after every step. The server sends the latest list whenever it
/// changes (latest wins), so the lists received must be the expected states
/// of some steps, in order.
class WakeFollower {
 public:
  explicit WakeFollower(SimStream* sim) : sim_(sim) {}

  /// Records the engine's set after a step and waits (bounded) until the
  /// stream's list is that set. False (and the test fails) when it does not
  /// get there or a list received was none of the engine's sets.
  [[nodiscard]] bool step(const std::vector<ObjectId>& expected, const std::string& what) {
    expected_.push_back(expected);
    if (!check_new(what)) return false;
    for (;;) {
      const auto h = sim_->wake_history();
      if (!h.empty() && h.back() == expected) return true;
      if (!sim_->wait_wake_count(h.size(), Seconds(10))) {
        ADD_FAILURE() << what << ": the wake list did not become " << show(expected)
                      << " within 10 s; last received "
                      << (h.empty() ? std::string("nothing") : show(h.back()));
        return false;
      }
      if (!check_new(what)) return false;
    }
  }

  std::size_t distinct_expected() const {
    std::vector<std::vector<ObjectId>> v = expected_;
    std::sort(v.begin(), v.end());
    return static_cast<std::size_t>(std::unique(v.begin(), v.end()) - v.begin());
  }

 private:
  bool check_new(const std::string& what) {
    if (const auto errors = sim_->protocol_errors(); !errors.empty()) {
      ADD_FAILURE() << what << ": " << errors.front();
      return false;
    }
    const auto h = sim_->wake_history();
    for (; seen_ < h.size(); ++seen_) {
      std::size_t j = matched_;
      while (j < expected_.size() && expected_[j] != h[seen_]) ++j;
      if (j == expected_.size()) {
        ADD_FAILURE() << what << ": wake list #" << seen_ << " " << show(h[seen_])
                      << " is not the engine's set at any step since step " << matched_ << " (now "
                      << show(expected_.back()) << ")";
        return false;
      }
      matched_ = j;
    }
    return true;
  }

  SimStream* sim_;
  std::vector<std::vector<ObjectId>> expected_;
  std::size_t matched_ = 0;
  std::size_t seen_ = 0;
};

TEST(ServerStreams, WakeListAndAnswersMatchEngine) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  std::size_t total_changes = 0;
  for (std::uint64_t seed : {21u, 22u}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const std::string json = scene_to_json(test::random_scene(stream_scene_params(), seed));
    // The engine's input exactly as the server parses it.
    SceneDesc desc;
    FormatError ferr;
    ASSERT_TRUE(parse_scene(json, "scene_json", &desc, &ferr)) << ferr.str();
    std::unique_ptr<Scene> scene;
    ASSERT_TRUE(Scene::create(desc, SceneOptions{}, &scene).ok);
    const std::string id = "wake-" + std::to_string(seed);
    ASSERT_TRUE(api.create_scene_json(id, json).ok());

    SimStream sim(api, id);
    WakeFollower follow(&sim);
    ASSERT_TRUE(follow.step(scene->wake_set(), "subscription"));

    const ViewerId viewer = scene->add_viewer();
    Scratch scratch;
    ViewStream view(api, id, v1::PVS_FULL);
    test::CameraPathParams cp;
    cp.frames = 50;
    const std::vector<Camera> path = test::random_camera_path(desc, seed, cp);
    test::Mover mover(desc, seed);
    ObjectId teleported = 0;
    for (const ObjectDesc& o : desc.objects)
      if (o.dynamic) teleported = o.id;
    ASSERT_NE(teleported, 0u);

    for (std::size_t i = 0; i < path.size(); ++i) {
      const double t = static_cast<double>(i + 1) / 30.0;
      std::vector<Move> moves = mover.step(1.0 / 30.0);
      if (i % 10 == 5) {
        // A jump far beyond max_speed: applied, reported too fast.
        moves.erase(std::remove_if(moves.begin(), moves.end(),
                                   [&](const Move& m) { return m.id == teleported; }),
                    moves.end());
        moves.push_back({teleported, Vec3(5.0 * static_cast<double>(i % 7), 50.0, 50.0)});
      }
      if (i % 4 != 3 && !moves.empty()) {
        const std::string what = "moves " + std::to_string(i);
        SCOPED_TRACE(what);
        v1::MoveAck ack;
        ASSERT_TRUE(sim.move(i, t, moves, &ack)) << sim.finish().error_message();
        MoveReport report;
        ASSERT_TRUE(scene->apply_moves(t, moves, &report).ok);
        EXPECT_EQ(ack.seq(), i);
        EXPECT_EQ(ack.applied(), report.applied);
        EXPECT_EQ(ids_of(ack.too_fast()), report.too_fast);
        EXPECT_EQ(ack.t(), t);
        ASSERT_TRUE(follow.step(scene->wake_set(), what));
      }
      const std::string what = "frame " + std::to_string(i);
      SCOPED_TRACE(what);
      v1::ViewResponse resp;
      ASSERT_TRUE(view.frame(i, t, path[i], &resp)) << view.finish().error_message();
      FrameResult result;
      ASSERT_TRUE(scene->frame(viewer, path[i], t, scratch, &result).ok);
      EXPECT_EQ(resp.frame(), i);
      EXPECT_EQ(resp.t(), t);
      EXPECT_EQ(ids_of(resp.pvs()), result.pvs);
      EXPECT_EQ(ids_of(resp.wake()), result.wake);
      EXPECT_EQ(counters(resp.stats()), counters(result.stats));
      const std::vector<ObjectId> wake = scene->wake_set();
      ASSERT_TRUE(follow.step(wake, what));
      v1::SceneInfo info;
      ASSERT_TRUE(api.stats(id, &info).ok());
      EXPECT_EQ(info.wake_size(), wake.size());
      EXPECT_EQ(info.tbvs_active(), result.stats.tbvs_active);
    }
    EXPECT_TRUE(view.finish().ok());
    EXPECT_TRUE(sim.finish().ok());
    const auto errors = sim.protocol_errors();
    EXPECT_TRUE(errors.empty()) << errors.front();
    // The walk must put objects to sleep and wake them again.
    EXPECT_GE(follow.distinct_expected(), 4u);
    total_changes += sim.wake_history().size();
    RecordProperty("wake_lists_" + std::to_string(seed), std::to_string(sim.wake_history().size()));
    RecordProperty("wake_states_" + std::to_string(seed),
                   std::to_string(follow.distinct_expected()));
  }
  EXPECT_GE(total_changes, 6u);
}

}  // namespace
}  // namespace voxvis::servertest
