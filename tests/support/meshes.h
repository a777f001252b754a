// meshes.h — triangle meshes for the tests of the references (ray caster,
// renderer): a cube, a subdivided icosahedron, a soup of random triangles,
// and mesh objects placing them (voxvis/mesh.h). Deterministic.
#pragma once

#include <cstdint>
#include <memory>

#include "voxvis/scene.h"
#include "voxvis/types.h"

namespace voxvis::test {

/// The box [-half, half] as 12 triangles (8 shared vertices), wound
/// counter-clockwise seen from outside.
std::shared_ptr<const Mesh> cube_mesh(const Vec3& half);

/// The unit sphere approximated by an icosahedron subdivided `levels`
/// times (20 * 4^levels triangles, shared vertices on the sphere): closed,
/// every edge shared by two triangles.
std::shared_ptr<const Mesh> icosphere(int levels);

/// `count` random triangles with corners in [-1, 1]^3, none degenerate,
/// each with vertices of its own (a soup: edges not shared, triangles may
/// cross).
std::shared_ptr<const Mesh> triangle_soup(int count, std::uint64_t seed);

/// One static mesh (id 1) of `copies` copies of a triangle with legs of
/// `leg` world units, each with vertices of its own, in a 64^3 grid over
/// [0, 100]^3: the hostile mesh builds (overlapping triangles, large or
/// small) whose cost the memory budget must bound.
SceneDesc copied_triangle_scene(int copies, double leg);

/// A mesh object: `mesh` placed at `center`, rotated by `rotation` (unit),
/// scaled by `scale`.
ObjectDesc mesh_object(ObjectId id, std::shared_ptr<const Mesh> mesh, const Vec3& center,
                       const Quat& rotation = Quat(1.0, 0.0, 0.0, 0.0), double scale = 1.0);

/// The same triangles placed by hand: a mesh of the object's placed
/// vertices (voxvis/mesh.h, place()) under the identity placement.
ObjectDesc placed_by_hand(const ObjectDesc& o);

/// A unit quaternion of `angle` radians about `axis` (any non-zero vector).
Quat rotation_about(const Vec3& axis, double angle);

}  // namespace voxvis::test
