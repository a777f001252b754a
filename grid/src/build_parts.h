// build_parts.h — what building a scene shares between its files: the
// description checked and its objects set up (build_validate.cpp), what the
// scene costs (build_cost.cpp: Scene::estimate) and the build itself
// (build.cpp: Scene::create).
//
// A build's memory is counted as it goes (BuildMeter::charge): the grid's
// layers and each list before it is allocated, each temporary while it
// lives. What the estimate reserved is the limit; past it the build asks
// its control for more (BuildControl::reserve, the server's budget) and
// stops with ResourceExhausted when none is given, so that a description
// whose real cost the estimate missed cannot take the process's memory.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "cells.h"
#include "mesh_cost.h"
#include "numeric.h"
#include "scene_impl.h"
#include "tri_box.h"
#include "voxvis/mesh.h"
#include "voxvis/scene.h"

namespace voxvis::build {

using detail::Obj;
using detail::VoxBox;
using detail::max_abs;

/// Longest side of an opaque box, voxels (opaque_boxes.h).
inline constexpr int kOpaqueBoxSide = 16;

/// Static entries per level of the pyramid.
using LevelCounts = std::array<std::uint64_t, detail::kMaxLevels>;

/// "12.5 MiB".
std::string mib_text(std::uint64_t bytes);

/// Polls a BuildControl every 2^16 steps of work, keeps the count, and
/// counts the build's memory against what the control reserved.
class BuildMeter {
 public:
  explicit BuildMeter(const BuildControl* c) : c_(c), granted_(c ? c->max_bytes : 0) {}
  /// Counts n steps; false once the caller cancelled.
  bool tick(std::uint64_t n = 1) {
    steps_ += n;
    if (steps_ < next_) return true;
    next_ = steps_ + (std::uint64_t{1} << 16);
    if (c_ && c_->cancelled && c_->cancelled()) cancelled_ = true;
    return !cancelled_;
  }
  /// Counts `bytes` about to be allocated, kept by the scene or (released
  /// later) a temporary. False when the build's memory would pass what was
  /// reserved and the control grants no more: the build stops (stopped()).
  bool charge(std::uint64_t bytes) {
    charged_ += bytes;
    peak_ = std::max(peak_, charged_);
    if (granted_ == 0 || charged_ <= granted_) return true;
    if (c_ && c_->reserve && c_->reserve(charged_)) {
      granted_ = charged_;
      return true;
    }
    over_ = true;
    return false;
  }
  /// A temporary's bytes, given back.
  void release(std::uint64_t bytes) { charged_ -= std::min(bytes, charged_); }
  /// Why the build stopped: ResourceExhausted past the memory reserved,
  /// else Cancelled.
  Status stopped() const;
  bool cancelled() const { return cancelled_; }
  std::uint64_t steps() const { return steps_; }
  std::uint64_t max_bytes() const { return c_ ? c_->max_bytes : 0; }
  /// Bytes counted and not released: the scene's, once the build is done.
  std::uint64_t charged() const { return charged_; }
  std::uint64_t peak() const { return peak_; }

