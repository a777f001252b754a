// TBVs keep clear of the space viewers see (docs/design.md, "Temporal
// bounding volumes"): hidden moving objects around a closed room stay
// hidden, unrevealed and off the wake list except when their TBV expires,
// while every frame keeps zero misses against the ray caster; and a TBV
// deep in space no one saw starts at the longest period.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vector_relational.hpp>

#include "engine_check.h"
#include "scene_impl.h"
#include "scenes.h"
#include "voxvis/scene.h"

namespace voxvis::test {
namespace {

constexpr double kSeenDt = 1.0 / 30.0;
constexpr ObjectId kFirstHidden = 100;

/// Bounds 0..48 on a 48^3 grid of unit voxels; a closed room (outer box
/// [12, 36]^3, walls 2 voxels thick on voxel planes) with a few static
/// spheres inside; `n` dynamic spheres (radius 0.3) outside it, at least 2
/// voxels from its walls, with `max_speed`.
SceneDesc room_with_hidden(int n, double max_speed, std::uint64_t seed) {
  SceneDesc s;
  s.bounds_min = Vec3(0.0);
  s.bounds_max = Vec3(48.0);
  s.grid = glm::ivec3(48);
  ObjectId id = 1;
  const Vec3 lo(12.0), hi(36.0);
  for (int a = 0; a < 3; ++a)
    for (int side = 0; side < 2; ++side) {
      Vec3 wlo = lo, whi = hi;
      if (side == 0)
        whi[a] = lo[a] + 2.0;
      else
        wlo[a] = hi[a] - 2.0;
      s.objects.push_back(box_between(id++, wlo, whi));
    }
  Rng rng(seed);
  for (int i = 0; i < 6; ++i) s.objects.push_back(sphere(id++, rng.in_box(Vec3(17.0), Vec3(31.0)), 1.0));
  id = kFirstHidden;
  while (static_cast<int>(s.objects.size()) < 12 + n) {
    const Vec3 c = rng.in_box(Vec3(1.0), Vec3(47.0));
    if (glm::all(glm::greaterThan(c, Vec3(10.0))) && glm::all(glm::lessThan(c, Vec3(38.0)))) continue;
    s.objects.push_back(dynamic(sphere(id++, c, 0.3), max_speed));
  }
  return s;
}

/// The eye at the room's centre, turning about the vertical axis: one whole
/// turn in the first second (30 frames), slowly after that.
Camera turning_camera(int frame) {
  Camera c;
  const double a = frame < 30 ? 0.22 * frame : 6.6 + 0.02 * (frame - 30);
  c.eye = Vec3(24.0, 24.5, 24.0);
  c.dir = Vec3(std::cos(a), -0.2, std::sin(a));
  c.up = Vec3(0.0, 1.0, 0.0);
  c.fov_y_deg = 75.0;
  c.aspect = 16.0 / 9.0;
  c.near = 0.05;
  c.far = 500.0;
  return c;
}

std::size_t hidden_in(const std::vector<ObjectId>& ids) {
  return static_cast<std::size_t>(
      std::count_if(ids.begin(), ids.end(), [](ObjectId id) { return id >= kFirstHidden; }));
}

TEST(TbvSeenSpace, HiddenObjectsAroundAClosedRoomAreNeverRevealed) {
  // Periods grow to the time to cross 8 voxels (12 with the per-object
  // factor): grown as they were, TBVs of objects 2 voxels outside the room
  // reach through its 2-voxel walls into the space the eye sees.
  EngineHarness h(room_with_hidden(400, 3.0, 77), buffer_off(), "closed room, 400 hidden");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  double t = 0.0;
  int f = 0;
  for (; f < 30; ++f, t += kSeenDt) ASSERT_EQ(h.frame(turning_camera(f), t), "") << "frame " << f;
  ASSERT_EQ(h.last().stats.tbvs_active, 400u);
  std::uint32_t revealed = 0, expired = 0;
  std::size_t in_pvs = 0;
  for (; f < 150; ++f, t += kSeenDt) {
    ASSERT_EQ(h.frame(turning_camera(f), t), "") << "frame " << f;
    const FrameResult& r = h.last();
    revealed += r.stats.tbvs_revealed;
    expired += r.stats.tbvs_expired;
    in_pvs += hidden_in(r.pvs);
    // Only expiry wakes a hidden object (a lazily simulating backend must
    // bring it up to date before it could have walked into view).
    EXPECT_EQ(r.wake.size(), r.stats.tbvs_expired) << "frame " << f;
  }
  EXPECT_EQ(revealed, 0u);
  EXPECT_EQ(in_pvs, 0u);
  EXPECT_GT(expired, 400u);  // Every TBV was renewed at least once on average.
}

TEST(TbvSeenSpace, WithTheBufferHiddenObjectsAroundAClosedRoomStayHidden) {
  // The same room with the buffer on (the default). Bricks holding
  // something and TBVs are tested over each pixel at their own depth there,
  // so the walls keep the space behind them out of the seen record and hide
  // the TBVs grown up to them. What the buffer leaves is few: TBVs grown in
  // the first second while the eye turned, and objects so close to seen
  // space that their TBVs are left uncut (tested at their least depth over
  // their whole rectangle instead, about 700 were revealed in these
  // frames, and hidden objects reached the PVS).
  EngineHarness h(room_with_hidden(400, 3.0, 77), SceneOptions{}, "closed room, 400 hidden, buffer");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  double t = 0.0;
  int f = 0;
  for (; f < 30; ++f, t += kSeenDt) ASSERT_EQ(h.frame(turning_camera(f), t), "") << "frame " << f;
  std::uint32_t revealed = 0, expired = 0;
  std::size_t in_pvs = 0;
  for (; f < 150; ++f, t += kSeenDt) {
    ASSERT_EQ(h.frame(turning_camera(f), t), "") << "frame " << f;
    const FrameResult& r = h.last();
    EXPECT_GT(r.stats.ob_width, 0u);
    revealed += r.stats.tbvs_revealed;
    expired += r.stats.tbvs_expired;
    in_pvs += hidden_in(r.pvs);
  }
  EXPECT_EQ(in_pvs, 0u);
  EXPECT_LE(revealed, 20u);  // One TBV in twenty at most (9 when written).
  EXPECT_GT(expired, 400u);
}

/// A wall across the grid (z 36..38) in front of the eye of wall_camera, 8
/// voxels away; 40 movers far behind it (z 1..3.5: a TBV grown as far as
/// its cells hold it whole stays in cells no frame sees), ids from
/// kFirstHidden, and 40 just behind it (z 26..33, whose boxes would reach
/// the seen space in front of the wall), ids from kFirstHidden + 40.
SceneDesc wall_with_movers() {
  SceneDesc d;
  d.bounds_min = Vec3(0.0);
  d.bounds_max = Vec3(48.0);
  d.grid = glm::ivec3(48);
  d.objects.push_back(box_between(1, Vec3(0.0, 0.0, 36.0), Vec3(48.0, 48.0, 38.0)));
  Rng rng(5);
  ObjectId id = kFirstHidden;
  for (int i = 0; i < 40; ++i)
    d.objects.push_back(dynamic(sphere(id++, rng.in_box(Vec3(2.0, 2.0, 1.0), Vec3(46.0, 46.0, 3.5)), 0.3), 1.0));
  for (int i = 0; i < 40; ++i)
    d.objects.push_back(dynamic(sphere(id++, rng.in_box(Vec3(2.0, 2.0, 26.0), Vec3(46.0, 46.0, 33.0)), 0.3), 1.0));
  return d;
}

/// A field of view of 150 degrees: the eye sees the whole front of the
/// wall, so every cell the near movers reach holds seen space.
Camera wall_camera() {
  return camera_along(Vec3(24.0, 24.0, 46.0), Vec3(0.0, 0.0, -1.0), 150.0, 1.0, 0.05, 500.0);
}

TEST(TbvSeenSpace, DeepInUnseenSpaceATbvStartsLong) {
  // Periods start at 2 s and double up to 8 s, each scaled by [0.5, 1.5):
  // the near movers are woken within 3 s. The far ones' TBVs are held whole
  // by the cells around them from the start, and take the period their
  // growth there holds (15.3 voxels at speed 1, scaled by [0.75, 1)): none
  // is woken in the first 11 s. Nothing hidden is revealed or kept.
  EngineHarness h(wall_with_movers(), SceneOptions{}, "wall, far and near movers");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  const ObjectId first_near = kFirstHidden + 40;
  std::vector<bool> near_woken(40, false);
  std::uint32_t revealed = 0;
  std::size_t in_pvs = 0;
  double t = 0.0;
  for (int f = 0; t < 11.0; ++f, t += kSeenDt) {
    ASSERT_EQ(h.frame(wall_camera(), t), "") << "frame " << f;
    const FrameResult& r = h.last();
    revealed += r.stats.tbvs_revealed;
    in_pvs += hidden_in(r.pvs);
    for (ObjectId w : r.wake) {
      EXPECT_GE(w, first_near) << "far mover " << w << " woken at t=" << t;
      if (w >= first_near) near_woken[static_cast<std::size_t>(w - first_near)] = true;
    }
  }
  EXPECT_EQ(revealed, 0u);
  EXPECT_EQ(in_pvs, 0u);
  EXPECT_EQ(std::count(near_woken.begin(), near_woken.end(), true), 40) << "the near movers' periods start short";
}

/// Runs `frames` frames of h's scene, each at kSeenDt after the last, and
/// checks every TBV made or renewed in a frame: on each side its box is
/// grown from the object's by at least max_speed times the time to its
/// expiry (or reaches the grid's bounds), so it holds every position the
/// object can reach before it expires.
void check_tbv_reach(EngineHarness& h, const std::function<Camera(int)>& camera, int frames) {
  const Scene::Impl& s = h.scene().impl();
  std::vector<std::uint32_t> epoch(s.objs.size(), 0);
  std::size_t checked = 0;
  double t = 0.0;
  for (int f = 0; f < frames; ++f, t += kSeenDt) {
    ASSERT_EQ(h.frame(camera(f), t), "") << "frame " << f;
    for (std::size_t slot = 0; slot < s.objs.size(); ++slot) {
      const detail::Obj& o = s.objs[slot];
      if (!o.under_tbv || o.tbv_epoch == epoch[slot]) continue;
      epoch[slot] = o.tbv_epoch;
      ++checked;
      const double reach = o.max_speed * (o.tbv_expiry - t) * (1.0 - 1e-12);
      for (int a = 0; a < 3; ++a) {
        if (o.tbv_lo[a] > s.spec.bounds_min[a]) {
          ASSERT_GE(o.box_lo()[a] - o.tbv_lo[a], reach) << "object " << o.id << " axis " << a << " frame " << f;
        }
        if (o.tbv_hi[a] < s.spec.bounds_max[a]) {
          ASSERT_GE(o.tbv_hi[a] - o.box_hi()[a], reach) << "object " << o.id << " axis " << a << " frame " << f;
        }
      }
    }
  }
  EXPECT_GT(checked, s.objs.size()) << "TBVs made and renewed";
}

TEST(TbvSeenSpace, EveryTbvHoldsWhereItsObjectCanReachBeforeItExpires) {
  // Behind a wall (TBVs started long, started short and doubling, cut short
  // by the seen space in front of it) and around a closed room with a
  // turning eye; 12 s of frames, past the long TBVs' first renewals.
  EngineHarness wall(wall_with_movers(), SceneOptions{}, "wall, far and near movers");
  ASSERT_TRUE(wall.status().ok) << wall.status().str();
  check_tbv_reach(wall, [](int) { return wall_camera(); }, 400);
  EngineHarness room(room_with_hidden(100, 3.0, 77), SceneOptions{}, "closed room, 100 hidden");
  ASSERT_TRUE(room.status().ok) << room.status().str();
  check_tbv_reach(room, turning_camera, 400);
}

TEST(TbvSeenSpace, WithoutMemoryTheTurningViewerRevealsTbvs) {
  // The same room with tbv_seen_memory 0: only the last frame's view is kept
  // clear, so TBVs grow into the part of the room behind the turning eye and
  // are revealed when it comes round. The memory is what the test above
  // relies on.
  SceneOptions options;
  options.tbv_seen_memory = 0.0;
  EngineHarness h(room_with_hidden(400, 3.0, 77), buffer_off(options), "closed room, no memory");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  double t = 0.0;
  std::uint32_t revealed = 0;
  for (int f = 0; f < 150; ++f, t += kSeenDt) {
    ASSERT_EQ(h.frame(turning_camera(f), t), "") << "frame " << f;
    if (f >= 30) revealed += h.last().stats.tbvs_revealed;
  }
  EXPECT_GT(revealed, 0u);
}

TEST(TbvSeenSpace, AnObjectWalkingIntoTheRoomIsRevealedAndSeen) {
  // Objects walk at their speed limit straight into the room (through its
  // wall). Their moves leave TBVs that keep clear of the room, so each is
  // revealed by a move; the harness checks every frame for misses.
  SceneDesc scene = room_with_hidden(40, 3.0, 78);
  std::vector<std::pair<ObjectId, Vec3>> walkers;
  for (const ObjectDesc& o : scene.objects)
    if (o.id >= kFirstHidden && walkers.size() < 8) walkers.emplace_back(o.id, o.center);
  EngineHarness h(scene, buffer_off(), "closed room, walkers");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  double t = 0.0;
  int f = 0;
  for (; f < 30; ++f, t += kSeenDt) ASSERT_EQ(h.frame(turning_camera(f), t), "") << "frame " << f;
  std::uint32_t revealed = 0;
  std::size_t walkers_seen = 0;
  for (; f < 330; ++f, t += kSeenDt) {
    std::vector<Move> moves;
    for (auto& [id, c] : walkers) {
      const Vec3 to = Vec3(24.0) - c;
      const double len = std::sqrt(glm::dot(to, to));
      if (len > 0.5) c += to * (0.95 * 3.0 * kSeenDt / len);
      moves.push_back({id, c});
    }
    ASSERT_TRUE(h.move(t, moves).ok);
    ASSERT_EQ(h.frame(turning_camera(f), t), "") << "frame " << f;
    revealed += h.last().stats.tbvs_revealed;
    walkers_seen = std::max(walkers_seen, hidden_in(h.last().pvs));
  }
  EXPECT_GE(revealed, walkers.size());
  EXPECT_GT(walkers_seen, 0u);
}

/// A wall z in [24, 34], x up to 44, past the whole height of a 64 x 32
/// x 64 grid, with `n` dynamic spheres behind it (z < 20, x < 32): their
/// TBVs, at most 12 voxels of growth, stay inside the wall.
SceneDesc wall_with_hidden(int n, std::uint64_t seed) {
  SceneDesc s;
  s.bounds_min = Vec3(0.0);
  s.bounds_max = Vec3(64.0, 32.0, 64.0);
  s.grid = glm::ivec3(64, 32, 64);
  s.objects.push_back(box_between(1, Vec3(-20.0, -20.0, 24.0), Vec3(44.0, 52.0, 34.0)));
  Rng rng(seed);
  for (int i = 0; i < n; ++i)
    s.objects.push_back(dynamic(sphere(kFirstHidden + static_cast<ObjectId>(i), rng.in_box(Vec3(1.0), Vec3(32.0, 31.0, 20.0)), 0.3), 1.5));
  return s;
}

TEST(TbvSeenSpace, TbvsHeldWholeBehindAWallAreRevealedWhenTheEyeWalksRoundIt) {
  // Three seconds in front of the wall: the objects behind it get TBVs,
  // held whole by the 16-voxel cells no one sees (Scene::Impl::
  // tbv_coarse_cells) and grown there without new entries. Then the eye
  // walks round the wall's end and looks back behind it: each TBV must be
  // tested by its part in the cells entered (reveal_part), and every object
  // the rays see must be in the PVS (the harness checks every frame).
  EngineHarness h(wall_with_hidden(300, 91), SceneOptions{}, "wall, 300 hidden, buffer");
  ASSERT_TRUE(h.status().ok) << h.status().str();
  Camera c = turning_camera(0);
  c.eye = Vec3(22.0, 16.0, 60.0);
  c.dir = Vec3(0.0, 0.0, -1.0);
  double t = 0.0;
  int f = 0;
  std::uint32_t revealed = 0;
  for (; f < 90; ++f, t += kSeenDt) {
    ASSERT_EQ(h.frame(c, t), "") << "frame " << f;
    if (f >= 30) revealed += h.last().stats.tbvs_revealed;
  }
  EXPECT_EQ(h.last().stats.tbvs_active, 300u);
  EXPECT_EQ(revealed, 0u);
  EXPECT_EQ(hidden_in(h.last().pvs), 0u);
  // Round the end of the wall (x 44) and back along its far side, looking
  // at the objects.
  std::size_t seen = 0;
  for (int k = 0; k < 60; ++k, ++f, t += kSeenDt) {
    const double a = k / 59.0;
    c.eye = a < 0.5 ? Vec3(22.0 + 2.0 * a * 32.0, 16.0, 60.0 - 2.0 * a * 25.0) : Vec3(54.0, 16.0, 35.0 - 2.0 * (a - 0.5) * 15.0);
    c.dir = glm::normalize(Vec3(20.0, 16.0, 14.0) - c.eye);
    ASSERT_EQ(h.frame(c, t), "") << "frame " << f;
    revealed += h.last().stats.tbvs_revealed;
    seen = std::max(seen, hidden_in(h.last().pvs));
  }
  EXPECT_GT(revealed, 100u);
  EXPECT_GT(seen, 100u);
}

TEST(TbvSeenSpace, BadSeenMemoryIsRefusedByName) {
  for (double bad : {-1.0, std::nan(""), std::numeric_limits<double>::infinity()}) {
    SceneOptions options;
    options.tbv_seen_memory = bad;
    std::unique_ptr<Scene> scene;
    const Status st = Scene::create(room_with_hidden(4, 1.0, 1), options, &scene);
    EXPECT_FALSE(st.ok) << bad;
    EXPECT_NE(st.str().find("tbv_seen_memory"), std::string::npos) << st.str();
  }
}

}  // namespace
}  // namespace voxvis::test
