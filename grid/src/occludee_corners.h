// occludee_corners.h — the occludee test's image of a box
// (OcclusionBuffer::hides, fine): the least and largest slopes X/Z and Y/Z of
// its eight corners in the view's frame, in two kernels that give the same
// values: a scalar reference and an AVX2 one (four corners to an
// instruction). Both add a corner's steps in the same order and divide and
// multiply the same numbers, so every slope is the same double; only the
// sign of a zero slope may differ (the least of +0 and -0 depends on the
// order compared), which nothing downstream can tell (OcclusionBuffer::rect
// widens the range by a positive margin first).
#pragma once

namespace voxvis::detail {

/// A box relative to the eye in the view's frame: corner k is (X0, Y0, Z0)
/// plus, for each axis a whose bit is set in k, the step (ex[a], ey[a],
/// ez[a]), added in the order a = 0, 1, 2.
struct BoxCorners {
  double X0 = 0.0, Y0 = 0.0, Z0 = 0.0;
  double ex[3] = {}, ey[3] = {}, ez[3] = {};
};

/// The corners' slopes' range: x0 <= X/Z <= x1 and y0 <= Y/Z <= y1 for
/// every corner. A NaN slope (a corner at Z = 0, or 0 / 0) is passed over;
/// when every one is NaN, x0 = y0 = +inf and x1 = y1 = -inf.
void corner_slopes_scalar(const BoxCorners& b, double* x0, double* x1, double* y0, double* y1);
/// The same with AVX2; call only where cpu_has_avx2() (occlusion_tile.h).
void corner_slopes_avx2(const BoxCorners& b, double* x0, double* x1, double* y0, double* y1);

}  // namespace voxvis::detail
