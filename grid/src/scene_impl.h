// scene_impl.h — the shared scene grid and per-thread scratch.
//
// Layout (flat arrays indexed by voxel, x fastest; cells.h for the cell
// pyramid over them):
//  * vflags          1 byte a voxel: covered by static objects, holding a
//    static object in its own list, inside a coarser cell holding one,
//    covered by the objects only with a discretized dynamic one among them.
//    One byte load answers the traversal's common case, an empty voxel.
//    "Covered" is the union rule of docs/design.md.
//  * static_lists    per level of the pyramid, CSR lists of the static
//    objects stored there: an object is stored in the coarsest cells whose
//    every voxel it touches, and in single voxels only where its surface
//    cuts a brick; built once (paper 4.5). A voxel's objects are its own
//    list and those of the cells above it.
//  * bricks, coarse_dyn   per brick (and per coarser cell wholly inside an
//    object's range of bricks, or holding a TBV whole where no viewer looks:
//    tbv_coarse_cells), the dynamic objects and TBVs touching it; an
//    entry is (slot << 1 | is_tbv, generation). The exact voxel test happens
//    when the traversal reaches a voxel, so a move or a TBV costs the cells
//    it covers (about its surface), not the voxels.
// Objects and TBVs beyond the grid box are also kept on `outside_` lists and
// tested against the frustum each frame, since no voxel stands for them.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <limits>
#include <mutex>
#include <shared_mutex>
#include <unordered_map>
#include <utility>
#include <vector>

#include "cells.h"
#include "expiry_queue.h"
#include "mesh_interior.h"
#include "mesh_pairs.h"
#include "occlusion_buffer.h"
#include "region_cavity.h"
#include "region_occlusion.h"
#include "voxbox.h"
#include "voxvis/assert.h"
#include "voxvis/mesh.h"
#include "voxvis/scene.h"

namespace voxvis {

namespace detail {

inline constexpr int kBrickShift = kCellShift;  ///< Bricks are the 4x4x4-voxel cells of level 1.
/// A dynamic object whose box touches more voxels than this adds no
/// dynamic opacity (only tightness is lost), so that a move costs about the
/// object's surface in cells, never its volume in voxels.
inline constexpr std::int64_t kDynOpacityMaxVoxels = 32768;
/// Objects the union test of one voxel looks at, at most (the first 16
/// with a volume in the voxel take part): beyond, "not covered".
inline constexpr std::size_t kCoverCandidates = 64;

/// CSR id lists over the cells of one level: cell i holds
/// ids[offsets[i] .. offsets[i+1]). Empty offsets: no cell holds any.
struct IdLists {
  std::vector<std::uint32_t> offsets;
  std::vector<std::uint32_t> ids;  ///< Object slots.
  bool any() const { return !ids.empty(); }
  const std::uint32_t* begin(std::size_t cell) const { return ids.data() + offsets[cell]; }
  const std::uint32_t* end(std::size_t cell) const { return ids.data() + offsets[cell + 1]; }
};

struct Obj {
  ObjectId id = 0;
  Shape shape = Shape::Sphere;
  bool dynamic = false;
  double max_speed = 0.0;    ///< World units / s.
  Vec3 center{0.0};          ///< Current centre, world units.
  double radius = 0.0;       ///< Sphere radius, world units.
  Vec3 half{0.0};            ///< Half extents of the bounding box, world units.
  double last_move_t = 0.0;  ///< Time of `center`, seconds.
  /// A dynamic object that takes no part in dynamic opacity (neither adds
  /// nor removes cover): one touching more than kDynOpacityMaxVoxels voxels,
  /// and every one with the occlusion buffer on, whose cell traversal reads
  /// no voxel's opacity (the buffer holds the object itself).
  bool no_opacity = false;

  // Grid state of a dynamic object.
  bool under_tbv = false;
  std::uint32_t claims = 0;   ///< Viewers whose last PVS holds it.
  bool pending_unclaimed = false;
  bool reveal_queued = false; ///< In Scene::Impl::queued_reveals.
  Vec3 disc_center{0.0};      ///< Centre it is discretized at (when !under_tbv).
  std::uint32_t disc_gen = 0; ///< Bumped when the discretization is removed.
  std::int32_t outside_pos = -1;  ///< Index in outside_objs_, or -1.

