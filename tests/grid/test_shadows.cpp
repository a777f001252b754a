// Shadows of the object-space test persist: behind an occluder of a few
// voxels, small objects straight behind it are culled at every distance, with
// the occlusion buffer off (docs/design.md, "Which shells"). The previous-shell
// test used to erode every shadow by a voxel a shell on each side, so that
// only bands of distances were culled. Every frame goes through EngineHarness:
// zero misses against the ray caster.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "engine_check.h"
#include "raycast.h"
#include "scenes.h"
#include "voxvis/scene.h"

namespace voxvis::test {
namespace {

constexpr int kLength = 160;  // Voxels along the view axis.
constexpr int kSide = 40;     // Voxels across.

/// A square wall W voxels across and one voxel thick, its near face K voxels
/// from the eye's voxel plane, on voxel boundaries, and a sphere of radius 0.1
/// at the centre of every voxel straight behind it (ids from 2).
SceneDesc shadow_scene(int width, int distance) {
  SceneDesc d;
  d.bounds_min = Vec3(0.0);
  d.bounds_max = Vec3(kLength, kSide, kSide);
  d.grid = glm::ivec3(kLength, kSide, kSide);
  const double lo = kSide / 2 - width / 2;  // Integer: the wall covers whole voxels.
  d.objects.push_back(box_between(1, Vec3(distance, lo, lo), Vec3(distance + 1, lo + width, lo + width)));
  for (int x = distance + 1; x < kLength; ++x)
    d.objects.push_back(sphere(static_cast<ObjectId>(x - distance + 1), Vec3(x + 0.5, kSide / 2 + 0.5, kSide / 2 + 0.5), 0.1));
  return d;
}

TEST(Shadows, PersistAtEveryDistanceBehindAnOccluder) {
  // The eye lies off every voxel plane, within the voxel behind the wall's
  // centre voxel (near its low corner for the odd widths), looking down the
  // axis; every target lies inside the wall's shadow cone, which only widens
  // with distance.
  const Camera cam =
      camera_along(Vec3(0.3, kSide / 2 + 0.13, kSide / 2 - 0.07), Vec3(1.0, 0.0, 0.0), 60.0, 16.0 / 9.0);
  for (int width : {3, 5, 11})
    for (int distance : {6, 17}) {
      const std::string label = "wall " + std::to_string(width) + " at " + std::to_string(distance);
      const SceneDesc d = shadow_scene(width, distance);
      EngineHarness h(d, buffer_off(), label);
      ASSERT_TRUE(h.status().ok) << label << ": " << h.status().str();
      const std::string err = h.frame(cam, 0.0);
      ASSERT_TRUE(err.empty()) << err;
      const std::vector<ObjectId>& pvs = h.last().pvs;
      EXPECT_TRUE(std::binary_search(pvs.begin(), pvs.end(), ObjectId{1})) << label << ": the wall is in view";
      std::vector<int> kept;  // Distances of targets in the PVS.
      for (ObjectId id : pvs)
        if (id >= 2) kept.push_back(static_cast<int>(id) - 2 + distance + 1);
      EXPECT_TRUE(kept.empty()) << label << ": " << kept.size() << " targets behind the wall kept, the nearest at x = "
                                << kept.front() << ", the farthest at x = " << kept.back();
    }
}

}  // namespace
}  // namespace voxvis::test
