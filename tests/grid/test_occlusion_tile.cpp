// The rasterizer's tiles (grid/src/occlusion_tile.h, occlusion_fill.cpp):
// the scalar and AVX2 kernels write the same bits, job by job and over whole
// buffers of every kind of occluder; the pixels past the image's sides are
// never written and never lower a tile's bound; a frame clears what the last
// one wrote; the occludee test's corner slopes agree between their two
// kernels (occludee_corners.h), and so do the frustum's box test's
// (frustum.h). (The bounds' conservativeness against exact
// rays is tested in test_occlusion_buffer.cpp with both kernels.)
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include <glm/geometric.hpp>

#include "engine_check.h"
#include "frustum.h"
#include "occludee_corners.h"
#include "occlusion_buffer.h"
#include "occlusion_tile.h"
#include "raycast.h"
#include "scenes.h"
#include "voxvis/rng.h"

namespace voxvis::test {
namespace {

using detail::BufferKernel;
using detail::kTileH;
using detail::kTilePixels;
using detail::kTileW;
using detail::OcclusionBuffer;
using detail::TileAffine;
using detail::TileJob;
using detail::TileResult;

std::uint32_t bits(float f) {
  std::uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  return u;
}

/// A random affine function over a tile, now and then one that crosses zero
/// inside it, with offsets as the rasterizer makes them.
struct RandomAffine {
  float row[kTileH], col[kTileW];
  TileAffine make(Rng& rng, float at_scale) {
    const auto gx = static_cast<float>(rng.uniform(-1.0, 1.0)), gy = static_cast<float>(rng.uniform(-1.0, 1.0));
    for (int k = 0; k < kTileW; ++k) col[k] = gx * static_cast<float>(k);
    for (int k = 0; k < kTileH; ++k) row[k] = gy * static_cast<float>(k);
    return TileAffine{static_cast<float>(rng.uniform(-1.0, 1.0)) * at_scale, row, col};
  }
};

TEST(OcclusionTile, KernelsWriteTheSameBits) {
  if (!detail::cpu_has_avx2()) GTEST_SKIP() << "this CPU has no AVX2: only the scalar kernel runs";
  Rng rng(7);
  std::vector<RandomAffine> edges(TileJob::kMaxEdges), planes(TileJob::kMaxPlanes);
  int raised = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    TileJob job;
    job.edges = rng.uniform_int(0, 6);
    for (int k = 0; k < job.edges; ++k) job.edge[k] = edges[static_cast<std::size_t>(k)].make(rng, 4.0f);
    job.planes = rng.uniform_int(1, TileJob::kMaxPlanes);
    for (int k = 0; k < job.planes; ++k) job.plane[k] = planes[static_cast<std::size_t>(k)].make(rng, 2.0f);
    job.cap = rng.chance(0.3) ? static_cast<float>(rng.uniform(0.0, 1.0)) : std::numeric_limits<float>::infinity();
    job.c0 = rng.uniform_int(0, kTileW - 1);
    job.c1 = rng.uniform_int(job.c0, kTileW - 1);
    job.r0 = rng.uniform_int(0, kTileH - 1);
    job.r1 = rng.uniform_int(job.r0, kTileH - 1);
    float a[kTilePixels], b[kTilePixels];
    for (float& v : a) v = rng.chance(0.3) ? 0.0f : static_cast<float>(rng.uniform(0.0, 1.0));
    if (rng.chance(0.1)) a[rng.uniform_int(0, kTilePixels - 1)] = std::numeric_limits<float>::infinity();
    std::memcpy(b, a, sizeof a);
    const TileResult rs = detail::raster_tile_scalar(a, job);
    const TileResult rv = detail::raster_tile_avx2(b, job);
    ASSERT_EQ(rs.raised, rv.raised) << "trial " << trial;
    ASSERT_EQ(bits(rs.min), bits(rv.min)) << "trial " << trial;
    ASSERT_EQ(bits(rs.max), bits(rv.max)) << "trial " << trial;
    for (int k = 0; k < kTilePixels; ++k) ASSERT_EQ(bits(a[k]), bits(b[k])) << "trial " << trial << " pixel " << k;
    raised += rs.raised;
  }
  EXPECT_GT(raised, 3000);  // The jobs raise bounds, not only keep them.
}

TEST(OcclusionTile, KernelsWriteOnlyTheJobsPixelsAndNeverLowerABound) {
  Rng rng(8);
  RandomAffine plane;
  for (int trial = 0; trial < 2000; ++trial) {
    TileJob job;
    job.planes = 1;
    job.plane[0] = plane.make(rng, 2.0f);
    job.cap = std::numeric_limits<float>::infinity();
    job.c0 = rng.uniform_int(0, kTileW - 1);
    job.c1 = rng.uniform_int(job.c0, kTileW - 1);
    job.r0 = rng.uniform_int(0, kTileH - 1);
    job.r1 = rng.uniform_int(job.r0, kTileH - 1);
    for (const bool simd : {false, true}) {
      if (simd && !detail::cpu_has_avx2()) continue;
      float before[kTilePixels], t[kTilePixels];
      for (float& v : before) v = static_cast<float>(rng.uniform(0.0, 1.0));
      std::memcpy(t, before, sizeof t);
      simd ? detail::raster_tile_avx2(t, job) : detail::raster_tile_scalar(t, job);
      for (int dj = 0; dj < kTileH; ++dj)
        for (int di = 0; di < kTileW; ++di) {
          const int k = dj * kTileW + di;
          ASSERT_GE(t[k], before[k]);
          if (dj < job.r0 || dj > job.r1 || di < job.c0 || di > job.c1) {
            ASSERT_EQ(bits(t[k]), bits(before[k])) << "pixel " << di << ", " << dj << " outside the job";
          }
        }
    }
  }
}

TEST(OcclusionTile, OccludeeKernelsAgreeAndReadOnlyTheirRectangle) {
  Rng rng(10);
  int above = 0, trials = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    float t[kTilePixels];
    for (float& v : t) v = static_cast<float>(rng.uniform(0.5, 1.0));
    const int c0 = rng.uniform_int(0, kTileW - 1), c1 = rng.uniform_int(c0, kTileW - 1);
    const int r0 = rng.uniform_int(0, kTileH - 1), r1 = rng.uniform_int(r0, kTileH - 1);
    // Now and then one pixel at or below w: inside the rectangle it decides,
    // outside it must not.
    const auto w = static_cast<float>(rng.uniform(0.0, 0.5));
    int di = -1, dj = -1;
    if (rng.chance(0.5)) {
      di = rng.uniform_int(0, kTileW - 1), dj = rng.uniform_int(0, kTileH - 1);
      t[dj * kTileW + di] = rng.chance(0.5) ? w : 0.0f;
    }
    const bool inside = di >= c0 && di <= c1 && dj >= r0 && dj <= r1;
    const bool s = detail::tile_above_scalar(t, c0, c1, r0, r1, w);
    ASSERT_EQ(s, !inside) << "trial " << trial;
    if (detail::cpu_has_avx2()) {
      ASSERT_EQ(detail::tile_above_avx2(t, c0, c1, r0, r1, w), s) << "trial " << trial;
    }
    above += s ? 1 : 0;
    ++trials;
  }
  EXPECT_GT(above, trials / 2);
}

