// occlusion_tile.cpp — the two tile kernels (see occlusion_tile.h). They
// perform the same single-precision operations in the same order, so they
// write the same bits; the tests run both on the same occluders and compare.
#include "occlusion_tile.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define VOXVIS_TILE_AVX2 1
#include <immintrin.h>
#endif

namespace voxvis::detail {
namespace {

// The kernels' minimum and maximum, written as the AVX2 instructions
// compute them (vminps returns its second operand when either is NaN).
inline float min_op(float a, float b) { return a < b ? a : b; }
inline float max_op(float a, float b) { return a > b ? a : b; }

}  // namespace

TileResult raster_tile_scalar(float* tile, const TileJob& job) {
  TileResult res;
  for (int dj = job.r0; dj <= job.r1; ++dj) {
    float* row = tile + dj * kTileW;
    for (int di = job.c0; di <= job.c1; ++di) {
      bool in = true;
      for (int k = 0; k < job.edges; ++k) {
        const TileAffine& e = job.edge[k];
        in &= (e.at + e.row[dj]) + e.col[di] >= 0.0f;
      }
      float w = (job.plane[0].at + job.plane[0].row[dj]) + job.plane[0].col[di];
      for (int k = 1; k < job.planes; ++k) {
        const TileAffine& p = job.plane[k];
        w = min_op(w, (p.at + p.row[dj]) + p.col[di]);
      }
      w = max_op(min_op(w, job.cap), 0.0f);
      if (in && w > row[di]) {
        row[di] = w;
        ++res.raised;
      }
    }
  }
  least_and_largest(tile, kTilePixels, &res.min, &res.max);
  return res;
}

bool tile_above_scalar(const float* tile, int c0, int c1, int r0, int r1, float w) {
  bool above = true;
  for (int dj = r0; dj <= r1; ++dj)
    for (int di = c0; di <= c1; ++di) above &= tile[dj * kTileW + di] > w;
  return above;
}

#if VOXVIS_TILE_AVX2

__attribute__((target("avx2"))) bool tile_above_avx2(const float* tile, int c0, int c1, int r0, int r1, float w) {
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256 cols = _mm256_castsi256_ps(
      _mm256_and_si256(_mm256_cmpgt_epi32(lane, _mm256_set1_epi32(c0 - 1)), _mm256_cmpgt_epi32(_mm256_set1_epi32(c1 + 1), lane)));
  const __m256 wv = _mm256_set1_ps(w);
  __m256 below = _mm256_setzero_ps();
  for (int dj = r0; dj <= r1; ++dj)
    below = _mm256_or_ps(below, _mm256_cmp_ps(_mm256_loadu_ps(tile + dj * kTileW), wv, _CMP_NGT_UQ));
  return _mm256_testz_ps(below, cols) != 0;
}

__attribute__((target("avx2"))) TileResult raster_tile_avx2(float* tile, const TileJob& job) {
  TileResult res;
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256 cols = _mm256_castsi256_ps(_mm256_and_si256(_mm256_cmpgt_epi32(lane, _mm256_set1_epi32(job.c0 - 1)),
                                                           _mm256_cmpgt_epi32(_mm256_set1_epi32(job.c1 + 1), lane)));
  const __m256 zero = _mm256_setzero_ps(), cap = _mm256_set1_ps(job.cap);
  for (int dj = job.r0; dj <= job.r1; ++dj) {
    __m256 in = cols;
    for (int k = 0; k < job.edges; ++k) {
      const TileAffine& e = job.edge[k];
      const __m256 v = _mm256_add_ps(_mm256_set1_ps(e.at + e.row[dj]), _mm256_loadu_ps(e.col));
      in = _mm256_and_ps(in, _mm256_cmp_ps(v, zero, _CMP_GE_OQ));
    }
    const TileAffine& p0 = job.plane[0];
    __m256 w = _mm256_add_ps(_mm256_set1_ps(p0.at + p0.row[dj]), _mm256_loadu_ps(p0.col));
    for (int k = 1; k < job.planes; ++k) {
      const TileAffine& p = job.plane[k];
      w = _mm256_min_ps(w, _mm256_add_ps(_mm256_set1_ps(p.at + p.row[dj]), _mm256_loadu_ps(p.col)));
    }
    w = _mm256_max_ps(_mm256_min_ps(w, cap), zero);
    float* row = tile + dj * kTileW;
    const __m256 old = _mm256_loadu_ps(row);
    const __m256 up = _mm256_and_ps(in, _mm256_cmp_ps(w, old, _CMP_GT_OQ));
    _mm256_storeu_ps(row, _mm256_blendv_ps(old, w, up));
    res.raised += __builtin_popcount(static_cast<unsigned>(_mm256_movemask_ps(up)));
  }
  __m256 lo = _mm256_loadu_ps(tile), hi = lo;
  for (int dj = 1; dj < kTileH; ++dj) {
    const __m256 r = _mm256_loadu_ps(tile + dj * kTileW);
    lo = _mm256_min_ps(lo, r);
    hi = _mm256_max_ps(hi, r);
  }
  // Across the eight lanes: halves, then pairs, then neighbours. The bounds
  // are never NaN or -0 (a bound is 0 or a value that compared above it), so
  // the order of the comparisons does not change the result.
  lo = _mm256_min_ps(lo, _mm256_permute2f128_ps(lo, lo, 1));
  hi = _mm256_max_ps(hi, _mm256_permute2f128_ps(hi, hi, 1));
  lo = _mm256_min_ps(lo, _mm256_shuffle_ps(lo, lo, 0x4E));
  hi = _mm256_max_ps(hi, _mm256_shuffle_ps(hi, hi, 0x4E));
  lo = _mm256_min_ps(lo, _mm256_shuffle_ps(lo, lo, 0xB1));
  hi = _mm256_max_ps(hi, _mm256_shuffle_ps(hi, hi, 0xB1));
  res.min = _mm256_cvtss_f32(lo);
  res.max = _mm256_cvtss_f32(hi);
  return res;
}

#else

TileResult raster_tile_avx2(float* tile, const TileJob& job) { return raster_tile_scalar(tile, job); }
bool tile_above_avx2(const float* tile, int c0, int c1, int r0, int r1, float w) {
  return tile_above_scalar(tile, c0, c1, r0, r1, w);
}

#endif

}  // namespace voxvis::detail
