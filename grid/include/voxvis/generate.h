// voxvis/generate.h — deterministic scenes and camera paths for examples,
// benchmarks and tests. The "paper" preset follows the evaluation scene of
// Batagelo & Wu (section 6): clusters of spheres of varied size, some of them
// moving, in bounds 100 x 60 x 100, seen by a walkthrough camera.
#pragma once

#include <cstdint>
#include <vector>

#include "voxvis/format.h"
#include "voxvis/scene.h"

namespace voxvis {

struct PaperSceneParams {
  int objects = 5000;   ///< Spheres in all.
  int dynamic = 200;    ///< Of which moving.
  int clusters = 60;    ///< Cluster centres, spread over the bounds.
  double max_speed = 2.0;  ///< World units per second for the moving ones.
  Vec3 bounds_min{0.0, 0.0, 0.0};
  Vec3 bounds_max{100.0, 60.0, 100.0};
  std::uint64_t seed = 1;
};

/// Builds the paper-like scene. Ids are 1..objects; the first `dynamic` are dynamic.
SceneDesc make_paper_scene(const PaperSceneParams& params);

struct WalkthroughParams {
  int frames = 300;
  double fps = 60.0;
  double fov_y_deg = 60.0;
  double aspect = 16.0 / 9.0;
  double near = 0.05;
  double far = 1000.0;
  bool moves = true;  ///< Move the dynamic objects at up to their max_speed.
  std::uint64_t seed = 2;
};

/// A camera walking an ellipse through the scene at mid height, looking
/// ahead, with the dynamic objects wandering at up to max_speed (bouncing off
/// the bounds). Deterministic for a given seed.
std::vector<FrameInput> make_walkthrough(const SceneDesc& scene, const WalkthroughParams& params);

}  // namespace voxvis
