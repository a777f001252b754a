// occlusion_fill.cpp — the rasterizer: a convex occluder written into the
// occlusion buffer a tile of 8 x 4 pixels at a time (after Intel's Masked
// Occlusion Culling), keeping the rules of occlusion_buffer.h: a pixel is
// written only when every edge's value at the pixel's worst corner is >= 0
// (inner coverage), with the least of the depth planes at the pixel's worst
// corner (the farthest first hit), lowered by the occluder's slack.
//
// Per occluder, in double precision: each edge and plane taken to its worst
// corner (the value at pixel (i, j) is c + gx i + gy j), each edge divided by
// its magnitude over the image (so its values lie within [-1, 1] and fit a
// float), each plane multiplied by near * slack.
//
// Per tile, in double precision: each edge's and plane's value at the tile's
// first pixel Et and its least and largest over the tile (four edges, or the
// planes, to an AVX2 instruction, or one at a time in the scalar reference:
// the same values, the same decisions). An edge below zero over the whole
// tile leaves the tile alone; one at or above its rounding allowance over
// the whole tile needs no test per pixel; the others go to the kernel. A
// tile whose least bound is already at least the occluder's largest, or at
// least the planes' largest over the tile, is skipped (skipping only ever
// writes less).
//
// Per pixel, in single precision (occlusion_tile.h), re-centred on the tile:
// f = fl(fl(fl(Et - m) + fl(fl(gy) dj)) + fl(fl(gx) di)), di < 8, dj < 4.
// Each of the five roundings is at most u = 2^-24 of its operand, and every
// operand is at most M = |Et| + m + 8|gx| + 4|gy| in magnitude, so
// |f - (E - m)| <= 5.1 u M + (denormals) 5 * 2^-149. With
// m = 2^-20 (|Et| + 8|gx| + 4|gy|) + 1e-30 = 16 u (M - m) + 1e-30, that is
// below m: f <= E, so f >= 0 only where the exact edge is >= 0, and a plane's
// f is never above its exact bound. The double-precision Et is itself off by
// a few eps of the function's magnitude over the image, which the edges'
// margin (occlusion_buffer.cpp: 1e-12 of it) covers and the planes' margin
// adds. Planes whose values over a tile exceed 1e30 would overflow a float:
// such a tile is skipped (a depth far inside the near plane; only ever writes
// less). Edges, normalized, never come near.
#include <cmath>
#include <limits>

#include "numeric.h"
#include "occlusion_buffer.h"
#include "occlusion_tile.h"
#include "voxvis/assert.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define VOXVIS_FILL_AVX2 1
#include <immintrin.h>
#endif

namespace voxvis::detail {
namespace {

constexpr double kMaxDouble = std::numeric_limits<double>::max();
constexpr double kEps = std::numeric_limits<double>::epsilon();
/// The single-precision allowance per unit of magnitude: 16 u, u = 2^-24.
constexpr double kFloatAllowance = 0x1p-20;
/// Plane values beyond this over a tile could overflow a float.
constexpr double kPlaneLimit = 1e30;

/// One affine function of the pixel indices, c + gx i + gy j, in double,
/// with its per-tile offsets in float and what a tile's set-up needs of it.
/// (No initializers: fill makes one of these per edge of every occluder, and
/// set() writes every member.)
struct TiledAffine {
  double c, gx, gy;
  double down, up;  ///< Least and largest change from a tile's first pixel over the tile.
  double m0;        ///< The allowance but for its part in the value: m = kFloatAllowance |a| + m0.
  float row[kTileH], col[kTileW];

