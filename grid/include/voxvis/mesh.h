// voxvis/mesh.h — triangle meshes placed in a scene: the rules a mesh and its
// placement must follow, and where its points go in the world.
//
// A mesh object (Shape::Mesh) is a Mesh in its own frame placed by
//   world = center + scale * rotate(rotation, model),
// a rigid transform with uniform scale. The mesh is shared and immutable; a
// move changes only the centre and (optionally) the rotation. Every layer
// (formats, wire, engine, references) applies the same rules, stated here.
#pragma once

#include <cstddef>
#include <string>
#include <unordered_map>

#include "voxvis/types.h"

namespace voxvis {

/// Most vertices and triangles one mesh may have.
inline constexpr std::size_t kMaxMeshVertices = std::size_t{1} << 24;
inline constexpr std::size_t kMaxMeshTriangles = std::size_t{1} << 25;
/// How far from 1 the norm of a rotation quaternion may be: a rotation
/// written with 7 significant digits (as exporters do) passes; it is then
/// used normalized.
inline constexpr double kQuatTolerance = 1e-6;

/// Checks a mesh: at least one triangle; at most kMaxMeshVertices vertices
/// and kMaxMeshTriangles triangles; every vertex finite and within
/// kMaxCoordinate of the model origin on every axis; every index below the
/// vertex count; no triangle degenerate (its edge vectors' cross product,
/// taken in double, is not zero: a triangle of no area covers no ray of
/// positive measure, and would only make planes of no direction).
/// Errors name `field` + ".vertices[i]" or ".triangles[i]".
Status validate_mesh(const Mesh& mesh, const std::string& field);

/// Checks a rotation: finite, its norm within kQuatTolerance of 1.
Status validate_rotation(const Quat& q, const std::string& field);

/// Checks a mesh object's placement: a mesh given and valid (validate_mesh),
/// scale finite and > 0, rotation valid, centre finite and within
/// kMaxCoordinate, and the mesh's model box (the box of its vertices),
/// placed, within kMaxCoordinate on every axis: a bound on every placed
/// vertex that costs O(1) per object once the mesh is measured. Errors name
/// `field` + ".mesh", ".scale", ".rotation" or ".center" (".center" when the
/// placed box would fit at the origin, so that the centre takes it beyond;
/// else ".scale"). O(the mesh's size): MeshPlacementCheck checks many
/// objects placing one mesh at O(1) each.
Status validate_mesh_object(const ObjectDesc& o, const std::string& field);

/// validate_mesh_object for many objects, each distinct mesh validated and
/// measured once (O(its vertices and triangles)), each object then in O(1):
/// a description that places one mesh many times costs what its text does.
/// Meshes are told apart by address: each must outlive the check. Not
/// thread-safe.
class MeshPlacementCheck {
 public:
  Status check(const ObjectDesc& o, const std::string& field);

 private:
  struct ModelBox {
    Vec3 lo, hi;
  };
  std::unordered_map<const Mesh*, ModelBox> measured_;
};

/// `q` scaled to unit norm (validate_rotation's rotations are within 1e-6).
Quat unit_rotation(const Quat& q);

/// Where model point `p` of mesh object `o` goes in the world (rotation
/// taken normalized). Rounded: within a few ulps of the magnitudes involved
/// per axis (callers that need a bound add their rounding allowance).
Vec3 place(const ObjectDesc& o, const Vec3& p);

/// The world box [lo, hi] of a mesh object's placed vertices (as place()
/// computes them).
void mesh_bounds(const ObjectDesc& o, Vec3* lo, Vec3* hi);

/// The world box [lo, hi] of any object: a sphere's and a box's exact, a
/// mesh's mesh_bounds.
void object_bounds(const ObjectDesc& o, Vec3* lo, Vec3* hi);

/// A mesh's centroid (mean of its vertices, model units) and its reach: the
/// largest distance of a vertex from it, rounded up. The centroid lies in
/// the mesh's convex hull, so under a rigid motion it is never faster than
/// the fastest point of the mesh; the ball of radius scale * reach around
/// it holds the placed mesh whatever its rotation.
Vec3 mesh_centroid(const Mesh& mesh);
double mesh_reach(const Mesh& mesh, const Vec3& centroid);

}  // namespace voxvis
