// build.cpp — building a scene (Scene::create): after its description is
// checked and its objects set up (build_validate.cpp) and its cost counted
// (build_cost.cpp), nothing is allocated before its figure fits; then the
// static id lists, the static cover, the occluders of the occlusion buffer
// (opaque boxes, meshes' quads and interiors), the cell traversal's
// summaries and the dynamic objects' state, each a named phase below, each
// charging its memory as it goes (build_parts.h). The rest of a scene's life
// (moves) is in scene.cpp, the TBVs' in scene_tbv.cpp.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include <glm/geometric.hpp>

#include "build_parts.h"
#include "mesh_interior.h"
#include "mesh_level_set.h"
#include "mesh_pairs.h"
#include "numeric.h"
#include "opaque_boxes.h"
#include "scene_impl.h"
#include "tri_box.h"

namespace voxvis {
namespace build {
namespace {

/// Builds the static id lists from the counts per level: a pass over the
/// objects counts each cell's entries, another fills them (no buffer of
/// pairs: the peak stays the lists' own size). Level 0's count from the
/// estimate is a bound for meshes: the lists are sized by the first pass.
Status build_static_lists(Scene::Impl& s, BuildMeter& meter, const LevelCounts& per_level) {
  for (int l = 0; l < s.pyr.levels; ++l) {
    detail::IdLists& lists = s.static_lists[static_cast<std::size_t>(l)];
    if (l == 0 || per_level[static_cast<std::size_t>(l)] > 0) lists.offsets.assign(s.pyr.cells(l) + 1, 0);
  }
  for (std::uint32_t slot = 0; slot < s.objs.size(); ++slot) {
    if (s.objs[slot].dynamic) continue;
    if (!static_cells(s, slot, meter, [&](int l, const glm::ivec3& c) {
          ++s.static_lists[static_cast<std::size_t>(l)].offsets[s.pyr.index(l, c) + 1];
        }))
      return meter.stopped();
  }
  for (int l = 0; l < s.pyr.levels; ++l) {
    detail::IdLists& lists = s.static_lists[static_cast<std::size_t>(l)];
    std::vector<std::uint32_t>& off = lists.offsets;
    std::uint64_t total = 0;
    for (std::size_t i = 1; i < off.size(); ++i) {
      total += off[i];
      if (total > std::numeric_limits<std::uint32_t>::max() - 1)
        return Status::Exhausted("grid", "static objects fill more than 2^32 cells of one level; choose a coarser grid");
      off[i] = static_cast<std::uint32_t>(total);
    }
    if (!meter.charge(4 * total)) return meter.stopped();
    lists.ids.resize(static_cast<std::size_t>(total));
  }
  // Fill, advancing each cell's start; then shift the starts back.
  for (std::uint32_t slot = 0; slot < s.objs.size(); ++slot) {
    const Obj& o = s.objs[slot];
    if (o.dynamic) continue;
    if (!static_cells(s, slot, meter, [&](int l, const glm::ivec3& c) {
          detail::IdLists& lists = s.static_lists[static_cast<std::size_t>(l)];
          lists.ids[lists.offsets[s.pyr.index(l, c)]++] = slot;
        }))
      return meter.stopped();
    if (!s.box_inside_grid(o.box_lo(), o.box_hi())) s.list_add(s.outside_objs, s.objs[slot].outside_pos, slot);
  }
  for (int l = 0; l < s.pyr.levels; ++l) {
    std::vector<std::uint32_t>& off = s.static_lists[static_cast<std::size_t>(l)].offsets;
    if (off.empty()) continue;
    for (std::size_t i = off.size() - 1; i > 0; --i) off[i] = off[i - 1];
    off[0] = 0;
  }
  // Flags: a voxel with its own list, a voxel inside a coarser cell with one.
  const detail::IdLists& own = s.static_lists[0];
  for (std::size_t i = 0; i + 1 < own.offsets.size(); ++i)
    if (own.offsets[i + 1] > own.offsets[i]) s.vflags[i] |= Scene::Impl::kStaticIds;
  for (int l = 1; l < s.pyr.levels; ++l) {
    const detail::IdLists& lists = s.static_lists[static_cast<std::size_t>(l)];
    if (!lists.any()) continue;
    const glm::ivec3 r = s.pyr.res[l];
    for (int z = 0; z < r.z; ++z)
      for (int y = 0; y < r.y; ++y)
        for (int x = 0; x < r.x; ++x) {
          const std::size_t c = s.pyr.index(l, glm::ivec3(x, y, z));
          if (lists.offsets[c + 1] == lists.offsets[c]) continue;
          const VoxBox v = s.pyr.span(l, glm::ivec3(x, y, z), 0);
          if (!meter.tick(static_cast<std::uint64_t>(v.hi.x - v.lo.x + 1) * (v.hi.y - v.lo.y + 1) * (v.hi.z - v.lo.z + 1)))
            return build_cancelled();
          for (int vz = v.lo.z; vz <= v.hi.z; ++vz)
            for (int vy = v.lo.y; vy <= v.hi.y; ++vy)
              for (int vx = v.lo.x; vx <= v.hi.x; ++vx)
                s.vflags[static_cast<std::size_t>(s.index(vx, vy, vz))] |= Scene::Impl::kCoarseIds;
        }
  }
  return Status::Ok();
}

/// The static masks, bottom up (Scene::Impl::static_mask).
void build_static_masks(Scene::Impl& s) {
  for (int l = 1; l < s.pyr.levels; ++l) s.static_mask[static_cast<std::size_t>(l)].assign(s.pyr.cells(l), 0);
  auto bit = [](const glm::ivec3& c) { return std::uint64_t{1} << ((c.x & 3) | (c.y & 3) << 2 | (c.z & 3) << 4); };
  for (int z = 0; z < s.res.z; ++z)
    for (int y = 0; y < s.res.y; ++y)
      for (int x = 0; x < s.res.x; ++x)
        if (s.vflags[static_cast<std::size_t>(s.index(x, y, z))] &
            (Scene::Impl::kStaticIds | Scene::Impl::kStaticOpaque | Scene::Impl::kMeshInside))
          s.static_mask[1][s.pyr.index(1, glm::ivec3(x, y, z) >> detail::kCellShift)] |= bit(glm::ivec3(x, y, z));
  for (int l = 1; l + 1 < s.pyr.levels; ++l) {
    const detail::IdLists& lists = s.static_lists[static_cast<std::size_t>(l)];
    const glm::ivec3 r = s.pyr.res[static_cast<std::size_t>(l)];
    for (int z = 0; z < r.z; ++z)
      for (int y = 0; y < r.y; ++y)
        for (int x = 0; x < r.x; ++x) {
          const glm::ivec3 c(x, y, z);
          const std::size_t i = s.pyr.index(l, c);
          const bool own = lists.any() && lists.offsets[i + 1] > lists.offsets[i];
          if (own || s.static_mask[static_cast<std::size_t>(l)][i] != 0)
            s.static_mask[static_cast<std::size_t>(l) + 1][s.pyr.index(l + 1, c >> detail::kCellShift)] |= bit(c);
        }
  }
}

/// Which opaque boxes need not be drawn: those lying wholly inside one
/// static object, and those whose every voxel lies wholly inside some static
/// ball. An object's own occluder is drawn whenever the traversal reaches a
/// brick of the box (the object is stored there or above); it covers a box
/// inside it at least as near for a box object, and all but slivers at the
/// rim for a ball (its inscribed polygons). A box of voxels each inside a
/// ball, though it spans several, adds no cover beyond the balls' own discs
/// but those slivers and the ring between a ball's two discs (where the box
/// is nearer): on the walkthrough at 200x120x200 such boxes were 13% of the
/// frame's instructions for 0.3% of its PVS (docs/performance.md). The boxes
/// that close seams, across blocks or where a block meets a ball, are kept.
/// Leaving an occluder out is always conservative. Candidates for the first
/// test: the objects at the box's least corner voxel.
std::vector<std::uint8_t> redundant_boxes(const Scene::Impl& s) {
  std::vector<std::uint8_t> inside(s.opaque_boxes.size(), 0);
  const detail::IdLists& own = s.static_lists[0];
  const GridSpec& g = s.spec;
  for (std::size_t b = 0; b < s.opaque_boxes.size(); ++b) {
    const VoxBox& vb = s.opaque_boxes[b];
    const Vec3 lo = g.bounds_min + Vec3(vb.lo) * g.voxel_size, hi = g.bounds_min + Vec3(vb.hi + 1) * g.voxel_size;
    const auto i = static_cast<std::size_t>(s.index(vb.lo.x, vb.lo.y, vb.lo.z));
    std::uint32_t slots[detail::kCoverCandidates];
    std::size_t n = 0;
    for (const std::uint32_t* p = own.begin(i); p != own.end(i) && n < std::size(slots); ++p) slots[n++] = *p;
    if (s.vflags[i] & Scene::Impl::kCoarseIds) s.coarse_static(vb.lo.x, vb.lo.y, vb.lo.z, slots, &n, std::size(slots));
    for (std::size_t k = 0; k < n && !inside[b]; ++k) {
      const Obj& o = s.objs[slots[k]];
      if (o.shape == Shape::Mesh) {
        continue;  // Not drawn into the buffer: the box must be.
      } else if (o.shape == Shape::Sphere) {
        // The farthest corner from the centre within the radius.
        const Vec3 far = glm::max(glm::abs(lo - o.center), glm::abs(hi - o.center));
        inside[b] = glm::dot(far, far) <= o.radius * o.radius;
      } else {
        inside[b] = glm::all(glm::lessThanEqual(o.box_lo(), lo)) && glm::all(glm::lessThanEqual(hi, o.box_hi()));
      }
    }
    bool balls = !inside[b];
    for (int z = vb.lo.z; z <= vb.hi.z && balls; ++z)
      for (int y = vb.lo.y; y <= vb.hi.y && balls; ++y)
        for (int x = vb.lo.x; x <= vb.hi.x && balls; ++x)
          balls = (s.vflags[static_cast<std::size_t>(s.index(x, y, z))] & Scene::Impl::kInOneBall) != 0;
    inside[b] = inside[b] || balls;
  }
  return inside;
}

/// The per-brick lists of the cell traversal (Scene::Impl::brick_static,
/// brick_boxes), from the voxels' own lists and opaque owners.
/// Opaque boxes their objects already cover are left out (redundant_boxes).
void build_brick_lists(Scene::Impl& s) {
  const std::size_t bricks = s.pyr.cells(1);
  const std::vector<std::uint8_t> redundant = redundant_boxes(s);
  const detail::IdLists& own = s.static_lists[0];
  std::vector<std::uint32_t> obj_mark(s.objs.size(), ~0u), box_mark(s.opaque_boxes.size(), ~0u);
  detail::IdLists& objs = s.brick_static;
  detail::IdLists& boxes = s.brick_boxes;
  objs.offsets.assign(1, 0);
  boxes.offsets.assign(1, 0);
  objs.ids.clear();
  boxes.ids.clear();
  for (std::size_t b = 0; b < bricks; ++b) {
    std::uint64_t m = s.static_mask[1][b];
    const glm::ivec3 c(static_cast<int>(b % static_cast<std::size_t>(s.pyr.res[1].x)),
                       static_cast<int>(b / static_cast<std::size_t>(s.pyr.res[1].x) % static_cast<std::size_t>(s.pyr.res[1].y)),
                       static_cast<int>(b / (static_cast<std::size_t>(s.pyr.res[1].x) * static_cast<std::size_t>(s.pyr.res[1].y))));
    const glm::ivec3 o = c << detail::kCellShift;
    while (m != 0) {
      const int bit = __builtin_ctzll(m);
      m &= m - 1;
      const auto idx = static_cast<std::size_t>(s.index(o.x + (bit & 3), o.y + (bit >> 2 & 3), o.z + (bit >> 4)));
      const auto tag = static_cast<std::uint32_t>(b);
      if (s.vflags[idx] & Scene::Impl::kStaticIds)
        for (const std::uint32_t* p = own.begin(idx); p != own.end(idx); ++p)
          if (obj_mark[*p] != tag) {
            obj_mark[*p] = tag;
            objs.ids.push_back(*p);
          }
      if (!s.opaque_owner.empty() && (s.vflags[idx] & Scene::Impl::kStaticOpaque)) {
        const std::uint32_t box = s.opaque_owner[idx];
        if (box != detail::kNoBox && !redundant[box] && box_mark[box] != tag) {
          box_mark[box] = tag;
          boxes.ids.push_back(box);
        }
      }
    }
    objs.offsets.push_back(static_cast<std::uint32_t>(objs.ids.size()));
    boxes.offsets.push_back(static_cast<std::uint32_t>(boxes.ids.size()));
  }
}

/// Calls emit(brick, triangle) for every brick each triangle of static
/// mesh `o` meets (the separating-axis test against the brick grown as
/// mesh_voxels grows voxels). False when cancelled.
template <class Emit>
bool mesh_triangle_bricks(const Scene::Impl& s, const Obj& o, BuildMeter& meter, Emit&& emit) {
  const int side = 1 << detail::kBrickShift;
  const Mesh& mesh = *o.mesh;
  const GridMesh gm(s, o);
  const Vec3 half = Vec3(0.5 * side) + gm.grow;
  for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    glm::ivec3 b0, b1;
    if (!gm.cell_range(tri, side, s.res, &b0, &b1)) continue;
    const Vec3 &a = gm.g[tri[0]], &b = gm.g[tri[1]], &c = gm.g[tri[2]];
    std::uint64_t n = 0;
    for (int z = b0.z; z <= b1.z; ++z)
      for (int y = b0.y; y <= b1.y; ++y)
        for (int x = b0.x; x <= b1.x; ++x) {
          ++n;
          const Vec3 centre = (Vec3(x, y, z) + 0.5) * static_cast<double>(side);
          if (detail::triangle_meets_box(a, b, c, centre, half)) emit(s.pyr.index(1, glm::ivec3(x, y, z)), t);
        }
    if (!meter.tick(n + 1)) return false;
  }
  return true;
}

/// The interiors of closed static meshes, with the buffer on: every voxel
/// some closed mesh's triangles touch gets kMeshTouched (mesh_voxels, the
/// exact triangle-box test grown by the rounding allowance); then every
/// voxel of a closed mesh's range that OpenVDB puts inside and that no
/// closed mesh touches gets kMeshInside (mesh_interior.h). Those voxels are
/// covered with boxes appended to opaque_boxes and listed per brick
/// (brick_mesh_boxes). Needs pair_mesh_triangles first (Obj::outward). A
/// mesh whose level set would be too large (interior_level_set) gets none; each
/// level set is charged while it lives, the boxes as they are kept.
Status build_mesh_interiors(Scene::Impl& s, BuildMeter& meter, const BuildControl* control) {
  std::vector<std::uint32_t> meshes;
  for (std::uint32_t slot = 0; slot < s.objs.size(); ++slot) {
    const Obj& o = s.objs[slot];
    // Closed (pair_mesh_triangles) and enclosing a volume.
    if (o.dynamic || o.shape != Shape::Mesh || o.outward == 0) continue;
    meshes.push_back(slot);
    if (!s.box_inside_grid(o.box_lo(), o.box_hi())) s.closed_mesh_beyond_grid = true;
    if (!mesh_voxels(s, o, meter, [&](int, const glm::ivec3& v) {
          s.vflags[static_cast<std::size_t>(s.index(v.x, v.y, v.z))] |= Scene::Impl::kMeshTouched;
        }))
      return meter.stopped();
  }
  bool any = false;
  const std::function<bool()> cancelled = control ? control->cancelled : std::function<bool()>();
  for (const std::uint32_t slot : meshes) {
    const Obj& o = s.objs[slot];
    std::uint64_t level_set = 0;
    if (!interior_level_set(s, o, meter, &level_set)) return build_cancelled();
    if (level_set == 0) continue;
    if (!meter.charge(level_set)) return meter.stopped();
    const GridMesh gm(s, o);
    const VoxBox range = s.touch_range(o.box_lo(), o.box_hi(), s.slop(max_abs(o.center) + max_abs(o.half)));
    const bool done = detail::level_set_inside(gm.g, *o.mesh, range, cancelled, [&](int x, int y, int z) {
      std::uint8_t& f = s.vflags[static_cast<std::size_t>(s.index(x, y, z))];
      if (!(f & Scene::Impl::kMeshTouched)) {
        f |= Scene::Impl::kMeshInside;
        any = true;
      }
    });
    meter.release(level_set);
    const glm::ivec3 n = range.empty() ? glm::ivec3(0) : range.hi - range.lo + 1;
    if (!done || !meter.tick(static_cast<std::uint64_t>(n.x) * static_cast<std::uint64_t>(n.y) *
                                 static_cast<std::uint64_t>(n.z) +
                             4 * o.mesh->triangles.size()))
      return build_cancelled();
  }
  if (!any) return Status::Ok();
  std::vector<detail::VoxBox> boxes;
  std::vector<std::uint32_t> owner;
  const std::uint64_t owners = 4 * static_cast<std::uint64_t>(s.spec.voxel_count());
  if (!meter.charge(owners)) return meter.stopped();
  detail::cover_with_boxes(s.res, s.vflags, Scene::Impl::kMeshInside, kOpaqueBoxSide, &boxes, &owner);
  if (!meter.charge(boxes.size() * sizeof(detail::VoxBox))) return meter.stopped();
  const auto first = static_cast<std::uint32_t>(s.opaque_boxes.size());
  s.opaque_boxes.insert(s.opaque_boxes.end(), boxes.begin(), boxes.end());
  // Per brick, the boxes owning its interior voxels, each once.
  detail::IdLists& lists = s.brick_mesh_boxes;
  lists.offsets.assign(1, 0);
  lists.ids.clear();
  std::vector<std::uint32_t> mark(boxes.size(), ~0u);
  const glm::ivec3 bres = s.pyr.res[1];
  for (int bz = 0; bz < bres.z; ++bz)
    for (int by = 0; by < bres.y; ++by)
      for (int bx = 0; bx < bres.x; ++bx) {
        const auto tag = static_cast<std::uint32_t>(lists.offsets.size() - 1);
        const glm::ivec3 o = glm::ivec3(bx, by, bz) << detail::kBrickShift;
        const glm::ivec3 end = glm::min(o + (1 << detail::kBrickShift), s.res);
        for (int z = o.z; z < end.z; ++z)
          for (int y = o.y; y < end.y; ++y)
            for (int x = o.x; x < end.x; ++x) {
              const std::uint32_t b = owner[static_cast<std::size_t>(s.index(x, y, z))];
              if (b == detail::kNoBox || mark[b] == tag) continue;
              mark[b] = tag;
              lists.ids.push_back(first + b);
            }
        lists.offsets.push_back(static_cast<std::uint32_t>(lists.ids.size()));
      }
  meter.release(owners);
  if (!meter.charge(4 * (lists.ids.size() + lists.offsets.size()))) return meter.stopped();
  return Status::Ok();
}

/// Pairs every mesh's triangles into quads (Obj::quads) and finds whether
/// it is closed and which way it runs (Obj::outward), once a mesh; then the
/// interiors of closed dynamic meshes. Each mesh's temporaries are charged
/// while they live (build_cost.cpp's figures), what is kept as it is.
Status pair_mesh_triangles(Scene::Impl& s, BuildMeter& meter, const BuildControl* control) {
  struct Done {
    std::shared_ptr<const detail::MeshQuads> quads;
    std::int8_t outward = 0;
  };
  std::unordered_map<const Mesh*, Done> done;
  for (Obj& o : s.objs) {
    if (o.shape != Shape::Mesh) continue;
    auto [it, fresh] = done.try_emplace(o.mesh.get());
    if (fresh) {
      const Mesh& m = *o.mesh;
      const std::uint64_t temporary = kPairBuildBytes * m.triangles.size();
      if (!meter.charge(temporary + kPairKeptBytes * m.triangles.size())) return meter.stopped();
      it->second.quads = std::make_shared<const detail::MeshQuads>(detail::pair_triangles(m));
      if (detail::mesh_closed(m)) {
        // Six times the signed volume (divergence theorem), about the
        // vertices' centroid to keep the products small.
        const Vec3 c = o.mesh_centroid;
        double vol = 0.0;
        for (const auto& t : m.triangles)
          vol += glm::dot(m.vertices[t[0]] - c, glm::cross(m.vertices[t[1]] - c, m.vertices[t[2]] - c));
        it->second.outward = vol > 0.0 ? 1 : vol < 0.0 ? -1 : 0;
      }
      meter.release(temporary);
      if (!meter.tick(8 * m.triangles.size() + 1)) return build_cancelled();
    }
    o.quads = it->second.quads;
    o.outward = it->second.outward;
    if (!o.dynamic && o.outward != 0) s.any_closed_mesh = true;
  }
  // Closed dynamic meshes' interiors in their own frames, at cubes of the
  // grid's least voxel side (in model units), once per mesh and side.
  std::map<std::pair<const Mesh*, double>, std::shared_ptr<const detail::ModelInterior>> interiors;
  const double side = std::fmin(s.spec.voxel_size.x, std::fmin(s.spec.voxel_size.y, s.spec.voxel_size.z));
  const detail::BuildStop stop{control ? control->cancelled : std::function<bool()>(),
                               [&meter](std::uint64_t n) { return meter.tick(n); }};
  for (Obj& o : s.objs) {
    if (!o.dynamic || o.shape != Shape::Mesh || o.outward == 0) continue;
    const double h = side / o.mesh_scale;
    auto& in = interiors[{o.mesh.get(), h}];
    if (!in) {
      double model = 0.0;
      for (const Vec3& v : o.mesh->vertices) model = std::fmax(model, max_abs(v));
      const glm::ivec3 n = detail::model_interior_cubes(*o.mesh, h);
      const std::uint64_t cubes = std::uint64_t(n.x) * std::uint64_t(n.y) * std::uint64_t(n.z);
      const std::uint64_t level_set = model_level_set_bytes(n);
      if (!meter.charge(level_set + cubes)) return meter.stopped();
      auto built = std::make_shared<detail::ModelInterior>();
      const bool finished = detail::model_interior(*o.mesh, h, 1e-9 * model, stop, built.get());
      meter.release(level_set);
      if (!finished) return build_cancelled();
      if (!meter.charge(built->boxes.size() * sizeof(detail::ModelInterior::Box))) return meter.stopped();
      in = std::move(built);
    }
    if (!in->boxes.empty()) o.interior = in;
  }
  return Status::Ok();
}

/// The static mesh triangles of each brick (Scene::Impl::brick_tris), for
/// the cell traversal with the buffer on: counted, then filled.
Status build_brick_triangles(Scene::Impl& s, BuildMeter& meter) {
  std::uint64_t total = 0;
  for (Obj& o : s.objs) {
    if (o.dynamic || o.shape != Shape::Mesh) continue;
    o.tri_base = static_cast<std::uint32_t>(total);
    total += o.mesh->triangles.size();
    if (total > std::numeric_limits<std::uint32_t>::max())
      return Status::Exhausted("grid", "static meshes hold more than 2^32 triangles in all");
  }
  if (total == 0) return Status::Ok();
  s.static_triangles = static_cast<std::uint32_t>(total);
  std::vector<std::uint32_t>& off = s.brick_tri_offsets;
  off.assign(s.pyr.cells(1) + 1, 0);
  std::uint64_t entries = 0;
  auto static_mesh = [](const Obj& o) { return !o.dynamic && o.shape == Shape::Mesh; };
  for (const Obj& o : s.objs)
    if (static_mesh(o) && !mesh_triangle_bricks(s, o, meter, [&](std::size_t b, std::uint32_t) {
          ++off[b + 1];
          ++entries;
        }))
      return meter.stopped();
  if (entries > std::numeric_limits<std::uint32_t>::max())
    return Status::Exhausted("grid", "static mesh triangles meet more than 2^32 bricks in all; choose a coarser grid");
  for (std::size_t i = 1; i < off.size(); ++i) off[i] += off[i - 1];
  if (!meter.charge(sizeof(detail::TriRef) * entries + 4 * off.size())) return meter.stopped();
  s.brick_tris.resize(static_cast<std::size_t>(entries));
  std::vector<std::uint32_t> next(off.begin(), off.end() - 1);
  for (std::uint32_t slot = 0; slot < s.objs.size(); ++slot) {
    Obj& o = s.objs[slot];
    if (!static_mesh(o)) continue;
    if (!mesh_triangle_bricks(s, o, meter, [&](std::size_t b, std::uint32_t t) {
          s.brick_tris[next[b]++] = detail::TriRef{slot, t};
        }))
      return build_cancelled();
    // The vertices the buffer draws, placed as the bricks were found.
    if (!meter.charge(sizeof(Vec3) * o.mesh->vertices.size())) return meter.stopped();
    const ObjectDesc d = o.mesh_desc();
    o.placed.resize(o.mesh->vertices.size());
    for (std::size_t i = 0; i < o.placed.size(); ++i) o.placed[i] = place(d, o.mesh->vertices[i]);
  }
  return Status::Ok();
}

/// The static cover, once: a voxel is opaque when the static objects
/// touching it (its own list, then the coarser cells', kCoverCandidates at
/// most) cover it whole.
Status build_static_cover(Scene::Impl& s, BuildMeter& meter) {
  const detail::IdLists& own = s.static_lists[0];
  for (int z = 0; z < s.res.z; ++z)
    for (int y = 0; y < s.res.y; ++y) {
      if (!meter.tick(static_cast<std::uint64_t>(s.res.x))) return build_cancelled();
      for (int x = 0; x < s.res.x; ++x) {
        const auto i = static_cast<std::size_t>(s.index(x, y, z));
        const std::uint8_t f = s.vflags[i];
        if ((f & (Scene::Impl::kStaticIds | Scene::Impl::kCoarseIds)) == 0) continue;
        std::uint32_t slots[detail::kCoverCandidates];
        const std::uint32_t* first = own.begin(i);
        auto n = static_cast<std::size_t>(own.end(i) - first);
        if (f & Scene::Impl::kCoarseIds) {
          std::size_t k = 0;
          for (const std::uint32_t* p = own.begin(i); p != own.end(i) && k < std::size(slots); ++p) slots[k++] = *p;
          s.coarse_static(x, y, z, slots, &k, std::size(slots));
          first = slots, n = k;
        }
        if (!s.union_covers(first, n, x, y, z)) continue;
        s.vflags[i] |= Scene::Impl::kStaticOpaque;
        if (s.in_one_ball(first, n, x, y, z)) s.vflags[i] |= Scene::Impl::kInOneBall;
      }
    }
  return Status::Ok();
}

/// The occlusion buffer's occluders (buffer on): opaque voxels covered with
/// boxes, meshes' quads and closedness, closed meshes' interiors.
Status build_occluders(Scene::Impl& s, BuildMeter& meter, const BuildControl* control) {
  detail::cover_with_boxes(s.res, s.vflags, Scene::Impl::kStaticOpaque, kOpaqueBoxSide, &s.opaque_boxes,
                           &s.opaque_owner);
  s.static_opaque_boxes = s.opaque_boxes.size();
  if (!meter.charge(s.opaque_boxes.size() * sizeof(detail::VoxBox))) return meter.stopped();
  if (Status st = pair_mesh_triangles(s, meter, control); !st) return st;
  return build_mesh_interiors(s, meter, control);
}

/// The static convex occluders of region frames (region_occlusion.h): static
/// boxes and balls, and the boxes of static opaque voxels (buffer on).
Status build_region_occluders(Scene::Impl& s, BuildMeter& meter) {
  std::vector<detail::RegionOccluder> occ;
  for (const detail::Obj& o : s.objs) {
    if (o.dynamic || o.shape == Shape::Mesh) continue;
    occ.push_back({o.box_lo(), o.box_hi(), o.shape == Shape::Sphere ? o.radius : 0.0});
  }
  const std::size_t most_boxes = std::min(s.static_opaque_boxes, detail::region_box_occluders(s.pyr.cells(1)));
  // Bounded before anything is made (region_occlusion.h).
  if (!meter.charge(detail::region_occluder_bytes(occ.size() + most_boxes))) return meter.stopped();
  // The objects first, then the opaque boxes that no box object holds whole
  // (a wall's own voxels add nothing to the wall), the largest first, so
  // many as the estimate allows.
  auto place = [&](std::vector<detail::RegionOccluder> all) {
    detail::place_region_occluders(std::move(all), &s.region_occ);
    detail::fill_region_buckets(&s.region_occ);
  };
  place(occ);
  const GridSpec& spec = s.spec;
  std::vector<detail::RegionOccluder> boxes;
  for (std::size_t b = 0; b < s.static_opaque_boxes; ++b) {
    const detail::VoxBox& vb = s.opaque_boxes[b];
    const Vec3 lo = spec.bounds_min + Vec3(vb.lo) * spec.voxel_size;
    const Vec3 hi = spec.bounds_min + Vec3(vb.hi + 1) * spec.voxel_size;
    if (!s.region_occ.inside_one(lo, hi)) boxes.push_back({lo, hi, 0.0});
  }
  auto volume = [](const detail::RegionOccluder& k) { return (k.hi.x - k.lo.x) * (k.hi.y - k.lo.y) * (k.hi.z - k.lo.z); };
  std::stable_sort(boxes.begin(), boxes.end(), [&](const auto& a, const auto& b) { return volume(a) > volume(b); });
  if (boxes.size() > most_boxes) boxes.resize(most_boxes);
  occ.insert(occ.end(), boxes.begin(), boxes.end());
  place(std::move(occ));
  return Status::Ok();
}

/// With dynamic objects: the free space's components (region_cavity.h), so
/// that a region shut in a room leaves out the movers outside it.
Status build_free_space(Scene::Impl& s, BuildMeter& meter) {
  const auto voxels = static_cast<std::uint64_t>(s.spec.voxel_count());
  if (voxels > detail::kMaxFreeSpaceVoxels) return Status::Ok();  // No free space (region_cavity.h).
  if (!meter.charge(detail::free_space_bytes(voxels))) return meter.stopped();
  if (!meter.charge(4 * voxels)) return meter.stopped();  // The flood's queue, at most a voxel each.
  const bool done = detail::label_free_space(s.res, s.vflags, Scene::Impl::kStaticOpaque,
                                             [&] { return meter.tick(static_cast<std::uint64_t>(s.res.x)); },
                                             &s.free_space);
  meter.release(4 * voxels);
  return done ? Status::Ok() : build_cancelled();
}

/// The cell traversal's summaries (buffer on: only its traversal reads
/// them): static masks, per-brick lists, per-brick mesh triangles.
Status build_cell_summaries(Scene::Impl& s, BuildMeter& meter) {
  build_static_masks(s);
  // The lists' marks (an object's and a box's last brick) while they are made.
  const std::uint64_t marks = 4 * (s.objs.size() + s.opaque_boxes.size());
  if (!meter.charge(marks)) return meter.stopped();
  build_brick_lists(s);
  meter.release(marks);
  if (!meter.charge(4 * (s.brick_static.ids.size() + s.brick_boxes.ids.size()))) return meter.stopped();
  return build_brick_triangles(s, meter);
}

/// The dynamic objects' cells, seen times and queues, and every dynamic
/// object discretized: until a viewer has looked, every object may be
/// visible; those no viewer claims get TBVs after a frame.
Status build_dynamic(Scene::Impl& s, BuildMeter& meter) {
  const bool cells = s.options.occlusion_buffer > 0;
  s.bricks_res = s.pyr.res[1];
  s.bricks.resize(s.pyr.cells(1));
  for (int l = 2; l < s.pyr.levels; ++l) s.coarse_dyn[static_cast<std::size_t>(l)].resize(s.pyr.cells(l));
  for (int l = 1; cells && l < s.pyr.levels; ++l) {
    s.dyn_count[static_cast<std::size_t>(l)].assign(s.pyr.cells(l), 0);
    s.dyn_mask[static_cast<std::size_t>(l)].assign(s.pyr.cells(l), 0);
  }
  s.seen_at.assign(s.bricks.size(), -std::numeric_limits<double>::infinity());
  s.seen_mask.assign(s.bricks.size(), 0);
  for (int l = 2; l < s.pyr.levels; ++l)
    s.cell_seen_at[static_cast<std::size_t>(l)].assign(s.pyr.cells(l), -std::numeric_limits<double>::infinity());
  if (s.pyr.levels > 2) s.cell_any_seen_at.assign(s.pyr.cells(2), -std::numeric_limits<double>::infinity());
  for (std::uint32_t slot = 0; slot < s.objs.size(); ++slot) {
    detail::Obj& o = s.objs[slot];
    if (!o.dynamic) continue;
    if (!meter.tick(64)) return build_cancelled();
    o.tbv_period = s.initial_period(o);
    s.discretize(slot);
    o.pending_unclaimed = true;
    s.unclaimed.push_back(slot);
  }
  s.pending = FrameStats{};
  return Status::Ok();
}

}  // namespace
}  // namespace build