  // TBV (when under_tbv): a box holding every position reachable before expiry.
  Vec3 tbv_lo{0.0}, tbv_hi{0.0};  ///< World units.
  double tbv_expiry = 0.0;        ///< Seconds.
  double tbv_period = 0.0;        ///< Seconds, the period of the current/next TBV.
  std::uint32_t tbv_gen = 0;      ///< Tells current brick entries from stale ones.
  std::uint32_t tbv_epoch = 0;    ///< Tells the live expiry entry from stale ones.
  Vec3 tbv_center{0.0};           ///< Centre the TBV was grown around.
  std::int32_t tbv_outside_pos = -1;
  VoxBox tbv_voxels;              ///< Voxels the TBV touches, clipped to the grid.
  /// The seen record's room around the object (unseen_growth towards its
  /// longest TBV box, and room_brick), as last asked at centre room_center
  /// and scene time room_at, while the record's seen_epoch was room_epoch
  /// (0: never asked). Scene::Impl::seen_room. (Before tbv_coarse, like
  /// the next: a renewal reads them, and prefetch_obj fetches an object's
  /// fields up to tbv_coarse.)
  std::uint64_t room_epoch = 0;
  double room_at = 0.0, room = 0.0, room_brick = 0.0;
  Vec3 room_center{0.0};
  /// The last answer of Scene::Impl::quiet_tbv_box, asked the same way:
  /// the first of its boxes found unseen (1 or 2), or 0 for neither.
  std::uint64_t quiet_epoch = 0;
  double quiet_at = 0.0;
  Vec3 quiet_center{0.0};
  int quiet_tier = 0;
  /// The level-2 cells over tbv_voxels holding one entry for the TBV whole
  /// (Scene::Impl::tbv_coarse_cells); 0: entries as brick_add's.
  std::uint32_t tbv_coarse = 0;

  // A mesh (shape Mesh): its triangles and placement. The engine's centre
  // and half above are a box holding it: for a static mesh its placed
  // vertices' box, for a dynamic one the cube around the ball of its
  // centroid (radius: scale x reach, whatever the rotation), so that every
  // test made on an object's box bounds the mesh. Which voxels a static
  // mesh touches comes from its triangles (build.cpp, mesh_voxels). A mesh
  // adds no opacity; with the occlusion buffer on, its triangles are drawn
  // into it: a static mesh's those of each brick the traversal reaches
  // (Scene::Impl::brick_tris), a dynamic one's all at once when it enters
  // the PVS (docs/design.md, "Meshes").
  std::shared_ptr<const Mesh> mesh;
  Vec3 mesh_origin{0.0};          ///< Where the model origin is (ObjectDesc::center, or the last move's).
  Quat mesh_rotation{1.0, 0.0, 0.0, 0.0};  ///< Unit.
  /// The rotation as last given (ObjectDesc::rotation or the last move's),
  /// before unit_rotation: what dynamic_centers reports, so that a scene
  /// created with it (a server resuming from its saved positions) computes
  /// mesh_rotation bit for bit as this one did.
  Quat mesh_rotation_given{1.0, 0.0, 0.0, 0.0};
  double mesh_scale = 1.0;
  Vec3 mesh_centroid{0.0};        ///< Model units (mesh_centroid()).
  /// scale x sqrt(3) x the largest model coordinate: with the origin's
  /// magnitude, the size of the placement's arithmetic, for the rounding
  /// allowance of placed points.
  double mesh_extent = 0.0;
  /// A static mesh with the buffer on: its placed vertices (world units, as
  /// place() computes them), and where its triangles start in the scene's
  /// numbering of static triangles (Scratch::Impl::tri_seen).
  std::vector<Vec3> placed;
  std::uint32_t tri_base = 0;
  /// With the buffer on: its triangles paired into quads (mesh_pairs.h),
  /// shared by the objects of one mesh.
  std::shared_ptr<const MeshQuads> quads;
  /// With the buffer on, for a closed mesh (mesh_interior.h): +1 when its
  /// triangles run counter-clockwise seen from outside (its signed volume
  /// is positive), -1 the other way; 0 for an open mesh.
  std::int8_t outward = 0;
  /// With the buffer on, for a closed dynamic mesh: its interior in its own
  /// frame, drawn as oriented boxes where it is (mesh_interior.h).
  std::shared_ptr<const ModelInterior> interior;

