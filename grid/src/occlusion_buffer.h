// occlusion_buffer.h — a conservative depth buffer in image space, per frame
// and per viewer (owned by the worker's Scratch), with a lazily updated grid
// of tiles over it (Hey et al., "lazy occlusion grid").
//
// Image and depth. A ray of the frame's camera is r(t) = eye + t*d with
// d = f + x*tan_x*r + y*tan_y*u, x, y in [-1, 1]; since d·f = 1, t is the
// depth of the ray's points along the view direction (the metric of the near
// and far planes). The image [-1, 1]^2 is cut into W x H closed pixels.
//
// Occluders (inner coverage, farthest first hit). A convex occluder K wholly
// beyond the near plane writes bound D into a pixel only when the rays
// through all four corners of the pixel hit K, and D is the largest of their
// entry depths (plus a rounding allowance). Why every ray through the pixel
// then hits K at a depth <= D: the rays meeting K form the cone over K, which
// is convex, so the pixel's square lies in it when its corners do; and the
// set of image points whose entry depth is <= tau is the central projection
// of K ∩ {depth <= tau}, which is convex, so the entry depth is quasiconvex
// over the square and its largest value is taken at a corner. The hit tests
// use K shrunk by an allowance, so a rounding error can only drop a pixel.
//
// Tests (outer coverage, nearest depth). A box is hidden when it lies wholly
// beyond the near plane and every pixel that its projection may touch (the
// bounding rectangle of its corners' projections, widened by an allowance)
// holds a bound D smaller than the box's least depth. Every ray to a point p
// of the box then passes through such a pixel and enters an occluder beyond
// the near plane at a depth < depth(p): p is not the first hit, so p is
// hidden in the sense of the ray caster (tests/support/raycast.h).
//
// Tiles. Each 8x8 tile keeps the largest bound of its pixels (+inf where any
// pixel is empty), recomputed only when a test reads a tile that occluders
// wrote since (the bounds only decrease, so a stale maximum is still an
// upper bound). A tile nothing was written to this frame is empty and costs
// nothing to clear. An occluder skips every tile whose largest bound is no
// farther than its own nearest depth: it could not lower any pixel there.
#pragma once

#include <cstdint>
#include <vector>

#include "frustum.h"

namespace voxvis::detail {

/// Deliberate violations of the rules above, for the tests that show the ray
/// caster catches a buffer that is not conservative. Never set by the engine.
enum class BufferFault : std::uint8_t {
  None,
  NearDepth,      ///< Occluders write their nearest depth instead of the farthest first hit.
  OuterCoverage,  ///< Occluders write every pixel one corner ray hits.
};

class OcclusionBuffer {
 public:
  static constexpr int kTile = 8;
  static constexpr int kMaxSide = 4096;

  /// Starts a frame over the image of `wf` with `width` columns (0: off) and
  /// rows from the aspect (square pixels), at most kMaxSide.
  void begin(const WorldFrustum& wf, int width);
  void end() { w_ = 0; }
  bool on() const { return w_ > 0; }
  int width() const { return w_; }
  int height() const { return h_; }

  /// Renders a sphere or a box (world units) as an occluder. Returns whether
  /// it wrote any pixel.
  bool render_sphere(const Vec3& center, double radius);
  bool render_box(const Vec3& lo, const Vec3& hi);

  /// Whether the axis-aligned box with least corner eye + rel and extents
  /// `size` (world units) is hidden. `tol` bounds the error of `rel` and
  /// `size` (world units).
  bool hides(const Vec3& rel, const Vec3& size, double tol) const;
  /// The same for a world box.
  bool hides_world(const Vec3& lo, const Vec3& hi) const;
  /// Whether the ball of `radius` around `center` (world units) is hidden:
  /// tested over the pixels of its own image rectangle, at its nearest depth,
  /// so tighter than its bounding box.
  bool hides_sphere(const Vec3& center, double radius) const;

  /// The bound of pixel (i, j), +inf when empty (for tests).
  float pixel(int i, int j) const;

  BufferFault fault = BufferFault::None;

 private:
  void write(int i, int j, double d);
  /// Pixel rectangle [i0, i1] x [j0, j1] (clamped) from the image range of a
  /// shape; false when it misses the image.
  bool rect(double x0, double x1, double y0, double y1, int* i0, int* i1, int* j0, int* j1) const;
  /// Image range [x0, x1] x [y0, y1] of the ball (center - eye = w), false
  /// when the ball reaches the eye's plane.
  bool sphere_range(const Vec3& w, double radius, double* x0, double* x1, double* y0, double* y1) const;
  /// Whether every pixel of [i0..i1] x [j0..j1] holds a bound below zmin.
  bool rect_hidden(int i0, int i1, int j0, int j1, double zmin) const;
  /// Writes the pixels of [i0..i1] x [j0..j1] from their corners' entry
  /// depths, `entry(dir, &t)` false for a miss; `nearest` bounds the
  /// occluder's depth from below, and `least(dirs)` over the square of
  /// the four corner rays `dirs` (0 when the shape cannot tell): tiles
  /// already nearer are skipped.
  template <class Entry, class Least>
  bool fill(int i0, int i1, int j0, int j1, double nearest, Entry&& entry, Least&& least);
  /// The same within one tile.
  template <class Entry>
  bool fill_tile(int i0, int i1, int j0, int j1, double nearest, Entry& entry);
  /// Largest bound of tile t (written this frame), refreshed when stale.
  float tile_max(std::size_t t) const;

  Vec3 eye_{0.0}, f_{0.0}, r_{0.0}, u_{0.0};
  double tan_x_ = 1.0, tan_y_ = 1.0, near_ = 0.0;
  int w_ = 0, h_ = 0, tw_ = 0, th_ = 0;
  std::uint32_t frame_ = 0;
  std::uint64_t written_ = 0;  ///< Pixels written this frame.
  std::vector<float> px_;      ///< Row-major by tile: tile (ti, tj) holds 64 floats.
  std::vector<std::uint32_t> tile_frame_;  ///< Frame the tile was cleared in.
  mutable std::vector<float> tile_max_;
  mutable std::vector<std::uint8_t> tile_dirty_;
};

}  // namespace voxvis::detail