  void set(double c_, double gx_, double gy_) {
    c = c_, gx = gx_, gy = gy_;
    const double dx = gx * (kTileW - 1), dy = gy * (kTileH - 1);
    down = (dx < 0.0 ? dx : 0.0) + (dy < 0.0 ? dy : 0.0);
    up = (dx > 0.0 ? dx : 0.0) + (dy > 0.0 ? dy : 0.0);
    m0 = kFloatAllowance * (kTileW * std::fabs(gx) + kTileH * std::fabs(gy)) + 1e-30;
    const float fx = static_cast<float>(gx), fy = static_cast<float>(gy);
    for (int k = 0; k < kTileW; ++k) col[k] = fx * static_cast<float>(k);
    for (int k = 0; k < kTileH; ++k) row[k] = fy * static_cast<float>(k);
  }
};

/// What fill derives once per occluder (setup_fill writes the first `edges`
/// and `planes` entries; the rest stay unwritten and unread).
struct FillSetup {
  static constexpr int kLanes = 4;  ///< Doubles to an AVX2 register.
  int edges, planes;
  TiledAffine edge[ConvexOccluder::kMaxEdges];
  /// The edges again, by field, padded to a multiple of kLanes with edges
  /// that pass every tile (c = 1, nothing else): what a tile's edge test
  /// reads, four at a time.
  int lanes;
  alignas(32) double ec[ConvexOccluder::kMaxEdges], egx[ConvexOccluder::kMaxEdges], egy[ConvexOccluder::kMaxEdges];
  alignas(32) double eup[ConvexOccluder::kMaxEdges], edown[ConvexOccluder::kMaxEdges], em0[ConvexOccluder::kMaxEdges];
  TiledAffine plane[ConvexOccluder::kMaxPlanes];
  /// The planes again, by field, padded to kLanes with planes that are 0
  /// everywhere and rise without bound over a tile (up = infinity), so that
  /// they bound nothing: what a tile's plane step reads, four at a time.
  /// peps: 8 eps of the plane's largest coefficient (the double evaluation
  /// at pixel (i, j) is off by less than peps (1 + i + j)).
  static_assert(ConvexOccluder::kMaxPlanes <= kLanes);
  alignas(32) double pc[kLanes], pgx[kLanes], pgy[kLanes], pup[kLanes], pm0[kLanes], peps[kLanes];
  float cap;
};

/// The largest float not above d (d >= 0).
float float_down(double d) {
  if (!(d > 0.0)) return 0.0f;
  if (d >= static_cast<double>(std::numeric_limits<float>::max())) return std::numeric_limits<float>::max();
  float f = static_cast<float>(d);
  if (static_cast<double>(f) > d) f = std::nextafter(f, 0.0f);
  return f;
}

/// The occluder's edges and planes at each pixel's worst corner (see the
/// file's comment); false when an edge is not finite or vanishes (nothing is
/// drawn then).
bool setup_fill(const ConvexOccluder& occ, BufferFault fault, double near, int w, int h, FillSetup* s) {
  const double sgn = fault == BufferFault::OuterCoverage ? 1.0 : -1.0;
  const double dsgn = fault == BufferFault::NearDepth ? 1.0 : -1.0;
  s->edges = occ.edges;
  for (int k = 0; k < occ.edges; ++k) {
    const PixelAffine& e = occ.edge[k];
    if (!(std::fabs(e.c) <= kMaxDouble && std::fabs(e.gx) <= kMaxDouble && std::fabs(e.gy) <= kMaxDouble))
      return false;
    const double mag = std::fabs(e.c) + std::fabs(e.gx) * w + std::fabs(e.gy) * h;
    // At pixel (i, j) the corner of least value: the centre (i + 0.5,
    // j + 0.5) less half the two slopes' magnitudes, less the rounding
    // margin of the double-precision evaluation.
    const double c = e.c + 0.5 * (e.gx + e.gy) + sgn * 0.5 * (std::fabs(e.gx) + std::fabs(e.gy)) - 1e-12 * mag - 1e-300;
    const double n = 1.0 / (std::fabs(c) + std::fabs(e.gx) * w + std::fabs(e.gy) * h);
    if (!(n > 0.0) || !std::isfinite(n)) return false;
    TiledAffine& t = s->edge[k];
    t.set(c * n, e.gx * n, e.gy * n);
    s->ec[k] = t.c, s->egx[k] = t.gx, s->egy[k] = t.gy, s->eup[k] = t.up, s->edown[k] = t.down, s->em0[k] = t.m0;
  }
  s->lanes = (occ.edges + FillSetup::kLanes - 1) / FillSetup::kLanes * FillSetup::kLanes;
  for (int k = occ.edges; k < s->lanes; ++k) s->ec[k] = 1.0, s->egx[k] = s->egy[k] = s->eup[k] = s->edown[k] = s->em0[k] = 0.0;
  const double scale = occ.slack * near;
  s->planes = occ.planes;
  for (int k = 0; k < occ.planes; ++k) {
    const PixelAffine& p = occ.plane[k];
    const double c = p.c + 0.5 * (p.gx + p.gy) + dsgn * 0.5 * (std::fabs(p.gx) + std::fabs(p.gy));
    TiledAffine& t = s->plane[k];
    t.set(c * scale, p.gx * scale, p.gy * scale);
    const double big = std::fabs(t.c) > std::fabs(t.gx) ? std::fabs(t.c) : std::fabs(t.gx);
    s->peps[k] = 8.0 * kEps * (big > std::fabs(t.gy) ? big : std::fabs(t.gy));
    // A plane whose values reach past the limit anywhere in the image is
    // caught per tile; its coefficients must be finite for that.
    if (!std::isfinite(big + std::fabs(t.gy))) return false;
    s->pc[k] = t.c, s->pgx[k] = t.gx, s->pgy[k] = t.gy, s->pup[k] = t.up, s->pm0[k] = t.m0;
  }
  // The padding, written out (a loop here became six calls to memset).
  const auto pad = [s](int k) {
    s->pc[k] = s->pgx[k] = s->pgy[k] = s->pm0[k] = s->peps[k] = 0.0;
    s->pup[k] = std::numeric_limits<double>::infinity();
  };
  static_assert(FillSetup::kLanes == 4);
  if (occ.planes < 2) pad(1);
  if (occ.planes < 3) pad(2);
  pad(3);
  s->cap = occ.w_cap > 0.0 ? float_down(occ.w_cap * scale) : std::numeric_limits<float>::infinity();
  return true;
}

/// The edges at the tile whose first pixel is (I0, J0): each edge's value v
/// there less its single-precision allowance m = 2^-20 |v| + m0, as the
/// float the kernel starts from, into at[k], and a bit in *partial for each
/// edge that does not pass the whole tile; false when an edge is below zero
/// over the whole tile. Both versions compute the same values
/// (v = (c + gx I0) + gy J0) and decide alike.
bool edge_test_scalar(const FillSetup& s, int I0, int J0, float* at, std::uint32_t* partial) {
  std::uint32_t part = 0;
  for (int k = 0; k < s.edges; ++k) {
    const double v = s.ec[k] + s.egx[k] * I0 + s.egy[k] * J0;
    if (v + s.eup[k] < 0.0) return false;
    const double m = kFloatAllowance * std::fabs(v) + s.em0[k];
    if (!(v + s.edown[k] >= m)) part |= 1u << k;
    at[k] = static_cast<float>(v - m);
  }
  *partial = part;
  return true;
}

#if VOXVIS_FILL_AVX2
__attribute__((target("avx2"))) bool edge_test_avx2(const FillSetup& s, int I0, int J0, float* at,
                                                   std::uint32_t* partial) {
  const __m256d i0 = _mm256_set1_pd(I0), j0 = _mm256_set1_pd(J0), zero = _mm256_setzero_pd();
  const __m256d allow = _mm256_set1_pd(kFloatAllowance), sign = _mm256_set1_pd(-0.0);
  int below = 0;
  std::uint32_t part = 0;
  for (int k = 0; k < s.lanes; k += FillSetup::kLanes) {
    const __m256d v = _mm256_add_pd(_mm256_add_pd(_mm256_load_pd(s.ec + k), _mm256_mul_pd(_mm256_load_pd(s.egx + k), i0)),
                                    _mm256_mul_pd(_mm256_load_pd(s.egy + k), j0));
    below |= _mm256_movemask_pd(_mm256_cmp_pd(_mm256_add_pd(v, _mm256_load_pd(s.eup + k)), zero, _CMP_LT_OQ));
    const __m256d m = _mm256_add_pd(_mm256_mul_pd(allow, _mm256_andnot_pd(sign, v)), _mm256_load_pd(s.em0 + k));
    const int full = _mm256_movemask_pd(_mm256_cmp_pd(_mm256_add_pd(v, _mm256_load_pd(s.edown + k)), m, _CMP_GE_OQ));
    part |= static_cast<std::uint32_t>(~full & 0xF) << k;
    _mm_storeu_ps(at + k, _mm256_cvtpd_ps(_mm256_sub_pd(v, m)));
  }
  if (below) return false;
  *partial = part;
  return true;
}
#else
bool edge_test_avx2(const FillSetup& s, int I0, int J0, float* at, std::uint32_t* partial) {
  return edge_test_scalar(s, I0, J0, at, partial);
}
#endif

/// The planes at the tile whose first pixel is (I0, J0): each plane's value
/// a there less its allowance m (the float allowance and the double
/// evaluation's own rounding), as a float, into job->plane[k].at; false when
/// no plane rises above `tile_min` over the tile (the least of the planes'
/// largest values there and the cap, at or below it) or a plane's values
/// there could overflow a float (skipped: writes less). Both versions
/// compute the same values and decide alike.
bool plane_step_scalar(const FillSetup& s, int I0, int J0, float tile_min, TileJob* job) {
  double w_hi = static_cast<double>(s.cap);
  const auto spread = static_cast<double>(I0 + J0 + kTileW + kTileH);
  for (int k = 0; k < s.planes; ++k) {
    const double a = s.pc[k] + s.pgx[k] * I0 + s.pgy[k] * J0;
    const double fa = std::fabs(a);
    if (!(fa <= kPlaneLimit)) return false;
    const double m = kFloatAllowance * fa + s.pm0[k] + s.peps[k] * spread;
    const double hi = a + s.pup[k];
    w_hi = hi < w_hi ? hi : w_hi;
    job->plane[k].at = static_cast<float>(a - m);
  }
  return w_hi > static_cast<double>(tile_min);
}

#if VOXVIS_FILL_AVX2
__attribute__((target("avx2"))) bool plane_step_avx2(const FillSetup& s, int I0, int J0, float tile_min,
                                                    TileJob* job) {
  const __m256d i0 = _mm256_set1_pd(I0), j0 = _mm256_set1_pd(J0), sign = _mm256_set1_pd(-0.0);
  const __m256d a = _mm256_add_pd(_mm256_add_pd(_mm256_load_pd(s.pc), _mm256_mul_pd(_mm256_load_pd(s.pgx), i0)),
                                  _mm256_mul_pd(_mm256_load_pd(s.pgy), j0));
  const __m256d fa = _mm256_andnot_pd(sign, a);
  if (_mm256_movemask_pd(_mm256_cmp_pd(fa, _mm256_set1_pd(kPlaneLimit), _CMP_NLE_UQ)) != 0) return false;
  const __m256d spread = _mm256_set1_pd(static_cast<double>(I0 + J0 + kTileW + kTileH));
  const __m256d allow = _mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(kFloatAllowance), fa), _mm256_load_pd(s.pm0));
  const __m256d m = _mm256_add_pd(allow, _mm256_mul_pd(_mm256_load_pd(s.peps), spread));
  alignas(16) float at[FillSetup::kLanes];
  _mm_store_ps(at, _mm256_cvtpd_ps(_mm256_sub_pd(a, m)));
  for (int k = 0; k < s.planes; ++k) job->plane[k].at = at[k];
  // The least of the four largest values (the padding's are infinite) and the cap.
  const __m256d hi = _mm256_add_pd(a, _mm256_load_pd(s.pup));
  const __m128d h2 = _mm_min_pd(_mm256_castpd256_pd128(hi), _mm256_extractf128_pd(hi, 1));
  const __m128d h1 = _mm_min_sd(h2, _mm_unpackhi_pd(h2, h2));
  const double w_hi = _mm_cvtsd_f64(_mm_min_sd(h1, _mm_set_sd(static_cast<double>(s.cap))));
  return w_hi > static_cast<double>(tile_min);
}
#else
bool plane_step_avx2(const FillSetup& s, int I0, int J0, float tile_min, TileJob* job) {
  return plane_step_scalar(s, I0, J0, tile_min, job);
}
#endif