  Vec3 box_lo() const { return center - half; }
  Vec3 box_hi() const { return center + half; }
  /// A mesh's placement as the ObjectDesc voxvis/mesh.h reads (place(),
  /// mesh_bounds()).
  ObjectDesc mesh_desc() const {
    ObjectDesc d;
    d.shape = Shape::Mesh;
    d.mesh = mesh;
    d.center = mesh_origin;
    d.rotation = mesh_rotation;
    d.scale = mesh_scale;
    return d;
  }
  /// The rounding allowance of placed points: 64 ulps of the placement's
  /// magnitudes (a few ulps of them is the rounding).
  double mesh_allowance() const;
};

/// A triangle of a static mesh: the mesh's slot and the triangle's index.
struct TriRef {
  std::uint32_t slot;
  std::uint32_t tri;
};

/// An entry of a brick: (slot << 1 | is_tbv) and the generation of the
/// object's discretization or TBV it was written for. Removal only lowers the
/// brick's live count; stale entries are skipped when read and dropped when
/// they outnumber the live ones, so removal never searches a list.
struct BrickEntry {
  std::uint32_t key;
  std::uint32_t gen;
};

struct Brick {
  std::vector<BrickEntry> entries;
  std::uint32_t live = 0;
};

struct ViewerState {
  std::vector<std::uint32_t> last_pvs;  ///< Slots, ascending.
};

/// The grid's reader-writer lock, with writers first. glibc's rwlock lets
/// new readers in while a writer waits, so viewers whose frames overlap
/// without a gap (several of them, each busy) would keep a move batch or an
/// expired TBV waiting forever. A writer holds `gate_` while it waits; a
/// reader passes through `gate_` before it takes the lock, so it queues
/// behind a waiting writer instead of overtaking it. No thread takes the
/// lock again while holding it (shared or not), so a writer holding the
/// gate only ever waits for readers that are already inside.
class GridMutex {
 public:
  void lock() {
    std::lock_guard<std::mutex> g(gate_);
    mu_.lock();
  }
  bool try_lock() { return mu_.try_lock(); }
  void unlock() { mu_.unlock(); }
  void lock_shared() {
    { std::lock_guard<std::mutex> g(gate_); }
    mu_.lock_shared();
  }
  bool try_lock_shared() { return mu_.try_lock_shared(); }
  void unlock_shared() { mu_.unlock_shared(); }

 private:
  std::mutex gate_;
  std::shared_mutex mu_;
};

}  // namespace detail

struct Scratch::Impl {
  /// Per voxel: (stamp_tag << 2) | status in the current frame. A voxel
  /// with another tag was not reached this frame, which the traversal reads
  /// as culled. Tags cycle through 1..63; the array is cleared when they
  /// wrap, so a stale tag can never match.
  std::vector<std::uint8_t> stamp;
  std::uint32_t stamp_tag = 0;
  /// Per object slot: frame in which it was put in the PVS.
  std::vector<std::uint32_t> obj_mark;
  /// Per object slot: frame in which it was tested against the frustum.
  std::vector<std::uint32_t> obj_seen;
  std::uint32_t frame = 0;
  /// Ticks (detail::ticks) spent drawing occluders this frame.
  std::uint64_t render_ticks = 0;

