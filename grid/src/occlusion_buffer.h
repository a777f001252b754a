// occlusion_buffer.h — a conservative depth buffer in image space, per frame
// and per viewer (owned by the worker's Scratch), stored by tiles of 8x4
// pixels, each tile's least and largest bound kept as it is written (the
// coarse level of Hey et al.'s occlusion grid, kept eagerly), filled by a
// rasterizer of convex occluders (after Intel's Masked Occlusion Culling:
// edge functions and plane depths, a tile of 8x4 pixels at a time with a
// coverage mask; occlusion_fill.cpp, occlusion_tile.h).
//
// Image and depth. A ray of the frame's camera is r(t) = eye + t*d with
// d = f + x*tan_x*r + y*tan_y*u, x, y in [-1, 1]; since d·f = 1, t is the
// depth of the ray's points along the view direction (the metric of the near
// and far planes). The image [-1, 1]^2 is cut into W x H closed pixels. In
// pixel coordinates (X, Y) in [0, W] x [0, H], d is affine, so every linear
// function of d — the side of a plane through the eye, the reciprocal depth
// d_a / P at which a ray meets the plane {p_a = P} — is affine in (X, Y).
//
// What a pixel holds: a lower bound w on near/depth (0: none; at most 1).
// Every ray through the closed pixel meets an occluder, beyond the near
// plane, at a depth no greater than near/w. (Scaled by `near`, every bound
// fits a float whatever the scene's scale: worlds of 1e-90 or 1e12.)
//
// Occluders (inner coverage, farthest first hit). A convex occluder K is
// given as the rays that meet it beyond the near plane — an intersection of
// half-planes g_k >= 0 of affine functions of (X, Y) — and its entry depth
// over those rays, 1 / min_a w_a(X, Y) for affine w_a (a box: its entry
// planes; a planar polygon: its plane). A pixel is written only when the
// minimum of every g_k over its square (at a corner: g_k(centre) minus half
// its two slopes' magnitudes) is >= 0: then all four corner rays meet K, and
// since the rays meeting K form a convex cone, so does every ray through the
// pixel. It receives the minimum of min_a w_a over the square, which is the
// reciprocal of the farthest entry depth among its corners; the set of image
// points whose entry depth is <= tau is the projection of K ∩ {depth <= tau},
// convex, so the entry depth is quasiconvex over the square and its largest
// value is at a corner. Every ray through the pixel therefore meets K beyond
// the near plane at a depth no greater than the written bound. Shapes are
// shrunk by a rounding allowance first and bounds lowered by a relative
// slack and rounded down to float, so a rounding can only drop a pixel or
// loosen a bound. (The rasterizer evaluates the pixels in single precision
// re-centred on each tile, with allowances that keep every value at or
// below the exact one: occlusion_fill.cpp.)
//
// Tests (outer coverage, nearest depth over each pixel). A box is hidden
// when it lies wholly beyond the near plane and every pixel that its
// projection may touch (the bounding rectangle of its corners' projections,
// widened by an allowance) holds a bound w greater than the box's largest
// reciprocal depth over that pixel: the least of near / (the box's least
// depth) and, for each axis along which the eye lies outside the box's
// slab, the entry plane's near * d_a / P at the pixel corner where it is
// largest (a ray meeting the box does so at depth >= P / d_a, and near d_a / P
// is affine over the pixel). Every ray to a point p of the box then passes
// through such a pixel and meets an occluder beyond the near plane at a
// depth < depth(p): p is not the first hit of that ray. (A ray through the
// pixel that misses the box needs nothing.) A ball is tested the same way
// with its own outline's rectangle, its least depth and its bounding box's
// planes. The planes (and, with them, the rectangle of the corners' own
// projections rather than a quicker superset) make a large box seen at a
// slant testable: one depth over its whole rectangle would be its nearest
// corner's. They cost more for a box in view, so the traversal's first
// tests of cells and objects go without them (`fine` below).
//
// Tiles. The pixels are stored by tiles of 8x4 (occlusion_tile.h), each
// with the least and the largest bound of its pixels (0 where any is empty;
// pixels past the image's right and bottom sides hold +inf, never written),
// kept as occluders write. The rasterizer (occlusion_fill.cpp) writes a tile
// at a time with coverage masks, in single precision re-centred on the tile
// (its rounding argued there), by a scalar kernel or an AVX2 one that give
// the same bits; it skips tiles whose least bound is at least the
// occluder's largest. Tests read tiles first: a tile whose least bound is
// above the occludee's hides it there, one whose largest is not does not;
// pixels are read only in a tile that cannot decide.
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "frustum.h"
#include "numeric.h"

