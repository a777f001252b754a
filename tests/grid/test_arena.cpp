// The arena preset (voxvis/generate.h, make_arena): its walls fill whole
// voxels, its players and camera keep clear of every wall, pillar and stair
// and run no faster than 320 units a second on both storeys, and the engine
// misses nothing in it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "engine_check.h"
#include "voxvis/generate.h"

namespace voxvis::test {
namespace {

constexpr double kRun = 320.0;
const Vec3 kPlayerHalf{16.0, 28.0, 16.0};

/// Whether the open boxes [alo, ahi] and [blo, bhi] share interior volume.
bool overlap(const Vec3& alo, const Vec3& ahi, const Vec3& blo, const Vec3& bhi) {
  for (int a = 0; a < 3; ++a)
    if (ahi[a] <= blo[a] || bhi[a] <= alo[a]) return false;
  return true;
}

std::vector<ObjectDesc> statics(const SceneDesc& d) {
  std::vector<ObjectDesc> out;
  for (const ObjectDesc& o : d.objects)
    if (!o.dynamic) out.push_back(o);
  return out;
}

TEST(Arena, WallsFillWholeVoxelsAndTheGridCoversTheLevel) {
  const ArenaLevel a = make_arena(4, 24, 0, 3);
  const SceneDesc& d = a.scene;
  ASSERT_TRUE(d.grid.has_value());
  const Vec3 size = d.bounds_max - d.bounds_min;
  for (int k = 0; k < 3; ++k) EXPECT_EQ(size[k], 16.0 * (*d.grid)[k]) << "axis " << k;
  // A few thousand units across, two storeys.
  EXPECT_GE(size.x, 2000.0);
  EXPECT_GE(size.z, 2000.0);
  int upper_slabs = 0, steps = 0;
  for (const ObjectDesc& o : statics(d)) {
    ASSERT_EQ(o.shape, Shape::Box);
    const Vec3 lo = o.center - o.half_extent, hi = o.center + o.half_extent;
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(std::fmod(lo[k], 16.0), 0.0) << "object " << o.id;
      EXPECT_EQ(std::fmod(hi[k], 16.0), 0.0) << "object " << o.id;
      EXPECT_GE(lo[k], d.bounds_min[k]);
      EXPECT_LE(hi[k], d.bounds_max[k]);
    }
    if (lo.y == 176.0 && hi.y == 192.0) ++upper_slabs;
    if (lo.y == 0.0 && hi.y <= 192.0 && o.half_extent.z == 8.0 && o.half_extent.x == 48.0) ++steps;
  }
  EXPECT_GE(upper_slabs, 3 + 2 * 3) << "the walkways and at least two upper floors";
  EXPECT_GE(steps, 2 * 12) << "a stair of 12 steps in each upper room";
  // The players: 24 dynamic boxes of 32 x 32 x 56 at max_speed 320.
  int players = 0;
  for (const ObjectDesc& o : d.objects)
    if (o.dynamic) {
      ++players;
      EXPECT_EQ(o.shape, Shape::Box);
      EXPECT_EQ(o.half_extent, kPlayerHalf);
      EXPECT_EQ(o.max_speed, kRun);
    }
  EXPECT_EQ(players, 24);
}

TEST(Arena, PlayersAndCameraRunClearOfTheLevelWithinTheirSpeed) {
  for (const std::uint64_t seed : {3u, 4u, 5u}) {
    const ArenaLevel a = make_arena(seed == 5 ? 2 : 4, 24, 600, seed);
    const std::vector<ObjectDesc> walls = statics(a.scene);
    std::map<ObjectId, Vec3> last;
    std::map<double, int> on_floor;  // Players' centre heights.
    double ran = 0.0, looked_back = 0.0;
    for (std::size_t i = 0; i < a.frames.size(); ++i) {
      const FrameInput& f = a.frames[i];
      const std::string where = "seed " + std::to_string(seed) + " frame " + std::to_string(i);
      ASSERT_EQ(f.moves.size(), 24u) << where;
      EXPECT_EQ(f.t, static_cast<double>(i) / 60.0);
      for (const Move& m : f.moves) {
        const Vec3 lo = m.center - kPlayerHalf, hi = m.center + kPlayerHalf;
        for (const ObjectDesc& w : walls) {
          EXPECT_FALSE(overlap(lo, hi, w.center - w.half_extent, w.center + w.half_extent))
              << where << ": player " << m.id << " at " << m.center.x << "," << m.center.y << "," << m.center.z
              << " inside object " << w.id;
        }
        if (i > 0) {
          const double step = glm::length(m.center - last[m.id]);
          EXPECT_LE(step, kRun / 60.0) << where << ": player " << m.id;
          ran += step;
        }
        last[m.id] = m.center;
        if (i == 0) ++on_floor[m.center.y];
      }
      // The eye: inside the level, outside every wall by more than near.
      const Vec3 e = f.camera.eye;
      for (const ObjectDesc& w : walls) {
        const Vec3 n(f.camera.near);
        EXPECT_FALSE(overlap(e - n, e + n, w.center - w.half_extent, w.center + w.half_extent))
            << where << ": eye inside object " << w.id;
      }
      if (i > 0) {
        const Vec3 before = a.frames[i - 1].camera.eye;
        EXPECT_LE(glm::length(e - before), kRun / 60.0) << where;
        const double turn = std::acos(std::clamp(
            glm::dot(glm::normalize(f.camera.dir), glm::normalize(a.frames[i - 1].camera.dir)), -1.0, 1.0));
        looked_back = std::max(looked_back, turn);
      }
    }
    // Half the players on each storey, and they run: at least 90% of
    // 320 units a second on average (corners and the walk's end aside).
    EXPECT_EQ(on_floor.size(), 2u);
    EXPECT_EQ(on_floor[28.0], 12);
    EXPECT_EQ(on_floor[220.0], 12);
    EXPECT_GT(ran, 0.9 * 24 * kRun * static_cast<double>(a.frames.size() - 1) / 60.0) << "seed " << seed;
    // The look-back turns fast: over 0.1 rad (6 degrees) in a frame.
    EXPECT_GT(looked_back, 0.1) << "seed " << seed;
  }
}

TEST(Arena, TheEngineMissesNothing) {
  const ArenaLevel a = make_arena(3, 24, 150, 7);
  EngineHarness h(a.scene, SceneOptions{}, "arena seed 7");
  ASSERT_TRUE(h.status().ok) << h.status().message;
  int seen_players = 0;
  for (std::size_t i = 0; i < a.frames.size(); i += 5) {
    const FrameInput& f = a.frames[i];
    ASSERT_TRUE(h.move(f.t, f.moves).ok);
    const std::string problem = h.frame(f.camera, f.t);
    EXPECT_EQ(problem, "") << "frame " << i;
    for (ObjectId id : h.last().pvs) seen_players += id > a.scene.objects.size() - 24 ? 1 : 0;
  }
  EXPECT_GT(seen_players, 0) << "no player ever in a PVS";
}

}  // namespace
}  // namespace voxvis::test
