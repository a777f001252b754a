// opaque_boxes.cpp — see opaque_boxes.h.
#include "opaque_boxes.h"

namespace voxvis::detail {

void cover_with_boxes(const glm::ivec3& res, const std::vector<std::uint8_t>& flags, std::uint8_t bit,
                      int max_side, std::vector<VoxBox>* boxes, std::vector<std::uint32_t>* owner) {
  boxes->clear();
  owner->clear();
  const std::int64_t sx = 1, sy = res.x, sz = std::int64_t{res.x} * res.y;
  const auto n = static_cast<std::size_t>(sz * res.z);
  bool any = false;
  for (std::size_t i = 0; i < n && !any; ++i) any = (flags[i] & bit) != 0;
  if (!any) return;
  owner->assign(n, kNoBox);
  auto idx = [&](int x, int y, int z) { return static_cast<std::size_t>(x * sx + y * sy + z * sz); };
  auto set = [&](int x, int y, int z) { return (flags[idx(x, y, z)] & bit) != 0; };
  // Whether the layer of box b one step beyond its face (axis a, side s) is
  // inside the grid and wholly set.
  auto layer_set = [&](const VoxBox& b, int a, int s) {
    const int c = s > 0 ? b.hi[a] + 1 : b.lo[a] - 1;
    if (c < 0 || c >= res[a]) return false;
    if (b.hi[a] - b.lo[a] + 1 >= max_side) return false;
    VoxBox l = b;
    l.lo[a] = l.hi[a] = c;
    for (int z = l.lo.z; z <= l.hi.z; ++z)
      for (int y = l.lo.y; y <= l.hi.y; ++y)
        for (int x = l.lo.x; x <= l.hi.x; ++x)
          if (!set(x, y, z)) return false;
    return true;
  };
  for (int z = 0; z < res.z; ++z)
    for (int y = 0; y < res.y; ++y)
      for (int x = 0; x < res.x; ++x) {
        if (!set(x, y, z) || (*owner)[idx(x, y, z)] != kNoBox) continue;
        VoxBox b;
        b.lo = b.hi = glm::ivec3(x, y, z);
        // Grow one layer at a time in each direction in turn (x, z, then
        // y), so that the box stays roughly balanced until a side stops.
        bool grew = true;
        while (grew) {
          grew = false;
          for (int a : {0, 2, 1})
            for (int s : {1, -1})
              if (layer_set(b, a, s)) {
                (s > 0 ? b.hi[a] : b.lo[a]) += s;
                grew = true;
              }
        }
        const auto id = static_cast<std::uint32_t>(boxes->size());
        boxes->push_back(b);
        for (int zz = b.lo.z; zz <= b.hi.z; ++zz)
          for (int yy = b.lo.y; yy <= b.hi.y; ++yy)
            for (int xx = b.lo.x; xx <= b.hi.x; ++xx) {
              std::uint32_t& o = (*owner)[idx(xx, yy, zz)];
              if (o == kNoBox) o = id;
            }
      }
}

}  // namespace voxvis::detail