namespace voxvis::detail {

/// Relative allowance taken off every written bound: far above the rounding
/// of the plane depths, far below any distance that matters.
inline constexpr double kDepthSlack = 1e-7;

/// Deliberate violations of the rules above, for the tests that show the ray
/// caster catches a buffer that is not conservative. Never set by the engine.
enum class BufferFault : std::uint8_t {
  None,
  NearDepth,      ///< Occluders write their nearest depth over the pixel instead of the farthest.
  OuterCoverage,  ///< Occluders write every pixel a corner ray may hit.
};

/// Which tile kernel the rasterizer runs (occlusion_tile.h).
enum class BufferKernel : std::uint8_t {
  Auto,    ///< AVX2 where the CPU has it, else the scalar reference.
  Scalar,  ///< The scalar reference (the tests compare the two).
};

/// An affine function of the pixel coordinates: c + gx * X + gy * Y.
struct PixelAffine {
  double c = 0.0, gx = 0.0, gy = 0.0;
};

/// A convex occluder in image space, ready to rasterize (see above).
struct ConvexOccluder {
  static constexpr int kMaxEdges = 32;
  static constexpr int kMaxPlanes = 3;
  int edges = 0;
  PixelAffine edge[kMaxEdges];   ///< Rays meeting the occluder: every edge >= 0.
  int planes = 0;
  PixelAffine plane[kMaxPlanes]; ///< Reciprocal entry depth: the least of these.
  double w_cap = 0.0;            ///< No bound above this (1 / near for a shape crossing it); 0: none.
  double w_max = 0.0;            ///< The occluder's largest reciprocal depth (1 / its nearest depth).
  double slack = 1.0;            ///< Factor (< 1) every written bound is multiplied by.
  int i0 = 0, i1 = -1, j0 = 0, j1 = -1;  ///< Pixel rectangle that may be written.
};

/// An occludee's largest reciprocal depth over a pixel rectangle, from the
/// entry planes of a box around it (OcclusionBuffer::hides): the least, over
/// the planes, of a plane's largest value over the rectangle's corners,
/// raised by an allowance for the rounding of the evaluation. The planes are
/// derived only when a test first needs them.
struct OccludeeDepth {
  OccludeeDepth(const Vec3& rel_, const Vec3& size_, double tol_) : rel(rel_), size(size_), tol(tol_) {}

  Vec3 rel, size;  ///< The box: least corner relative to the eye, extents.
  double tol;      ///< Their error, world units.
  int planes = -1; ///< -1: not derived yet.
  PixelAffine plane[3];
  double margin[3] = {0.0, 0.0, 0.0};

  void add(const PixelAffine& p, int w, int h) {
    plane[planes] = p;
    margin[planes] = 1e-9 * (std::fabs(p.c) + std::fabs(p.gx) * w + std::fabs(p.gy) * h);
    ++planes;
  }
  /// Plane k's largest value over pixels [i0, i1] x [j0, j1] (closed squares).
  double max_over(int k, int i0, int i1, int j0, int j1) const {
    const PixelAffine& p = plane[k];
    const double X = p.gx > 0.0 ? i1 + 1.0 : static_cast<double>(i0);
    const double Y = p.gy > 0.0 ? j1 + 1.0 : static_cast<double>(j0);
    return p.c + p.gx * X + p.gy * Y + margin[k];
  }
  /// The least of w and every plane's largest value over the rectangle.
  double bound(double w, int i0, int i1, int j0, int j1) const {
    for (int k = 0; k < planes; ++k) w = least(w, max_over(k, i0, i1, j0, j1));
    return w;
  }
};

class OcclusionBuffer {
 public:
  static constexpr int kMaxSide = 4096;

  /// Starts a frame over the image of `wf` with `width` columns (0: off) and
  /// rows from the aspect (square pixels), at most kMaxSide.
  void begin(const WorldFrustum& wf, int width);
  void end() { on_ = false; }
  bool on() const { return on_; }
  const Vec3& eye() const { return eye_; }
  int width() const { return on_ ? w_ : 0; }
  int height() const { return on_ ? h_ : 0; }

