// traverse_shells.cpp — the traversal with the occlusion buffer off: the paper's
// chess-metric shells of voxels front to back, with shell-by-shell occlusion
// (traverse.h; the frame around it is frame.cpp).
//
// Occlusion (paper 5.3, done without cap polygons). Let C_k be the cube of
// voxels at chess distance <= k from the eye's voxel E; the eye is inside it.
// A segment from the eye to a point p of a voxel v in shell k+1 leaves C_k
// once, through a point q on a face of C_k, and q lies in a voxel u of shell
// k. If u is opaque (wholly inside an object beyond the near plane) q is an
// object point before p; if u is occluded, q is hidden and so is p. The q's of
// all points of v lie in the central projection of v onto the faces of C_k
// that v is beyond, a convex region bounded by the projections of v's
// corners. So v is occluded when every shell-k voxel that region meets is
// opaque or occluded. Occluder fusion is implicit: any mix of opaque and
// occluded voxels hides what lies behind it.
//
// Only segments inside the view pyramid matter: a shell-k voxel the pyramid
// misses cannot hold any such q, so it counts as blocking. The traversal
// therefore never computes voxels outside the pyramid, and a voxel it did not
// reach in shell k (outside the pyramid, or culled because no live voxel of
// shell k-1 was near it) reads as blocking. Voxels beyond the grid are empty
// space: they never block.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "numeric.h"
#include "traverse.h"
#include "voxvis/assert.h"
#include "voxvis/inspect.h"

namespace voxvis {

using detail::LocalFrustum;
using detail::Obj;
using detail::WorldFrustum;
using detail::max_abs;

namespace {

// A reached voxel's status (its stamp's low bits). Both blocking ones have
// the kBlocked bit, which is all the tests read; the two are told apart only
// for the frame's record (trace_voxels): hidden, or an occluder in view.
constexpr std::uint32_t kLive = 1;     ///< In view, not blocking.
constexpr std::uint32_t kBlocked = 2;  ///< Proven hidden.
constexpr std::uint32_t kOpaque = 3;   ///< In view and opaque beyond the near plane: it blocks.

/// The six faces of a shell, numbered 2a + side: a face is normal to axis
/// a (face / 2) on the + side (face % 2 == 0) or the - side; b and d are the
/// other two axes in increasing order. The one rule for every loop over
/// faces or axes below.
struct FaceAxes {
  int a, b, d;
};
constexpr FaceAxes face_axes(int face) {
  const int a = face >> 1;
  return {a, a == 0 ? 1 : 0, a == 2 ? 1 : 2};
}
constexpr FaceAxes axis_axes(int a) { return face_axes(2 * a); }
/// The layer of shell m that a face lies in, on its axis.
constexpr std::int64_t face_layer(int face, std::int64_t m) { return (face & 1) ? -m : m; }

/// Inclusive box of local voxel coordinates.
struct IBox {
  std::int64_t lo[3];
  std::int64_t hi[3];
};

/// An inclusive int64 range [lo, hi]; empty when hi < lo.
struct Range {
  std::int64_t lo = 0, hi = -1;
  bool empty() const { return hi < lo; }
};

/// Where the segments to a face's voxels leave C_j, tabulated per row and
/// column: for a voxel (b, d) whose projection falls wholly on the face of
/// C_j it faces, the exit voxels of shell j are [b_lo, b_hi] x [d_lo, d_hi] on the
/// face of C_j at `ua` on the face's axis. Empty ranges: prove nothing.
struct ExitTable {
  std::int64_t j = 0;   ///< Shell the exits are on.
  std::int64_t ua = 0;  ///< Local coordinate of C_j's face layer on the face axis.
  std::int64_t b0 = 0, d0 = 0;
  std::int64_t base = 0;          ///< Voxel index of local (ua, 0, 0) on (a, b, d).
  std::int64_t sb = 0, sd = 0;    ///< Index strides along b and d.
  bool layer_in_grid = true;      ///< The face layer of C_j lies in the grid.
  /// Per column / row: (lo, hi) exit range, and whether the whole
  /// projection falls on this face of C_j (else the segments may leave
  /// through a side face and the general routine must answer).
  std::vector<std::int64_t> b, d;
  std::vector<std::uint8_t> b_whole, d_whole;
};


class Traversal {
 public:
  Traversal(const Scene::Impl& s, Scratch::Impl& w, FrameStats& st, const detail::FrameGeometry& g,
            detail::Collector& col)
      : s_(s), w_(w), st_(st), col_(col), tag_(static_cast<std::uint32_t>(w.stamp_tag << 2)) {
    // A tag of six bits above the status's two, never 0 (a cleared
    // stamp), over a stamp per voxel of the grid (begin_voxels).
    VOXVIS_ASSERT(w.stamp_tag >= 1 && w.stamp_tag < 64 && w.stamp.size() >= s.vflags.size());
    for (int a = 0; a < 3; ++a) {
      E_[a] = g.E[a];
      glo_[a] = g.glo[a];
      ghi_[a] = g.ghi[a];
      stride_[a] = g.stride[a];
    }
    lf_ = g.lf;
    tol_ = g.tol;
    depth_tol_ = g.depth_tol;
  }