  // Reused buffers.
  std::vector<std::uint32_t> pvs;
  /// The frame's PVS slots sorted (Scene::frame, phase 3); traded with the
  /// viewer's last PVS.
  std::vector<std::uint32_t> sorted_pvs;
  /// Slots of the frame's wake list (Scene::frame); traded with the scene's
  /// pending wake.
  std::vector<std::uint32_t> wake;
  std::vector<std::uint32_t> reveals;
  /// TBVs the traversal reached, revealed after it (Scene::frame, phase 3).
  std::vector<std::uint32_t> deferred;
  /// The frame's occlusion buffer (off unless SceneOptions::occlusion_buffer).
  detail::OcclusionBuffer ob;
  /// Per opaque box (Scene::Impl::opaque_boxes): frame it was rendered in.
  std::vector<std::uint32_t> box_seen;
  /// Voxels this frame saw (reached and not proven hidden), per brick a mask
  /// of its 64 voxels (bit x + 4y + 16z), and the bricks with a bit set.
  /// Scenes with dynamic objects only; emptied by Scene::Impl::mark_seen.
  std::vector<std::uint64_t> seen_vox;
  std::vector<std::uint32_t> seen_list;
  /// Whole cells of levels >= 2 this frame saw (empty space in view), as
  /// (level, cell index): recorded once per cell instead of per brick.
  std::vector<std::pair<std::uint8_t, std::uint32_t>> seen_cells;
  /// Per triangle of the static meshes (Obj::tri_base): frame in which it
  /// was drawn into the occlusion buffer.
  std::vector<std::uint32_t> tri_seen;
  /// Per region occluder (Scene::Impl::region_occ): the stamp of the last
  /// test that tried it (region_occlusion.h), and the stamps' counter.
  std::vector<std::uint32_t> region_mark;
  std::uint32_t region_stamp = 0;
  /// A dynamic mesh's placed vertices, while its triangles are drawn.
  std::vector<Vec3> placed;
  /// Per cell of levels 1 and up (Scene::Impl::cell_base): frame in which
  /// its static objects were collected.
  std::vector<std::uint32_t> cell_seen;
  /// Where the frame records what its traversal did (Scratch::set_trace,
  /// voxvis/inspect.h); null: nothing is recorded. Tested once per cell the
  /// cell traversal skips or enters whole, never per voxel: the voxel
  /// traversal's record is read from `stamp` after it.
  FrameTrace* trace = nullptr;

  /// Starts a frame for a scene of `objects` slots, `boxes` opaque boxes,
  /// `bricks` bricks, `cells` cells of levels >= 1 and `triangles` static
  /// mesh triangles drawn into the buffer.
  void begin(std::size_t objects, std::size_t boxes, std::size_t bricks, std::size_t cells,
             std::size_t triangles = 0);
  /// Starts the voxel traversal's stamps for a grid of `voxels` voxels: only
  /// frames that walk voxels (the buffer off) size, touch and clear them.
  void begin_voxels(std::size_t voxels);
};

struct Scene::Impl {
  /// Two locks, always taken in this order (docs/design.md,
  /// "Thread-safety"):
  ///  * `mu` guards the grid: voxels, bricks, discretizations, TBVs and their
  ///    expiry queue, objects' positions. Frames hold it shared while they
  ///    traverse; it is held exclusive (with `book` too) only to change them:
  ///    moves, expired TBVs, and the queued reveals and new TBVs.
  ///  * `book` guards the bookkeeping: the clock, viewers and their claims,
  ///    the seen record, the queues below, counters between frames and the
  ///    wake epoch. A frame takes it briefly, so frames of different viewers
  ///    do not wait for each other's traversals.
  mutable detail::GridMutex mu;
  mutable std::mutex book;

  GridSpec spec;
  SceneOptions options;
  glm::ivec3 res{1};
  Vec3 inv_vs{1.0};
  double slop_bounds = 0.0;  ///< Rounding allowance of grid mapping, world units.

  std::vector<detail::Obj> objs;
  std::unordered_map<ObjectId, std::uint32_t> slot_of;
  std::size_t dynamic_count = 0;
  /// The slots of the static and of the dynamic objects (a region frame
  /// tests the static ones all, the dynamic ones through the cells:
  /// region_candidates.h), and the dynamic objects' fastest max_speed.
  std::vector<std::uint32_t> static_slots, dynamic_slots;
  double max_dynamic_speed = 0.0;