/// Renders random occluders of every kind into a buffer with the given
/// kernel, from the same random stream.
/// The ranges of a random camera's field of view (degrees), aspect and
/// near plane (the last two log-uniform).
struct ViewRanges {
  double fov_lo, fov_hi, aspect_lo, aspect_hi, near_lo, near_hi;
};

/// A camera at `eye` looking a random way, its shape drawn from `r`; false
/// when its direction and up are refused (too near parallel).
bool random_camera(Rng& rng, const Vec3& eye, const ViewRanges& r, Camera* cam) {
  cam->eye = eye;
  cam->dir = rng.unit_vector();
  cam->up = rng.unit_vector();
  if (!validate_camera(*cam).ok) return false;
  cam->fov_y_deg = rng.uniform(r.fov_lo, r.fov_hi);
  cam->aspect = rng.log_uniform(r.aspect_lo, r.aspect_hi);
  cam->near = rng.log_uniform(r.near_lo, r.near_hi);
  return true;
}

OcclusionBuffer render_random(const Camera& cam, int width, BufferKernel kernel, std::uint64_t seed) {
  OcclusionBuffer ob;
  ob.kernel = kernel;
  ob.begin(detail::make_world_frustum(cam), width);
  Rng rng(seed);
  const Vec3 f = glm::normalize(cam.dir);
  for (int k = 0; k < 40; ++k) {
    const Vec3 at = cam.eye + f * rng.uniform(0.5, 30.0) + rng.in_box(Vec3(-6.0), Vec3(6.0));
    switch (rng.uniform_int(0, 2)) {
      case 0:
        ob.render_sphere(at, rng.log_uniform(0.05, 4.0));
        break;
      case 1: {
        const Vec3 h = rng.in_box(Vec3(0.05), Vec3(4.0));
        ob.render_box(at - h, at + h);
        break;
      }
      default: {
        const double s = rng.log_uniform(0.1, 8.0);
        ob.render_triangle(at + rng.in_box(Vec3(-s), Vec3(s)), at + rng.in_box(Vec3(-s), Vec3(s)),
                           at + rng.in_box(Vec3(-s), Vec3(s)));
      }
    }
  }
  return ob;
}