Status Scene::create(const SceneDesc& desc, const SceneOptions& options, std::unique_ptr<Scene>* out,
                     const BuildControl* control) {
  auto impl = std::make_unique<Impl>();
  Impl& s = *impl;
  build::BuildMeter meter(control);
  if (Status st = build::prepare(desc, options, s, meter); !st) return st;
  build::LevelCounts per_level{};
  {
    // Refused before the grid's layers are allocated.
    SceneCost cost;
    if (Status st = build::count_cost(s, meter, &cost, &per_level); !st) return st;
  }
  if (!meter.charge(build::grid_bytes(s) + build::mesh_bytes(s))) return meter.stopped();
  s.vflags.assign(static_cast<std::size_t>(s.spec.voxel_count()), 0);
  if (Status st = build::build_static_lists(s, meter, per_level); !st) return st;
  if (Status st = build::build_static_cover(s, meter); !st) return st;
  if (s.options.occlusion_buffer > 0) {
    if (Status st = build::build_occluders(s, meter, control); !st) return st;
    if (Status st = build::build_cell_summaries(s, meter); !st) return st;
  }
  if (Status st = build::build_region_occluders(s, meter); !st) return st;
  if (s.dynamic_count > 0) {
    if (Status st = build::build_free_space(s, meter); !st) return st;
    if (Status st = build::build_dynamic(s, meter); !st) return st;
  }
  s.built_bytes = meter.charged();
  out->reset(new Scene(std::move(impl)));
  return Status::Ok();
}

std::uint64_t Scene::built_bytes() const { return impl_->built_bytes; }

}  // namespace voxvis
