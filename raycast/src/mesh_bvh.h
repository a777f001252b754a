// mesh_bvh.h — triangle meshes in the ray caster (voxvis/raycast.h): a
// hierarchy over a mesh's triangles in its own frame, built once per mesh and
// kept while the mesh lives, and the ray–triangle test, watertight, in double
// precision.
//
// Model space. A mesh object is its mesh placed by world = center + scale *
// rotate(rotation, model) (voxvis/mesh.h). A ray eye + t*d is taken into the
// mesh's frame once per object and ray — origin R^-1 (eye - center) / scale,
// direction R^-1 d / scale — where the same t names the same point, so the
// hierarchy built over the model-space triangles serves every object placing
// the mesh, at any centre, rotation and scale, and a hit's t is its depth in
// the world. Moving the ray costs a few roundings (relative 2^-52 or so of
// the ray's origin and direction); from then on every triangle of the mesh
// is tested against that one model-space ray, so the hits are exactly those
// of a ray within those roundings of the world ray.
//
// Watertight test (Woop, Benthin and Wald, "Watertight Ray/Triangle
// Intersection", JCGT 2(1), 2013, in double): the ray's dominant axis
// becomes z and a shear maps the ray onto the z axis, so that a triangle's
// three edge functions are 2D cross products of its sheared vertices,
// U = Cx*By - Cy*Bx and its two rotations. Rounding to nearest is monotone
// and symmetric: the computed sign of a*b - c*d is its exact sign or 0, and
// fl(a*b - c*d) = -fl(c*d - a*b). So each edge function is exact, but for
// calling "on the edge" (0) a ray that passes within rounding of it, for
// the triangles as the shear places them; and it places each vertex once,
// bit-identically, for every triangle around it. Two triangles sharing an
// edge see the ray on opposite sides of it or both on it, never both
// outside. A hit needs U, V, W of one sign, zeros included: a ray on an edge
// or a vertex hits every triangle around it, and no ray passes between two
// triangles that share an edge or through a fan round a shared vertex. The
// paper falls back to wider arithmetic when U, V or W is 0, to decide such
// rays exactly; in double there is none here, and a 0 stays a hit: extra
// hits within rounding of an edge, the conservative side (the caster reads
// ties as visible). Both faces of a triangle are hit. Needs plain IEEE
// arithmetic (-ffp-contract=off: a fused multiply-add breaks the symmetry).
//
// The hierarchy prunes with the boxes of the model-space triangles grown per
// ray by `pad` = 1e-12 * (|origin| + the mesh's largest coordinate),
// thousands of times what the sheared coordinates (a few 2^-53 of that
// magnitude) and the box test lose to rounding:
// a triangle the test accepts is never in a box the ray misses. A box is
// skipped when it is entered beyond the best hit so far; that agrees with
// testing every triangle except where a hit's computed depth strays from
// its exact one by more than `pad`, which only a ray almost in the plane of
// a triangle (grazing it, a set of rays of measure zero) can do.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <unordered_map>
#include <vector>

#include <glm/mat3x3.hpp>

#include "bvh_build.h"
#include "voxvis/types.h"

namespace voxvis::raycast::detail {

/// The hierarchy over one mesh's triangles, in model space. Immutable once
/// built, so threads share it.
class MeshBvh {
 public:
  explicit MeshBvh(const Mesh& mesh);
  const std::vector<BvhNode>& nodes() const { return nodes_; }
  /// Triangle indices (into Mesh::triangles) in leaf order.
  const std::vector<std::uint32_t>& order() const { return order_; }
  /// The largest magnitude of a vertex coordinate, model units.
  double max_abs() const { return max_abs_; }

 private:
  std::vector<BvhNode> nodes_;  ///< Empty for a mesh without triangles.
  std::vector<std::uint32_t> order_;
  double max_abs_ = 0.0;
};

/// The hierarchy of `mesh` (not null): built on first use, then found in a
/// process-wide cache by the mesh's address while the mesh lives (the cache
/// holds meshes weakly, and forgets those gone whenever it adds one, so an
/// address reused by a new mesh is not mistaken for the old). Meshes are
/// immutable (voxvis/types.h), so a hierarchy never goes stale. Thread-safe;
/// `built` (optional) tells whether this call built it.
std::shared_ptr<const MeshBvh> mesh_bvh(const std::shared_ptr<const Mesh>& mesh, bool* built = nullptr);

/// A mesh object placed for rays from one eye: the map from the world into
/// its model frame, and its hierarchy (null: every triangle is tested, the
/// brute-force definition). Holds the object's mesh by address: the objects
/// must outlive it.
class PlacedMesh {
 public:
  PlacedMesh(const ObjectDesc& o, const Vec3& eye, std::shared_ptr<const MeshBvh> bvh);

  /// The least t (`last` false) or the greatest in [lo, hi] at which the ray
  /// eye + t*d meets a triangle, into `t`; false when it meets none there.
  /// Adds the ray–triangle tests made to `*tests`.
  bool hit(const Vec3& d, double lo, double hi, bool last, double* t, std::uint64_t* tests) const;

  /// A world box [lo, hi] that holds every hit hit() may return: the model
  /// box's corners placed, grown by 1e-10 of the magnitudes involved (the
  /// eye's distance, the centre, the scaled model coordinates), far above
  /// the roundings of placing the corners and of moving the ray.
  void world_box(Vec3* lo, Vec3* hi) const { *lo = box_lo_; *hi = box_hi_; }

 private:
  const Mesh* mesh_;
  std::shared_ptr<const MeshBvh> bvh_;
  glm::dmat3 to_model_;  ///< R^-1 / scale.
  Vec3 org_;             ///< The eye in model space.
  double pad_ = 0.0;     ///< Model units (the header comment).
  Vec3 box_lo_, box_hi_;
};

/// The mesh objects of one call, placed for its eye: get(i) is objects[i]'s
/// PlacedMesh (null for a sphere, a box or a mesh object without a mesh),
/// made on first use with the cached hierarchy (or none, brute force).
/// Pointers stay valid for the set's life. Not thread-safe: get() what the
/// threads need before they start.
class MeshSet {
 public:
  MeshSet(const std::vector<ObjectDesc>& objects, const Vec3& eye, bool brute_force);
  const PlacedMesh* get(std::size_t i);
  /// Hierarchies this set built (the others came from the cache).
  std::size_t built() const { return built_; }

 private:
  const std::vector<ObjectDesc>& objects_;
  Vec3 eye_;
  bool brute_force_;
  std::vector<std::int32_t> slot_;  ///< Per object: its place in placed_, -1 none yet.
  std::deque<PlacedMesh> placed_;   ///< A deque: get()'s pointers survive growth.
  std::unordered_map<const Mesh*, std::shared_ptr<const MeshBvh>> bvhs_;
  std::size_t built_ = 0;
};

}  // namespace voxvis::raycast::detail