// The whole rasterizer both ways: the per-tile edge test (four edges at a
// time) and the tile kernel, AVX2 against the scalar reference.
TEST(OcclusionTile, ScalarAndAvx2BuffersAgreeBitForBit) {
  if (!detail::cpu_has_avx2()) GTEST_SKIP() << "this CPU has no AVX2: only the scalar kernel runs";
  Rng rng(9);
  std::uint64_t written = 0;
  for (int trial = 0; trial < 60; ++trial) {
    Camera cam;
    if (!random_camera(rng, rng.in_box(Vec3(-5), Vec3(5)), {20.0, 150.0, 0.3, 3.0, 1e-3, 0.5}, &cam)) continue;
    // Widths and heights that are not multiples of the tile's sides too.
    const int width = rng.uniform_int(5, 203);
    const OcclusionBuffer a = render_random(cam, width, BufferKernel::Auto, 100 + static_cast<std::uint64_t>(trial));
    const OcclusionBuffer b = render_random(cam, width, BufferKernel::Scalar, 100 + static_cast<std::uint64_t>(trial));
    ASSERT_EQ(a.writes(), b.writes()) << "trial " << trial;
    for (int j = 0; j < a.height(); ++j)
      for (int i = 0; i < a.width(); ++i) ASSERT_EQ(bits(a.pixel(i, j)), bits(b.pixel(i, j))) << "trial " << trial << " pixel " << i << ", " << j;
    EXPECT_EQ(a.farthest_bound(), b.farthest_bound());
    written += a.writes();
  }
  EXPECT_GT(written, 50000u);
}

TEST(OcclusionTile, PixelsPastTheImageNeitherWrittenNorLoweringTheBound) {
  // An image of 37 x 13 pixels (neither side a multiple of the tile's) with a
  // wall across the whole view: every pixel is written, exactly once, and the
  // farthest bound is finite (a pixel past the image counted as empty would
  // make it +inf, and the traversal would never end early).
  Camera cam = camera_along(Vec3(0.0), Vec3(0.0, 0.0, -1.0), 60.0, 37.0 / 13.0, 0.1);
  for (const BufferKernel kernel : {BufferKernel::Auto, BufferKernel::Scalar}) {
    OcclusionBuffer ob;
    ob.kernel = kernel;
    ob.begin(detail::make_world_frustum(cam), 37);
    ASSERT_EQ(ob.width(), 37);
    ASSERT_EQ(ob.height(), 13);
    EXPECT_TRUE(ob.render_box(Vec3(-100.0, -100.0, -6.0), Vec3(100.0, 100.0, -5.0)));
    EXPECT_EQ(ob.writes(), 37u * 13u);
    const double far = ob.farthest_bound();
    EXPECT_TRUE(std::isfinite(far));
    EXPECT_GE(far, 5.0);  // Depth along the view direction: the wall's face is at 5 for every ray.
    EXPECT_LT(far, 5.001);
    // A box behind the wall is hidden, one in front is not.
    EXPECT_TRUE(ob.hides_world(Vec3(-1.0, -1.0, -9.0), Vec3(1.0, 1.0, -8.0)));
    EXPECT_FALSE(ob.hides_world(Vec3(-1.0, -1.0, -4.0), Vec3(1.0, 1.0, -3.0)));
  }
}

