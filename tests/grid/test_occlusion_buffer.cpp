// The conservative occlusion buffer (grid/src/occlusion_buffer.h): unit tests
// of its two rules, a property test of the written bounds against exact ray
// intersections, the engine with the buffer on against the ray caster (zero
// misses), and deliberately broken rules that the ray caster must catch.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "engine_check.h"
#include "frustum.h"
#include "numeric.h"
#include "occlusion_buffer.h"
#include "raycast.h"
#include "scene_impl.h"
#include "scenes.h"

namespace voxvis::test {
namespace {

using detail::BufferFault;
using detail::OcclusionBuffer;

Camera look_down_z(double fov = 60.0, double aspect = 1.0, double near = 0.1) {
  return camera_along(Vec3(0.0), Vec3(0.0, 0.0, -1.0), fov, aspect, near);
}

OcclusionBuffer begin(const Camera& c, int width) {
  OcclusionBuffer ob;
  ob.begin(detail::make_world_frustum(c), width);
  return ob;
}

// The occludee test's scan compares tile bounds in float against
// float_at_or_below(w) (numeric.h) instead of converting each to double:
// the same answer for every float and double, at the edges of the float
// range, at floats, between them, and for NaN and the infinities.
TEST(OcclusionBuffer, FloatAtOrBelowComparesAsTheDoubleDoes) {
  Rng rng(31);
  const float fmax = std::numeric_limits<float>::max(), finf = std::numeric_limits<float>::infinity();
  const double dinf = std::numeric_limits<double>::infinity(), dnan = std::numeric_limits<double>::quiet_NaN();
  std::vector<float> ms = {0.0f, -0.0f, 1.0f, fmax, -fmax, finf, -finf, std::numeric_limits<float>::denorm_min()};
  std::vector<double> ds = {0.0, -0.0, 1.0, double(fmax), -double(fmax), 2.0 * double(fmax), -2.0 * double(fmax),
                            dinf, -dinf, dnan, 1e-50, -1e-50, double(std::nextafter(1.0f, 2.0f)) - 1e-12};
  for (int k = 0; k < 20000; ++k) {
    const float m = static_cast<float>(rng.log_uniform(1e-40, 1e38)) * (rng.uniform(0.0, 1.0) < 0.1 ? -1.0f : 1.0f);
    ms.push_back(m);
    ds.push_back(static_cast<double>(m));                                    // A float itself,
    ds.push_back(static_cast<double>(m) * (1.0 + rng.uniform(-1e-7, 1e-7)));  // or near one.
  }
  int above = 0;
  for (std::size_t k = 0; k < ds.size(); ++k) {
    const float d_down = detail::float_at_or_below(ds[k]);
    std::vector<float> near_d;  // The floats around d: where the two compares could part.
    if (std::fabs(ds[k]) <= double(fmax)) {
      const float f = static_cast<float>(ds[k]);
      near_d = {f, std::nextafter(f, finf), std::nextafter(f, -finf)};
    }
    for (std::size_t q = 0; q < 16 + near_d.size(); ++q) {
      const float m = q < 16 ? ms[(k * 16 + q) % ms.size()] : near_d[q - 16];
      const bool want = static_cast<double>(m) > ds[k];
      ASSERT_EQ(want, m > d_down) << "m " << m << " d " << ds[k];
      above += want ? 1 : 0;
    }
    ASSERT_EQ(std::isnan(ds[k]), std::isnan(d_down));
    ASSERT_TRUE(std::isnan(ds[k]) || static_cast<double>(d_down) <= ds[k]) << ds[k];
  }
  EXPECT_GT(above, 1000);
}

TEST(OcclusionBuffer, SphereInFrontOfABoxHidesIt) {
  OcclusionBuffer ob = begin(look_down_z(), 128);
  ASSERT_TRUE(ob.render_sphere(Vec3(0, 0, -10), 3.0));
  EXPECT_TRUE(ob.hides_world(Vec3(-0.5, -0.5, -20), Vec3(0.5, 0.5, -19)));
  // In front of the sphere, or reaching into it: not hidden.
  EXPECT_FALSE(ob.hides_world(Vec3(-0.5, -0.5, -6), Vec3(0.5, 0.5, -5)));
  EXPECT_FALSE(ob.hides_world(Vec3(-0.5, -0.5, -20), Vec3(0.5, 0.5, -6.9)));  // Sphere front at 7.
  // A ball occludes with polygons inscribed in discs inside it: its rim
  // (the circle of its tangent points, at depth 10 - 3^2 / 10 = 9.1 here)
  // and, across its middle, a disc 3 / sqrt(2) = 2.12 before the centre
  // (depth 7.88). Beyond that, inside the ball, is hidden; nearer, though
  // inside the ball, is not.
  EXPECT_TRUE(ob.hides_world(Vec3(-0.5, -0.5, -20), Vec3(0.5, 0.5, -7.95)));
  EXPECT_FALSE(ob.hides_world(Vec3(-0.5, -0.5, -20), Vec3(0.5, 0.5, -7.8)));
  // Beside it: not hidden.
  EXPECT_FALSE(ob.hides_world(Vec3(8, -0.5, -20), Vec3(9, 0.5, -19)));
}

TEST(OcclusionBuffer, BoxPeekingOutByAFractionOfAPixelIsNotHidden) {
  // A box occluder x, y in [-2, 2] at z = -10 covers image x in [-0.2, 0.2]
  // at fov 90 (tan = 1). At 100 pixels a pixel is 0.02 wide.
  OcclusionBuffer ob = begin(look_down_z(90.0), 100);
  ASSERT_TRUE(ob.render_box(Vec3(-2, -2, -11), Vec3(2, 2, -10)));
  // Behind it at z in [-21, -20] the silhouette reaches |x| = 2 * 20 / 10 =
  // 4 (at the occluder's front face depth the slope is 0.2). A box wholly
  // within slope 0.16 is hidden; one reaching slope 0.2 + 0.1 pixel is not.
  EXPECT_TRUE(ob.hides_world(Vec3(-3.2, -3.2, -21), Vec3(3.2, 3.2, -20)));
  const double peek = (0.2 + 0.1 * 0.02) * 20.0;
  EXPECT_FALSE(ob.hides_world(Vec3(-1, -1, -21), Vec3(peek, 1, -20)));
  EXPECT_FALSE(ob.hides_world(Vec3(-1, -peek, -21), Vec3(1, 1, -20)));
}

TEST(OcclusionBuffer, TrianglesHideWhatLiesBehindThem) {
  // A square wall x, y in [-2, 2] at z = -10 as two triangles sharing a
  // diagonal. Pixels straddling the diagonal belong wholly to neither (the
  // inner-coverage rule), so what lies behind the diagonal's pixels is not
  // hidden by the wall alone: a box behind one triangle's half is.
  OcclusionBuffer ob = begin(look_down_z(90.0), 100);
  const Vec3 a(-2, -2, -10), b(2, -2, -10), c(2, 2, -10), d(-2, 2, -10);
  ASSERT_TRUE(ob.render_triangle(a, b, c));
  ASSERT_TRUE(ob.render_triangle(a, c, d));
  // Behind the lower-right half (below the diagonal y = x), at depth 20.
  EXPECT_TRUE(ob.hides_world(Vec3(1.0, -3.0, -21), Vec3(3.0, -1.0, -20)));
  EXPECT_TRUE(ob.hides_world(Vec3(-3.0, 1.0, -21), Vec3(-1.0, 3.0, -20)));
  // In front of the wall, or reaching it: not hidden.
  EXPECT_FALSE(ob.hides_world(Vec3(0.5, -1.0, -9.5), Vec3(1.0, -0.5, -9.0)));
  EXPECT_FALSE(ob.hides_world(Vec3(1.0, -1.5, -20), Vec3(1.5, -1.0, -10.0)));
  // Beside it, or peeking out by a pixel: not hidden.
  EXPECT_FALSE(ob.hides_world(Vec3(5, -1, -21), Vec3(6, 1, -20)));
  const double peek = (0.2 + 0.5 * 0.02) * 20.0;
  EXPECT_FALSE(ob.hides_world(Vec3(1.0, -3.0, -21), Vec3(peek, -1.0, -20)));
  // Drawn as one quad, the two close the seam: behind the diagonal too.
  OcclusionBuffer quad = begin(look_down_z(90.0), 100);
  const Vec3 corners[4] = {b, c, d, a};  // Triangles (b, c, a) and (c, d, a).
  bool raised = false;
  ASSERT_TRUE(quad.render_quad(corners, 0.0, &raised));
  EXPECT_TRUE(raised);
  EXPECT_TRUE(quad.hides_world(Vec3(-1.0, -1.0, -21), Vec3(1.0, 1.0, -20)));
  EXPECT_FALSE(ob.hides_world(Vec3(-1.0, -1.0, -21), Vec3(1.0, 1.0, -20)));
  // A quad whose image is not convex is refused (drawn as triangles).
  const Vec3 dart[4] = {Vec3(-2, -2, -10), Vec3(0, -1, -10), Vec3(2, -2, -10), Vec3(0, 2, -10)};
  EXPECT_FALSE(quad.render_quad(dart, 0.0, &raised));
  // Seen edge-on (the eye in its plane), a triangle writes nothing.
  OcclusionBuffer edge = begin(look_down_z(90.0), 100);
  EXPECT_FALSE(edge.render_triangle(Vec3(0, -2, -5), Vec3(0, 2, -5), Vec3(0, 0, -20)));
  EXPECT_FALSE(edge.hides_world(Vec3(-0.1, -0.1, -30), Vec3(0.1, 0.1, -29)));
}

// A dynamic mesh whose ball is under a pixel places no vertex
// (Collector::render_mesh): every triangle in such a ball must be one the
// buffer would have dropped anyway, so that skipping them changes nothing.
TEST(OcclusionBuffer, TrianglesInABallBelowAPixelWriteNothing) {
  Rng rng(17);
  int below = 0, above = 0;
  for (int k = 0; k < scaled(400); ++k) {
    OcclusionBuffer ob = begin(look_down_z(rng.uniform(20.0, 120.0)), 160);
    const Vec3 centre(rng.uniform(-30.0, 30.0), rng.uniform(-30.0, 30.0), -rng.uniform(0.5, 200.0));
    const double radius = std::exp(rng.uniform(std::log(1e-3), std::log(5.0)));
    if (!ob.ball_below_a_pixel(centre, radius)) {
      ++above;
      continue;
    }
    ++below;
    for (int t = 0; t < 20; ++t) {
      Vec3 v[3];
      for (Vec3& p : v) p = centre + radius * rng.unit_vector() * std::sqrt(rng.uniform(0.0, 1.0));
      EXPECT_FALSE(ob.render_triangle(v[0], v[1], v[2])) << "ball " << k << " triangle " << t;
    }
  }
  EXPECT_GT(below, 20);
  EXPECT_GT(above, 20);
  // A ball reaching the near plane is never skipped.
  const OcclusionBuffer ob = begin(look_down_z(), 160);
  EXPECT_FALSE(ob.ball_below_a_pixel(Vec3(0.0, 0.0, -0.1005), 0.001));
}

TEST(OcclusionBuffer, TrianglesCrossingTheNearPlaneOccludeWithTheirFarPart) {
  // A triangle from behind the eye to far ahead, under a camera with near
  // 1: it occludes what lies behind its part beyond the near plane, and its
  // bounds are never nearer than that plane.
  OcclusionBuffer ob = begin(look_down_z(90.0, 1.0, 1.0), 64);
  ASSERT_TRUE(ob.render_triangle(Vec3(-50, -50, 5), Vec3(50, -50, 5), Vec3(0, 50, -40)));
  for (int j = 0; j < ob.height(); ++j)
    for (int i = 0; i < ob.width(); ++i) EXPECT_GE(ob.pixel(i, j), 1.0f);
  EXPECT_TRUE(ob.hides_world(Vec3(-0.2, -0.2, -30), Vec3(0.2, 0.2, -29)));
}

TEST(OcclusionBuffer, FineTestHidesALongBoxUnderAFloorSeenAtASlant) {
  // Looking down at a slant over a floor slab (top at y = -1): a long box
  // under it spans depths 5 to 30. At its least depth (its near corner) it
  // is not hidden over its whole rectangle, whose far part shows floor much
  // nearer than the box there; tested over each pixel at its own depth
  // there (its entry planes), it is.
  const Camera cam = camera_along(Vec3(0.0), glm::normalize(Vec3(0.0, -0.4, -1.0)), 60.0, 1.0, 0.1);
  OcclusionBuffer ob = begin(cam, 128);
  ASSERT_TRUE(ob.render_box(Vec3(-50, -2, -60), Vec3(50, -1, 1)));
  const Vec3 lo(-3, -6, -30), hi(3, -3, -5);
  EXPECT_FALSE(ob.hides_world(lo, hi));
  EXPECT_TRUE(ob.hides_world(lo, hi, true));
  EXPECT_TRUE(ob.hides_world_split(lo, hi, 0));
  // Reaching a tenth above the floor's top: seen, whatever the test.
  EXPECT_FALSE(ob.hides_world(lo, Vec3(3, -0.9, -5), true));
  EXPECT_FALSE(ob.hides_world_split(lo, Vec3(3, -0.9, -5), 4));
  // A ball under the floor, tested fine with its bounding box's planes.
  EXPECT_TRUE(ob.hides_sphere(Vec3(0, -8, -20), 6.5, true));
  EXPECT_FALSE(ob.hides_sphere(Vec3(0, -8, -20), 7.2, true));
  // Half of a box out of view to the side and the rest under the floor:
  // the split test drops the pieces no ray of the frame reaches.
  EXPECT_TRUE(ob.hides_world_split(Vec3(-3, -6, -30), Vec3(60, -3, -5), 3));
}

TEST(OcclusionBuffer, SplitTestHidesNothingWhenTheBufferIsOff) {
  // A frame with the buffer off (or a far-eye fallback) after one with it
  // on: the split test must not judge pieces by the earlier frame's view.
  OcclusionBuffer ob = begin(look_down_z(), 128);
  ASSERT_TRUE(ob.render_box(Vec3(-50, -50, -11), Vec3(50, 50, -10)));
  EXPECT_TRUE(ob.hides_world_split(Vec3(-1, -1, -21), Vec3(1, 1, -20), 2));
  ob.begin(detail::make_world_frustum(camera_along(Vec3(0.0), Vec3(0.0, 0.0, 1.0))), 0);
  EXPECT_FALSE(ob.hides_world_split(Vec3(-1, -1, 20), Vec3(1, 1, 21), 2));
  EXPECT_FALSE(ob.hides_world_split(Vec3(-1, -1, -21), Vec3(1, 1, -20), 2));
}

TEST(OcclusionBuffer, EyeOnABoxFacePlaneWritesNoRayHeadingOutThroughIt) {
  // The eye lies exactly on the plane of the (shrunk) box's low x face,
  // beside the box: L.x = lo.x + delta - eye.x is exactly 0 in the box's
  // ray test. Rays heading to x below the eye never enter the box, so the
  // pixels they cross must stay empty (a reciprocal 1 / 0.0 = +inf for that
  // face once made such rays seem never to leave the slab).
  const Vec3 lo(0.0, -10.0, 10.0), hi(10.0, 10.0, 20.0);
  Camera cam = look_down_z();
  cam.eye = Vec3(0.0, 0.0, 5.0);
  const double mag = 5.0 + detail::max_abs(lo) + detail::max_abs(hi);  // As render_box computes it.
  cam.eye.x = 0.0 + 1e-9 * mag;
  ASSERT_EQ(detail::max_abs(cam.eye) + detail::max_abs(lo) + detail::max_abs(hi), mag);
  cam.dir = Vec3(-0.3, 0.0, 1.0);
  ViewBasis vb;
  ASSERT_TRUE(make_basis(cam, &vb));
  constexpr int kWidth = 64;
  OcclusionBuffer ob = begin(cam, kWidth);
  ASSERT_TRUE(ob.render_box(lo, hi));  // Rays heading to larger x do hit it.
  int checked = 0;
  for (int j = 0; j < ob.height(); ++j)
    for (int i = 0; i < ob.width(); ++i) {
      bool away = true;  // Every corner ray heads to x below the eye.
      for (int c = 0; c < 4; ++c) {
        const double x = 2.0 * (i + (c & 1)) / ob.width() - 1.0, y = 2.0 * (j + (c >> 1)) / ob.height() - 1.0;
        away = away && vb.ray_dir(x, y).x < 0.0;
      }
      if (!away) continue;
      ++checked;
      EXPECT_TRUE(std::isinf(ob.pixel(i, j))) << "pixel " << i << ", " << j << " holds " << ob.pixel(i, j);
    }
  EXPECT_GT(checked, kWidth * ob.height() / 2) << "most rays should head away from the box";
}

TEST(OcclusionBuffer, OccludersCrossingTheNearPlaneOccludeWithTheirFarPart) {
  // near = 1. A ball from depth 0.5 to 2.5 and a slab from 0.5 to 3 cross
  // the near plane: only their parts beyond it occlude, first hit at the
  // near plane at the latest.
  {
    OcclusionBuffer ob = begin(look_down_z(60.0, 1.0, 1.0), 64);
    ASSERT_TRUE(ob.render_sphere(Vec3(0, 0, -1.5), 1.0));
    EXPECT_TRUE(ob.hides_world(Vec3(-0.1, -0.1, -30), Vec3(0.1, 0.1, -29)));
    EXPECT_TRUE(ob.hides_world(Vec3(-0.1, -0.1, -1.3), Vec3(0.1, 0.1, -1.2)));  // Inside the ball.
    EXPECT_FALSE(ob.hides_world(Vec3(-0.1, -0.1, -30), Vec3(0.1, 0.1, -0.9)));  // Crosses near.
    // The ball's part beyond near spans slopes up to sqrt(1 - 0.25) / 1 =
    // 0.87 > tan 30: it covers the whole image.
    EXPECT_TRUE(ob.hides_world(Vec3(12, 12, -30), Vec3(13, 13, -29)));
  }
  {
    OcclusionBuffer ob = begin(look_down_z(60.0, 1.0, 1.0), 64);
    ASSERT_TRUE(ob.render_box(Vec3(-5, -5, -3), Vec3(5, 5, -0.5)));
    EXPECT_TRUE(ob.hides_world(Vec3(-0.1, -0.1, -30), Vec3(0.1, 0.1, -29)));
    EXPECT_FALSE(ob.hides_world(Vec3(-0.1, -0.1, -30), Vec3(0.1, 0.1, -0.5)));
    EXPECT_FALSE(ob.hides_world(Vec3(-0.1, -0.1, 1), Vec3(0.1, 0.1, 2)));  // Behind the eye.
    // Beyond its side x = 5 at depth 3 (slope 1.67, outside the image) the
    // box still covers the image at depth <= 3: at slope tan 30 = 0.58 its
    // side is reached at depth 8.7 > 3, so its back face (depth 3) is hit.
    EXPECT_TRUE(ob.hides_world(Vec3(10, -0.1, -30), Vec3(11, 0.1, -29)));
  }
  {
    // Wholly before the near plane: nothing.
    OcclusionBuffer ob = begin(look_down_z(60.0, 1.0, 1.0), 64);
    EXPECT_FALSE(ob.render_sphere(Vec3(0, 0, -0.5), 0.4));
    EXPECT_FALSE(ob.render_box(Vec3(-5, -5, -0.9), Vec3(5, 5, -0.5)));
    EXPECT_FALSE(ob.hides_world(Vec3(-0.1, -0.1, -30), Vec3(0.1, 0.1, -29)));
  }
}

TEST(OcclusionBuffer, EyeInsideAnOccludersBoxWritesNothing) {
  OcclusionBuffer ob = begin(look_down_z(), 64);
  EXPECT_FALSE(ob.render_box(Vec3(-1, -1, -1), Vec3(1, 1, 1)));
  EXPECT_FALSE(ob.render_sphere(Vec3(0, 0, -0.5), 1.0));
  EXPECT_FALSE(ob.hides_world(Vec3(-0.1, -0.1, -30), Vec3(0.1, 0.1, -29)));
}

/// Every ray through a written pixel must be inside the occluder beyond the
/// near plane at a depth no greater than the pixel's bound: sampled inside pixels and
/// exactly on their corners and edges, for random cameras, lenses and shapes.
/// Random occluders and cameras, the scene scaled by `scale` (and, with
/// `tiny_near`, a near plane far below the scene's scale): every ray through
/// every written pixel meets the occluder beyond near no deeper than the
/// pixel's bound. Returns the number of rays checked.
/// Where the ray eye + t d meets triangle (a, b, c) (Moller-Trumbore in
/// double, no tolerance): the buffer's corner rays lie well inside what it
/// writes, so a rounding here cannot decide a test.
bool ray_triangle(const Vec3& eye, const Vec3& d, const Vec3& a, const Vec3& b, const Vec3& c, double* t) {
  const Vec3 e1 = b - a, e2 = c - a, p = glm::cross(d, e2);
  const double det = glm::dot(e1, p);
  if (det == 0.0) return false;
  const Vec3 s = eye - a;
  const double u = glm::dot(s, p) / det;
  const Vec3 q = glm::cross(s, e1);
  const double v = glm::dot(d, q) / det;
  *t = glm::dot(e2, q) / det;
  return u >= 0.0 && v >= 0.0 && u + v <= 1.0 && *t > 0.0;
}

int check_written_bounds(double scale, bool tiny_near, std::uint64_t seed,
                         detail::BufferKernel kernel = detail::BufferKernel::Auto) {
  Rng rng(seed);
  int checked = 0;
  for (int trial = 0; trial < scaled(300); ++trial) {
    Camera cam;
    cam.eye = rng.in_box(Vec3(-5), Vec3(5));
    cam.dir = rng.unit_vector();
    cam.up = rng.unit_vector();
    if (!validate_camera(cam).ok) continue;
    const int lens = rng.uniform_int(0, 3);
    cam.fov_y_deg = lens == 0 ? rng.uniform(1.0, 5.0) : lens == 1 ? rng.uniform(160.0, 179.0) : rng.uniform(20.0, 120.0);
    cam.aspect = rng.chance(0.2) ? rng.log_uniform(0.01, 100.0) : rng.uniform(0.5, 2.5);
    cam.near = tiny_near && rng.chance(0.5) ? 1e-100 * scale : rng.log_uniform(1e-3, 1.0) * scale;
    cam.eye *= scale;
    cam.far *= scale;
    if (!validate_camera(cam).ok) continue;
    ViewBasis vb;
    EXPECT_TRUE(make_basis(cam, &vb));
    const int width = rng.chance(0.5) ? 16 : 64;
    OcclusionBuffer ob = begin(cam, width);
    ob.kernel = kernel;
    ObjectDesc o;
    // A third of the shapes sit at the near plane, so that they cross it.
    const Vec3 at = rng.chance(0.33) ? cam.eye + glm::normalize(cam.dir) * (cam.near * rng.uniform(0.5, 3.0)) +
                                           rng.in_box(Vec3(-0.5), Vec3(0.5)) * scale
                                     : cam.eye + glm::normalize(cam.dir) * rng.uniform(1.0, 20.0) * scale +
                                           rng.in_box(Vec3(-3), Vec3(3)) * scale;
    const int kind = rng.uniform_int(0, 4);
    Vec3 tri[4];
    Vec3 axes[3];
    if (kind == 0) {
      o = sphere(1, at, rng.log_uniform(0.05, 5.0) * scale);
      ob.render_sphere(o.center, o.radius);
    } else if (kind == 1) {
      o = box_around(1, at, rng.in_box(Vec3(0.05), Vec3(4.0)) * scale);
      ob.render_box(o.center - o.half_extent, o.center + o.half_extent);
    } else if (kind == 4) {
      // A box turned about a random axis: drawn along its own axes; the
      // rays are tested in its frame (an axis-aligned box there).
      const Quat q = glm::normalize(Quat(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0),
                                         rng.uniform(-1.0, 1.0)));
      for (int a = 0; a < 3; ++a) {
        Vec3 e(0.0);
        e[a] = 1.0;
        axes[a] = q * e;
      }
      o = box_around(1, at, rng.in_box(Vec3(0.05), Vec3(4.0)) * scale);
      ob.render_oriented_box(o.center, axes, o.half_extent);
    } else {
      // A triangle, now and then a sliver or one seen almost edge-on.
      const double size = rng.log_uniform(0.05, 5.0) * scale;
      for (Vec3& v : tri) v = at + rng.in_box(Vec3(-1.0), Vec3(1.0)) * size;
      if (rng.chance(0.2)) tri[2] = tri[0] + (tri[1] - tri[0]) * rng.uniform() + rng.in_box(Vec3(-1e-6), Vec3(1e-6)) * size;
      if (rng.chance(0.1)) tri[2] = cam.eye + (tri[1] - cam.eye) * rng.uniform(0.5, 2.0) + rng.in_box(Vec3(-1e-3), Vec3(1e-3)) * size;
      o = box_around(1, at, Vec3(size));
      if (kind == 2) {
        ob.render_triangle(tri[0], tri[1], tri[2]);
      } else {
        // A quad: a parallelogram's corners, the fourth bent off its plane
        // now and then (the two triangles (0, 1, 3) and (1, 2, 3)).
        tri[3] = tri[0] + tri[2] - tri[1];
        if (rng.chance(0.5)) tri[3] += rng.in_box(Vec3(-0.05), Vec3(0.05)) * size;
        bool raised = false;
        if (!ob.render_quad(tri, 0.0, &raised)) {
          ob.render_triangle(tri[0], tri[1], tri[3]);
          ob.render_triangle(tri[1], tri[2], tri[3]);
        }
      }
    }
    for (int j = 0; j < ob.height(); ++j) {
      for (int i = 0; i < ob.width(); ++i) {
        const float bound = ob.pixel(i, j);
        if (std::isinf(bound)) continue;
        for (int s = 0; s < 12; ++s) {
          // Corners and edges of the pixel, then random points inside.
          const double fx = s < 4 ? (s & 1) : s < 8 ? (s & 1) * 0.5 + (s & 2) * 0.25 : rng.uniform();
          const double fy = s < 4 ? (s >> 1) : s < 8 ? ((s >> 1) & 1) : rng.uniform();
          const double x = 2.0 * (i + fx) / ob.width() - 1.0, y = 2.0 * (j + fy) / ob.height() - 1.0;
          double t0 = 0.0, t1 = 0.0;
          const Vec3 dir = vb.ray_dir(x, y);
          bool hit = false;
          if (kind < 2) {
            hit = intersect(o, vb.eye, dir, &t0, &t1);
          } else if (kind == 4) {
            // In the box's frame, about its centre.
            const Vec3 e = vb.eye - o.center;
            ObjectDesc local = o;
            local.center = Vec3(0.0);
            const Vec3 le(glm::dot(axes[0], e), glm::dot(axes[1], e), glm::dot(axes[2], e));
            const Vec3 ld(glm::dot(axes[0], dir), glm::dot(axes[1], dir), glm::dot(axes[2], dir));
            hit = intersect(local, le, ld, &t0, &t1);
          } else if (kind == 2) {
            hit = ray_triangle(vb.eye, dir, tri[0], tri[1], tri[2], &t0);
          } else {
            hit = ray_triangle(vb.eye, dir, tri[0], tri[1], tri[3], &t0) ||
                  ray_triangle(vb.eye, dir, tri[1], tri[2], tri[3], &t0);
          }
          if (kind == 2 || kind == 3) t1 = t0;
          EXPECT_TRUE(hit) << "pixel " << i << "," << j << " written but a ray misses: " << describe(cam) << " "
                           << (kind < 2 || kind == 4 ? describe(o) : "a triangle");
          // The first hit beyond the near plane (objects are clipped there).
          EXPECT_GE(t1, cam.near) << "pixel " << i << "," << j << " written but a ray leaves before near: "
                                  << describe(cam) << " " << (kind < 2 || kind == 4 ? describe(o) : "a triangle");
          EXPECT_LE(std::max(t0, cam.near), static_cast<double>(bound))
              << "pixel " << i << "," << j << " bound too near: " << describe(cam) << " "
              << (kind < 2 || kind == 4 ? describe(o) : "a triangle");
          if (!hit || t1 < cam.near || std::max(t0, cam.near) > static_cast<double>(bound)) return checked;
          ++checked;
        }
      }
    }
  }
  return checked;
}

TEST(OcclusionBuffer, AlmostLevelEdgesWriteOnlyWhatTheirRaysHit) {
  // A camera rolled by a hair (up tilted by 1e-305 to 1e-20): the top and
  // bottom edges of a box or a ball's polygon are level but for a rounding's
  // slope, so their row crossings leave the doubles and the rasterizer takes
  // them as level. The rows they pass must still be covered, and every
  // written pixel's rays must meet the shape no deeper than its bound.
  for (double tilt : {0.0, 1e-305, 1e-200, 1e-20}) {
    SCOPED_TRACE("tilt " + std::to_string(tilt));
    Camera cam = look_down_z();
    cam.up = Vec3(tilt, 1.0, 0.0);
    ASSERT_TRUE(validate_camera(cam).ok);
    ViewBasis vb;
    ASSERT_TRUE(make_basis(cam, &vb));
    const ObjectDesc shapes[2] = {box_around(1, Vec3(0.0, 0.25, -11.0), Vec3(2.0, 1.25, 1.0)),
                                  sphere(2, Vec3(0.5, -0.5, -12.0), 2.0)};
    for (const ObjectDesc& o : shapes) {
      OcclusionBuffer ob = begin(cam, 32);
      if (o.shape == Shape::Sphere) {
        ob.render_sphere(o.center, o.radius);
      } else {
        ob.render_box(o.center - o.half_extent, o.center + o.half_extent);
      }
      int written = 0;
      for (int j = 0; j < ob.height(); ++j)
        for (int i = 0; i < ob.width(); ++i) {
          const float bound = ob.pixel(i, j);
          if (std::isinf(bound)) continue;
          ++written;
          for (int c = 0; c < 5; ++c) {
            const double fx = c < 4 ? (c & 1) : 0.5, fy = c < 4 ? (c >> 1) : 0.5;
            const double x = 2.0 * (i + fx) / ob.width() - 1.0, y = 2.0 * (j + fy) / ob.height() - 1.0;
            double t0 = 0.0, t1 = 0.0;
            ASSERT_TRUE(intersect(o, vb.eye, vb.ray_dir(x, y), &t0, &t1)) << "pixel " << i << "," << j << " " << describe(o);
            EXPECT_LE(std::max(t0, cam.near), static_cast<double>(bound)) << "pixel " << i << "," << j << " " << describe(o);
          }
        }
      // About 5 x 3 of its pixels for the box, 12 for the ball, at any tilt.
      EXPECT_GE(written, 10) << describe(o);
    }
  }
}

TEST(OcclusionBuffer, WrittenBoundsHoldForEveryRayOfThePixel) { EXPECT_GT(check_written_bounds(1.0, false, 42), 1000); }

TEST(OcclusionBuffer, WrittenBoundsHoldWithTheScalarTileKernel) {
  EXPECT_GT(check_written_bounds(1.0, false, 44, detail::BufferKernel::Scalar), 1000);
  EXPECT_GT(check_written_bounds(1e-90, true, 45, detail::BufferKernel::Scalar), 500);
}

TEST(OcclusionBuffer, WrittenBoundsHoldAtEveryScale) {
  // A world shrunk to 1e-90 or grown to 1e8, and near planes far below the
  // scene's scale: the bounds are stored as near / depth, in float.
  for (double scale : {1e-90, 1e-5, 1e8})
    for (bool tiny_near : {false, true}) {
      SCOPED_TRACE("scale " + std::to_string(scale) + (tiny_near ? " tiny near" : ""));
      EXPECT_GT(check_written_bounds(scale, tiny_near, 43), 500);
      if (HasFailure()) return;
    }
}

TEST(OcclusionBuffer, BentQuadsWriteBoundsEveryRayOfThePixelKeeps) {
  // Quads of two triangles (0, 1, 3) and (1, 2, 3), their fourth corner bent
  // off the plane of the other three, towards the eye or away, large in the
  // image: every written pixel's rays meet one of the triangles no deeper
  // than its bound (the farther of the two planes is the one written).
  Rng rng(44);
  int checked = 0, drawn = 0;
  for (int trial = 0; trial < scaled(200); ++trial) {
    const Camera cam = camera_along(rng.in_box(Vec3(-5), Vec3(5)), rng.unit_vector(), rng.uniform(30.0, 120.0),
                                    rng.uniform(0.5, 2.0), rng.log_uniform(1e-3, 1.0));
    ViewBasis vb;
    if (!validate_camera(cam).ok || !make_basis(cam, &vb)) continue;
    OcclusionBuffer ob = begin(cam, 32);
    const double dist = rng.uniform(2.0, 20.0);
    const Vec3 centre = cam.eye + glm::normalize(cam.dir) * dist;
    const Vec3 n = rng.unit_vector();
    const Vec3 e1 = glm::normalize(glm::cross(n, rng.unit_vector())), e2 = glm::cross(n, e1);
    const double a = dist * rng.uniform(0.2, 1.0), b = dist * rng.uniform(0.2, 1.0);
    Vec3 q[4] = {centre - a * e1 - b * e2, centre + a * e1 - b * e2, centre + a * e1 + b * e2, centre - a * e1 + b * e2};
    q[3] += n * (rng.uniform(-0.3, 0.3) * std::min(a, b));
    bool raised = false;
    if (!ob.render_quad(q, 0.0, &raised)) continue;
    drawn += raised ? 1 : 0;
    for (int j = 0; j < ob.height(); ++j)
      for (int i = 0; i < ob.width(); ++i) {
        const float bound = ob.pixel(i, j);
        if (std::isinf(bound)) continue;
        for (int c = 0; c < 5; ++c) {
          const double fx = c < 4 ? (c & 1) : rng.uniform(), fy = c < 4 ? (c >> 1) : rng.uniform();
          const Vec3 dir = vb.ray_dir(2.0 * (i + fx) / ob.width() - 1.0, 2.0 * (j + fy) / ob.height() - 1.0);
          double t = 0.0;
          const bool hit = ray_triangle(vb.eye, dir, q[0], q[1], q[3], &t) || ray_triangle(vb.eye, dir, q[1], q[2], q[3], &t);
          ASSERT_TRUE(hit) << "pixel " << i << "," << j << " " << describe(cam);
          ASSERT_LE(std::max(t, cam.near), static_cast<double>(bound)) << "pixel " << i << "," << j << " " << describe(cam);
          ++checked;
        }
      }
  }
  EXPECT_GT(drawn, scaled(200) / 4);
  EXPECT_GT(checked, 1000);
}

TEST(OcclusionBuffer, SphereTestIsTighterThanItsBox) {
  // An occluder ball of radius 4 at depth 10 covers slopes up to
  // 4 / sqrt(84) = 0.436 (fov 90, 256 pixels: a pixel is 0.0078). A ball of
  // radius 1 at depth 20 and slope 0.36 reaches slope 0.41: hidden. Its
  // bounding box's near corners reach slope (7.2 + 1) / 19 = 0.43 at depth
  // 19, within a pixel of the outline: not hidden.
  OcclusionBuffer ob = begin(look_down_z(90.0), 256);
  ASSERT_TRUE(ob.render_sphere(Vec3(0, 0, -10), 4.0));
  EXPECT_TRUE(ob.hides_sphere(Vec3(0, 0, -20), 1.0));
  EXPECT_TRUE(ob.hides_world(Vec3(-1, -1, -21), Vec3(1, 1, -19)));
  const Vec3 side(0.36 * 20.0, 0.0, -20.0);
  EXPECT_TRUE(ob.hides_sphere(side, 1.0));
  EXPECT_FALSE(ob.hides_world(side - 1.0, side + 1.0));
  // Reaching in front of the occluder's surface (depth 6), or beside it:
  // not hidden.
  EXPECT_FALSE(ob.hides_sphere(Vec3(0, 0, -5.5), 1.0));
  EXPECT_FALSE(ob.hides_sphere(Vec3(0.45 * 20.0, 0.0, -20.0), 1.0));
}

/// A random camera near the origin looking down -z, pitched by up to
/// `pitch_lo`..`pitch_hi` (the y component of its direction before
/// normalizing), with a random lens and near plane.
Camera random_camera(Rng& rng, double pitch_lo, double pitch_hi) {
  Camera cam = look_down_z(rng.uniform(20.0, 150.0), rng.uniform(0.5, 2.0), rng.log_uniform(1e-3, 0.5));
  cam.eye = rng.in_box(Vec3(-3), Vec3(3));
  cam.dir = glm::normalize(Vec3(rng.uniform(-0.3, 0.3), rng.uniform(pitch_lo, pitch_hi), -1.0));
  return cam;
}

/// Random occluders ahead of the camera, ids from `first_id`, each a ball
/// or a box, rendered into `ob` and appended to `occ`; sizes and distances
/// times `scale`.
void add_random_occluders(Rng& rng, const Camera& cam, const ViewBasis& vb, int first_id, int count,
                          OcclusionBuffer* ob, std::vector<ObjectDesc>* occ, double scale = 1.0) {
  for (int k = 0; k < count; ++k) {
    const Vec3 at = cam.eye + scale * (vb.f * rng.uniform(3.0, 12.0) + rng.in_box(Vec3(-4, -4, 0), Vec3(4, 4, 0)));
    if (rng.chance(0.5)) {
      occ->push_back(sphere(first_id + k, at, scale * rng.uniform(0.5, 4.0)));
      ob->render_sphere(occ->back().center, occ->back().radius);
    } else {
      occ->push_back(box_around(first_id + k, at, scale * rng.in_box(Vec3(0.3), Vec3(4.0))));
      ob->render_box(occ->back().center - occ->back().half_extent, occ->back().center + occ->back().half_extent);
    }
  }
}

/// For a point p: -1 when it is out of view (beyond the image or before the
/// near plane), 1 when its ray from the eye is inside an occluder beyond the
/// near plane strictly before p, else 0.
int hit_before(const std::vector<ObjectDesc>& occ, const ViewBasis& vb, double near, const Vec3& p) {
  const double depth = glm::dot(p - vb.eye, vb.f);
  if (!(depth >= near)) return -1;
  const Vec3 d = (p - vb.eye) / depth;  // d·f = 1: parameter = depth.
  const double x = glm::dot(p - vb.eye, vb.right) / (depth * vb.tanx);
  const double y = glm::dot(p - vb.eye, vb.up) / (depth * vb.tany);
  if (!(std::fabs(x) <= 1.0 && std::fabs(y) <= 1.0)) return -1;
  for (const ObjectDesc& o : occ) {
    double t0 = 0.0, t1 = 0.0;
    if (intersect(o, vb.eye, d, &t0, &t1) && t1 >= near && std::max(t0, near) < depth) return 1;
  }
  return 0;
}

TEST(OcclusionBuffer, HiddenSpheresAreHiddenForEveryRay) {
  // Random occluders, random balls: whenever hides_sphere says hidden, every
  // sampled point of the ball has an occluder hit before it on its ray.
  Rng rng(77);
  int hidden = 0;
  for (int trial = 0; trial < scaled(200); ++trial) {
    const Camera cam = random_camera(rng, -0.3, 0.3);
    ViewBasis vb;
    ASSERT_TRUE(make_basis(cam, &vb));
    OcclusionBuffer ob = begin(cam, rng.chance(0.5) ? 32 : 128);
    std::vector<ObjectDesc> occ;
    add_random_occluders(rng, cam, vb, 1, 6, &ob, &occ);
    for (int q = 0; q < 40; ++q) {
      Vec3 c = cam.eye + vb.f * rng.uniform(2.0, 30.0) + rng.in_box(Vec3(-6, -6, 0), Vec3(6, 6, 0));
      const double r = rng.log_uniform(0.01, 3.0);
      if (q % 2) {
        // Close behind (or reaching in front of) an occluder's nearest
        // point along the ray to its centre, where a wrong depth shows.
        const ObjectDesc& o = occ[static_cast<std::size_t>(rng.uniform_int(0, 5))];
        const Vec3 to = glm::normalize(o.center - cam.eye);
        double t0 = 0.0, t1 = 0.0;
        if (!intersect(o, cam.eye, to, &t0, &t1)) continue;
        c = cam.eye + to * (t0 + r * rng.uniform(0.5, 2.0));
      }
      if (!ob.hides_sphere(c, r)) continue;
      ++hidden;
      for (int s = 0; s < 200; ++s) {
        // Points on and in the ball.
        const Vec3 p = c + rng.unit_vector() * (s % 2 ? r : r * rng.uniform());
        ASSERT_NE(hit_before(occ, vb, cam.near, p), 0) << "hidden ball has a point in view: centre " << c.x << "," << c.y << ","
                             << c.z << " r " << r << " " << describe(cam);
      }
    }
  }
  EXPECT_GT(hidden, 50) << "too few hidden balls: the test proves little";
}

TEST(OcclusionBuffer, FinelyHiddenBoxesAreHiddenForEveryRay) {
  // Random occluders (a floor slab below the eye among them, seen at a
  // slant), random boxes long and short: whenever the fine test or the
  // split test says hidden, every sampled point of the box in view has an
  // occluder hit before it on its ray. Balls tested fine, the same. The
  // whole set-up at scales 1, 1e-4 and 1e4, half of it 1e5 times its scale
  // from the origin.
  Rng rng(78);
  int hidden = 0, fine_only = 0, balls = 0;
  for (int trial = 0; trial < scaled(200); ++trial) {
    const double sc = trial % 3 == 0 ? 1.0 : trial % 3 == 1 ? 1e-4 : 1e4;
    Camera cam = random_camera(rng, -0.8, 0.1);
    cam.eye = sc * (cam.eye + (trial % 2 ? Vec3(1e5, -2e5, 3e5) : Vec3(0.0)));
    cam.near *= sc;
    cam.far *= sc;
    ViewBasis vb;
    ASSERT_TRUE(make_basis(cam, &vb));
    OcclusionBuffer ob = begin(cam, rng.chance(0.5) ? 32 : 128);
    std::vector<ObjectDesc> occ;
    occ.push_back(box_between(1, cam.eye + sc * Vec3(-80, -rng.uniform(1.0, 3.0) - 1.0, -80),
                              cam.eye + sc * Vec3(80, -rng.uniform(0.5, 1.0), 1)));
    ob.render_box(occ.back().center - occ.back().half_extent, occ.back().center + occ.back().half_extent);
    add_random_occluders(rng, cam, vb, 2, 4, &ob, &occ, sc);
    for (int q = 0; q < 40; ++q) {
      const Vec3 c = cam.eye + sc * (vb.f * rng.uniform(2.0, 30.0) + rng.in_box(Vec3(-8, -10, 0), Vec3(8, 4, 0)));
      const Vec3 half =
          sc * (q % 2 ? rng.in_box(Vec3(0.05), Vec3(1.0)) : rng.in_box(Vec3(0.2, 0.2, 2.0), Vec3(3.0, 2.0, 12.0)));
      const bool ball = q % 5 == 0;
      bool says_hidden = false;
      if (ball) {
        says_hidden = ob.hides_sphere(c, half.x, true);
        balls += says_hidden;
      } else if (q % 3 == 0) {
        says_hidden = ob.hides_world_split(c - half, c + half, 3);
      } else {
        says_hidden = ob.hides_world(c - half, c + half, true);
        fine_only += says_hidden && !ob.hides_world(c - half, c + half);
      }
      if (!says_hidden) continue;
      ++hidden;
      for (int s = 0; s < 300; ++s) {
        // Points on the box's faces and inside it (or the ball's).
        Vec3 p;
        if (ball) {
          p = c + rng.unit_vector() * (s % 2 ? half.x : half.x * rng.uniform());
        } else {
          p = c + rng.in_box(-half, half);
          if (s % 2) {
            const int a = rng.uniform_int(0, 2);
            p[a] = c[a] + (rng.chance(0.5) ? half[a] : -half[a]);
          }
        }
        ASSERT_NE(hit_before(occ, vb, cam.near, p), 0) << "hidden " << (ball ? "ball" : "box") << " has a point in view: centre " << c.x << ","
                             << c.y << "," << c.z << " half " << half.x << "," << half.y << "," << half.z << " "
                             << describe(cam);
      }
    }
  }
  EXPECT_GT(hidden, 200) << "too few hidden boxes: the test proves little";
  EXPECT_GT(fine_only, 20) << "the fine test hid no more than the coarse one";
  EXPECT_GT(balls, 10);
}

SceneOptions with_buffer(std::uint64_t seed, int width) {
  Rng rng(mix_seed(seed, 0x0971));
  SceneOptions opt;
  if (rng.uniform_int(0, 1) == 1) opt.tbv_period = rng.uniform(0.01, 0.2);
  opt.occlusion_buffer = width;
  return opt;
}

/// Random scenes, camera paths (eyes on voxel planes, extreme lenses, large
/// near planes) and moving objects with the buffer on: zero misses.
void run_scenes(int width, std::uint64_t first, int count, const CameraPathParams& params,
                BufferFault fault, int* misses, std::uint64_t* culled) {
  constexpr double kDt = 1.0 / 30.0;
  for (int k = 0; k < count; ++k) {
    const std::uint64_t seed = first + static_cast<std::uint64_t>(k);
    const SceneDesc scene = random_scene(random_scene_params(seed), seed);
    const std::string label = describe_scene(scene, seed) + " ob=" + std::to_string(width);
    EngineHarness h(scene, with_buffer(seed, width), label);
    ASSERT_TRUE(h.status().ok) << h.status().str();
    h.scratch().impl().ob.fault = fault;
    const std::vector<Camera> path = random_camera_path(scene, seed, params);
    Mover mover(scene, seed);
    for (int f = 0; f < params.frames; ++f) {
      const double t = f * kDt;
      if (f > 0) {
        ASSERT_TRUE(h.move(t, mover.step(kDt)).ok);
      }
      const std::string err = h.frame(path[static_cast<std::size_t>(f)], t);
      *culled += h.last().stats.ob_voxels_culled + h.last().stats.ob_objects_culled;
      if (!err.empty()) {
        ++*misses;
        if (fault == BufferFault::None) FAIL() << err;
        break;  // A broken buffer: one miss per scene is enough.
      }
      EXPECT_EQ(h.last().stats.ob_width, static_cast<std::uint32_t>(width));
    }
  }
}

TEST(OcclusionBuffer, EngineWithBufferHasZeroMisses) {
  for (int width : {64, 256}) {
    SCOPED_TRACE("width " + std::to_string(width));
    int misses = 0;
    std::uint64_t culled = 0;
    CameraPathParams p;
    p.frames = std::max(2, scaled(20));
    run_scenes(width, 7000, scaled(30), p, BufferFault::None, &misses, &culled);
    if (HasFatalFailure()) return;
    EXPECT_EQ(misses, 0);
    EXPECT_GT(culled, 0u) << "the buffer never culled anything: the test proves nothing";
  }
}

TEST(OcclusionBuffer, EngineWithBufferAndLargeNearPlanesHasZeroMisses) {
  int misses = 0;
  std::uint64_t culled = 0;
  CameraPathParams p;
  p.frames = std::max(2, scaled(15));
  p.near_min = 0.02;
  p.near_max = 0.4;
  p.snap_eye_chance = 0.5;
  p.extreme_lens_chance = 0.3;
  run_scenes(128, 7500, scaled(15), p, BufferFault::None, &misses, &culled);
  EXPECT_EQ(misses, 0);
}

TEST(OcclusionBuffer, NonConservativeBuffersAreCaught) {
  // The same harness with a rule flipped must report misses: the ray caster
  // sees what a wrong buffer hides.
  for (BufferFault fault : {BufferFault::NearDepth, BufferFault::OuterCoverage}) {
    SCOPED_TRACE(fault == BufferFault::NearDepth ? "near depth" : "outer coverage");
    int misses = 0;
    std::uint64_t culled = 0;
    CameraPathParams p;
    p.frames = 20;
    run_scenes(64, 7000, 30, p, fault, &misses, &culled);
    EXPECT_GT(misses, 0) << "a non-conservative buffer went unnoticed";
  }
}

TEST(OcclusionBuffer, OptionIsValidated) {
  SceneDesc d;
  d.bounds_max = Vec3(10.0);
  d.objects.push_back(sphere(1, Vec3(5.0), 1.0));
  std::unique_ptr<Scene> s;
  for (int bad : {-1, 1, 7, 4097}) {
    SceneOptions o;
    o.occlusion_buffer = bad;
    const Status st = Scene::create(d, o, &s);
    EXPECT_FALSE(st.ok) << bad;
    EXPECT_EQ(st.field, "occlusion_buffer");
  }
  for (int good : {0, 8, 4096}) {
    SceneOptions o;
    o.occlusion_buffer = good;
    EXPECT_TRUE(Scene::create(d, o, &s).ok) << good;
  }
}

}  // namespace
}  // namespace voxvis::test