/// Where fill writes: the buffer's pixels and per-tile records.
struct FillTarget {
  float* px;
  float* tile_min;
  float* tile_max;
  std::uint8_t* tile_written;
  std::vector<std::uint32_t>* written_tiles;
  std::size_t tw;  ///< Tiles a row.
};

/// The tiles of the occluder's rectangle, each set up (edges, then planes)
/// and handed to the kernel; returns the bounds raised. Inlined into the
/// scalar and the AVX2 entry points below, so that each tile's steps are
/// inlined into its loop.
template <bool kAvx2>
[[gnu::always_inline]] inline std::uint64_t fill_tiles(const ConvexOccluder& occ, const FillSetup& s, float skip_at,
                                                       const FillTarget& b) {
  TileJob job;
  job.planes = s.planes;
  job.cap = s.cap;
  for (int k = 0; k < s.planes; ++k) job.plane[k] = TileAffine{0.0f, s.plane[k].row, s.plane[k].col};
  std::uint64_t raised = 0;
  float at[ConvexOccluder::kMaxEdges];
  for (int ty = occ.j0 / kTileH; ty <= occ.j1 / kTileH; ++ty) {
    const int J0 = ty * kTileH;
    job.r0 = std::max(occ.j0, J0) - J0;
    job.r1 = std::min(occ.j1, J0 + kTileH - 1) - J0;
    for (int tx = occ.i0 / kTileW; tx <= occ.i1 / kTileW; ++tx) {
      const std::size_t t = static_cast<std::size_t>(ty) * b.tw + static_cast<std::size_t>(tx);
      if (b.tile_min[t] >= skip_at) continue;  // Every pixel holds this occluder's largest bound already.
      const int I0 = tx * kTileW;
      std::uint32_t partial;
      if constexpr (kAvx2) {
        if (!edge_test_avx2(s, I0, J0, at, &partial) || !plane_step_avx2(s, I0, J0, b.tile_min[t], &job)) continue;
      } else {
        if (!edge_test_scalar(s, I0, J0, at, &partial) || !plane_step_scalar(s, I0, J0, b.tile_min[t], &job)) continue;
      }
      job.edges = 0;
      for (; partial != 0; partial &= partial - 1) {
        const int k = __builtin_ctz(partial);
        job.edge[job.edges++] = TileAffine{at[k], s.edge[k].row, s.edge[k].col};
      }
      job.c0 = std::max(occ.i0, I0) - I0;
      job.c1 = std::min(occ.i1, I0 + kTileW - 1) - I0;
      float* tile = b.px + t * kTilePixels;
      const TileResult r = kAvx2 ? raster_tile_avx2(tile, job) : raster_tile_scalar(tile, job);
      VOXVIS_ASSERT(r.min >= b.tile_min[t]);  // Bounds only rise (farthest_bound relies on it).
      b.tile_min[t] = r.min;
      b.tile_max[t] = r.max;
      if (r.raised == 0) continue;
      raised += static_cast<std::uint64_t>(r.raised);
      if (!b.tile_written[t]) {
        b.tile_written[t] = 1;
        b.written_tiles->push_back(static_cast<std::uint32_t>(t));
      }
    }
  }
  return raised;
}

