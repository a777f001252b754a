// voxvis/scene.h — the visibility engine.
//
// A Scene owns the shared grid of one scene: static objects' ids and
// opacity per voxel, built once (Batagelo & Wu, "Dynamic scene occlusion
// culling using a regular grid", 4.5), summarized in a pyramid of cells
// (cells.h); dynamic objects' ids and opacity kept up to date as they move
// (apply_moves); and temporal bounding volumes (TBVs, after Sudarsky &
// Gotsman) for dynamic objects hidden from every viewer, so that a hidden
// mover costs nothing per frame until its TBV may show or expires
// (grid/src/scene_tbv.cpp).
//
// A frame (Scene::frame; its phases in grid/src/frame.cpp) answers one
// viewer's camera with its potentially visible set (PVS). By default
// (SceneOptions::occlusion_buffer > 0) it walks the cell pyramid front to
// back (grid/src/traverse_cells.cpp): a cell is entered only when it holds
// something, meets the frustum and is not proven hidden by a conservative
// occlusion buffer (grid/src/occlusion_buffer.h: every pixel holds a lower
// bound on the reciprocal depth of the first hit of every ray through it;
// its tile rasterizer in occlusion_fill.cpp). The objects of a cell entered
// are tested against the frustum and the buffer, and drawn into it when
// they may be visible (collect.h). With the buffer off, the frame walks
// the frustum's voxels in the paper's chess-metric shells around the eye
// (grid/src/traverse_shells.cpp): a voxel is occluded when every voxel of the
// shell before that its central projection can cross blocks, which fuses
// occluders in object space. Both are conservative by construction
// (docs/design.md gives the arguments): a visible object is never missing.
// A frame whose camera is a region (an eye box, every direction, a time
// horizon: Camera's region fields) answers for all of it (region.h).
//
// Each viewer keeps only its last PVS in the scene. The per-frame layers
// (visited status, PVS marks, the buffer) live in a Scratch that each
// worker thread owns and reuses across viewers and scenes.
//
// Thread-safety: a Scene synchronizes itself with a reader-writer lock.
// Frames of different viewers run in parallel: a frame changes the scene
// briefly before and after its traversal (clock, expired TBVs; reveals,
// claims, new TBVs) and traverses under a shared lock, deferring the TBVs it
// reaches to the end (they go into its PVS meanwhile, which keeps it
// conservative). Moves, add_viewer and remove_viewer are exclusive. Frames of
// one viewer must not overlap (each needs the previous one's PVS). A Scratch
// must not be shared between threads.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "voxvis/types.h"