  /// Renders a sphere or a box (world units) as an occluder. Returns whether
  /// it raised any pixel's bound.
  bool render_sphere(const Vec3& center, double radius);
  bool render_box(const Vec3& lo, const Vec3& hi);
  /// Renders the box of half extents `half` about `center` along the unit,
  /// orthogonal `axes` (world units) as an occluder, as render_box does an
  /// axis-aligned one (the slab test in the box's frame: a ray's coordinate
  /// along an axis is linear in it). `err` bounds the error of the centre
  /// and the half extents (world units).
  bool render_oriented_box(const Vec3& center, const Vec3 axes[3], const Vec3& half, double err = 0.0);
  /// Whether every triangle within the ball (world units) is one
  /// render_triangle would drop as under 1.5 pixels across: its vertices are
  /// at most 2 radius apart per axis, at depths of at least the ball's
  /// nearest. So a mesh far enough away costs no vertex placed.
  bool ball_below_a_pixel(const Vec3& center, double radius) const;
  /// Renders a triangle (world units) as an occluder: the part of it
  /// beyond the near plane, a planar convex polygon of at most four
  /// vertices, shrunk by its rounding allowance, at its plane's depth
  /// (occlusion_triangle.cpp). Slivers too thin to trust and triangles seen
  /// edge-on write nothing. `err` (world units) bounds how far each given
  /// vertex may lie from the true one (a mesh's placement rounding).
  bool render_triangle(const Vec3& a, const Vec3& b, const Vec3& c, double err = 0.0);
  /// Renders two triangles sharing a side, (q0, q1, q3) and (q1, q2, q3),
  /// as one convex occluder when the quad q0..q3 lies wholly beyond the near
  /// plane and its image is convex (at the farther of the two planes along
  /// each ray). False when it is not (then draw the triangles); `raised`:
  /// whether it raised a bound. `err` as for render_triangle.
  bool render_quad(const Vec3 q[4], double err, bool* raised);

  /// Whether the axis-aligned box with least corner eye + rel and extents
  /// `size` (world units) is hidden. `tol` bounds the error of `rel` and
  /// `size` (world units).
  /// `fine`: over each pixel at the box's own depth there (its entry
  /// planes; see "Tests" above), else at its least depth everywhere: fine
  /// hides more of a large box or one seen at a slant, at some cost.
  bool hides(const Vec3& rel, const Vec3& size, double tol, bool fine = false) const;
  /// The same for a world box.
  bool hides_world(const Vec3& lo, const Vec3& hi, bool fine = false) const;
  /// The same, fine, and when the box is not proved hidden whole, its
  /// halves (along its longest side) tested the same way, to `levels`
  /// levels: the box is hidden when every piece is, a piece wholly outside
  /// the frustum counting as hidden (no ray of the frame reaches it). For
  /// large boxes, whose rectangle reaches far beyond what hides them.
  bool hides_world_split(const Vec3& lo, const Vec3& hi, int levels) const;
  /// Whether the ball of `radius` around `center` (world units) is hidden:
  /// tested over the pixels of its own image rectangle, at its nearest depth,
  /// so tighter than its bounding box.
  bool hides_sphere(const Vec3& center, double radius, bool fine = false) const;

  /// The largest depth bound over the whole image: every ray of the frustum
  /// meets an occluder beyond the near plane no deeper than this; +inf while
  /// any pixel is empty. Everything deeper is hidden (the traversal's early
  /// end).
  double farthest_bound() const;

  /// The depth bound of pixel (i, j), +inf when empty (for tests).
  float pixel(int i, int j) const;
  /// Pixel bounds raised this frame (a count of writes, for the counters).
  std::uint64_t writes() const { return written_; }

  BufferFault fault = BufferFault::None;
  BufferKernel kernel = BufferKernel::Auto;

