// build_cost.cpp — what a scene costs to build and keep (Scene::estimate,
// SceneCost), counted from its objects' footprints without building it:
// spheres' and boxes' cells exactly, meshes' by their triangles' bounds
// (mesh_cost.h), each O(1) a triangle, so that the count costs what reading
// the description does. The count stops as soon as its figure passes the
// limit it is checked against.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <unordered_map>
#include <vector>

#include "build_parts.h"
#include "mesh_cost.h"
#include "mesh_interior.h"
#include "scene_impl.h"

namespace voxvis {
namespace build {
namespace {

/// Entries (cells of levels >= 1) a dynamic object can hold at most: its
/// box grown by its largest TBV growth (a TBV replaces the object's own
/// entries, never adds to them), clamped to the grid.
std::uint64_t dynamic_entries(const Scene::Impl& s, const Obj& o) {
  const double period = s.options.tbv_period > 0.0 ? s.options.tbv_period : s.max_period(o);
  const double grow = 1.5 * o.max_speed * period;  // The period's jitter is below 1.5.
  const Vec3 lo = glm::max(o.box_lo() - grow, s.spec.bounds_min), hi = glm::min(o.box_hi() + grow, s.spec.bounds_max);
  const VoxBox vb = s.touch_range(glm::min(lo, o.box_lo()), glm::max(hi, o.box_hi()), s.slop(max_abs(lo) + max_abs(hi)));
  std::uint64_t n = 0;
  if (vb.empty()) return 0;
  detail::decompose(
      s.pyr, 1, VoxBox{vb.lo >> detail::kBrickShift, vb.hi >> detail::kBrickShift}, [](const VoxBox&) { return true; },
      [](const VoxBox&) { return false; }, true, [&](int, const glm::ivec3&) { ++n; },
      [](std::uint64_t) { return true; });
  return n;
}

/// What meshes add (bytes): the scene's (static meshes' placed vertices,
/// their triangles' brick entries, the quad pairing, dynamic meshes'
/// interiors), a worker's (a drawn mark per static triangle, a dynamic
/// mesh's placed vertices while drawn), the meshes' own vertices and
/// triangles (mesh_bytes()), and the build's temporaries at their peak.
struct MeshCost {
  std::uint64_t bytes = 0, scratch = 0, own = 0, build = 0;
};

/// Upper bounds on what static mesh `o` adds, from its triangles' bounds:
/// level-0 id-list entries (the voxels it touches, each once), its
/// triangles' brick entries, and the voxels of its range (the bitset that
/// marks them while the build finds them).
struct StaticMeshEntries {
  double voxels = 0.0, bricks = 0.0, range = 0.0;
};

/// A triangle whose box holds at most this many voxels has them marked
/// (a fine mesh's neighbours share most of theirs); a larger one is counted
/// by its bound.
constexpr double kMarkedBox = 64.0;

bool static_mesh_entries(const Scene::Impl& s, const Obj& o, BuildMeter& meter, StaticMeshEntries* out) {
  const GridMesh gm(s, o);
  const double grow = std::fmax(gm.grow.x, std::fmax(gm.grow.y, gm.grow.z));
  const bool buffer = s.options.occlusion_buffer > 0;
  glm::ivec3 r0(s.res), r1(-1);
  for (const auto& t : o.mesh->triangles) {
    glm::ivec3 v0, v1;
    if (!gm.cell_range(t, 1, s.res, &v0, &v1)) continue;
    r0 = glm::min(r0, v0);
    r1 = glm::max(r1, v1);
  }
  out->range = detail::cells_of(r0, r1);
  if (out->range == 0.0) return meter.tick(o.mesh->triangles.size() + 1);
  // The small triangles' boxes marked in a bitset over the range (the
  // build's own mark, build_parts.h: mesh_voxels, is charged the same);
  // the large ones' bounds summed.
  const glm::ivec3 n = r1 - r0 + 1;
  const auto bits = static_cast<std::uint64_t>(out->range);
  std::vector<std::uint64_t> marked((bits + 63) / 64, 0);
  double large = 0.0;
  std::size_t count = 0;
  for (const auto& t : o.mesh->triangles) {
    if (++count % 1024 == 0 && !meter.tick(1024)) return false;
    glm::ivec3 v0, v1;
    if (!gm.cell_range(t, 1, s.res, &v0, &v1)) continue;
    const Vec3 &a = gm.g[t[0]], &b = gm.g[t[1]], &c = gm.g[t[2]];
    const double box = detail::cells_of(v0, v1);
    if (box <= kMarkedBox) {
      for (int z = v0.z; z <= v1.z; ++z)
        for (int y = v0.y; y <= v1.y; ++y)
          for (int x = v0.x; x <= v1.x; ++x) {
            const auto i = static_cast<std::uint64_t>(x - r0.x) +
                           static_cast<std::uint64_t>(n.x) * (static_cast<std::uint64_t>(y - r0.y) +
                                                              static_cast<std::uint64_t>(n.y) *
                                                                  static_cast<std::uint64_t>(z - r0.z));
            marked[i >> 6] |= std::uint64_t{1} << (i & 63);
          }
    } else {
      large += std::fmin(box, detail::cells_touched_bound(a, b, c, 1.0, grow));
    }
    if (buffer && gm.cell_range(t, 1 << detail::kBrickShift, s.res, &v0, &v1))
      out->bricks += std::fmin(detail::cells_of(v0, v1),
                               detail::cells_touched_bound(a, b, c, 1 << detail::kBrickShift, grow));
  }
  double small = 0.0;
  for (const std::uint64_t w : marked) small += static_cast<double>(std::popcount(w));
  out->voxels = std::fmin(small + large, out->range);
  return meter.tick(o.mesh->vertices.size() + marked.size() + 1);
}

/// A whole number of bytes (or entries) from a bound, saturating.
std::uint64_t whole(double x) {
  return x < 1.8e19 ? static_cast<std::uint64_t>(std::ceil(x)) : std::numeric_limits<std::uint64_t>::max() / 4;
}

/// The figure of a scene with `per_level` static entries, in the terms of
/// SceneCost; the refusal when it exceeds the meter's limit. `counted`:
/// objects counted so far (all: the figure is the scene's; fewer: a lower
/// bound, and a refusal says so).
Status scene_cost(const Scene::Impl& s, const LevelCounts& per_level, std::uint64_t dyn_entries,
                  const BuildMeter& meter, SceneCost* cost, std::size_t counted, std::uint64_t convex = 0,
                  const MeshCost& mesh = {}) {
  const auto nvox = static_cast<std::uint64_t>(s.spec.voxel_count());
  const bool buffer = s.options.occlusion_buffer > 0;
  std::uint64_t entries = 0;
  for (int l = 0; l < s.pyr.levels; ++l) entries += per_level[static_cast<std::size_t>(l)];
  const std::uint64_t bricks = s.dynamic_count > 0 ? s.pyr.cells(1) : 0;
  const std::uint64_t coarse = s.dynamic_count > 0 ? s.cell_base[static_cast<std::size_t>(s.pyr.levels)] - bricks : 0;
  // Opaque boxes are not known before the cover is: about one per brick is
  // a generous figure for every scene measured (the build counts the real
  // ones, and asks for more memory when there are more).
  const std::uint64_t boxes = buffer ? s.pyr.cells(1) : 0;
  const std::uint64_t cells = s.cell_base[static_cast<std::size_t>(s.pyr.levels)];
  const std::uint64_t objects = s.objs.size(), dynamic = s.dynamic_count;
  cost->res = s.res;
  cost->id_entries = entries + dyn_entries;
  // Beyond the grid's layers: the CSR entries (4 each); with the buffer on,
  // the opaque boxes and the per-brick lists (at most the voxels' own
  // entries and one box per brick); per dynamic entry 64 (grid_bytes says
  // why); the meshes'; the region occluders (region_occlusion.h: the
  // `convex` static boxes and balls counted, and opaque boxes).
  cost->bytes = grid_bytes(s) + 4 * entries + (buffer ? boxes * (sizeof(VoxBox) + 4) + 4 * per_level[0] : 0) +
                64 * dyn_entries + mesh.bytes + mesh.own +
                detail::region_occluder_bytes(convex + (buffer ? detail::region_box_occluders(boxes) : 0)) +
                (dynamic > 0 ? detail::free_space_bytes(nvox) : 0);
  // The build's temporaries at their peak: a mark per object and per box
  // (the per-brick lists), or a mesh's.
  // The free space's flood queue (4 a voxel), with dynamic objects.
  const bool free_space = dynamic > 0 && detail::free_space_bytes(nvox) > 0;
  cost->build_bytes = std::max<std::uint64_t>({8 * (objects + boxes), mesh.build, free_space ? 4 * nvox : 0});
  // A worker's scratch: the voxel traversal's stamps (a byte a voxel, the
  // buffer off); per object a PVS mark and a frustum mark (8) and its place
  // in the PVS (4, doubled by the list's growth); per dynamic object its
  // places in the frame's reveals and deferred TBVs (8, doubled); per box
  // and per cell a mark (4); with dynamic objects, per brick the voxels a
  // frame saw (8) and its place in their list (4, doubled), per coarser
  // cell its place in the cells seen whole (8, doubled); per region
  // occluder a region frame's mark (4).
  cost->scratch_bytes = (buffer ? 0 : nvox) + 16 * objects + 16 * dynamic + 4 * boxes + 4 * cells +
                        4 * (convex + (buffer ? detail::region_box_occluders(boxes) : 0)) +
                        16 * bricks + 16 * coarse + mesh.scratch;
  cost->work = meter.steps() + nvox * 2;
  const std::uint64_t needed = cost->bytes + cost->build_bytes;
  if (meter.max_bytes() > 0 && needed > meter.max_bytes()) {
    const std::string grid = std::to_string(s.res.x) + "x" + std::to_string(s.res.y) + "x" + std::to_string(s.res.z);
    if (counted == 0 && !s.objs.empty())
      return Status::Exhausted("memory", "the grid " + grid + " alone needs about " + mib_text(needed) +
                                             ", over the limit of " + mib_text(meter.max_bytes()));
    const std::string building =
        cost->build_bytes > cost->bytes / 4 ? ", " + mib_text(cost->build_bytes) + " of it while it builds" : "";
    const std::string what =
        counted < s.objs.size()
            ? "at least " + mib_text(needed) + " (" + std::to_string(cost->id_entries) +
                  " id-list entries from its first " + std::to_string(counted) + " of " +
                  std::to_string(s.objs.size()) + " objects, grid " + grid + building + ")"
            : "about " + mib_text(needed) + " (" + std::to_string(cost->id_entries) + " id-list entries, grid " +
                  grid + (mesh.own > 0 ? ", meshes " + mib_text(mesh.own) : std::string()) + building + ")";
    return Status::Exhausted("memory", "the scene needs " + what + ", over the limit of " + mib_text(meter.max_bytes()));
  }
  for (std::uint64_t e : per_level)
    if (e > std::numeric_limits<std::uint32_t>::max() - 1)
      return Status::Exhausted("grid", "static objects fill more than 2^32 cells of one level; choose a coarser grid");
  return Status::Ok();
}

/// What dynamic mesh `o` adds with the buffer on: the quad pairing, and,
/// closed, its interior's cubes and boxes, built once a mesh and side
/// (build.cpp, pair_mesh_triangles), and while they are built the level
/// set over the cubes.
void dynamic_mesh_cost(const Scene::Impl& s, const Obj& o, MeshCost* mesh) {
  const double side = std::fmin(s.spec.voxel_size.x, std::fmin(s.spec.voxel_size.y, s.spec.voxel_size.z));
  const glm::ivec3 n = detail::model_interior_cubes(*o.mesh, side / o.mesh_scale);
  const std::uint64_t cubes = std::uint64_t(n.x) * std::uint64_t(n.y) * std::uint64_t(n.z);
  const std::uint64_t triangles = o.mesh->triangles.size();
  mesh->bytes += kPairKeptBytes * triangles + cubes + 8 * cubes / 4 + 256;
  mesh->build = std::max(mesh->build, std::max(kPairBuildBytes * triangles, model_level_set_bytes(n)));
}

}  // namespace

std::string mib_text(std::uint64_t bytes) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.1f MiB", static_cast<double>(bytes) / (1024.0 * 1024.0));
  return buf;
}

Status BuildMeter::stopped() const {
  if (!over_) return build_cancelled();
  return Status::Exhausted("memory", "the build needed " + mib_text(peak_) + ", more than the " + mib_text(granted_) +
                                         " reserved for it (its estimate) and the memory budget could give");
}

/// The bytes of the scene's meshes, each counted once however many objects
/// place it (the objects share it): vertices, triangles and the vectors'
/// bookkeeping. A mesh is kept as given, so that is what it costs.
std::uint64_t mesh_bytes(const Scene::Impl& s) {
  std::uint64_t bytes = 0;
  std::vector<const Mesh*> seen;
  for (const Obj& o : s.objs)
    if (o.mesh) seen.push_back(o.mesh.get());
  std::sort(seen.begin(), seen.end());
  seen.erase(std::unique(seen.begin(), seen.end()), seen.end());
  for (const Mesh* m : seen)
    bytes += m->vertices.size() * sizeof(Vec3) + m->triangles.size() * sizeof(m->triangles[0]) + sizeof(Mesh) + 64;
  return bytes;
}

std::uint64_t grid_bytes(const Scene::Impl& s) {
  const auto nvox = static_cast<std::uint64_t>(s.spec.voxel_count());
  const bool buffer = s.options.occlusion_buffer > 0;
  std::uint64_t offsets = 0;
  for (int l = 0; l < s.pyr.levels; ++l) offsets += s.pyr.cells(l) + 1;
  const std::uint64_t bricks = s.dynamic_count > 0 ? s.pyr.cells(1) : 0;
  const std::uint64_t coarse = s.dynamic_count > 0 ? s.cell_base[static_cast<std::size_t>(s.pyr.levels)] - bricks : 0;
  const std::uint64_t cells = s.cell_base[static_cast<std::size_t>(s.pyr.levels)];
  const std::uint64_t objects = s.objs.size(), dynamic = s.dynamic_count;
  // Per voxel: flags (1), the opaque boxes' owners (4, buffer on); the CSR
  // offsets of every level (4 each); per brick its dynamic list head, seen
  // time and mask; per coarser cell a list head; each object's state and
  // index entry; with the buffer on, the per-brick lists' offsets; per cell
  // of levels >= 1 its static mask (8), with dynamic objects its dynamic
  // count and mask (12) — masks and counts with the buffer only — and, from
  // level 2, the time it was last seen whole (8), and at level 2 the time
  // anything in it was seen (8).
  //
  // The dynamic lists: a cell drops its stale entries only once they are
  // 16 more than twice its live ones (scene_tbv.cpp, brick_add), and a list
  // grows by doubling, so a cell that ever held one entry keeps up to 16
  // (128 bytes), and one that held L >= 2 at once up to 192 + 32 L bytes:
  // 128 bytes a dynamic cell (bricks and coarser) and 64 a dynamic entry
  // (scene_cost). Per dynamic object, its entries in the TBV expiry queue
  // (a live one and a stale one) and the reveal, unclaimed and wake queues,
  // doubled by their growth: 64 bytes; and the expiry queue's ring of
  // buckets, once per scene with dynamic objects.
  return nvox * (1 + (buffer ? 4 : 0)) + 4 * offsets + bricks * (sizeof(detail::Brick) + 16) +
         coarse * (sizeof(detail::Brick) + 8) + (bricks > 0 && s.pyr.levels > 2 ? 8 * s.pyr.cells(2) : 0) +
         128 * (bricks + coarse) + 64 * dynamic + (buffer ? 8 * cells + (bricks > 0 ? 12 * cells : 0) : 0) +
         (buffer ? 8 * (s.pyr.cells(1) + 1) : 0) + objects * (sizeof(Obj) + 52) + (1u << 16) +
         (dynamic > 0 ? sizeof(std::vector<detail::ExpiryEntry>) * detail::ExpiryQueue::kBuckets : 0);
}

bool interior_level_set(const Scene::Impl& s, const Obj& o, BuildMeter& meter, std::uint64_t* bytes) {
  const GridMesh gm(s, o);
  // OpenVDB's band: three voxels each side of the surface (mesh_interior.cpp),
  // two more for its own dilation.
  constexpr double kBand = 5.0;
  const std::uint64_t max_leaves = static_cast<std::uint64_t>(s.spec.voxel_count()) / 128 + 64;
  detail::LevelSetNodes nodes;
  bool stopped = false;
  const bool within = detail::level_set_nodes(gm.g, *o.mesh, kBand, max_leaves, [&](std::uint64_t n) {
    stopped = !meter.tick(n);
    return !stopped;
  }, &nodes);
  *bytes = within ? nodes.bytes() : 0;
  return !stopped;
}

std::uint64_t model_level_set_bytes(const glm::ivec3& cubes) {
  const auto leaves = [](int n) { return static_cast<std::uint64_t>((n + 7) / 8 + 1); };
  return detail::LevelSetNodes{leaves(cubes.x) * leaves(cubes.y) * leaves(cubes.z), 8, 8}.bytes();
}

Status count_cost(const Scene::Impl& s, BuildMeter& meter, SceneCost* cost, LevelCounts* counts) {
  LevelCounts per_level{};
  std::uint64_t dyn = 0;
  MeshCost mesh;
  const bool buffer = s.options.occlusion_buffer > 0;
  std::uint64_t widest = 0;  // Vertices of the largest dynamic mesh.
  std::uint64_t convex = 0;  // Static boxes and balls (region occluders).
  // The grid alone may be over the limit: refused before any object is looked at.
  if (Status st = scene_cost(s, per_level, 0, meter, cost, 0); !st) return st;
  mesh.own = mesh_bytes(s);
  std::unordered_map<const Mesh*, bool> paired;  // Static meshes' pairing, counted once a mesh.
  std::unordered_map<const Mesh*, bool> closed;  // Whether a mesh is closed, found once a mesh.
  for (std::uint32_t slot = 0; slot < s.objs.size(); ++slot) {
    const Obj& o = s.objs[slot];
    if (o.dynamic) {
      dyn += dynamic_entries(s, o);
      if (o.shape == Shape::Mesh && buffer) dynamic_mesh_cost(s, o, &mesh);
      if (o.shape == Shape::Mesh && buffer && o.mesh->vertices.size() > widest) {
        mesh.scratch += 24 * (o.mesh->vertices.size() - widest);
        widest = o.mesh->vertices.size();
      }
      if (!meter.tick(8)) return build_cancelled();
    } else if (o.shape == Shape::Mesh) {
      StaticMeshEntries e;
      if (!static_mesh_entries(s, o, meter, &e)) return build_cancelled();
      per_level[0] += whole(e.voxels);
      mesh.build = std::max(mesh.build, whole(e.range / 8.0) + 64);  // The voxels' marks.
      if (buffer) {
        if (mesh.bytes == 0) mesh.bytes = 4 * (s.pyr.cells(1) + 1);
        // Placed vertices, brick entries; the quad pairing once a mesh.
        const std::uint64_t triangles = o.mesh->triangles.size();
        mesh.bytes += 24 * o.mesh->vertices.size() + sizeof(detail::TriRef) * whole(e.bricks);
        if (!paired[o.mesh.get()]) {
          paired[o.mesh.get()] = true;
          mesh.bytes += kPairKeptBytes * triangles;
          mesh.build = std::max(mesh.build, kPairBuildBytes * triangles);
        }
        mesh.scratch += 4 * triangles;
        // A closed mesh's interior: its level set while it is built.
        const auto [known, fresh] = closed.try_emplace(o.mesh.get(), false);
        if (fresh) known->second = detail::mesh_closed(*o.mesh);
        std::uint64_t level_set = 0;
        if (known->second && !interior_level_set(s, o, meter, &level_set)) return build_cancelled();
        mesh.build = std::max(mesh.build, level_set);
      }
    } else if (!static_cells(s, slot, meter, [&](int l, const glm::ivec3&) { ++per_level[static_cast<std::size_t>(l)]; })) {
      return build_cancelled();
    } else {
      ++convex;
    }
    // Stop as soon as the limit is passed: the count costs no more than
    // the budget it is checked against.
    if (Status st = scene_cost(s, per_level, dyn, meter, cost, slot + 1, convex, mesh); !st) return st;
  }
  if (counts) *counts = per_level;
  return scene_cost(s, per_level, dyn, meter, cost, s.objs.size(), convex, mesh);
}

}  // namespace build

Status Scene::estimate(const SceneDesc& desc, const SceneOptions& options, SceneCost* out,
                       const BuildControl* control) {
  Impl s;
  build::BuildMeter meter(control);
  if (Status st = build::prepare(desc, options, s, meter); !st) return st;
  SceneCost cost;
  if (Status st = build::count_cost(s, meter, &cost); !st) return st;
  *out = cost;
  return Status::Ok();
}

}  // namespace voxvis