  // Static layer.
  static constexpr std::uint8_t kStaticOpaque = 1, kStaticIds = 2, kDynOpaque = 4, kCoarseIds = 8;
  /// A static opaque voxel wholly inside one static ball (read when the
  /// opaque boxes are chosen: build.cpp, redundant_boxes).
  static constexpr std::uint8_t kInOneBall = 16;
  /// With the buffer on: a voxel wholly inside a closed static mesh (no
  /// triangle touches it, OpenVDB's level set puts its centre inside), and
  /// a voxel some closed static mesh's triangles touch (build.cpp,
  /// build_mesh_interiors; docs/design.md, "Meshes").
  static constexpr std::uint8_t kMeshInside = 32, kMeshTouched = 64;
  std::vector<std::uint8_t> vflags;
  detail::Pyramid pyr;
  /// Per level, the static objects stored there (level 0: voxels).
  std::array<detail::IdLists, detail::kMaxLevels> static_lists;
  /// Where each level's cells start in a flat array of all cells of levels
  /// 1 and up (Scratch::Impl::cell_seen).
  std::array<std::size_t, detail::kMaxLevels + 1> cell_base{};
  /// With the buffer on (the cell traversal's), per level >= 1, per cell, a
  /// bit per child (x + 4y + 16z within the
  /// cell) that holds static content: at level 1 a voxel with static
  /// objects in its own list, or static opaque; above, a child with a bit
  /// set or static objects stored in it. Empty space is skipped by them.
  std::array<std::vector<std::uint64_t>, detail::kMaxLevels> static_mask;
  /// With the occlusion buffer on, per brick: the static objects in its
  /// voxels' own lists (static_lists[0]) and the opaque boxes owning its
  /// opaque voxels, each once, so that the cell traversal reads a brick's
  /// content as two short lists instead of voxel by voxel.
  detail::IdLists brick_static;
  detail::IdLists brick_boxes;
  /// With the occlusion buffer on: the static opaque voxels as overlapping
  /// boxes, and each opaque voxel's owner box (opaque_boxes.h).
  std::vector<detail::VoxBox> opaque_boxes;
  std::vector<std::uint32_t> opaque_owner;
  /// How many of opaque_boxes cover static opaque voxels (the closed
  /// meshes' interiors follow them).
  std::size_t static_opaque_boxes = 0;
  /// The static convex occluders a region frame uses (region_occlusion.h).
  detail::RegionOccluders region_occ;
  /// With dynamic objects: the free space's components, for what a region
  /// frame's eyes are shut in (region_cavity.h).
  detail::FreeSpace free_space;
  /// With the occlusion buffer on, per brick: the triangles of static meshes
  /// that meet it (brick b holds brick_tris[brick_tri_offsets[b] ..
  /// brick_tri_offsets[b+1])), drawn when the traversal reaches the brick; a
  /// triangle is listed in every brick it meets and drawn once a frame.
  std::vector<std::uint32_t> brick_tri_offsets;
  std::vector<detail::TriRef> brick_tris;
  std::uint32_t static_triangles = 0;  ///< Triangles of static meshes, all.
  /// With the buffer on, per brick: the boxes of kMeshInside voxels
  /// (indices into opaque_boxes, after the static ones) owning its voxels,
  /// drawn only in frames whose eye and near plane lie outside every closed
  /// mesh (FrameGeometry::mesh_interiors).
  detail::IdLists brick_mesh_boxes;
  /// A closed static mesh reaches beyond the grid box (then an eye beyond
  /// it may be inside one).
  bool closed_mesh_beyond_grid = false;
  bool any_closed_mesh = false;  ///< A static mesh is closed (buffer on).

  // Dynamic layer (allocated only when the scene has dynamic objects).
  glm::ivec3 bricks_res{0};
  std::vector<detail::Brick> bricks;
  /// Per level 2 and up, the cells wholly inside an object's or TBV's range
  /// of bricks, and at level 2 those holding a TBV whole (Obj::tbv_coarse)
  /// (the same entries as a brick's; [0] and [1] unused).
  std::array<std::vector<detail::Brick>, detail::kMaxLevels> coarse_dyn;
  /// Live entries in coarse_dyn, all levels: readers skip those levels at 0.
  std::uint64_t coarse_dyn_live = 0;
  /// With the buffer on, per level >= 1, per cell: its own live dynamic
  /// entries plus its children whose count is not 0, and a bit per such
  /// child (as static_mask). A count is not 0 exactly when something lives
  /// in the cell or below it.
  std::array<std::vector<std::uint32_t>, detail::kMaxLevels> dyn_count;
  std::array<std::vector<std::uint64_t>, detail::kMaxLevels> dyn_mask;
  /// Per brick: the latest scene time a frame saw a voxel of it (reached it
  /// and did not prove it hidden), -inf if never, and which voxels frames
  /// saw since it was last forgotten (Scratch::Impl::seen_vox). TBVs keep
  /// clear of voxels seen within SceneOptions::tbv_seen_memory.
  std::vector<double> seen_at;
  std::vector<std::uint64_t> seen_mask;
  /// Per level >= 2, per cell: the latest scene time a frame saw the whole
  /// cell (Scratch::Impl::seen_cells); a brick inside such a cell counts as
  /// wholly seen then (layer_seen).
  std::array<std::vector<double>, detail::kMaxLevels> cell_seen_at;
  /// Per level-2 cell (4 x 4 x 4 bricks): the latest scene time anything in
  /// it was recorded seen, a brick of it or the cell whole (mark_seen), so
  /// that a TBV deep in space nobody saw asks a few cells, not every brick
  /// layer it grows through (unseen_range). Empty below three levels.
  std::vector<double> cell_any_seen_at;
  double last_seen_at = -std::numeric_limits<double>::infinity();  ///< Latest of seen_at.
  /// Counts the changes to the seen record that can bring seen space nearer
  /// a TBV: a voxel recorded seen that was not within the memory, a brick
  /// or a whole cell newly recent (mark_seen). Forgetting only leaves more
  /// room, so an answer about room given at one count holds, conservatively,
  /// while the count stands (seen_room).
  std::uint64_t seen_epoch = 1;

