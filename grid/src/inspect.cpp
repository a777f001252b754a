// inspect.cpp — voxvis/inspect.h: the grid read row by row for tools, and
// the switch of a Scratch's frame record.
//
// The objects a voxel holds are counted the way the traversal collects
// them (collect.h): a static object from the lists of the voxel and of the
// cells above it (each object is stored in cells that do not overlap, so it
// counts once per voxel it touches), a dynamic one by the exact test at its
// centre over its range of voxels. A static object stored in a coarse cell
// costs one count per cell and level, not one per voxel, so a row costs its
// voxels and the levels above them, whatever the objects' sizes.
#include <algorithm>
#include <mutex>
#include <shared_mutex>

#include "numeric.h"
#include "scene_impl.h"
#include "voxvis/inspect.h"

namespace voxvis {

using detail::Obj;
using detail::VoxBox;

void Scratch::set_trace(FrameTrace* trace) { impl_->trace = trace; }

namespace {

/// A dynamic object's voxels to test: those its box may touch at its centre
/// (as Scene::Impl::discretize finds them).
struct DynRange {
  std::uint32_t slot;
  VoxBox vb;
};

}  // namespace

void inspect_grid(const Scene& scene, const std::function<void(const GridRow&)>& row,
                  const std::vector<ObjectId>* only) {
  const Scene::Impl& s = scene.impl();
  std::shared_lock<detail::GridMutex> lock(s.mu);
  const glm::ivec3 res = s.res;

  // Which objects count: all, or those `only` names.
  std::vector<std::uint8_t> counted(s.objs.size(), only == nullptr ? 1 : 0);
  if (only != nullptr)
    for (const ObjectId id : *only)
      if (const auto it = s.slot_of.find(id); it != s.slot_of.end()) counted[it->second] = 1;

  // Per cell of each level >= 1, its counted static objects: every voxel
  // of the cell holds them.
  std::array<std::vector<std::uint32_t>, detail::kMaxLevels> cell_count;
  for (int l = 1; l < s.pyr.levels; ++l) {
    const detail::IdLists& lists = s.static_lists[static_cast<std::size_t>(l)];
    if (!lists.any()) continue;
    std::vector<std::uint32_t>& n = cell_count[static_cast<std::size_t>(l)];
    n.assign(s.pyr.cells(l), 0);
    for (std::size_t c = 0; c < n.size(); ++c)
      for (const std::uint32_t* p = lists.begin(c); p != lists.end(c); ++p) n[c] += counted[*p];
  }

  // Counted dynamic objects by the first layer of z they reach; `active`
  // holds those whose range contains the current layer.
  std::vector<DynRange> dyn;
  for (std::uint32_t slot = 0; slot < s.objs.size(); ++slot) {
    const Obj& o = s.objs[slot];
    if (!o.dynamic || !counted[slot]) continue;
    const VoxBox vb = s.touch_range(o.box_lo(), o.box_hi(), s.slop(detail::max_abs(o.center) + o.radius + detail::max_abs(o.half)));
    if (!vb.empty()) dyn.push_back(DynRange{slot, vb});
  }
  std::sort(dyn.begin(), dyn.end(), [](const DynRange& a, const DynRange& b) { return a.vb.lo.z < b.vb.lo.z; });
  std::vector<DynRange> active;
  std::size_t next_dyn = 0;

  const auto nx = static_cast<std::size_t>(res.x);
  std::vector<std::uint8_t> opaque(nx);
  std::vector<std::uint32_t> objects(nx);
  const detail::IdLists& own = s.static_lists[0];
  GridRow r;
  r.opaque = opaque;
  r.objects = objects;
  for (int z = 0; z < res.z; ++z) {
    std::erase_if(active, [z](const DynRange& d) { return d.vb.hi.z < z; });
    while (next_dyn < dyn.size() && dyn[next_dyn].vb.lo.z <= z) active.push_back(dyn[next_dyn++]);
    for (int y = 0; y < res.y; ++y) {
      const std::int64_t base = s.index(0, y, z);
      for (std::size_t x = 0; x < nx; ++x) {
        const auto i = static_cast<std::size_t>(base) + x;
        opaque[x] = static_cast<std::uint8_t>(((s.vflags[i] & Scene::Impl::kStaticOpaque) ? GridRow::kCovered : 0) |
                                              ((s.vflags[i] & Scene::Impl::kMeshInside) ? GridRow::kInsideMesh : 0));
        std::uint32_t n = 0;
        if (own.any())
          for (const std::uint32_t* p = own.begin(i); p != own.end(i); ++p) n += counted[*p];
        objects[x] = n;
      }
      for (int l = 1; l < s.pyr.levels; ++l) {
        const std::vector<std::uint32_t>& n = cell_count[static_cast<std::size_t>(l)];
        if (n.empty()) continue;
        const int sh = detail::kCellShift * l;
        for (int cx = 0; cx < s.pyr.res[static_cast<std::size_t>(l)].x; ++cx) {
          const std::uint32_t k = n[s.pyr.index(l, glm::ivec3(cx, y >> sh, z >> sh))];
          if (k == 0) continue;
          const int x1 = std::min(res.x, (cx + 1) << sh);
          for (int x = cx << sh; x < x1; ++x) objects[static_cast<std::size_t>(x)] += k;
        }
      }
      for (const DynRange& d : active) {
        if (y < d.vb.lo.y || y > d.vb.hi.y) continue;
        const Obj& o = s.objs[d.slot];
        for (int x = d.vb.lo.x; x <= d.vb.hi.x; ++x)
          if (s.touches(o, o.center, x, y, z)) ++objects[static_cast<std::size_t>(x)];
      }
      r.y = y;
      r.z = z;
      row(r);
    }
  }
}

}  // namespace voxvis