 private:
  const BuildControl* c_;
  std::uint64_t steps_ = 0, next_ = 0;
  std::uint64_t charged_ = 0, peak_ = 0, granted_ = 0;
  bool cancelled_ = false, over_ = false;
};

inline Status build_cancelled() { return Status::Cancelled("scene build cancelled"); }

/// Validates `desc`, chooses the grid and sets up the objects of `s`: every
/// part of a scene but its grid layers (build_validate.cpp). Each mesh's
/// own figures (centroid, extent) are taken once however many objects
/// place it.
Status prepare(const SceneDesc& desc, const SceneOptions& options, Scene::Impl& s, BuildMeter& meter);

/// Counts what the scene costs (SceneCost), static objects' entries per
/// level into `counts` when given: spheres' and boxes' exactly, meshes' by
/// their triangles' bounds (mesh_cost.h). Stops as soon as the figure
/// passes the meter's limit (build_cost.cpp).
Status count_cost(const Scene::Impl& s, BuildMeter& meter, SceneCost* cost, LevelCounts* counts = nullptr);

/// What the grid's layers cost, bytes: every per-voxel and per-cell array a
/// built scene keeps, its objects' state, without entries (build_cost.cpp).
std::uint64_t grid_bytes(const Scene::Impl& s);

/// The bytes of the scene's meshes, each counted once however many objects
/// place it (build_cost.cpp).
std::uint64_t mesh_bytes(const Scene::Impl& s);

/// What the level set that finds the interior of `o`, a static closed mesh,
/// takes while it is made, bytes (mesh_cost.h's LevelSetNodes), into
/// `*bytes`; 0 when the mesh gets no interior, because its level set would
/// pass a leaf per 128 voxels of the grid (a mesh reaching far beyond the
/// grid, or much finer than it): its triangles still occlude, and no
/// interior is always conservative. False when the meter says stop
/// (build_cost.cpp).
bool interior_level_set(const Scene::Impl& s, const Obj& o, BuildMeter& meter, std::uint64_t* bytes);

/// The level set over a dynamic closed mesh's `cubes` (mesh_interior.h,
/// model_interior): at most every leaf of them.
std::uint64_t model_level_set_bytes(const glm::ivec3& cubes);

/// A mesh's triangles paired into quads and its closedness found, once a
/// mesh (build.cpp, pair_mesh_triangles): the pairs kept (20 bytes a
/// triangle) and, while it runs, a hash map of the sides and the normals
/// (256 bytes a triangle, generously).
inline constexpr std::uint64_t kPairKeptBytes = 20, kPairBuildBytes = 256;

/// A static mesh's vertices placed and mapped to grid coordinates, and how
/// far a voxel (or brick) is grown for their rounding: the placement's and
/// the mapping's (slop) allowances, in voxels.
struct GridMesh {
  std::vector<Vec3> g;
  Vec3 grow{0.0};
  GridMesh(const Scene::Impl& s, const Obj& o) : g(o.mesh->vertices.size()) {
    const ObjectDesc d = o.mesh_desc();
    for (std::size_t i = 0; i < g.size(); ++i) g[i] = s.to_grid(place(d, o.mesh->vertices[i]));
    grow = (o.mesh_allowance() + s.slop(max_abs(o.center) + max_abs(o.half))) * s.inv_vs + 1e-9;
  }
  /// The cells of `side` voxels (1: voxels, 4: bricks) that triangle `t`'s
  /// box may touch, in a grid of `res` voxels: [*lo, *hi], false when it
  /// lies beyond the grid.
  bool cell_range(const std::array<std::uint32_t, 3>& t, int side, const glm::ivec3& res, glm::ivec3* lo,
                  glm::ivec3* hi) const {
    const Vec3 &a = g[t[0]], &b = g[t[1]], &c = g[t[2]];
    const Vec3 tlo = glm::min(a, glm::min(b, c)) - grow, thi = glm::max(a, glm::max(b, c)) + grow;
    for (int k = 0; k < 3; ++k) {
      if (thi[k] < 0.0 || tlo[k] > res[k]) return false;
      // Cell i spans [side i, side (i+1)]: it meets [lo, hi] iff
      // ceil(lo / side) - 1 <= i <= floor(hi / side).
      const int cells = (res[k] + side - 1) / side;
      (*lo)[k] = detail::clamp_floor(std::ceil(tlo[k] / side) - 1.0, 0, cells - 1);
      (*hi)[k] = detail::clamp_floor(thi[k] / side, -1, cells - 1);
    }
    return true;
  }
};

/// The voxels static mesh `o` touches, from its triangles: each triangle
/// against the voxels of its own box (detail::triangle_voxels), with the voxel
/// grown by the rounding allowance of placing and mapping its vertices (a
/// rounding only adds a voxel the mesh touches within it). emit(0, voxel)
/// once a voxel, in index order; a voxel is marked in a bitset over the
/// mesh's range (charged while it lives), so that a mesh whose triangles
/// overlap costs its voxels, not its triangles times theirs. False when
/// cancelled or over the memory reserved (meter.stopped()).
template <class Emit>
bool mesh_voxels(const Scene::Impl& s, const Obj& o, BuildMeter& meter, Emit&& emit) {
  const Mesh& mesh = *o.mesh;
  const GridMesh gm(s, o);
  glm::ivec3 r0(s.res), r1(-1);
  for (const auto& t : mesh.triangles) {
    glm::ivec3 v0, v1;
    if (!gm.cell_range(t, 1, s.res, &v0, &v1)) continue;
    r0 = glm::min(r0, v0);
    r1 = glm::max(r1, v1);
  }
  if (r1.x < r0.x || r1.y < r0.y || r1.z < r0.z) return true;
  const glm::ivec3 n = r1 - r0 + 1;
  const auto bits = static_cast<std::uint64_t>(n.x) * static_cast<std::uint64_t>(n.y) * static_cast<std::uint64_t>(n.z);
  const std::uint64_t bytes = (bits + 63) / 64 * 8;
  if (!meter.charge(bytes)) return false;
  std::vector<std::uint64_t> marked((bits + 63) / 64, 0);
  const auto at = [&](int x, int y, int z) {
    return static_cast<std::uint64_t>(x - r0.x) +
           static_cast<std::uint64_t>(n.x) * (static_cast<std::uint64_t>(y - r0.y) +
                                              static_cast<std::uint64_t>(n.y) * static_cast<std::uint64_t>(z - r0.z));
  };
  for (const auto& t : mesh.triangles) {
    glm::ivec3 v0, v1;
    if (!gm.cell_range(t, 1, s.res, &v0, &v1)) continue;
    const std::uint64_t tests = detail::triangle_voxels(gm.g[t[0]], gm.g[t[1]], gm.g[t[2]], v0, v1, gm.grow,
                                                [&](int x, int y, int z) {
                                                  const std::uint64_t i = at(x, y, z);
                                                  marked[i >> 6] |= std::uint64_t{1} << (i & 63);
                                                });
    if (!meter.tick(tests + 1)) {
      meter.release(bytes);
      return false;
    }
  }
  for (int z = r0.z; z <= r1.z; ++z)
    for (int y = r0.y; y <= r1.y; ++y)
      for (int x = r0.x; x <= r1.x; ++x) {
        const std::uint64_t i = at(x, y, z);
        if (marked[i >> 6] >> (i & 63) & 1) emit(0, glm::ivec3(x, y, z));
      }
  meter.release(bytes);
  return true;
}

/// Splits static object `slot` into the cells it is stored in (cells.h):
/// emit(level, cell). False when cancelled (or, for a mesh, over the
/// memory reserved: meter.stopped()).
template <class Emit>
bool static_cells(const Scene::Impl& s, std::uint32_t slot, BuildMeter& meter, Emit&& emit) {
  const Obj& o = s.objs[slot];
  if (o.shape == Shape::Mesh) return mesh_voxels(s, o, meter, emit);
  const double sl = s.slop(max_abs(o.center) + o.radius + max_abs(o.half));
  const VoxBox vb = s.touch_range(o.box_lo(), o.box_hi(), sl);
  // A box touches exactly the voxels of its touch range; a ball's touched
  // voxels are a convex set of it, tested at a cell's corners.
  const bool ball = o.shape == Shape::Sphere;
  // Within a brick the surface cuts, a ball's voxels row by row: the voxels
  // of row (y, z) it touches are those meeting [cx - w, cx + w], w the half
  // chord left by the row's distance from the centre (touches()'s test,
  // solved for x; widened, so a rounding only adds a voxel).
  const Vec3 cg = s.to_grid(o.center);
  const double rr = o.radius + s.slop(max_abs(o.center) + o.radius + max_abs(o.half));
  const Vec3& vs = s.spec.voxel_size;
  auto gap = [&](int a, int i) {
    const double d = std::fmax(0.0, std::fmax(static_cast<double>(i) - cg[a], cg[a] - static_cast<double>(i + 1)));
    return d * vs[a];
  };
  auto ball_rows = [&](const VoxBox& in) {
    if (!ball) return false;
    for (int z = in.lo.z; z <= in.hi.z; ++z) {
      const double dz = gap(2, z);
      for (int y = in.lo.y; y <= in.hi.y; ++y) {
        const double dy = gap(1, y);
        const double rem = rr * rr - dy * dy - dz * dz;
        if (!(rem >= 0.0)) continue;
        const double w = std::sqrt(rem) * (1.0 + 1e-12) * s.inv_vs.x + 1e-9 + 1e-12 * std::fabs(cg.x);
        const double x0 = std::fmax(std::ceil(cg.x - w) - 1.0, static_cast<double>(in.lo.x));
        const double x1 = std::fmin(std::floor(cg.x + w), static_cast<double>(in.hi.x));
        for (double x = x0; x <= x1; x += 1.0) emit(0, glm::ivec3(static_cast<int>(x), y, z));
      }
    }
    return true;
  };
  return detail::decompose(
      s.pyr, 0, vb,
      [&](const VoxBox& r) {
        return !ball || detail::corners_pass(r, [&](int x, int y, int z) { return s.touches(o, o.center, x, y, z); });
      },
      ball_rows, false, emit, [&](std::uint64_t n) { return meter.tick(n); });
}

}  // namespace voxvis::build