namespace voxvis {

/// Input for Scene::create: bounds, optional resolution, objects.
struct SceneDesc {
  Vec3 bounds_min{0.0};  ///< World units; min < max on every axis.
  Vec3 bounds_max{1.0};
  std::optional<glm::ivec3> grid;  ///< Voxels per axis; empty: choose automatically.
  std::vector<ObjectDesc> objects;
};

struct SceneOptions {
  /// Refuse resolutions above this many voxels (before allocating anything).
  /// The grid costs about 9 bytes a voxel (5 with the occlusion buffer
  /// off, and then 1 more in each worker's Scratch), and about 5 more with
  /// dynamic objects (2 of them, up to 2^21 voxels, the free space a
  /// region's eyes are shut in);
  /// SceneCost has the figure of a scene (Scene::estimate).
  std::int64_t max_voxels = std::int64_t{1} << 27;
  /// Per-axis resolution limit.
  int max_resolution = kMaxResolution;
  /// Voxel count the automatic resolution aims at when none is given.
  std::int64_t auto_voxels = 600'000;
  /// TBV validity period in seconds; 0 chooses one per object: the time to
  /// cross `tbv_voxels` voxels at max_speed, doubled each time the TBV expires
  /// unrevealed (an object hidden long gets longer-lived TBVs) up to the time
  /// to cross `tbv_max_voxels`, reset when it is revealed; a TBV deep in
  /// space no viewer saw within `tbv_seen_memory` starts long instead, as
  /// wide as the cells holding it allow (docs/design.md, "Temporal bounding
  /// volumes"). Each period is scaled by a per-object factor (in [0.5, 1.5),
  /// or [0.75, 1) for those) so that renewals do not come in waves.
  double tbv_period = 0.0;
  double tbv_voxels = 2.0;
  double tbv_max_voxels = 8.0;
  /// Longest period a TBV is given before the scaling `tbv_period` describes,
  /// seconds: a TBV can last up to 1.5 times this.
  double tbv_max_period = 60.0;
  /// TBVs keep clear of space a viewer saw within this many seconds: their
  /// growth and period are cut to the distance to it (docs/design.md,
  /// "Temporal bounding volumes"), so hidden objects next to a room in view
  /// are not revealed and woken. Finite, >= 0.
  double tbv_seen_memory = 10.0;
  /// Width in pixels of the conservative occlusion buffer each frame renders
  /// the objects it finds into and tests voxels, objects and TBVs against
  /// (height from the camera's aspect, square pixels); 0 turns it off.
  /// 0 or 8..4096 (docs/design.md, "Occlusion buffer"). The default, 160,
  /// is the narrowest width that keeps the bundled walkthrough's PVS within
  /// 1.5 times the exactly visible set (docs/performance.md).
  int occlusion_buffer = 160;
  /// Object-space occlusion also tests, for a voxel the previous and
  /// half-distance shells leave visible, shells m-2, m-4, m-8, ... behind it
  /// (docs/design.md, "Which shells"), so that shadows seen off the axes
  /// persist with the occlusion buffer off too. Tighter without the buffer
  /// (city 2.07 -> 1.30 of the exactly visible set, indoor 2.27 -> 1.54) but
  /// up to 3x the frame time where much space is in view (the walkthrough);
  /// ignored with the buffer on, whose occluders keep their shadows already.
  bool deep_shells = false;
};

/// Counters of one frame. All counts are for this frame only.
struct FrameStats {
  std::uint64_t voxels_visited = 0;   ///< Voxels whose status the traversal computed.
  std::uint32_t shells = 0;           ///< Chess-metric shells traversed.
  std::uint32_t objects_discretized = 0;  ///< Dynamic objects (re)written into the grid.
  std::uint32_t tbvs_created = 0;
  std::uint32_t tbvs_revealed = 0;    ///< TBVs reached as not occluded (or left by a move).
  /// TBVs renewed: expired, or (while other viewers' frames run) within
  /// 0.1 s of expiring, renewed with them.
  std::uint32_t tbvs_expired = 0;
  std::uint32_t tbvs_active = 0;      ///< TBVs alive after the frame.
  std::uint32_t speed_violations = 0; ///< Moves since the last frame faster than max_speed.
  std::uint32_t outside_tested = 0;   ///< Objects and TBVs beyond the grid tested against the frustum.
  std::uint32_t pvs_size = 0;
  bool early_exit = false;            ///< Traversal stopped at a fully occluded shell.
  /// The frame was answered by frustum culling alone: the eye is too far
  /// from the grid (over 2^40 voxels) for the occlusion tests' arithmetic, or
  /// the camera's basis came out degenerate. Always conservative.
  bool frustum_fallback = false;
  /// The camera asked for a region (Camera::eye_extent, omnidirectional,
  /// horizon_s): answered by culling to what the region can reach, every
  /// object and TBV tested, no occlusion (docs/design.md, "Regions").
  bool region = false;
  /// Voxels hidden by the static opaque voxels beside them on the eye's side.
  std::uint64_t front_voxels_culled = 0;
  /// Static objects in voxels so hidden, though they touch voxels in view.
  std::uint32_t front_objects_culled = 0;
  std::uint32_t ob_width = 0;         ///< Occlusion buffer width this frame; 0: off.
  std::uint64_t ob_voxels_culled = 0; ///< Voxels the occlusion buffer proved hidden.
  std::uint32_t ob_objects_culled = 0;///< Objects and TBVs it proved hidden.
  std::uint32_t ob_occluders = 0;     ///< Objects rendered into it (that wrote a pixel).
  std::uint64_t ob_pixels_written = 0;///< Pixel bounds occluders raised.
  /// With the buffer on, the traversal of the cell pyramid: cells entered
  /// (their objects tested), and cells skipped whole, hidden by the buffer
  /// (or beyond its farthest bound, the early end: early_exit). A region
  /// frame: the cells it read for moving objects (0: it read their list).
  std::uint64_t cells_visited = 0;
  std::uint64_t cells_hidden = 0;
  /// Cells of bricks far enough to be taken whole: their bricks entered
  /// without a test of their own unless they hold much (docs/design.md,
  /// "Cells taken whole").
  std::uint64_t cells_whole = 0;
  double time_us = 0.0;               ///< Engine time for the frame, microseconds.
  /// Where time_us went: the traversal (its occluders' drawing included),
  /// drawing occluders into the buffer alone, and the tests beyond the grid
  /// and of the PVS against the finished buffer. The rest is bookkeeping
  /// (TBV renewal, claims, queues, the answer).
  double traverse_us = 0.0;
  double render_us = 0.0;
  double retest_us = 0.0;
};

struct FrameResult {
  double t = 0.0;              ///< Scene time the frame was computed at, seconds.
  std::vector<ObjectId> pvs;   ///< Ascending ids that may be visible.
  std::vector<ObjectId> wake;  ///< Ascending ids of dynamic objects whose fresh
                               ///< positions the engine needs: PVS members and
                               ///< objects whose TBV was revealed or expired.
  FrameStats stats;
  /// The scene's move epoch the frame saw: it changes with every accepted
  /// apply_moves, so objects were where dynamic_centers() says exactly when
  /// it reports the same epoch (used to verify served frames later).
  std::uint64_t positions_epoch = 0;
};

/// What Scene::apply_moves saw. Moves are applied even when too fast; such an
/// object is revealed (its TBV can no longer be trusted) and counted here.
struct MoveReport {
  double t = 0.0;  ///< Scene time the moves were applied at, seconds.
  std::uint32_t applied = 0;
  std::vector<ObjectId> too_fast;  ///< Ids that moved faster than max_speed.
};

/// Resolution and mapping of a scene's grid.
struct GridSpec {
  glm::ivec3 res{1};       ///< Voxels per axis.
  Vec3 bounds_min{0.0};    ///< World units.
  Vec3 bounds_max{1.0};
  Vec3 voxel_size{1.0};    ///< World units per voxel, per axis.
  std::int64_t voxel_count() const {
    return std::int64_t{res.x} * res.y * res.z;
  }
};

struct FrameTrace;  // voxvis/inspect.h

/// Per-thread per-frame working memory. Reused across frames, viewers and
/// scenes; grows to the largest scene it has served.
class Scratch {
 public:
  Scratch();
  ~Scratch();
  Scratch(const Scratch&) = delete;
  Scratch& operator=(const Scratch&) = delete;
  /// From now on the frames computed with this Scratch record what their
  /// traversal did into `*trace` (emptied as each frame starts), until
  /// set_trace(nullptr); off by default. Recording changes no frame's
  /// answer, and off it costs a pointer test per cell the traversal skips
  /// or enters whole (none per voxel), and one per frame with the buffer off.
  void set_trace(FrameTrace* trace);
  struct Impl;
  Impl& impl() { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

using ViewerId = std::uint32_t;

/// What a scene costs to build and keep, from its objects' footprints (the
/// voxels and bricks each object's box touches), computed without building
/// it: Scene::estimate.
struct SceneCost {
  glm::ivec3 res{1};              ///< The grid the scene gets (given or automatic).
  std::uint64_t bytes = 0;        ///< Memory the scene keeps, bytes: grid layers, id lists, objects, meshes (each once).
  std::uint64_t scratch_bytes = 0;///< What each worker's Scratch grows by to serve it, bytes.
  std::uint64_t id_entries = 0;   ///< Entries of the id lists (each object once per cell it is stored in).
  std::uint64_t work = 0;         ///< Steps the build takes (cells written and tested), for progress.
  /// What the build needs beyond `bytes` while it runs, bytes: its
  /// temporaries at their peak (a mesh's voxel marks, its triangles'
  /// pairing, a closed mesh's level set).
  std::uint64_t build_bytes = 0;

  /// What serving the scene from `workers` threads costs, bytes: the
  /// scene's own and each worker's scratch (the figure a server's memory
  /// budget counts). A worker's Scratch grows to the largest scene it
  /// serves, so counting it for every scene is on the high side, as a
  /// budget's figure should be.
  std::uint64_t served_bytes(unsigned workers) const { return bytes + scratch_bytes * workers; }
};

/// Cooperative control of a long Scene::create or Scene::estimate, polled
/// every few milliseconds of work.
struct BuildControl {
  /// When set and returning true, the work stops: Status::Code::Cancelled.
  /// May be called from other threads than the caller's (a level set's).
  std::function<bool()> cancelled;
  /// 0: none. What the scene and its build may take (SceneCost::bytes +
  /// SceneCost::build_bytes, counted before anything large is allocated)
  /// and, for Scene::create, the memory reserved for the build: the build
  /// counts what it allocates as it goes, and past this figure asks
  /// `reserve`. Refused with Status::Code::ResourceExhausted naming the
  /// figures.
  std::uint64_t max_bytes = 0;
  /// Called when a build's memory would pass `max_bytes` (or the last
  /// figure granted) with the bytes it needs in all: true grants them (the
  /// caller reserved more), false stops the build (ResourceExhausted). Not
  /// set: the build stops.
  std::function<bool(std::uint64_t)> reserve;
};

class Scene {
 public:
  /// Validates `desc` (ids unique, finite values, radius > 0, min <= max,
  /// resolution within the options) and builds the grid. On error returns the
  /// Status naming the field; nothing is allocated for a refused resolution.
  static Status create(const SceneDesc& desc, const SceneOptions& options,
                       std::unique_ptr<Scene>* out, const BuildControl* control = nullptr);
  /// What create() would cost (memory, id-list entries, work), validated as
  /// create() validates, without building: O(objects) for boxes, O(the cells
  /// a sphere's surface crosses) for spheres, O(vertices + triangles) for a
  /// mesh (each triangle's voxels, bricks and interior band bounded, never
  /// counted one by one: docs/design.md, "What a mesh costs"), and it stops
  /// as soon as `control->max_bytes` is exceeded (ResourceExhausted) or it
  /// is cancelled.
  static Status estimate(const SceneDesc& desc, const SceneOptions& options, SceneCost* out,
                         const BuildControl* control = nullptr);
  /// Resolution the engine would choose for `desc` when it names none.
  static glm::ivec3 auto_resolution(const SceneDesc& desc, const SceneOptions& options);
  /// Bytes the build counted as the scene's (its grid's layers, id lists,
  /// boxes and meshes' parts) where SceneCost::bytes foresaw them: what a
  /// memory budget keeps for it when the build needed more than foreseen.
  std::uint64_t built_bytes() const;

  ~Scene();
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;

  const GridSpec& grid() const;
  std::size_t object_count() const;
  std::size_t dynamic_count() const;
  /// Scene time, seconds: the latest time given to apply_moves or frame.
  double time() const;

  /// Adds a viewer; its first frame treats every object as possibly visible.
  ViewerId add_viewer();
  /// Removes a viewer and releases its claim on the objects of its last PVS.
  void remove_viewer(ViewerId viewer);

  /// How frame() and apply_moves() treat a time earlier than time().
  enum class Clock {
    Strict,  ///< Refused: the caller owns the scene's clock.
    Latest,  ///< Taken as time(), atomically: for callers whose viewers and
             ///< simulations share one clock and may race (a later time only
             ///< makes TBVs expire sooner and speed checks stricter).
  };

  /// Sets dynamic objects' centres at time `t` (seconds, not earlier than
  /// time() unless `clock` is Latest). Validated whole before anything
  /// changes: unknown or static ids, non-finite values and time going
  /// backwards are refused.
  Status apply_moves(double t, std::span<const Move> moves, MoveReport* report = nullptr,
                     Clock clock = Clock::Strict);

  /// Computes the viewer's PVS at time `t` (not earlier than time() unless
  /// `clock` is Latest; out->t says the time used). Validates the camera
  /// (finite, up not parallel to dir, 0 < fov < 180, 0 < near < far, aspect
  /// in range) before touching any state. May run in parallel with frames of
  /// other viewers (see the thread-safety note above).
  Status frame(ViewerId viewer, const Camera& camera, double t, Scratch& scratch,
               FrameResult* out, Clock clock = Clock::Strict);

  /// Dynamic objects whose positions the engine currently uses: those in any
  /// viewer's last PVS and those not yet under a TBV. Ascending ids.
  std::vector<ObjectId> wake_set() const;
  /// The same into `ids` (cleared first), reusing its memory.
  void wake_set(std::vector<ObjectId>* ids) const;
  /// Changes whenever wake_set() may have changed (an object entered or left
  /// a TBV), so that callers recompute the set only then.
  std::uint64_t wake_epoch() const;
  /// Current centres of the dynamic objects, ascending ids, world units, and
  /// (when `time` is given) the scene time they are at and (when `epoch` is
  /// given) the positions' epoch (FrameResult::positions_epoch), all read
  /// together. A mesh's entry has its model origin's position and its
  /// rotation as last given (has_rotation set; before normalization), so
  /// that a scene created with them places the mesh bit for bit as this one.
  std::vector<Move> dynamic_centers(double* time = nullptr, std::uint64_t* epoch = nullptr) const;

  struct Impl;
  /// The engine's internals (grid/src/scene_impl.h), for its own tests and
  /// voxvis/inspect.h.
  Impl& impl() { return *impl_; }
  const Impl& impl() const { return *impl_; }

 private:
  explicit Scene(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// Validates a camera as Scene::frame does. Exposed for the formats.
Status validate_camera(const Camera& camera);

/// Validates a scene time (finite, within ±kMaxSceneTime seconds) as
/// Scene::frame and Scene::apply_moves do; the error names `field`.
Status validate_time(const std::string& field, double t);

/// Makes `out` the box [lo, hi] (finite, lo <= hi on every axis), as every
/// reader of box corners does (the scene format, the wire). The engine's box
/// is centre ± half extent (scene_impl.h), and in doubles a centre and half
/// extent computed from arbitrary corners give other corners back (about
/// one box in four an ulp smaller). So the corners are first rounded
/// outwards to a multiple of 2^-52 of the power of two at or above the larger
/// corner magnitude (never past kMaxCoordinate): then every sum and half is exact,
/// centre ± half extent are those corners exactly, the engine's box contains
/// [lo, hi], each side moved out by less than two ulps of the larger corner
/// magnitude, and corners written from it (scene_to_json) read back to the
/// same centre and half extent.
void set_box_corners(const Vec3& lo, const Vec3& hi, ObjectDesc* out);

}  // namespace voxvis