TEST(OcclusionTile, ANewFrameOfTheSameSizeStartsEmpty) {
  Camera cam = camera_along(Vec3(0.0), Vec3(0.0, 0.0, -1.0), 60.0, 1.5, 0.1);
  OcclusionBuffer ob;
  const detail::WorldFrustum wf = detail::make_world_frustum(cam);
  ob.begin(wf, 50);
  EXPECT_TRUE(ob.render_box(Vec3(-100.0, -100.0, -6.0), Vec3(100.0, 100.0, -5.0)));
  EXPECT_TRUE(ob.hides_world(Vec3(-1.0, -1.0, -9.0), Vec3(1.0, 1.0, -8.0)));
  ob.end();
  EXPECT_FALSE(ob.on());
  EXPECT_FALSE(ob.hides_world(Vec3(-1.0, -1.0, -9.0), Vec3(1.0, 1.0, -8.0)));  // Off: hides nothing.
  ob.begin(wf, 50);
  EXPECT_EQ(ob.writes(), 0u);
  for (int j = 0; j < ob.height(); ++j)
    for (int i = 0; i < ob.width(); ++i) ASSERT_TRUE(std::isinf(ob.pixel(i, j))) << i << ", " << j;
  EXPECT_TRUE(std::isinf(ob.farthest_bound()));
  // A smaller occluder in the second frame: only its pixels hold a bound.
  EXPECT_TRUE(ob.render_box(Vec3(-0.5, -0.5, -6.0), Vec3(0.5, 0.5, -5.0)));
  EXPECT_FALSE(ob.hides_world(Vec3(-3.0, -3.0, -9.0), Vec3(3.0, 3.0, -8.0)));
  EXPECT_TRUE(ob.hides_world(Vec3(-0.1, -0.1, -9.0), Vec3(0.1, 0.1, -8.0)));
}

// The occludee test's corner slopes (occludee_corners.h): the AVX2 kernel
// gives the scalar reference's values, and both hold every corner's slope,
// computed here on its own, with NaN slopes passed over.
TEST(OccludeeCorners, KernelsAgreeAndHoldEveryCorner) {
  if (!detail::cpu_has_avx2()) GTEST_SKIP() << "this CPU has no AVX2: only the scalar kernel runs";
  Rng rng(21);
  for (int trial = 0; trial < 20000; ++trial) {
    detail::BoxCorners b;
    const double mag = rng.log_uniform(1e-6, 1e12);
    b.X0 = rng.uniform(-mag, mag), b.Y0 = rng.uniform(-mag, mag), b.Z0 = rng.log_uniform(1e-6, 1.0) * mag;
    for (int a = 0; a < 3; ++a) {
      b.ex[a] = rng.uniform(-mag, mag), b.ey[a] = rng.uniform(-mag, mag);
      b.ez[a] = rng.uniform(0.0, mag);
      if (trial % 7 == 0) b.ex[a] = b.ey[a] = 0.0;  // Flat and zero slopes.
    }
    if (trial % 11 == 0) b.Z0 = 0.0, b.X0 = 0.0;  // Corner 0 at 0 / 0: a NaN slope.
    double s[4], v[4];
    detail::corner_slopes_scalar(b, &s[0], &s[1], &s[2], &s[3]);
    detail::corner_slopes_avx2(b, &v[0], &v[1], &v[2], &v[3]);
    for (int q = 0; q < 4; ++q) ASSERT_EQ(s[q], v[q]) << "trial " << trial << " bound " << q;
    for (int k = 0; k < 8; ++k) {
      double X = b.X0, Y = b.Y0, Z = b.Z0;
      for (int a = 0; a < 3; ++a)
        if (k >> a & 1) X += b.ex[a], Y += b.ey[a], Z += b.ez[a];
      const double iz = 1.0 / Z, x = X * iz, y = Y * iz;  // As hides() takes a slope (its margins cover the rounding).
      ASSERT_TRUE(std::isnan(x) || (s[0] <= x && x <= s[1])) << "trial " << trial << " corner " << k;
      ASSERT_TRUE(std::isnan(y) || (s[2] <= y && y <= s[3])) << "trial " << trial << " corner " << k;
    }
  }
}

