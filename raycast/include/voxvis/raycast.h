// voxvis/raycast.h — the CPU ray caster: the exactly visible set of a frame
// in double precision, written independently of the engine. It uses only the
// public value types (ObjectDesc, Camera) and none of the engine's code, so
// it is the tests' ground truth, and `voxvis report` and `voxvis verify`
// take it as the exact reference where no EGL is available
// (docs/accuracy.md, docs/verify.md).
//
// Definition of "visible" used here (docs/design.md, "What visible means"):
//   An object is visible when it is the first hit (ties in depth included)
//   on a set of rays from the eye, inside the frustum, of positive measure:
//   a solid angle, however small, whose rays reach a point of the object
//   between the near and far planes before they reach any other object.
//   An object seen only along an edge or at a corner (a set of rays of
//   measure zero) is not visible; two faces tied in depth over an area are
//   both visible; a slit of any positive width shows what lies behind it.
//
// A sampled ray stands for the rays around it: jittered rays fall on an
// edge, a corner or the frustum's boundary with probability zero, and the
// optional corner samples are small cones of rays around the cell corners
// (RaySampling::corners), never the exact corner rays, which on a voxel
// grid seen from a voxel corner run exactly along voxel edges.
//
// Rays: r(t) = eye + t*d with d = f + x*tanx*right + y*tany*up', where
// f = normalize(dir), right = normalize(cross(f, up)), up' = cross(right, f),
// tany = tan(fov_y/2), tanx = aspect*tany and x, y in [-1, 1]. Since d·f = 1,
// the parameter t of a point is its depth along the view direction, so the
// frustum is exactly t in [near, far] over x, y in [-1, 1].
//
// Near-plane choice: each object's intersection interval with a ray is clipped
// to [near, far]; the object with the smallest clipped entry is the one hit.
// Objects (or the parts of objects) wholly before the near plane are clipped
// away: they are not visible and they do NOT block what lies behind them. This
// is the more conservative reading (it makes more objects visible), and it
// matches rasterization with near-plane clipping. An object that contains the
// eye is hit at depth `near` on every ray that leaves it beyond the near plane.
// Ties (several objects entered at exactly the same depth) make all of them
// visible, again the conservative reading.
//
// Meshes (Shape::Mesh, voxvis/mesh.h) are surfaces, not solids: a ray meets
// a mesh where it crosses one of its triangles (either face), and the mesh's
// depth on the ray is its least such t within [near, far]. A mesh cut by
// the near plane therefore shows what lies inside it, as rasterization with
// near-plane clipping does, and an eye inside a closed mesh sees its inner
// faces (the "contains the eye" rule above is for solids). Triangles are
// tested in double precision with a watertight test (Woop, Benthin and Wald
// 2013): a ray on a shared edge or vertex hits the triangles around it,
// never passes between them, and a ray the rounding puts on an edge counts
// as a hit (conservative, as ties). The mesh is placed exactly as
// voxvis/mesh.h says, by taking each ray into the mesh's own frame, where
// one hierarchy per mesh (built on its first call and kept while the mesh
// lives, raycast/src/mesh_bvh.h) serves every object that places it. Two
// objects' surfaces that coincide tie only as far as rounding lets them: a
// mesh's face and a box's face in the same plane are computed by different
// operations and may come out a few ulps apart (only the nearer shows).
//
// The caster samples the image: it proves visibility (every id it returns is
// visible), never invisibility. Tests therefore assert PVS ⊇ visible_objects.
// With pixel_centres(W, H) it samples what the headless renderer samples
// (voxvis/render.h): the first hit at every pixel centre. The renderer
// computes in single precision and may show, at a pixel centre whose ray
// runs along an edge, what lies behind the edge (seen there only, a set of
// rays of measure zero); confirm_near_pixels tells such sightings apart,
// with cones of rays around the pixel centres (visible_near_pixel).
//
// Every computed hit is the same as testing every object on every ray
// (CastOptions::brute_force); visible_objects only finds it faster, through a
// bounding volume hierarchy built per call (see raycast.cpp), and through
// each mesh's hierarchy over its triangles (the same but for rays grazing
// a triangle's plane, mesh_bvh.h). Every function is thread-safe: the
// meshes' hierarchies are shared read-only, their cache behind a mutex.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "voxvis/types.h"