  /// Runs the traversal; adds PVS slots to w.pvs, and the slots of the TBVs
  /// it reaches to w.deferred. It only reads the scene, so frames of
  /// different viewers traverse in parallel (Scene::frame).
  void run();

 private:
  bool in_grid(const std::int64_t v[3]) const {
    return v[0] >= glo_[0] && v[0] <= ghi_[0] && v[1] >= glo_[1] && v[1] <= ghi_[1] &&
           v[2] >= glo_[2] && v[2] <= ghi_[2];
  }
  std::int64_t gindex(const std::int64_t v[3]) const {
    return (E_[0] + v[0]) + stride_[1] * (E_[1] + v[1]) + stride_[2] * (E_[2] + v[2]);
  }
  /// Status of a voxel of the previous shell: true when it blocks.
  bool blocks(const std::int64_t u[3]) const {
    if (!in_grid(u)) return false;  // Empty space beyond the grid.
    const std::uint8_t st = w_.stamp[static_cast<std::size_t>(gindex(u))];
    return (st & ~3u) != tag_ || (st & kBlocked) != 0;
  }
  Range required(int b, std::int64_t vb, double t0, double t1, std::int64_t k,
                 bool* whole = nullptr) const;
  bool occluded_at(const std::int64_t v[3], std::int64_t j) const;
  bool occluded_further_back(const std::int64_t v[3], std::int64_t m) const;
  Range frustum_rect_axis(int a, std::int64_t la, int b, bool* any) const;
  Range row_in_pyramid(int a, std::int64_t la, int b, int d, std::int64_t vd, std::int64_t b0,
                       std::int64_t b1) const;
  void fill_table(ExitTable& t, int face, std::int64_t la, std::int64_t j, const Range& rb,
                  const Range& rd) const;
  /// Per-row view of an exit table: the row's exit rows on C_j, if the
  /// table answers for this row at all.
  struct RowExits {
    bool whole = false;      ///< The table answers for voxels of this row (per column too).
    bool never = false;      ///< No voxel of the row can be proven occluded by it.
    std::int64_t ud0 = 0, ud1 = -1;
  };
  RowExits row_exits(const ExitTable& t, int d, std::int64_t vd) const;
  bool row_occluded(const ExitTable& t, const RowExits& r, std::int64_t vb, int b,
                    const std::int64_t v[3]) const;
  void visit_row(int face, int a, int b, int d, std::int64_t la, std::int64_t vd, Range row,
                 std::int64_t m);
  void collect(std::int64_t idx, const std::int64_t v[3], std::uint8_t flags);

  const Scene::Impl& s_;
  Scratch::Impl& w_;
  FrameStats& st_;
  detail::Collector& col_;
  const std::uint32_t tag_;