  // Beyond the grid.
  std::vector<std::uint32_t> outside_objs;
  std::vector<std::uint32_t> outside_tbvs;

  // TBVs.
  detail::ExpiryQueue expiry;
  std::uint32_t tbv_count = 0;
  std::vector<std::uint32_t> unclaimed;  ///< Slots that may need a TBV.
  /// TBVs frames found not occluded, to be revealed by the next holder of
  /// `mu` exclusive; until then they keep bounding their objects.
  std::vector<std::uint32_t> queued_reveals;
  /// A frame has made its claims: from then on a frame may make the TBVs of
  /// unclaimed objects before its traversal (before, every dynamic object is
  /// unclaimed and would be put under a TBV only to be revealed).
  bool claims_made = false;
  /// Frames of this scene running now (Scene::frame renews TBVs ahead of
  /// expiry only when it is not alone).
  std::atomic<int> frames_in_flight{0};

  // Viewers.
  std::unordered_map<ViewerId, detail::ViewerState> viewers;
  ViewerId next_viewer = 1;

  double time = 0.0;
  bool time_set = false;
  std::uint64_t wake_epoch = 0;  ///< Bumped whenever an object enters or leaves a TBV.
  std::uint64_t moves_epoch = 0;  ///< Bumped by every accepted apply_moves (under `mu` exclusive).
  /// Time of the first frame: objects that have not moved since have been at
  /// their initial centres from then on. NaN before the first frame.
  double first_frame_time = std::numeric_limits<double>::quiet_NaN();

  // Counters gathered between frames (moves), reported with the next frame.
  FrameStats pending;
  /// Bytes the build counted as the scene's (Scene::built_bytes).
  std::uint64_t built_bytes = 0;
  std::vector<std::uint32_t> pending_wake;

  // --- geometry -----------------------------------------------------------
  std::int64_t index(int x, int y, int z) const {
    VOXVIS_ASSERT(x >= 0 && y >= 0 && z >= 0 && x < res.x && y < res.y && z < res.z);
    return x + std::int64_t{res.x} * (y + std::int64_t{res.y} * z);
  }

  Vec3 to_grid(const Vec3& p) const { return (p - spec.bounds_min) * inv_vs; }
  /// Rounding allowance for an object near `mag` world units, world units.
  double slop(double mag) const;
  /// Voxels the box [lo, hi] (world) may touch, clipped to the grid.
  detail::VoxBox touch_range(const Vec3& lo, const Vec3& hi, double slop_w) const;
  bool touches(const detail::Obj& o, const Vec3& c, int x, int y, int z) const;
  bool contains_voxel(const detail::Obj& o, const Vec3& c, int x, int y, int z) const;
  /// A box (grid coordinates) that the object at centre c contains: exact
  /// faces where the mapping is exact, shrunk by the rounding allowance
  /// elsewhere; a sphere gives its inscribed cube. May be empty (lo > hi).
  void inner_box(const detail::Obj& o, const Vec3& c, Vec3* lo, Vec3* hi) const;
  /// The voxels whose closed cells together hold the whole closed box of a
  /// static object: exact faces where the mapping is exact, grown by the
  /// rounding allowance elsewhere. False when it reaches beyond the grid.
  bool own_voxels(const detail::Obj& o, detail::VoxBox* out) const;
  /// Whether the objects in `slots` (at their discretized or static centres)
  /// together cover voxel (x, y, z): one sphere contains it, or the union of
  /// their inner boxes covers the closed unit cube (docs/design.md, "Opacity").
  bool union_covers(const std::uint32_t* slots, std::size_t n, int x, int y, int z) const;
  /// Whether one of the static balls among `slots` holds voxel (x, y, z) whole.
  bool in_one_ball(const std::uint32_t* slots, std::size_t n, int x, int y, int z) const;
  /// union_covers over every static object touching the voxel and every
  /// discretized dynamic object of its cells (kCoverCandidates at most).
  bool covered_now(int x, int y, int z) const;
  /// Appends the static objects of the cells of levels >= 1 holding voxel
  /// (x, y, z), finest first, up to `cap` in all.
  void coarse_static(int x, int y, int z, std::uint32_t* out, std::size_t* n, std::size_t cap) const;
  bool box_inside_grid(const Vec3& lo, const Vec3& hi) const;

