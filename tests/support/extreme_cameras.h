// extreme_cameras.h — cameras at and near every documented bound, for the
// property tests of the engine (tests/grid) and of the server's wire
// (tests/server): lenses at the narrowest fov and just below 180 degrees,
// aspect at both limits, directions of any magnitude (1e308 and denormal
// components, signed zeros), eyes on the grid's bounds, on voxel corners and
// far outside, near planes of 1e-300 and far planes of 1e300 or a hair
// beyond near. Every camera it returns passes validate_camera.
#pragma once

#include "voxvis/rng.h"
#include "voxvis/scene.h"
#include "voxvis/types.h"

namespace voxvis::test {

/// The smallest positive double (a denormal).
inline constexpr double kDenormal = 4.9406564584124654e-324;

/// One camera drawn from the extremes above, for `scene`'s bounds.
Camera extreme_camera(Rng& rng, const SceneDesc& scene);

}  // namespace voxvis::test