  LocalFrustum lf_;
  std::int64_t E_[3]{};
  std::int64_t glo_[3]{}, ghi_[3]{};
  std::int64_t stride_[3]{1, 0, 0};
  bool eye_inside_ = false;
  double tol_ = 0.0;        ///< Local grid units.
  double depth_tol_ = 0.0;  ///< World units.
  bool deep_ = false;  ///< SceneOptions::deep_shells.
  bool has_dyn_ = false;
  ExitTable prev_, half_;  ///< Exits on shell m-1 and on shell m/2.
  IBox face_live_[6]{};
  bool face_has_live_[6]{};
};

Range Traversal::required(int b, std::int64_t vb, double t0, double t1, std::int64_t k,
                          bool* whole) const {
  // Exit points q_b = e_b + (p_b - e_b) * t for p_b in {vb, vb+1}, t in {t0, t1}.
  const double eb = lf_.e[b];
  const double p0 = static_cast<double>(vb) - eb;
  const double p1 = p0 + 1.0;
  const double q[4] = {eb + p0 * t0, eb + p1 * t0, eb + p0 * t1, eb + p1 * t1};
  const double lo = std::min(std::min(q[0], q[1]), std::min(q[2], q[3]));
  const double hi = std::max(std::max(q[0], q[1]), std::max(q[2], q[3]));
  const double kd = static_cast<double>(k);
  Range r;
  if (whole) *whole = lo >= -kd - tol_ && hi <= kd + 1.0 + tol_;
  if (hi < -kd - tol_ || lo > kd + 1.0 + tol_) return r;  // Leaves through another face.
  if (t0 == 1.0 || t1 == 1.0) {
    // v's face towards the eye lies on C_k's boundary (k is the previous
    // shell): those points exit exactly where they are, q = p, with q_b in
    // [vb, vb+1] exactly, and no rounding. What must block is the voxel
    // holding the segment's points just before q, on the eye's side of q
    // along b: for q_b = vb that is vb-1 when the eye lies below vb and vb
    // when above; for q_b = vb+1, vb when the eye lies below vb+1 and vb+1
    // when above; both voxels when the eye is (within the rounding allowance)
    // on the plane. So the near face needs {vb-1, vb} with the eye below v's
    // slab, {vb, vb+1} above it and only vb within it. Counting both
    // neighbours always (as the rounded range below would) erodes every
    // shadow by a voxel a shell on each side. The other face's exits lie
    // strictly inside (t < 1) and keep the rounded range.
    const double t = t0 == 1.0 ? t1 : t0;
    const double a0 = eb + p0 * t, a1 = eb + p1 * t;
    std::int64_t lo_i = static_cast<std::int64_t>(std::floor(std::fmin(a0, a1) - tol_));
    std::int64_t hi_i = static_cast<std::int64_t>(std::floor(std::fmax(a0, a1) + tol_));
    const std::int64_t n_lo = p0 < -tol_ ? vb : vb - 1;
    const std::int64_t n_hi = p1 > tol_ ? vb : vb + 1;
    lo_i = std::min(lo_i, n_lo);
    hi_i = std::max(hi_i, n_hi);
    r.lo = std::max(-k, lo_i);
    r.hi = std::min(k, hi_i);
  } else {
    r.lo = std::max(-k, static_cast<std::int64_t>(std::floor(lo - tol_)));
    r.hi = std::min(k, static_cast<std::int64_t>(std::floor(hi + tol_)));
  }
  if (eye_inside_) {
    // Eye and v are in the grid box, so is the segment: clamp to the grid.
    r.lo = std::max(r.lo, glo_[b]);
    r.hi = std::min(r.hi, ghi_[b]);
  }
  return r;
}

bool Traversal::occluded_at(const std::int64_t v[3], std::int64_t j) const {
  // Segments from the eye to v leave C_j through the faces of C_j that v lies
  // wholly beyond; j may be any shell before v's.
  bool any = false;
  for (int a = 0; a < 3; ++a) {
    std::int64_t ua;
    double c;
    if (v[a] >= j + 1) {
      ua = j;
      c = static_cast<double>(j + 1);
    } else if (v[a] <= -(j + 1)) {
      ua = -j;
      c = static_cast<double>(-j);
    } else {
      continue;
    }
    const double ea = lf_.e[a];
    const double va = static_cast<double>(v[a]);
    const double t0 = (c - ea) / (va - ea);
    const double t1 = (c - ea) / (va + 1.0 - ea);
    const FaceAxes ax = axis_axes(a);
    const int b = ax.b, d = ax.d;
    const Range rb = required(b, v[b], t0, t1, j);
    const Range rd = required(d, v[d], t0, t1, j);
    if (rb.empty() || rd.empty()) continue;
    std::int64_t u[3];
    u[a] = ua;
    for (u[d] = rd.lo; u[d] <= rd.hi; ++u[d])
      for (u[b] = rb.lo; u[b] <= rb.hi; ++u[b]) {
        if (!blocks(u)) return false;
        any = true;
      }
  }
  return any;  // No exit voxel found at all: cannot prove anything.
}

bool Traversal::occluded_further_back(const std::int64_t v[3], std::int64_t m) const {
  // Off the axes a shadow's edge moves across the shells, and the previous
  // shell's test, which needs every voxel v's projection meets (two or three
  // across where rays cross voxel boundaries at an angle), loses up to a
  // voxel of it per shell: the shadow of a small occluder dies within a few
  // shells. One test against shell j loses at most that voxel once, however
  // far j is, so shells m-2, m-4, m-8, ... reach back to the occluder in a
  // few hops (each is the argument of docs/design.md for another earlier
  // shell, as conservative). A shell is tried only when the voxel where the
  // ray through v's centre leaves C_j blocks: that voxel is among those the
  // full test needs, so the test could not succeed otherwise.
  const Vec3 r{static_cast<double>(v[0]) + 0.5 - lf_.e.x, static_cast<double>(v[1]) + 0.5 - lf_.e.y,
               static_cast<double>(v[2]) + 0.5 - lf_.e.z};
  for (std::int64_t step = 2; step < m; step *= 2) {
    const std::int64_t j = m - step;
    if (j == m / 2) continue;  // Tested already.
    // The centre ray leaves C_j = [-j, j+1]^3 through the face it reaches first.
    double t = std::numeric_limits<double>::infinity();
    int k = 0;
    for (int ax = 0; ax < 3; ++ax) {
      if (r[ax] == 0.0) continue;
      const double bound = r[ax] > 0.0 ? static_cast<double>(j + 1) : static_cast<double>(-j);
      const double tk = (bound - lf_.e[ax]) / r[ax];
      if (tk < t) {
        t = tk;
        k = ax;
      }
    }
    std::int64_t u[3];
    for (int ax = 0; ax < 3; ++ax) {
      const double q = std::floor(lf_.e[ax] + r[ax] * t);
      u[ax] = std::clamp(static_cast<std::int64_t>(q), -j, j);
    }
    u[k] = r[k] > 0.0 ? j : -j;
    if (blocks(u) && occluded_at(v, j)) return true;
  }
  return false;
}

Range Traversal::frustum_rect_axis(int a, std::int64_t la, int b, bool* any) const {
  // Bounding range on axis b of the pyramid cut by the slab [la, la+1] on axis a.
  const double s0 = static_cast<double>(la), s1 = s0 + 1.0;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  auto take = [&](const Vec3& p) {
    lo = std::fmin(lo, p[b]);
    hi = std::fmax(hi, p[b]);
  };
  const auto& V = lf_.verts;
  for (const Vec3& p : V)
    if (p[a] >= s0 - tol_ && p[a] <= s1 + tol_) take(p);
  static constexpr int kEdges[8][2] = {{0, 1}, {0, 2}, {0, 3}, {0, 4}, {1, 2}, {2, 4}, {4, 3}, {3, 1}};
  for (const auto& ed : kEdges) {
    const Vec3& p = V[static_cast<std::size_t>(ed[0])];
    const Vec3& q = V[static_cast<std::size_t>(ed[1])];
    for (double c : {s0, s1}) {
      if ((p[a] - c) * (q[a] - c) <= 0.0 && p[a] != q[a]) {
        const double t = (c - p[a]) / (q[a] - p[a]);
        take(p + (q - p) * t);
      }
    }
  }
  Range r;
  *any = lo <= hi;
  if (!*any) return r;
  const double clampv = 9e15;  // Far beyond any grid; keeps the casts defined.
  r.lo = static_cast<std::int64_t>(std::floor(std::fmax(lo - tol_, -clampv)));
  r.hi = static_cast<std::int64_t>(std::floor(std::fmin(hi + tol_, clampv)));
  return r;
}

Range Traversal::row_in_pyramid(int a, std::int64_t la, int b, int d, std::int64_t vd,
                                std::int64_t b0, std::int64_t b1) const {
  // The voxels (la, b, vd) the pyramid may meet form an interval in b: each
  // plane's largest value over a voxel is linear in b. Widened by one voxel
  // on each side so rounding never drops one; a voxel it keeps in error is
  // only computed, which is conservative.
  double lo = static_cast<double>(b0), hi = static_cast<double>(b1);
  const double fa = static_cast<double>(la), fd = static_cast<double>(vd);
  for (const detail::Plane& p : lf_.side) {
    const double na = p.n[a], nb = p.n[b], nd = p.n[d];
    const double c = p.d + (na > 0 ? na * (fa + 1.0) : na * fa) + (nd > 0 ? nd * (fd + 1.0) : nd * fd) +
                     (nb > 0 ? nb : 0.0);
    const double need = -lf_.tol - c;  // nb * b >= need
    if (nb > 0.0) {
      lo = std::fmax(lo, std::ceil(need / nb) - 1.0);
    } else if (nb < 0.0) {
      hi = std::fmin(hi, std::floor(need / nb) + 1.0);
    } else if (need > 0.0) {
      return Range{};
    }
    if (!(lo <= hi)) return Range{};
  }
  return Range{static_cast<std::int64_t>(lo), static_cast<std::int64_t>(hi)};
}

void Traversal::collect(std::int64_t idx, const std::int64_t v[3], std::uint8_t flags) {
  const auto i = static_cast<std::size_t>(idx);
  const detail::IdLists& own = s_.static_lists[0];
  if (flags & Scene::Impl::kStaticIds)
    for (const std::uint32_t* p = own.begin(i); p != own.end(i); ++p) col_.add(*p);
  const int gx = static_cast<int>(E_[0] + v[0]);
  const int gy = static_cast<int>(E_[1] + v[1]);
  const int gz = static_cast<int>(E_[2] + v[2]);
  if (flags & Scene::Impl::kCoarseIds) {
    // The objects of the coarser cells holding the voxel touch all of it:
    // collected with the first voxel of the cell the frame reaches.
    for (int l = 1; l < s_.pyr.levels; ++l) {
      const detail::IdLists& lists = s_.static_lists[static_cast<std::size_t>(l)];
      if (!lists.any()) continue;
      const int sh = detail::kCellShift * l;
      const std::size_t c = s_.pyr.index(l, glm::ivec3(gx >> sh, gy >> sh, gz >> sh));
      std::uint32_t& mark = w_.cell_seen[s_.cell_base[static_cast<std::size_t>(l)] + c];
      if (mark == w_.frame) continue;
      mark = w_.frame;
      for (const std::uint32_t* p = lists.begin(c); p != lists.end(c); ++p) col_.add(*p);
    }
  }
  if (!has_dyn_) return;
  const auto bi = static_cast<std::size_t>(
      (gx >> detail::kBrickShift) +
      s_.bricks_res.x * ((gy >> detail::kBrickShift) + std::int64_t{s_.bricks_res.y} * (gz >> detail::kBrickShift)));
  // The voxel is in view and not proven hidden: this frame sees it, and TBVs
  // made after the frame keep clear of it (Scene::Impl::mark_seen).
  col_.see_voxel(gx, gy, gz);
  // The dynamic entries of the voxel's brick and of the coarser cells
  // holding it (those wholly inside an object's range of bricks).
  const int levels = s_.coarse_dyn_live > 0 ? s_.pyr.levels : 2;
  for (int l = 1; l < levels; ++l) {
    const int sh = detail::kCellShift * l;
    const detail::Brick& cell = l == 1 ? s_.bricks[bi]
                                       : s_.coarse_dyn[static_cast<std::size_t>(l)][s_.pyr.index(l, glm::ivec3(gx >> sh, gy >> sh, gz >> sh))];
    if (cell.live == 0) continue;
    for (const detail::BrickEntry& e : cell.entries) {
      if (!s_.current(e)) continue;
      const std::uint32_t slot = e.key >> 1;
      const Obj& o = s_.objs[slot];
      if (e.key & 1u) {
        if (o.tbv_voxels.contains(glm::ivec3(gx, gy, gz))) col_.reveal(slot);
      } else if (w_.obj_seen[slot] != w_.frame && s_.touches(o, o.center, gx, gy, gz)) {
        col_.add(slot);
      }
    }
  }
}

void Traversal::fill_table(ExitTable& t, int face, std::int64_t la, std::int64_t j,
                           const Range& rb, const Range& rd) const {
  const FaceAxes ax = face_axes(face);
  const int a = ax.a, b = ax.b, d = ax.d;
  const double c = (face & 1) ? static_cast<double>(-j) : static_cast<double>(j + 1);
  const double ea = lf_.e[a];
  const double t0 = (c - ea) / (static_cast<double>(la) - ea);
  const double t1 = (c - ea) / (static_cast<double>(la) + 1.0 - ea);
  t.j = j;
  t.ua = face_layer(face, j);
  t.b0 = rb.lo;
  t.d0 = rd.lo;
  t.sb = stride_[b];
  t.sd = stride_[d];
  t.base = (E_[a] + t.ua) * stride_[a] + E_[b] * stride_[b] + E_[d] * stride_[d];
  t.layer_in_grid = t.ua >= glo_[a] && t.ua <= ghi_[a];
  auto fill = [&](int axis, const Range& range, std::vector<std::int64_t>& out,
                  std::vector<std::uint8_t>& whole) {
    out.resize(static_cast<std::size_t>(2 * (range.hi - range.lo + 1)));
    whole.resize(static_cast<std::size_t>(range.hi - range.lo + 1));
    for (std::int64_t x = range.lo; x <= range.hi; ++x) {
      bool w = false;
      const Range r = required(axis, x, t0, t1, j, &w);
      const auto i = static_cast<std::size_t>(x - range.lo);
      out[2 * i] = r.lo;
      out[2 * i + 1] = r.hi;
      whole[i] = w;
    }
  };
  fill(b, rb, t.b, t.b_whole);
  fill(d, rd, t.d, t.d_whole);
}

Traversal::RowExits Traversal::row_exits(const ExitTable& t, int d, std::int64_t vd) const {
  RowExits r;
  const auto i = static_cast<std::size_t>(vd - t.d0);
  r.whole = t.d_whole[i] != 0;
  r.ud0 = t.d[2 * i];
  r.ud1 = t.d[2 * i + 1];
  // An empty exit range, or exits beyond the grid (empty space) with the
  // eye outside, prove nothing.
  r.never = r.ud0 > r.ud1 ||
            (!eye_inside_ && (!t.layer_in_grid || r.ud0 < glo_[d] || r.ud1 > ghi_[d]));
  return r;
}

bool Traversal::row_occluded(const ExitTable& t, const RowExits& r, std::int64_t vb, int b,
                             const std::int64_t v[3]) const {
  const auto i = static_cast<std::size_t>(vb - t.b0);
  if (!r.whole || !t.b_whole[i]) return occluded_at(v, t.j);  // May leave through a side face.
  if (r.never) return false;
  const std::int64_t ub0 = t.b[2 * i], ub1 = t.b[2 * i + 1];
  if (ub0 > ub1) return false;
  if (!eye_inside_ && (ub0 < glo_[b] || ub1 > ghi_[b])) return false;
  const std::uint8_t* stamp = w_.stamp.data();
  for (std::int64_t ud = r.ud0; ud <= r.ud1; ++ud) {
    const std::int64_t rowi = t.base + ud * t.sd;
    for (std::int64_t ub = ub0; ub <= ub1; ++ub) {
      const std::uint8_t st = stamp[static_cast<std::size_t>(rowi + ub * t.sb)];
      if ((st & ~3u) == tag_ && (st & 3u) == kLive) return false;
    }
  }
  return true;
}

void Traversal::visit_row(int face, int a, int b, int d, std::int64_t la, std::int64_t vd,
                          Range row, std::int64_t m) {
  // Visits a row of a face layer, with what is constant along it hoisted:
  // the voxel index steps by one stride, the exit rows are fixed, and the
  // live range is gathered once per row.
  std::int64_t v[3];
  v[a] = la;
  v[d] = vd;
  v[b] = 0;
  const std::int64_t base = gindex(v);
  const std::int64_t sb = stride_[b];
  RowExits pe, he;
  if (m >= 2) pe = row_exits(prev_, d, vd);
  if (m >= 4) he = row_exits(half_, d, vd);
  std::uint8_t* stamps = w_.stamp.data();
  const std::uint8_t* flags_arr = s_.vflags.data();
  std::int64_t live_lo = std::numeric_limits<std::int64_t>::max(), live_hi = std::numeric_limits<std::int64_t>::min();
  for (std::int64_t vb = row.lo; vb <= row.hi; ++vb) {
    v[b] = vb;
    // The row's ends were widened for rounding: test them exactly.
    if ((vb == row.lo || vb == row.hi) &&
        !lf_.may_contain_voxel(Vec3(static_cast<double>(v[0]), static_cast<double>(v[1]),
                                    static_cast<double>(v[2]))))
      continue;
    const std::int64_t idx = base + vb * sb;
    VOXVIS_ASSERT(idx >= 0 && static_cast<std::size_t>(idx) < s_.vflags.size());
    std::uint8_t& stamp = stamps[static_cast<std::size_t>(idx)];
    if ((stamp & ~3u) == tag_) continue;  // Reached through another face already.
    ++st_.voxels_visited;
    // Exits rounded at voxel boundaries can still erode a shadow at the
    // previous shell where rays cross them at an angle; the half-distance
    // shell keeps the occluders' own voxels in view for twice as long, so
    // its test stops the losses adding up (docs/design.md, "Which shells").
    if (m >= 2 && (row_occluded(prev_, pe, vb, b, v) || (m >= 4 && row_occluded(half_, he, vb, b, v)))) {
      stamp = static_cast<std::uint8_t>(tag_ | kBlocked);
      continue;
    }
    const std::uint8_t flags = flags_arr[static_cast<std::size_t>(idx)];
    // Opaque voxels only: those are the ones under a surface, and the test
    // costs too much for every empty voxel in view.
    if ((flags & Scene::Impl::kStaticOpaque) && col_.front_blocked(v, idx)) {
      stamp = static_cast<std::uint8_t>(tag_ | kBlocked);
      ++st_.front_voxels_culled;
      continue;
    }
    if (deep_ && m >= 3 && occluded_further_back(v, m)) {
      stamp = static_cast<std::uint8_t>(tag_ | kBlocked);
      continue;
    }
    bool blocking = false;
    if (flags & (Scene::Impl::kStaticOpaque | Scene::Impl::kDynOpaque)) {
      // An opaque voxel occludes only when wholly beyond the near plane:
      // nearer geometry is clipped away by a renderer and hides nothing.
      const Vec3 lo{static_cast<double>(v[0]), static_cast<double>(v[1]), static_cast<double>(v[2])};
      blocking = lf_.depth_min(lo) >= lf_.near + depth_tol_;
    }
    stamp = static_cast<std::uint8_t>(tag_ | (blocking ? kOpaque : kLive));
    if (!blocking) {
      live_lo = std::min(live_lo, vb);
      live_hi = vb;
    }
    if ((flags & (Scene::Impl::kStaticIds | Scene::Impl::kCoarseIds)) == 0 && !has_dyn_) continue;  // Nothing to collect.
    const Vec3 lo{static_cast<double>(v[0]), static_cast<double>(v[1]), static_cast<double>(v[2])};
    if (lf_.depth_max(lo) >= lf_.near - depth_tol_) collect(idx, v, flags);
  }
  if (live_lo > live_hi) return;
  IBox& fl = face_live_[face];
  if (!face_has_live_[face]) {
    fl.lo[a] = fl.hi[a] = la;
    fl.lo[d] = fl.hi[d] = vd;
    fl.lo[b] = live_lo;
    fl.hi[b] = live_hi;
    face_has_live_[face] = true;
  } else {
    fl.lo[d] = std::min(fl.lo[d], vd);
    fl.hi[d] = std::max(fl.hi[d], vd);
    fl.lo[b] = std::min(fl.lo[b], live_lo);
    fl.hi[b] = std::max(fl.hi[b], live_hi);
  }
}

void Traversal::run() {
  has_dyn_ = !s_.bricks.empty();
  deep_ = s_.options.deep_shells;

  std::int64_t k0 = 0, kmax = 0;
  for (int a = 0; a < 3; ++a) {
    const std::int64_t da = glo_[a] > 0 ? glo_[a] : (ghi_[a] < 0 ? -ghi_[a] : 0);
    k0 = std::max(k0, da);
    kmax = std::max(kmax, std::max<std::int64_t>(std::llabs(glo_[a]), std::llabs(ghi_[a])));
  }
  eye_inside_ = k0 == 0;

  std::vector<IBox> live, next;
  auto add_face_rects = [&](std::int64_t m, std::vector<IBox>& out, bool only_outside) {
    // The pyramid's cut with each face layer of shell m, minus the grid when
    // only_outside: empty space that never blocks.
    for (int face = 0; face < 6; ++face) {
      const FaceAxes ax = face_axes(face);
      const int a = ax.a, b = ax.b, d = ax.d;
      const std::int64_t la = face_layer(face, m);
      bool any_b = false, any_d = false;
      Range rb = frustum_rect_axis(a, la, b, &any_b);
      Range rd = frustum_rect_axis(a, la, d, &any_d);
      if (!any_b || !any_d) continue;
      rb.lo = std::max(rb.lo, -m), rb.hi = std::min(rb.hi, m);
      rd.lo = std::max(rd.lo, -m), rd.hi = std::min(rd.hi, m);
      if (rb.empty() || rd.empty()) continue;
      auto push = [&](Range pb, Range pd) {
        if (pb.empty() || pd.empty()) return;
        IBox bx;
        bx.lo[a] = bx.hi[a] = la;
        bx.lo[b] = pb.lo, bx.hi[b] = pb.hi, bx.lo[d] = pd.lo, bx.hi[d] = pd.hi;
        out.push_back(bx);
      };
      const bool layer_in = la >= glo_[a] && la <= ghi_[a];
      if (!only_outside || !layer_in) {
        push(rb, rd);
        continue;
      }
      push({rb.lo, std::min(rb.hi, glo_[b] - 1)}, rd);
      push({std::max(rb.lo, ghi_[b] + 1), rb.hi}, rd);
      const Range mid{std::max(rb.lo, glo_[b]), std::min(rb.hi, ghi_[b])};
      push(mid, {rd.lo, std::min(rd.hi, glo_[d] - 1)});
      push(mid, {std::max(rd.lo, ghi_[d] + 1), rd.hi});
    }
  };

  std::int64_t m = 0;
  if (eye_inside_) {
    live.push_back(IBox{{0, 0, 0}, {0, 0, 0}});
  } else {
    m = k0;
    add_face_rects(k0 - 1, live, false);
  }

  for (; m <= kmax; ++m) {
    ++st_.shells;
    next.clear();
    for (int f = 0; f < 6; ++f) face_has_live_[f] = false;
    if (!eye_inside_) add_face_rects(m, next, true);
    const std::int64_t R = m - 1 <= 1 ? 4 : 3;  // Exit voxels lie within R of v (docs/design.md).
    for (int face = 0; face < 6; ++face) {
      const FaceAxes ax = face_axes(face);
      const int a = ax.a, b = ax.b, d = ax.d;
      const std::int64_t la = face_layer(face, m);
      if (la < glo_[a] || la > ghi_[a]) continue;
      if (m == 0 && face > 0) break;
      bool any_b = false, any_d = false;
      Range rb = frustum_rect_axis(a, la, b, &any_b);
      Range rd = frustum_rect_axis(a, la, d, &any_d);
      if (!any_b || !any_d) continue;
      rb.lo = std::max({rb.lo, -m, glo_[b]});
      rb.hi = std::min({rb.hi, m, ghi_[b]});
      rd.lo = std::max({rd.lo, -m, glo_[d]});
      rd.hi = std::min({rd.hi, m, ghi_[d]});
      if (rb.empty() || rd.empty()) continue;

      // Only the part of the rectangle near shell m-1's live voxels can
      // hold a non-occluded voxel.
      Range cb, cd;
      cb.lo = cd.lo = std::numeric_limits<std::int64_t>::max();
      cb.hi = cd.hi = std::numeric_limits<std::int64_t>::min();
      for (const IBox& L : live) {
        if (la < L.lo[a] - R || la > L.hi[a] + R) continue;
        cb.lo = std::min(cb.lo, std::max(rb.lo, L.lo[b] - R));
        cb.hi = std::max(cb.hi, std::min(rb.hi, L.hi[b] + R));
        cd.lo = std::min(cd.lo, std::max(rd.lo, L.lo[d] - R));
        cd.hi = std::max(cd.hi, std::min(rd.hi, L.hi[d] + R));
      }
      if (cb.empty() || cd.empty()) continue;
      if (m >= 2) fill_table(prev_, face, la, m - 1, cb, cd);
      if (m >= 4) fill_table(half_, face, la, m / 2, cb, cd);
      for (const IBox& L : live) {
        if (la < L.lo[a] - R || la > L.hi[a] + R) continue;
        const std::int64_t b0 = std::max(cb.lo, L.lo[b] - R), b1 = std::min(cb.hi, L.hi[b] + R);
        const std::int64_t d0 = std::max(cd.lo, L.lo[d] - R), d1 = std::min(cd.hi, L.hi[d] + R);
        std::int64_t v[3];
        v[a] = la;
        for (v[d] = d0; v[d] <= d1; ++v[d]) {
          const Range row = row_in_pyramid(a, la, b, d, v[d], b0, b1);
          if (!row.empty()) visit_row(face, a, b, d, la, v[d], row, m);
        }
      }
    }
    for (int f = 0; f < 6; ++f)
      if (face_has_live_[f]) next.push_back(face_live_[f]);
    live.swap(next);
    if (live.empty()) {
      st_.early_exit = m < kmax;
      break;
    }
  }
}

}  // namespace

namespace detail {

void traverse_voxels(const Scene::Impl& s, Scratch::Impl& w, const WorldFrustum& wf, FrameStats& st,
                     const FrameGeometry& g) {
  Collector col(s, w, wf, st, g);
  Traversal(s, w, st, g, col).run();
}

void trace_voxels(const Scene::Impl& s, const Scratch::Impl& w, FrameTrace& trace) {
  // The stamps hold every reached voxel's status, so the record costs the
  // traversal nothing: it is read here, a run at a time. 0: not reached.
  const std::uint32_t tag = w.stamp_tag << 2;
  auto status = [tag](std::uint8_t stamp) { return (stamp & ~3u) == tag ? stamp & 3u : 0u; };
  // Live and opaque voxels are both visited: one run.
  auto kind = [](std::uint32_t st) { return st == kOpaque ? kLive : st; };
  for (int z = 0; z < s.res.z; ++z)
    for (int y = 0; y < s.res.y; ++y) {
      const std::uint8_t* row = w.stamp.data() + s.index(0, y, z);
      for (int x = 0; x < s.res.x;) {
        const std::uint32_t k = kind(status(row[x]));
        int end = x + 1;
        while (end < s.res.x && kind(status(row[end])) == k) ++end;
        if (k != 0) {
          const VoxelBox run{glm::ivec3(x, y, z), glm::ivec3(end - 1, y, z)};
          (k == kLive ? trace.visited : trace.occluded).push_back(run);
        }
        x = end;
      }
    }
}

}  // namespace detail
}  // namespace voxvis