  // --- dynamic state ------------------------------------------------------
  void discretize(std::uint32_t slot);
  void undiscretize(std::uint32_t slot);
  /// Adds an entry to every brick voxel box vb touches: to the coarsest
  /// cells wholly inside its range of bricks (cells.h), and, for the
  /// level-2 cells of `coarse` (tbv_coarse_cells), to the cell whole.
  void brick_add(const detail::VoxBox& vb, std::uint32_t key, std::uint32_t gen, std::uint32_t coarse = 0);
  /// Lowers the live count of the same cells brick_add(vb, .., coarse) wrote.
  void brick_remove(const detail::VoxBox& vb, std::uint32_t coarse = 0);
  /// The level-2 cells (16 voxels a side) over a TBV's voxels vb that may
  /// hold its entry whole rather than one per brick it touches: those it
  /// only partly covers where no viewer saw anything within
  /// tbv_seen_memory, when its range spans at most 3 of them a side and the
  /// cell traversal runs (the occlusion buffer on). Bit k: the k-th cell of
  /// the range, x fastest. docs/design.md, "Where TBVs are stored".
  /// `quiet`: unseen_around(vb) is known to hold.
  std::uint32_t tbv_coarse_cells(const detail::VoxBox& vb, bool quiet = false) const;
  /// unseen_range over the level-2 cells (16 voxels a side) around voxels
  /// vb: nothing in them was seen within tbv_seen_memory.
  bool unseen_around(const detail::VoxBox& vb) const;
  /// Adds `delta` live entries to cell c of `level` and the counts above it,
  /// flipping the parents' dyn_mask bits where a count leaves or reaches 0.
  void dyn_count_add(int level, glm::ivec3 c, int delta);
  /// The dynamic cell (level >= 1) of an entry.
  detail::Brick& dyn_cell(int level, const glm::ivec3& c) {
    return level == 1 ? bricks[pyr.index(1, c)] : coarse_dyn[static_cast<std::size_t>(level)][pyr.index(level, c)];
  }
  /// Whether a brick entry still stands for a discretization or TBV.
  bool current(const detail::BrickEntry& e) const {
    const detail::Obj& o = objs[e.key >> 1];
    return (e.key & 1u) ? (o.under_tbv && o.tbv_gen == e.gen)
                        : (!o.under_tbv && o.disc_gen == e.gen);
  }
  /// A TBV's box and validity period (tbv_box).
  struct TbvBox {
    Vec3 lo, hi;
    double period;
  };
  /// Puts object `slot` under a TBV from `now`: `box` if given (computed
  /// for it at this renewal), else tbv_box's.
  void make_tbv(std::uint32_t slot, double now, const TbvBox* box = nullptr);
  /// A quiet TBV for object `slot`: its box grown as far as the cells of 16
  /// voxels around it hold it whole, or else as far as the longest period
  /// at its largest scale (which holds every box full_tbv_box makes),
  /// whichever first has no level-2 cell around it seen within the memory
  /// (unseen_around); its voxels, and the period that growth holds (scaled
  /// into [0.75, 1)). 0 when neither is unseen, outputs unset (also for
  /// automatic periods off or no seen record). make_tbv and renew_tbv.
  double quiet_tbv_box(std::uint32_t slot, Vec3* lo, Vec3* hi, detail::VoxBox* vb);
  /// The per-object, per-renewal factor in [kMaxPeriodScale - 1,
  /// kMaxPeriodScale) that periods are scaled by (full_tbv_box).
  double period_scale(std::uint32_t slot) const;
  static constexpr double kMaxPeriodScale = 1.5;
  /// Object o's box grown by `grow` on every side, clamped to the grid's
  /// bounds (never cutting the object's own box): every TBV box.
  void grown_box(const detail::Obj& o, double grow, Vec3* lo, Vec3* hi) const;
  /// The growth of o's longest period at its largest scale: its TBV box
  /// then holds every box full_tbv_box makes for it.
  double longest_growth(const detail::Obj& o) const;
  /// Gives an expired TBV a new validity period (see scene_tbv.cpp).
  void renew_tbv(std::uint32_t slot, double now);
  /// The TBV box for the object's current centre and a period starting now;
  /// returns the (jittered) period. `cut` (if given) says whether seen space
  /// cut the growth short.
  double tbv_box(std::uint32_t slot, Vec3* lo, Vec3* hi, bool* cut = nullptr);
  /// tbv_box's two steps: the box grown by the whole (jittered) period,
  /// which it returns, and that box cut by seen space (returns the period
  /// left).
  double full_tbv_box(std::uint32_t slot, Vec3* lo, Vec3* hi) const;
  double cut_tbv_box(std::uint32_t slot, double period, Vec3* lo, Vec3* hi, bool* cut);
  /// unseen_growth of object `slot` towards its longest TBV box (the longest
  /// period at its largest scale; it holds every box full_tbv_box makes, so
  /// the room is no more than towards any of them), and its room_brick:
  /// asked again only when the object moved, the seen record changed
  /// (seen_epoch) or tbv_seen_memory passed since last asked.
  double seen_room(std::uint32_t slot, double* room_brick);
  void drop_tbv(std::uint32_t slot);
  /// How far (world units, on every side) the box of object `o` may grow
  /// towards the TBV box [lo, hi] and stay half a voxel clear of every voxel
  /// a viewer saw within tbv_seen_memory; infinity when nothing is in the way
  /// (docs/design.md, "Temporal bounding volumes"). `room_brick`: the same,
  /// keeping out of every brick that holds such a voxel.
  double unseen_growth(const detail::Obj& o, const Vec3& lo, const Vec3& hi, double* room_brick) const;
  /// Records the voxels a frame at time t saw, and empties w's record.
  void mark_seen(Scratch::Impl& w, double t);
  bool seen_recently(std::size_t brick) const {
    return time - seen_at[brick] <= options.tbv_seen_memory;
  }
  /// The voxels (bit x + 4y + 16z of a brick) seen within the memory in any
  /// brick of `range` (bricks_res coordinates), OR-ed.
  std::uint64_t layer_seen(const detail::VoxBox& range) const;
  /// True when no voxel of the bricks `range` (bricks_res coordinates) was
  /// seen within the memory: the cells above them say so (false when they
  /// cannot tell).
  bool unseen_range(const detail::VoxBox& range) const;
  /// Whether a cell of level l (times `at`, one per cell) above the bricks
  /// `range` was seen within the memory.
  bool recent_cell(const std::vector<double>& at, int l, const detail::VoxBox& range) const;
  void reveal(std::uint32_t slot);
  /// Sets a mesh's centre, half (and for a dynamic one radius) from its
  /// placement: the box holding it (see Obj).
  void place_mesh(detail::Obj& o) const;
  /// Whether apply_queue(st, tbvs) has work. Needs `book`.
  bool queued(bool tbvs) const { return !queued_reveals.empty() || (tbvs && !unclaimed.empty()); }
  /// Reveals the queued TBVs and, with `tbvs`, gives a TBV to every
  /// unclaimed dynamic object (counted in st.tbvs_created), at the scene's
  /// time. Needs `mu` exclusive and `book`.
  void apply_queue(FrameStats& st, bool tbvs = true);
  void list_add(std::vector<std::uint32_t>& list, std::int32_t& pos, std::uint32_t slot);
  void list_remove(std::vector<std::uint32_t>& list, std::int32_t& pos, bool tbv);

  double initial_period(const detail::Obj& o) const;
  double max_period(const detail::Obj& o) const;
};

}  // namespace voxvis