namespace voxvis::raycast {

/// How the image is sampled: a cols x rows grid of cells over x, y in
/// [-1, 1], one ray per cell at a jittered position drawn from `seed`
/// (or at the cell centre when `jitter` is false), plus optionally a small
/// cone of rays around every cell corner, frustum edges and corners
/// (x, y = ±1) included: four rays `cone` cells from the corner, in
/// directions that are neither the image axes nor its diagonals, those
/// strictly inside the image. They find what shows through a slit or past
/// an edge that the corner ray runs along (the hard cases: an eye on voxel
/// corners looking along an axis or a diagonal), without counting what the
/// exact corner ray alone meets first (a tie along an edge, a set of rays
/// of measure zero: not visible).
struct RaySampling {
  int cols = 96;
  int rows = 96;
  bool jitter = true;
  bool corners = false;
  std::uint64_t seed = 0x5eed;
  double cone = 1e-3;  ///< Radius of the corner cones, in cells.
};

/// The rays through the pixel centres of a width x height image: pixel
/// (i, j) samples x = -1 + (2i+1)/width, y = -1 + (2j+1)/height, as the
/// headless renderer does.
inline RaySampling pixel_centres(int width, int height) { return RaySampling{width, height, false, false, 0}; }

/// How visible_objects computes (never what it returns).
struct CastOptions {
  /// Threads casting rays: 0 chooses (the hardware's threads, one for small
  /// images); the answer is the same for any number.
  int threads = 0;
  /// Test every object on every ray (every triangle of a mesh), with no
  /// hierarchy and no culling: the definition itself, slow; the tests'
  /// reference for the fast path.
  bool brute_force = false;
};

/// What one visible_objects call cost.
struct CastStats {
  std::size_t in_frustum = 0;  ///< Objects that may be hit (the hierarchy's leaves).
  std::size_t rays = 0;
  int threads = 1;
  std::size_t meshes_built = 0;      ///< Mesh hierarchies this call built (the others were kept from before).
  std::uint64_t triangle_tests = 0;  ///< Ray–triangle tests, all rays together.
  double build_ms = 0.0;  ///< Culling and building the hierarchy, wall clock.
  double cast_ms = 0.0;   ///< Casting the rays, wall clock.
};

/// The per-camera frame of reference used by the caster (see the header
/// comment for the definitions).
struct ViewBasis {
  Vec3 eye{0.0};
  Vec3 f{0.0, 0.0, -1.0};      ///< Unit view direction.
  Vec3 right{1.0, 0.0, 0.0};   ///< Unit.
  Vec3 up{0.0, 1.0, 0.0};      ///< Unit, = cross(right, f).
  double tanx = 1.0;
  double tany = 1.0;
  double near = 0.05;
  double far = 1000.0;

