// voxvis/generate.h — deterministic scenes and camera paths for examples,
// benchmarks and tests (`voxvis generate` writes them as files). The "paper"
// preset follows the evaluation scene of Batagelo & Wu (section 6): clusters
// of spheres of varied size, some of them moving, in bounds 100 x 60 x 100,
// seen by a walkthrough camera. The static scenes (indoor level, voxel world,
// city) come with a camera path of their own; the arena with players running
// through it and a first-person walk. Every result is a pure
// function of the arguments, the same on every platform (voxvis/rng.h).
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

/// Object builders (for generators and hand-written scenes).
ObjectDesc sphere(ObjectId id, Vec3 center, double radius);
/// A box from its corners.
ObjectDesc box_between(ObjectId id, Vec3 lo, Vec3 hi);
/// A box from its centre and half extents.
ObjectDesc box_around(ObjectId id, Vec3 center, Vec3 half_extent);

/// A static scene and a camera path through it. The cameras have up +y,
/// a 16:9 aspect, near 0.05 and far 500.
struct ScenePath {
  SceneDesc scene;
  std::vector<Camera> cameras;
};

/// An indoor level on unit voxels: a rooms_x x rooms_z array of 12 x 12
/// rooms with 4 units of height, walls 1 voxel thick built from abutting
/// boxes (one per wall segment between doorways 2 voxels wide), floor and
/// ceiling slabs, a few boxes and spheres in each room; every wall face lies
/// on a voxel plane. The path walks along the middle row of rooms at eye
/// height, looking ahead and turning. rooms_x, rooms_z >= 1; frames >= 0.
ScenePath make_indoor_level(int rooms_x, int rooms_z, int frames, std::uint64_t seed);

/// A voxel world of unit blocks, one object per voxel: terrain of height
/// 4..12 over size x size columns, with caves carved out below the surface
/// (one of them open to the sky). cave_path chooses a path through a cave
/// (else over the surface at 2 voxels above the ground); the scene does not
/// depend on it. size >= 1, frames >= 0; the cave path stays inside its
/// tunnel from size 8 (`voxvis generate` asks for 16 to 256).
ScenePath make_voxel_world(int size, int frames, bool cave_path, std::uint64_t seed);

/// A city at street level: blocks x blocks city blocks of 4 box buildings
/// each (footprints and heights varied, not voxel-aligned), streets 8 units
/// wide between them with parked cars (small boxes) along both sides, and a
/// ground slab; grid of 2-unit voxels. The path drives along one street at
/// eye height 1.7, looking ahead and glancing into the cross streets.
/// blocks >= 1; frames >= 0.
ScenePath make_city(int blocks, int frames, std::uint64_t seed);

/// A level like the ones players fight in, on the scale of a Quake-3 arena
/// and in its units: rooms x rooms rooms of 496 x 496 units with walls 16
/// thick, a corridor 128 wide between every two rows, two storeys (floors at
/// y 0 and 192, roof at 384): about half the rooms have an upper floor with
/// a stair of 12 steps up to it, the others are halls two storeys high with
/// four pillars, and a walkway runs over every corridor. Doorways 96 wide
/// and 128 high join the rooms to their corridors and neighbours on each
/// storey both sides have. `players` boxes of 32 x 32 x 56 (dynamic,
/// max_speed 320) run along random routes through the doorways at 320 units
/// a second, alternately on floor 0 and floor 1; the camera walks floor 0 at
/// the same speed, eye 48 above the floor, 90 degrees across at 4:3 (fov_y
/// 73.74, aspect 16:9, near 4, far 8192), swaying and every 4 s looking back
/// for half a second. Grid voxels of 16 units, so walls fill whole voxels.
/// Frames at 60 per second, each moving every player. rooms >= 2 (less is
/// taken as 2), players >= 0, frames >= 0.
struct ArenaLevel {
  SceneDesc scene;
  std::vector<FrameInput> frames;
};
ArenaLevel make_arena(int rooms, int players, int frames, std::uint64_t seed);

/// The frames of a camera path: line i (1-based) is camera i - 1 at time
/// (i - 1) / fps, without moves (as make_walkthrough numbers and times them).
std::vector<FrameInput> camera_frames(const std::vector<Camera>& cameras, double fps = 60.0);

}  // namespace voxvis