// The occludee test as the engine asks it (fine: the corners' own hull),
// with the AVX2 corner kernel and with the scalar one, on random buffers:
// the same answer for every box.
TEST(OccludeeCorners, HidesAnswersTheSameWithBothKernels) {
  if (!detail::cpu_has_avx2()) GTEST_SKIP() << "this CPU has no AVX2: only the scalar kernel runs";
  Rng rng(22);
  int hidden = 0, asked = 0;
  for (int trial = 0; trial < 30; ++trial) {
    Camera cam;
    if (!random_camera(rng, rng.in_box(Vec3(-5), Vec3(5)), {30.0, 120.0, 0.5, 2.0, 1e-3, 0.5}, &cam)) continue;
    const OcclusionBuffer a = render_random(cam, 160, BufferKernel::Auto, 200 + static_cast<std::uint64_t>(trial));
    OcclusionBuffer b = a;
    b.kernel = BufferKernel::Scalar;
    const Vec3 f = glm::normalize(cam.dir);
    for (int k = 0; k < 300; ++k) {
      const Vec3 at = cam.eye + f * rng.uniform(1.0, 60.0) + rng.in_box(Vec3(-10.0), Vec3(10.0));
      const Vec3 h = rng.in_box(Vec3(0.01), Vec3(3.0));
      const bool hides = a.hides_world(at - h, at + h, true);
      ASSERT_EQ(hides, b.hides_world(at - h, at + h, true)) << "trial " << trial << " box " << k;
      hidden += hides ? 1 : 0;
      ++asked;
    }
  }
  EXPECT_GT(hidden, asked / 20);  // Enough boxes hidden for the comparison to mean something.
  EXPECT_LT(hidden, asked);
}

// The frustum's box test (frustum.h): the AVX2 kernel and the scalar
// reference answer alike for boxes inside, outside, straddling and far
// beyond every plane, huge and tiny, cameras of every shape included; and
// a box the test calls outside has no point inside (its corners checked
// against the planes with the margin).
TEST(FrustumBoxTest, KernelsAgree) {
  if (!detail::cpu_has_avx2()) GTEST_SKIP() << "this CPU has no AVX2: only the scalar kernel runs";
  Rng rng(23);
  int outside = 0, inside = 0;
  for (int trial = 0; trial < 200; ++trial) {
    Camera cam;
    const Vec3 eye = rng.in_box(Vec3(-5), Vec3(5)) * rng.log_uniform(1e-3, 1e6);
    if (!random_camera(rng, eye, {1.0, 179.0, 0.05, 20.0, 1e-4, 1.0}, &cam)) continue;
    cam.far = cam.near * rng.log_uniform(2.0, 1e6);
    if (!validate_camera(cam).ok) continue;
    const detail::WorldFrustum f = detail::make_world_frustum(cam);
    for (int k = 0; k < 500; ++k) {
      const double scale = rng.log_uniform(1e-3, cam.far * 2.0);
      const Vec3 lo = rng.in_box(Vec3(-scale), Vec3(scale));
      const Vec3 hi = lo + rng.in_box(Vec3(0.0), Vec3(scale));
      const double margin = -1e-9 * (1.0 + scale);
      const bool a = detail::box_outside_avx2(f, lo, hi, margin);
      ASSERT_EQ(a, detail::box_outside_scalar(f, lo, hi, margin)) << "trial " << trial << " box " << k;
      (a ? outside : inside) += 1;
      if (!a) continue;
      bool separated = false;  // Some plane with all eight corners strictly outside it.
      for (const detail::Plane& p : f.planes) {
        bool all = true;
        for (int c = 0; c < 8; ++c) {
          const Vec3 q((c & 1) ? hi.x : lo.x, (c & 2) ? hi.y : lo.y, (c & 4) ? hi.z : lo.z);
          all = all && glm::dot(p.n, q) + p.d < 0.0;
        }
        separated = separated || all;
      }
      ASSERT_TRUE(separated) << "trial " << trial << " box " << k;
    }
  }
  EXPECT_GT(outside, 1000);
  EXPECT_GT(inside, 1000);
}

}  // namespace
}  // namespace voxvis::test