  /// The (unnormalized, d·f = 1) direction of the ray through image point (x, y).
  Vec3 ray_dir(double x, double y) const { return f + (x * tanx) * right + (y * tany) * up; }
};

/// Builds the basis. Returns false (and leaves `out` alone) for a camera that
/// does not define a frustum: non-finite values, zero dir, up parallel to dir,
/// fov outside (0, 180), aspect <= 0, near <= 0 or far <= near.
bool make_basis(const Camera& cam, ViewBasis* out);

/// Intersection of the closed solid `obj` with the line eye + t*d: the
/// interval [t0, t1] of t. Returns false when they do not meet. Unbounded
/// intervals (d = 0 inside a slab) are reported as ±infinity. For a mesh (a
/// surface): the least and the greatest t at which the line crosses one of
/// its triangles; the caster takes a mesh's depth as its least crossing
/// within [near, far], which the interval alone does not give. A mesh's
/// hierarchy comes from the cache (built on its first use).
bool intersect(const ObjectDesc& obj, const Vec3& eye, const Vec3& d, double* t0, double* t1);

/// The ids of the objects hit first (ties included) by at least one sampled
/// ray (see the header comment), ascending and unique. Empty for an invalid camera.
/// `stats` (optional) receives the costs.
std::vector<ObjectId> visible_objects(const std::vector<ObjectDesc>& objects, const Camera& cam,
                                      const RaySampling& sampling = {}, const CastOptions& options = {},
                                      CastStats* stats = nullptr);

/// How region_visible samples a region camera (Camera::eye_extent,
/// omnidirectional, horizon_s).
struct RegionSampling {
  /// Eyes: the box's centre and its 8 corners, and this many more uniform
  /// in the box (none for a point eye).
  int random_eyes = 8;
  /// With a horizon and dynamic objects: placements of the objects besides
  /// where they are, each object moved by a random vector of up to
  /// max_speed * horizon_s (the last placement: every object the whole way,
  /// in a random direction).
  int placements = 3;
  /// The rays of each view: the camera's frustum, or six faces of 90 degrees
  /// (a cube about the eye) when omnidirectional.
  RaySampling rays{48, 48};
  std::uint64_t seed = 1;
};

/// What a region camera sees, sampled: the union of visible_objects over the
/// sampled eyes, views and placements (RegionSampling), ascending. A lower
/// bound of the region's visible set: an answer conservative for the region
/// holds every id. For a point camera, visible_objects(objects, cam,
/// sampling.rays). Empty for an invalid camera.
std::vector<ObjectId> region_visible(const std::vector<ObjectDesc>& objects, const Camera& cam,
                                     const RegionSampling& sampling = {});

/// The ids of the objects hit first by the single ray through image point
/// (x, y), x, y in [-1, 1] (several on a tie; empty when the ray hits nothing).
/// Tests every object (brute force; a mesh through its hierarchy).
std::vector<ObjectId> first_hit(const std::vector<ObjectDesc>& objects, const Camera& cam, double x,
                                double y);

/// Whether object `id` is visible near the centre of pixel (i, j) of a
/// width x height image (pixel (i, j) as pixel_centres samples it): the
/// first hit (ties included) of at least one of four rays 1e-3 pixel from
/// the centre, in the directions of the corner cones (RaySampling::corners;
/// one in each quadrant, none along an image axis or diagonal). The centre
/// ray itself is not cast: it may run exactly along an edge, where what it
/// meets first is seen on a set of rays of measure zero (not visible), while
/// the cone's rays pass on either side of the edge. What shows near the
/// centre only through a gap narrower than the cone (1e-3 pixel) is missed.
/// Brute force (first_hit's code path) over the objects whose projected
/// bounding boxes overlap the object's, a ray cast only where it meets the
/// object: linear in the objects. False for an invalid camera, a size below
/// 1 or an id not in `objects`.
bool visible_near_pixel(const std::vector<ObjectDesc>& objects, const Camera& cam, int width, int height, int i,
                        int j, ObjectId id);

/// Confirms what a single-precision renderer showed at the pixel centres of
/// width x height (voxvis/render.h): each id of `seen` goes to `confirmed`
/// when it is visible_near_pixel at one of its pixels, else to `dismissed`
/// (both ascending, unique). Its pixels are those whose entry in `pixel_ids`
/// is the id (width * height ids, row-major from the bottom row, 0 where
/// nothing shows: render::Renderer::last_ids); with `pixel_ids` empty, every
/// pixel. An id `objects` lacks is dismissed. Only pixels within the
/// projection of an object's bounding box are tried (no other can confirm
/// it), each with four intersections, and a ray that meets the object is
/// cast by brute force over the objects whose projections overlap its own;
/// an id is confirmed at its first such pixel.
void confirm_near_pixels(const std::vector<ObjectDesc>& objects, const Camera& cam, int width, int height,
                         const std::vector<ObjectId>& pixel_ids, const std::vector<ObjectId>& seen,
                         std::vector<ObjectId>* confirmed, std::vector<ObjectId>* dismissed);

/// Image coordinates (x, y) of point `p` (the ray through them passes
/// through p); false when p is not in front of the eye or the camera is
/// invalid. The point is in the image when |x|, |y| <= 1.
bool project(const Camera& cam, const Vec3& p, double* x, double* y);

/// The ids of the objects that may intersect the view frustum, ascending:
/// the AABB test — an object is rejected only when its axis-aligned bounding
/// box lies wholly outside one of the frustum's six planes (by more than a
/// tiny relative tolerance). This is the view-frustum-culling-only set; it is
/// exact for most objects and includes a few outside near the frustum's edges
/// and corners, but never excludes an object that meets the frustum, so it is
/// a superset of visible_objects.
std::vector<ObjectId> frustum_objects(const std::vector<ObjectDesc>& objects, const Camera& cam);

/// How many voxels of the grid over [bmin, bmax] with `res` voxels a side
/// the rays through the cell centres of `sampling` pass through, from the near
/// plane up to and including their first hit (or the far plane): a sampled
/// lower bound of the voxels in view, which a traversal must visit at least.
std::size_t voxels_in_view(const std::vector<ObjectDesc>& objects, const Camera& cam, const Vec3& bmin,
                           const Vec3& bmax, const glm::ivec3& res, const RaySampling& sampling);

}  // namespace voxvis::raycast
