// occlusion_tile.h — the rasterizer's inner step: one tile of 8 x 4 pixels
// of the occlusion buffer raised by one convex occluder, in two kernels that
// give the same bits: a scalar reference and an AVX2 one (a row of 8 pixels
// to an instruction). OcclusionBuffer::fill (occlusion_fill.cpp) decides per
// tile in double precision which edges pass the whole tile and hands the
// kernel the rest, and the depth planes, as single-precision functions
// re-centred on the tile and lowered by their rounding allowance there: a
// value the kernel computes is never above the exact one (the argument is in
// occlusion_fill.cpp).
//
// A tile's 32 bounds are stored together, row by row (pixel (di, dj) of the
// tile at index 8 dj + di), so that a kernel reads and writes a row with one
// load and one store.
#pragma once

#include <cstdint>

#include "numeric.h"  // cpu_has_avx2

namespace voxvis::detail {

inline constexpr int kTileW = 8;
inline constexpr int kTileH = 4;
inline constexpr int kTilePixels = kTileW * kTileH;

/// An affine function over one tile in single precision: at the tile's
/// pixel (di, dj), (at + row[dj]) + col[di], summed in that order by both
/// kernels (no fused operation: the engine is built with -ffp-contract=off).
struct TileAffine {
  float at;
  const float* row;  ///< kTileH offsets.
  const float* col;  ///< kTileW offsets.
};

/// What one occluder writes into one tile. Only the first `edges` and
/// `planes` entries are read.
struct TileJob {
  static constexpr int kMaxEdges = 32;
  static constexpr int kMaxPlanes = 3;
  int edges = 0;  ///< Edges that do not pass the whole tile: a pixel needs each >= 0.
  TileAffine edge[kMaxEdges];
  int planes = 0;  ///< At least one: the bound is the least of them.
  TileAffine plane[kMaxPlanes];
  float cap = 0.0f;        ///< No bound above this.
  int c0 = 0, c1 = -1;     ///< Columns of the tile that may be written (inclusive).
  int r0 = 0, r1 = -1;     ///< Rows of the tile that may be written (inclusive).
};

/// Bounds raised, and the least and largest bound of the tile's 32 after.
struct TileResult {
  int raised = 0;
  float min = 0.0f, max = 0.0f;
};

/// The least and the largest of v[0..n), n >= 1, into *lo and *hi.
inline void least_and_largest(const float* v, int n, float* lo, float* hi) {
  float l = v[0], h = v[0];
  for (int k = 1; k < n; ++k) {
    l = v[k] < l ? v[k] : l;
    h = v[k] > h ? v[k] : h;
  }
  *lo = l;
  *hi = h;
}

/// Raises each pixel of the tile within [c0, c1] x [r0, r1] whose edges are
/// all >= 0 to the least of the planes and the cap (never below 0) where
/// that is larger. A NaN raises nothing.
TileResult raster_tile_scalar(float* tile, const TileJob& job);
/// The same with AVX2; call only where cpu_has_avx2().
TileResult raster_tile_avx2(float* tile, const TileJob& job);
/// Whether every pixel of the tile within [c0, c1] x [r0, r1] holds a bound
/// above w (the occludee test's inner step).
bool tile_above_scalar(const float* tile, int c0, int c1, int r0, int r1, float w);
/// The same with AVX2; call only where cpu_has_avx2().
bool tile_above_avx2(const float* tile, int c0, int c1, int r0, int r1, float w);

}  // namespace voxvis::detail