std::uint64_t fill_tiles_scalar(const ConvexOccluder& occ, const FillSetup& s, float skip_at, const FillTarget& b) {
  return fill_tiles<false>(occ, s, skip_at, b);
}

#if VOXVIS_FILL_AVX2
__attribute__((target("avx2"))) std::uint64_t fill_tiles_avx2(const ConvexOccluder& occ, const FillSetup& s,
                                                             float skip_at, const FillTarget& b) {
  return fill_tiles<true>(occ, s, skip_at, b);
}
#else
std::uint64_t fill_tiles_avx2(const ConvexOccluder& occ, const FillSetup& s, float skip_at, const FillTarget& b) {
  return fill_tiles_scalar(occ, s, skip_at, b);
}
#endif

}  // namespace

bool OcclusionBuffer::fill(const ConvexOccluder& occ) {
  if (occ.planes == 0 || occ.i0 > occ.i1 || occ.j0 > occ.j1) return false;
  FillSetup s;
  if (!setup_fill(occ, fault, near_, w_, h_, &s)) return false;
  VOXVIS_ASSERT(occ.i0 >= 0 && occ.i1 < w_ && occ.j0 >= 0 && occ.j1 < h_);
  const bool avx2 = kernel == BufferKernel::Auto && cpu_has_avx2();
  const float skip_at = float_down(occ.w_max * near_ * occ.slack);
  const FillTarget target{px_.data(), tile_min_.data(), tile_max_.data(), tile_written_.data(), &written_tiles_,
                          static_cast<std::size_t>(tw_)};
  const std::uint64_t raised =
      avx2 ? fill_tiles_avx2(occ, s, skip_at, target) : fill_tiles_scalar(occ, s, skip_at, target);
  written_ += raised;
  return raised != 0;
}

}  // namespace voxvis::detail
