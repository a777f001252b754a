// collect.h — what both traversals do with what they reach: the frame's
// geometry in grid coordinates, objects and TBVs put into the PVS (tested
// against the frustum, the front-neighbour rule and the occlusion buffer,
// then drawn into the buffer), opaque boxes drawn, and the record of the
// voxels the frame saw.
#pragma once

#include <cstdint>

#include "frustum.h"
#include "scene_impl.h"

namespace voxvis::detail {

/// The frame's camera in the grid: the eye's voxel E and "local"
/// coordinates relative to it (small numbers wherever the world is), the
/// pyramid there, and the rounding allowances of both.
struct FrameGeometry {
  Vec3 eg{0.0};                       ///< Eye, grid coordinates.
  std::int64_t E[3]{};                ///< The eye's voxel.
  std::int64_t glo[3]{}, ghi[3]{};    ///< The grid's voxels, local coordinates.
  std::int64_t stride[3]{1, 0, 0};    ///< Voxel index strides.
  LocalFrustum lf;                    ///< The pyramid, local grid units.
  double tol = 0.0;                   ///< Rounding allowance, local grid units.
  double depth_tol = 0.0;             ///< Rounding allowance of depths, world units.
  Vec3 vs{1.0};                       ///< Voxel size, world units.
  /// Whether the interiors of closed meshes occlude this frame: the eye and
  /// the near plane lie in voxels outside every closed mesh (mesh_tip_clear).
  bool mesh_interiors = false;
  /// The same tip lies outside every closed static mesh (the scene has
  /// one): closed meshes' triangles facing away from the eye are not drawn.
  bool outside_meshes = false;

  std::int64_t gindex(const std::int64_t v[3]) const {
    return (E[0] + v[0]) + stride[1] * (E[1] + v[1]) + stride[2] * (E[2] + v[2]);
  }
  bool in_grid(const std::int64_t v[3]) const {
    return v[0] >= glo[0] && v[0] <= ghi[0] && v[1] >= glo[1] && v[1] <= ghi[1] && v[2] >= glo[2] &&
           v[2] <= ghi[2];
  }
};

/// Beyond 2^40 voxels from the grid, shell arithmetic in doubles would lose
/// the precision the conservative tests need (Scene::frame falls back to
/// frustum culling).
bool eye_too_far(const Vec3& eye_grid);

/// The frame's geometry; false when the grid lies wholly before the near
/// plane or behind the eye (nothing to traverse).
bool make_frame_geometry(const Scene::Impl& s, const WorldFrustum& wf, FrameGeometry* g);

/// Whether every voxel the frustum's tip (the eye and its near rectangle)
/// may touch lies outside every closed static mesh: no closed mesh touches
/// it and none puts it inside (kMeshTouched, kMeshInside), and, where the
/// tip leaves the grid, no closed mesh reaches beyond it. Then a ray meets
/// an interior voxel only after crossing its mesh's surface beyond the near
/// plane (docs/design.md, "Meshes"). False when the tip spans more than
/// 4,096 voxels (a near plane far larger than a voxel).
bool mesh_tip_clear(const Scene::Impl& s, const WorldFrustum& wf);

/// Whether the buffer proves an object (at the position the scene holds)
/// hidden: a ball by its own outline, a box by itself (`fine`: see
/// OcclusionBuffer::hides).
bool ob_hides_object(const OcclusionBuffer& ob, const Obj& o, bool fine = false);
/// Whether the buffer proves object o's TBV hidden: tested fine, then in
/// pieces (OcclusionBuffer::hides_world_split, three levels: a TBV is
/// large, and a reveal wakes its object).
bool ob_hides_tbv(const OcclusionBuffer& ob, const Obj& o);

class Collector {
 public:
  Collector(const Scene::Impl& s, Scratch::Impl& w, const WorldFrustum& wf, FrameStats& st, const FrameGeometry& g)
      : s_(s), w_(w), wf_(wf), st_(st), g_(g) {}

  /// An object reached: into the PVS unless its box misses the frustum (a
  /// voxel in view can hold objects that are not), every voxel holding it
  /// is hidden by its front neighbours, or the buffer hides it; then drawn
  /// into the buffer. Once a frame.
  void add(std::uint32_t slot);
  /// A TBV reached (docs/design.md, "Objects revealed during a frame").
  void reveal(std::uint32_t slot);
  /// A TBV reached through a cell [lo, hi] (world units) that holds its
  /// entry whole but may hold only part of it (Obj::tbv_coarse): revealed
  /// unless the buffer hides the part inside the cell. The cells holding
  /// its entries cover all of it, so each part is tested where it lies.
  void reveal_part(std::uint32_t slot, const Vec3& lo, const Vec3& hi);
  /// Draws the opaque box owning static opaque voxel `idx`, once a frame.
  void render_opaque_box(std::size_t idx) {
    if (!s_.opaque_owner.empty()) render_opaque_box_at(s_.opaque_owner[idx]);
  }
  /// Draws opaque box b (kNoBox: none), once a frame.
  void render_opaque_box_at(std::uint32_t b);
  /// Draws the static mesh triangles meeting brick `bi` (Scene::Impl::
  /// brick_tris), each once a frame, and the boxes of closed meshes'
  /// interiors owning its voxels when the frame allows them
  /// (FrameGeometry::mesh_interiors).
  void render_brick_triangles(std::size_t bi);
  /// Whether the static opaque face neighbours of local voxel v on the eye's
  /// side hide it (idx: its grid index; docs/design.md, "Front neighbours").
  bool front_blocked(const std::int64_t v[3], std::int64_t idx) const;
  /// Records voxel (x, y, z) (grid indices) as seen by this frame, or a
  /// whole brick (TBVs keep clear of seen space; scenes with dynamic objects).
  void see_voxel(int x, int y, int z);
  /// `mask`: the brick's voxels seen (bit x + 4y + 16z).
  void see_brick(std::size_t brick, std::uint64_t mask = ~std::uint64_t{0});
  /// Records the whole cell c of level l (>= 2) as seen.
  void see_cell(int l, const glm::ivec3& c) {
    w_.seen_cells.emplace_back(static_cast<std::uint8_t>(l), static_cast<std::uint32_t>(s_.pyr.index(l, c)));
  }

 private:
  /// Whether every voxel holding static object o is hidden by its front
  /// neighbours: then no point of o is visible though it touches voxels in
  /// view (a block just under the ground touches the air above it).
  bool own_voxels_hidden(const Obj& o) const;
  /// Draws every triangle of dynamic mesh o at its current placement, and
  /// its interior (Obj::interior) when model_tip_clear.
  void render_mesh(const Obj& o);
  /// Whether the frustum's tip lies wholly outside closed dynamic mesh o,
  /// in its own frame: in cubes of its interior's grid neither touched nor
  /// inside, or beyond that grid (then beyond the mesh's box).
  bool model_tip_clear(const Obj& o) const;
  /// Draws triangle t of mesh o (placed vertices p), with its partner as
  /// one quad when it has one (mesh_pairs.h).
  void render_triangle_of(const Obj& o, const Vec3* p, std::uint32_t t);

  const Scene::Impl& s_;
  Scratch::Impl& w_;
  const WorldFrustum& wf_;
  FrameStats& st_;
  const FrameGeometry& g_;
};

}  // namespace voxvis::detail