 private:
  /// Pixel rectangle [i0, i1] x [j0, j1] (clamped) from the image range of a
  /// shape; false when it misses the image.
  bool rect(double x0, double x1, double y0, double y1, int* i0, int* i1, int* j0, int* j1) const;
  /// Image range [x0, x1] x [y0, y1] of the ball (center - eye = w), false
  /// when the ball reaches the eye's plane.
  bool sphere_range(const Vec3& w, double radius, double* x0, double* x1, double* y0, double* y1) const;
  /// Whether every pixel of [i0..i1] x [j0..j1] holds a bound above w
  /// (near / depth) and above the occludee's `depth` over that pixel.
  bool rect_hidden(int i0, int i1, int j0, int j1, double w, OccludeeDepth* depth) const;
  /// rect_hidden's step for tile t (first pixel (I0, J0)), whose least
  /// bound is not above w: whether its pixels in the rectangle hide the
  /// occludee.
  bool tile_hides(std::size_t t, int I0, int J0, int i0, int i1, int j0, int j1, double w, OccludeeDepth* depth) const;
  /// Derives the entry planes of the box of `depth` if not done yet: over
  /// a pixel, no point of the box lies nearer than every plane's bound there
  /// allows.
  void entry_planes(OccludeeDepth* depth) const;
  /// The affine function of the pixel coordinates equal to n·d.
  PixelAffine linear(const Vec3& n) const;
  /// Adds the constraint that a planar convex polygon (vertices relative to
  /// the eye, in order, at most 24) is met: one edge function per side.
  /// False (the occluder must not be drawn) when a side defines no plane.
  bool polygon_edges(const Vec3* v, int n, ConvexOccluder* occ) const;
  /// Whether the shape of vertices v[0..n) (relative to the eye, wholly
  /// beyond the near plane) is so small in the image, at its nearest depth
  /// and the image's centre, that it is not worth drawing (under 1.5
  /// pixels across).
  bool below_a_pixel(const Vec3* v, int n) const;
  /// Fills the convex polygon q[0..nq) (relative to the eye, beyond the near
  /// plane, every ray within its sides meeting the occluder) at the least of
  /// the reciprocal depths `planes`, whose relative error is `depth_err`;
  /// shrunk first by the rounding allowance (`err`: the vertices' own
  /// error, world units; `mag`: the magnitude of the coordinates).
  bool fill_polygon(Vec3* q, int nq, const PixelAffine* planes, int np, double depth_err, double mag, double err);
  /// Renders the box {p : L <= axes[a]·(p - eye) <= H} (shrunk by its
  /// allowance already; gl, gh: grown by it, for the eye-inside test);
  /// `mag`: the magnitude of the coordinates.
  bool render_box_frame(const Vec3 axes[3], const Vec3& L, const Vec3& H, const Vec3& gl, const Vec3& gh, double mag);
  /// Renders a disc (centre relative to the eye, unit normal, radius) as an
  /// inscribed polygon at its plane's depth; w_max and slack as in
  /// ConvexOccluder.
  bool render_disc(const Vec3& centre, const Vec3& normal, double rho, double w_max, double slack);
  /// Renders a disc that faces the eye (centre relative to the eye, the
  /// disc's normal along it) as render_disc does, its edges from the disc's
  /// frame instead of its vertices (docs/design.md, "The rasterizer"), over
  /// pixels within the image range [x0, x1] x [y0, y1] (a ball around the
  /// disc). The disc must lie beyond the near plane, as render_sphere's
  /// discs do (their ball does).
  bool render_facing_disc(const Vec3& centre, double rho, double w_max, double slack, double x0, double x1,
                          double y0, double y1);
  /// Pixels across the image of a disc (centre relative to the eye,
  /// radius), at its nearest depth: an overestimate.
  double disc_pixels(const Vec3& centre, double rho) const;
  /// Fills a disc's polygon (its edges set) at the depth of the plane
  /// {n·p = den} given as n / den; w_max and slack as in ConvexOccluder.
  bool fill_disc(ConvexOccluder* occ, const Vec3& plane, double w_max, double slack);
  /// Rasterizes the occluder (occlusion_fill.cpp); whether a bound was raised.
  bool fill(const ConvexOccluder& occ);
  /// Index of pixel (i, j) in px_.
  std::size_t at(int i, int j) const;
  /// Zeroes the pixels the last frame wrote and their tiles' bounds.
  void clear_written();

  WorldFrustum view_;
  Vec3 eye_{0.0}, f_{0.0}, r_{0.0}, u_{0.0};
  Vec3 d0_{0.0}, dx_{0.0}, dy_{0.0};  ///< d(X, Y) = d0 + X dx + Y dy.
  double tan_x_ = 1.0, tan_y_ = 1.0, near_ = 0.0;
  double inv_tan_x_ = 1.0, inv_tan_y_ = 1.0;
  bool on_ = false;  ///< Between begin (with a width) and end.
  /// The image's size, kept after end so that the next frame of the same
  /// size clears only what was written instead of the whole buffer.
  int w_ = 0, h_ = 0, tw_ = 0, th_ = 0;
  std::uint64_t written_ = 0;  ///< Pixel bounds raised this frame.
  /// Reciprocal depth bounds, tile by tile (tw_ x th_ tiles of 8x4 pixels,
  /// occlusion_tile.h), row-major within a tile.
  std::vector<float> px_;
  std::vector<float> tile_min_, tile_max_;  ///< Least and largest bound of each tile.
  /// Every tile before this one holds a bound above 0 (a tile's least
  /// bound only rises within a frame), so farthest_bound() looks for a tile
  /// still at 0 from here on: each tile is passed once a frame.
  mutable std::size_t covered_tiles_ = 0;
  /// Tiles written this frame (listed once each), so that a frame clears
  /// only what the previous one wrote.
  std::vector<std::uint32_t> written_tiles_;
  std::vector<std::uint8_t> tile_written_;
};

}  // namespace voxvis::detail
