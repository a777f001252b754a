// occludee_corners.cpp — the two kernels of occludee_corners.h.
#include "occludee_corners.h"

#include <limits>

#include "numeric.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define VOXVIS_CORNERS_AVX2 1
#include <immintrin.h>
#endif

namespace voxvis::detail {
namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
}  // namespace

void corner_slopes_scalar(const BoxCorners& b, double* x0, double* x1, double* y0, double* y1) {
  double lx = kInf, hx = -kInf, ly = kInf, hy = -kInf;
  for (int k = 0; k < 8; ++k) {
    double X = b.X0, Y = b.Y0, Z = b.Z0;
    for (int a = 0; a < 3; ++a)
      if (k >> a & 1) X += b.ex[a], Y += b.ey[a], Z += b.ez[a];
    const double iz = 1.0 / Z;
    lx = least(lx, X * iz), hx = greatest(hx, X * iz);
    ly = least(ly, Y * iz), hy = greatest(hy, Y * iz);
  }
  *x0 = lx, *x1 = hx, *y0 = ly, *y1 = hy;
}

#if VOXVIS_CORNERS_AVX2
namespace {

/// One coordinate of the eight corners: corners 0-3 in *lo, 4-7 in *hi
/// (lane i of *lo is corner i), the steps added as the scalar kernel adds
/// them (a blend keeps a lane whose bit is clear exactly as it was).
__attribute__((target("avx2"))) inline void corner_coordinate(double v0, const double* e, __m256d* lo, __m256d* hi) {
  __m256d v = _mm256_set1_pd(v0);
  v = _mm256_blend_pd(v, _mm256_add_pd(v, _mm256_set1_pd(e[0])), 0b1010);
  v = _mm256_blend_pd(v, _mm256_add_pd(v, _mm256_set1_pd(e[1])), 0b1100);
  *lo = v;
  *hi = _mm256_add_pd(v, _mm256_set1_pd(e[2]));
}

/// The least and the largest lane of `lo` and `hi`, NaN lanes passed over as
/// least() and greatest() pass them: vminpd(v, m) is v < m ? v : m.
__attribute__((target("avx2"))) inline void range(__m256d a, __m256d b, double* least_out, double* greatest_out) {
  __m256d l = _mm256_min_pd(a, _mm256_set1_pd(kInf)), h = _mm256_max_pd(a, _mm256_set1_pd(-kInf));
  l = _mm256_min_pd(b, l);
  h = _mm256_max_pd(b, h);
  l = _mm256_min_pd(l, _mm256_permute2f128_pd(l, l, 1));
  h = _mm256_max_pd(h, _mm256_permute2f128_pd(h, h, 1));
  l = _mm256_min_pd(l, _mm256_permute_pd(l, 0b0101));
  h = _mm256_max_pd(h, _mm256_permute_pd(h, 0b0101));
  *least_out = _mm256_cvtsd_f64(l);
  *greatest_out = _mm256_cvtsd_f64(h);
}

}  // namespace

__attribute__((target("avx2"))) void corner_slopes_avx2(const BoxCorners& b, double* x0, double* x1, double* y0,
                                                        double* y1) {
  __m256d xl, xh, yl, yh, zl, zh;
  corner_coordinate(b.X0, b.ex, &xl, &xh);
  corner_coordinate(b.Y0, b.ey, &yl, &yh);
  corner_coordinate(b.Z0, b.ez, &zl, &zh);
  const __m256d one = _mm256_set1_pd(1.0);
  const __m256d izl = _mm256_div_pd(one, zl), izh = _mm256_div_pd(one, zh);
  range(_mm256_mul_pd(xl, izl), _mm256_mul_pd(xh, izh), x0, x1);
  range(_mm256_mul_pd(yl, izl), _mm256_mul_pd(yh, izh), y0, y1);
}
#else
void corner_slopes_avx2(const BoxCorners& b, double* x0, double* x1, double* y0, double* y1) {
  corner_slopes_scalar(b, x0, x1, y0, y1);
}
#endif

}  // namespace voxvis::detail
