// voxvis/types.h — the value types every layer shares: objects, cameras, moves,
// and the status value returned at the library boundary.
//
// Coordinate spaces: "world" is the caller's space (double precision, any
// units); "grid" is world mapped so that voxel (i,j,k) is the unit cube
// [i,i+1]x[j,j+1]x[k,k+1]. The mapping is a per-axis scale and offset, so
// voxels may be non-cubic in world space while every visibility computation
// runs on unit cubes.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <glm/gtc/quaternion.hpp>
#include <glm/vec3.hpp>

namespace voxvis {

using Vec3 = glm::dvec3;   ///< World-space point or vector, double precision.
using ObjectId = std::uint32_t;

/// Largest magnitude accepted for any world coordinate, radius, or extent.
/// Beyond it squared distances lose the precision conservative tests need.
inline constexpr double kMaxCoordinate = 1e12;

/// Smallest accepted extent of a scene's bounds along any axis, world units.
/// Squared distances of points a voxel apart then stay far above the
/// underflow of doubles (about 1e-308), where the conservative tests would
/// lose every digit.
inline constexpr double kMinExtent = 1e-100;

/// Scene times are seconds within [-kMaxSceneTime, kMaxSceneTime], about
/// ±317 years: seconds since 1970 fit, milliseconds and microseconds do not.
/// Within it the shortest TBV validity period (1 ms) spans thousands of ulps
/// of any time, so a renewal always moves an expiry forward.
inline constexpr double kMaxSceneTime = 1e10;

/// Shortest validity period of a temporal bounding volume, seconds: a
/// period is never cut or clamped below it (SceneOptions::tbv_period too).
inline constexpr double kMinTbvPeriod = 1e-3;

/// Most voxels along one axis of a grid: the scene file, the wire and
/// SceneOptions::max_resolution's default.
inline constexpr int kMaxResolution = 8192;

enum class Shape : std::uint8_t { Sphere, Box, Mesh };

/// A rotation, as a unit quaternion (w, x, y, z).
using Quat = glm::dquat;

/// Triangles in their own frame ("model space"): each triangle is three
/// indices into `vertices`. Immutable once made and shared between the
/// objects that place it (voxvis/mesh.h: validate_mesh states the rules).
struct Mesh {
  std::vector<Vec3> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;
};

/// One object of a scene. A box is axis-aligned; it moves rigidly (its centre
/// moves, its half extents stay). A mesh is its triangles placed by a rigid
/// transform with uniform scale, world = center + scale * rotate(rotation,
/// model): it moves rigidly, its centre and rotation (voxvis/mesh.h).
struct ObjectDesc {
  ObjectId id = 0;
  Shape shape = Shape::Sphere;
  Vec3 center{0.0};       ///< World units. For a box from corners: set_box_corners (scene.h); for a mesh, where its model origin goes.
  double radius = 0.0;    ///< Sphere radius, world units, > 0. Unused for boxes and meshes.
  Vec3 half_extent{0.0};  ///< Box half size per axis, world units, >= 0. Unused for spheres and meshes.
  bool dynamic = false;
  /// World units per second, >= 0; dynamic objects only. For a mesh, a bound
  /// on the speed of every point of it (rotation included).
  double max_speed = 0.0;
  std::shared_ptr<const Mesh> mesh;  ///< Meshes only.
  Quat rotation{1.0, 0.0, 0.0, 0.0};  ///< Meshes only: a unit quaternion.
  double scale = 1.0;                 ///< Meshes only: > 0.
};

/// Narrowest accepted vertical field of view, degrees (about 17 nanoradians,
/// a thousandth of the finest telescope's resolution). Below it the tangents
/// of the half angles approach the underflow of doubles (a denormal fov has a
/// tangent of zero) and image coordinates lose every digit.
inline constexpr double kMinFovDeg = 1e-6;
/// Accepted width/height of the image: [1 / kMaxAspect, kMaxAspect].
inline constexpr double kMaxAspect = 1e3;

/// A viewer's camera for one frame. `dir` and `up` need not be normalized
/// (any finite non-zero vectors, of any magnitude); `up` must not be parallel
/// to `dir`. The frustum is the symmetric perspective pyramid of full
/// vertical angle `fov_y_deg` and width/height `aspect`, cut by the planes
/// perpendicular to `dir` at depths `near` and `far` (world units from the
/// eye). validate_camera (voxvis/scene.h) states every rule; the engine, the
/// frames format and the server all apply it.
struct Camera {
  Vec3 eye{0.0};            ///< World units, magnitude at most kMaxCoordinate.
  Vec3 dir{0.0, 0.0, -1.0};
  Vec3 up{0.0, 1.0, 0.0};
  double fov_y_deg = 60.0;  ///< Degrees, in [kMinFovDeg, 180).
  double aspect = 1.0;      ///< Width / height, in [1 / kMaxAspect, kMaxAspect].
  double near = 0.05;       ///< World units, > 0.
  double far = 1000.0;      ///< World units, > near.
  // A region: the answer holds for every eye of a box, every direction,
  // and every scene time of a horizon (docs/design.md, "Regions"). With all
  // three at their defaults it is the point answer, bit for bit.
  /// Half extents of an axis-aligned box of eye positions centred on `eye`,
  /// world units, each in [0, kMaxCoordinate]; zero: the eye is a point.
  Vec3 eye_extent{0.0};
  /// Every direction counts: dir, up, fov_y_deg and aspect are then not used
  /// for the answer (still validated); near and far still bound distance.
  bool omnidirectional = false;
  /// Seconds, in [0, kMaxHorizon]: the answer holds for every scene time in
  /// [t, t + horizon_s], each dynamic object anywhere its max_speed lets it
  /// reach from where it is at t.
  double horizon_s = 0.0;
};

/// Longest accepted Camera::horizon_s, seconds (about 32 years).
inline constexpr double kMaxHorizon = 1e9;

/// Whether a camera asks for a region (any of eye_extent, omnidirectional,
/// horizon_s off its default).
inline bool is_region(const Camera& c) {
  return c.eye_extent.x != 0.0 || c.eye_extent.y != 0.0 || c.eye_extent.z != 0.0 || c.omnidirectional ||
         c.horizon_s != 0.0;
}

/// A new centre for a dynamic object, and for a mesh, optionally a new
/// rotation (else it keeps its last).
struct Move {
  ObjectId id = 0;
  Vec3 center{0.0};  ///< World units.
  bool has_rotation = false;
  Quat rotation{1.0, 0.0, 0.0, 0.0};  ///< With has_rotation: a unit quaternion.
};

/// The result of an operation on untrusted input: ok, or what is wrong and
/// where. `field` names the offending input (for example "objects[3].radius"
/// or "moves[0].id"); formats add the file and line.
struct Status {
  /// What kind of failure: the caller's input is wrong (Invalid), the work
  /// it asks for exceeds a stated limit of memory or time
  /// (ResourceExhausted), the caller cancelled it (Cancelled).
  enum class Code : std::uint8_t { Ok, Invalid, ResourceExhausted, Cancelled };

  bool ok = true;
  std::string field;
  std::string message;
  Code code = Code::Ok;

  static Status Ok() { return {}; }
  static Status Error(std::string field_name, std::string text) {
    return Status{false, std::move(field_name), std::move(text), Code::Invalid};
  }
  static Status Exhausted(std::string field_name, std::string text) {
    return Status{false, std::move(field_name), std::move(text), Code::ResourceExhausted};
  }
  static Status Cancelled(std::string text) { return Status{false, "", std::move(text), Code::Cancelled}; }
  explicit operator bool() const { return ok; }
  /// "field: message", or just the message when no field applies.
  std::string str() const { return field.empty() ? message : field + ": " + message; }
};

/// A double as text in the shortest form that reads back to the same value
/// ("0.1", "1e+308", "5e-324"), or "nan", "inf", "-inf": the one way every
/// message and format of voxvis writes a number.
std::string number_text(double v);
/// Appends number_text(v) to `out`, without a string of its own (the
/// formats' writers, which write numbers by the million).
void append_number_text(std::string& out, double v);

}  // namespace voxvis
