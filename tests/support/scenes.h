// scenes.h — deterministic random scenes, camera paths and object motion for
// the property tests and benchmarks. Everything is a pure function of a seed:
// the random numbers come from std::mt19937_64 (whose output the standard
// fixes) through our own mappings, never the implementation-defined std
// distributions, so a failing seed reproduces on any platform.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "voxvis/generate.h"
#include "voxvis/rng.h"
#include "voxvis/scene.h"
#include "voxvis/types.h"

namespace voxvis::test {

/// Seeded random numbers with portable mappings (shared with the engine's
/// scene generators).
using voxvis::Rng;

/// Derives an independent sub-seed (splitmix64 of the pair).
std::uint64_t mix_seed(std::uint64_t a, std::uint64_t b);

/// Count multiplier from the environment variable VOXVIS_TEST_SCALE (default
/// 1.0; for example 0.2 under AddressSanitizer, 5 for a long soak).
double test_scale();
/// max(1, round(n * test_scale())).
int scaled(int n);

struct RandomSceneParams {
  Vec3 bounds_min{0.0};
  Vec3 bounds_max{100.0, 60.0, 100.0};
  /// The grid the scene is meant for: sizes objects in voxels and makes walls
  /// thinner than a voxel. (The scene itself does not name it.)
  glm::ivec3 grid{32, 20, 32};
  int spheres = 100;
  int boxes = 50;
  int occluders = 8;   ///< Big boxes, several voxels per axis.
  int walls = 8;       ///< Thin boxes (thinner than a voxel, some flat) spanning many voxels.
  int outside = 4;     ///< Objects wholly outside the bounds.
  double partly_outside = 0.1;  ///< Chance an ordinary object straddles the bounds.
  double dynamic_fraction = 0.3;
  double max_speed = 20.0;      ///< Dynamic objects get max_speed in [0, this] (a few exactly 0).
  double min_size_voxels = 0.1;  ///< Ordinary object sizes, in voxels (log-uniform).
  double max_size_voxels = 5.0;
};

/// Random parameters for a property-test scene: bounds of random extent and
/// position, a grid of random per-axis resolution (so voxels are generally
/// non-cubic), object counts up to about 300.
RandomSceneParams random_scene_params(std::uint64_t seed);

/// Builds a random scene. Ids are unique, not contiguous, and the objects are
/// in shuffled order. `desc.grid` is set to params.grid.
SceneDesc random_scene(const RandomSceneParams& params, std::uint64_t seed);

struct CameraPathParams {
  int frames = 25;
  double fov_min = 20.0;
  double fov_max = 120.0;
  double aspect_min = 0.5;
  double aspect_max = 2.5;
  double outside_chance = 0.15;  ///< Chance the path starts well outside the bounds.
  double short_far_chance = 0.2; ///< Chance the far plane cuts the scene.
  /// Near plane, as a fraction of the bounds' smallest extent (log-uniform).
  double near_min = 1e-4;
  double near_max = 2e-2;
  /// Chance a path puts the eye on voxel planes (1 to 3 axes: faces, edges,
  /// corners) of scene.grid, when the scene names one.
  double snap_eye_chance = 0.2;
  /// Chance a path looks along axes and exact diagonals only.
  double axis_dir_chance = 0.1;
  /// Chance a path uses an extreme fov (1..5 or 160..179 degrees) or aspect.
  double extreme_lens_chance = 0.1;
};

/// A camera path through (and sometimes from outside) the scene's bounds:
/// the eye follows a polyline of random waypoints, looking at a moving target
/// or ahead along the path; fov, aspect, near, far and the roll are random per
/// path. Every camera is valid.
std::vector<Camera> random_camera_path(const SceneDesc& scene, std::uint64_t seed,
                                       const CameraPathParams& params = {});

/// Moves a scene's dynamic objects: each has a velocity of at most 0.999 of
/// its max_speed that turns now and then and bounces off the bounds expanded
/// by `margin` (a fraction of the extent), so objects also leave the grid.
/// Per step, displacement <= max_speed * dt.
class Mover {
 public:
  Mover(const SceneDesc& scene, std::uint64_t seed, double margin = 0.1);
  /// Advances by dt seconds; returns the new centres of the objects that moved.
  std::vector<Move> step(double dt);
  /// The objects at their current positions (the scene's order).
  const std::vector<ObjectDesc>& objects() const { return objects_; }

 private:
  std::vector<ObjectDesc> objects_;
  std::vector<Vec3> velocity_;
  Vec3 lo_;
  Vec3 hi_;
  Rng rng_;
};

/// Frames of two scenes side by side (each with its own viewer, one
/// Scratch), the i-th of both at time i / hz: check(i, a's result, b's)
/// after each pair. Returns "" or what failed (a build or a frame).
std::string frames_side_by_side(const SceneDesc& a, const Camera& cam_a, const SceneDesc& b, const Camera& cam_b,
                                int frames, double hz,
                                const std::function<void(int, const FrameResult&, const FrameResult&)>& check);

/// An empty scene over [0, n]^3 with n^3 unit voxels.
SceneDesc unit_grid(int n);

/// A camera at `eye` looking along `dir`, up +y (dir must not be vertical),
/// with the given lens.
Camera camera_along(const Vec3& eye, const Vec3& dir, double fov_y_deg = 60.0, double aspect = 1.0,
                    double near = 0.05, double far = 1000.0);

/// Applies moves (by id) to the objects: the centre, and a mesh's rotation
/// when the move has one. Unknown ids are ignored.
void apply_moves_to(std::vector<ObjectDesc>* objects, const std::vector<Move>& moves);

/// World transform p -> p * scale + offset applied to a scene, camera or moves
/// (sizes and speeds scale; the camera's near and far scale too).
SceneDesc transform_scene(const SceneDesc& scene, double scale, const Vec3& offset);
Camera transform_camera(const Camera& cam, double scale, const Vec3& offset);
std::vector<Move> transform_moves(const std::vector<Move>& moves, double scale, const Vec3& offset);

/// "seed=..., grid=..., bounds=..." for failure messages.
std::string describe_scene(const SceneDesc& scene, std::uint64_t seed);

/// Object builders for hand-written test scenes (sphere, box_between and
/// box_around are the generators', voxvis/generate.h).
using voxvis::box_around;
using voxvis::box_between;
using voxvis::sphere;
ObjectDesc dynamic(ObjectDesc o, double max_speed);

/// The static scenes with a camera path: indoor level, voxel world, city
/// (voxvis/generate.h, where `voxvis generate` finds them too).
using voxvis::make_city;
using voxvis::make_indoor_level;
using voxvis::make_voxel_world;
using voxvis::ScenePath;

}  // namespace voxvis::test
