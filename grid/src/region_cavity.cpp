// region_cavity.cpp — see region_cavity.h.
#include "region_cavity.h"

#include <algorithm>

#include <glm/common.hpp>

namespace voxvis::detail {

namespace {

/// Floods the free voxels 26-connected to `seed` with `label`; whether the
/// component reaches the grid's boundary. False when `keep_going` says stop.
bool flood(const glm::ivec3& res, std::uint32_t seed, std::uint16_t label, std::vector<std::uint16_t>& lab,
           std::vector<std::uint32_t>& queue, const std::function<bool()>& keep_going, bool* open, VoxBox* box) {
  const std::int64_t rx = res.x, rxy = std::int64_t{res.x} * res.y;
  queue.clear();
  queue.push_back(seed);
  lab[seed] = label;
  for (std::size_t head = 0; head < queue.size(); ++head) {
    if ((head & 4095) == 4095 && !keep_going()) return false;
    const std::int64_t i = queue[head];
    const int x = static_cast<int>(i % rx), y = static_cast<int>(i / rx % res.y), z = static_cast<int>(i / rxy);
    if (x == 0 || y == 0 || z == 0 || x == res.x - 1 || y == res.y - 1 || z == res.z - 1) *open = true;
    box->lo = glm::min(box->lo, glm::ivec3(x, y, z));
    box->hi = glm::max(box->hi, glm::ivec3(x, y, z));
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int nx = x + dx, ny = y + dy, nz = z + dz;
          if (nx < 0 || ny < 0 || nz < 0 || nx >= res.x || ny >= res.y || nz >= res.z) continue;
          const std::int64_t n = nx + rx * ny + rxy * nz;
          if (lab[static_cast<std::size_t>(n)] != kUnlabelled) continue;
          lab[static_cast<std::size_t>(n)] = label;
          queue.push_back(static_cast<std::uint32_t>(n));
        }
  }
  return true;
}

}  // namespace

bool label_free_space(const glm::ivec3& res, const std::vector<std::uint8_t>& flags, std::uint8_t opaque,
                      const std::function<bool()>& keep_going, FreeSpace* out) {
  *out = FreeSpace{};
  std::vector<std::uint16_t> lab(flags.size());
  for (std::size_t i = 0; i < flags.size(); ++i) lab[i] = (flags[i] & opaque) ? kOpaqueLabel : kUnlabelled;
  std::vector<std::uint8_t> open(1, 0);  // Label 0: opaque.
  std::vector<VoxBox> boxes(1);
  std::vector<std::uint32_t> queue;
  std::uint16_t next = 1;
  const std::size_t row = static_cast<std::size_t>(res.x);
  for (std::size_t start = 0; start < lab.size(); start += row) {
    if (!keep_going()) return false;
    for (std::size_t i = start; i < start + row && next <= kMaxLabel; ++i) {
      if (lab[i] != kUnlabelled) continue;
      bool reaches = false;
      VoxBox box{res, glm::ivec3(-1)};
      if (!flood(res, static_cast<std::uint32_t>(i), next, lab, queue, keep_going, &reaches, &box)) return false;
      open.push_back(reaches ? 1 : 0);
      boxes.push_back(box);
      ++next;
    }
  }
  out->label = std::move(lab);
  out->open = std::move(open);
  out->box = std::move(boxes);
  return true;
}

RegionCavity::RegionCavity(const FreeSpace& space, const glm::ivec3& res, const VoxBox& eyes, bool inside)
    : space_(space), res_(res) {
  if (!space.built() || !inside || eyes.empty()) return;
  const glm::ivec3 n = eyes.hi - eyes.lo + 1;
  if (std::int64_t{n.x} * n.y * n.z > kMaxEyeVoxels) return;
  for (int z = eyes.lo.z; z <= eyes.hi.z; ++z)
    for (int y = eyes.lo.y; y <= eyes.hi.y; ++y)
      for (int x = eyes.lo.x; x <= eyes.hi.x; ++x) {
        const std::uint16_t l = at(x, y, z);
        // An eye near a wall (the near plane may clip it) or in an
        // unlabelled component: no test this frame.
        if (l == kOpaqueLabel || l == kUnlabelled) return;
        if (mine(l)) continue;
        if (count_ == static_cast<int>(std::size(labels_))) return;
        labels_[count_] = l;
        box_ = count_++ == 0 ? space.box[l] : VoxBox{glm::min(box_.lo, space.box[l].lo), glm::max(box_.hi, space.box[l].hi)};
        open_ = open_ || space.open[l] != 0;
      }
  on_ = true;
}

bool RegionCavity::mine(std::uint16_t l) const {
  for (int k = 0; k < count_; ++k)
    if (labels_[k] == l) return true;
  return false;
}

bool RegionCavity::hides(const VoxBox& range, bool inside) const {
  if (!on_ || (!inside && open_)) return false;
  // Only the part within the eyes' components' box can hold their voxels.
  const VoxBox part{glm::max(range.lo, box_.lo), glm::min(range.hi, box_.hi)};
  if (range.empty() || part.empty()) return true;
  const glm::ivec3 n = part.hi - part.lo + 1;
  if (std::int64_t{n.x} * n.y * n.z > kMaxObjectVoxels) return false;
  for (int z = part.lo.z; z <= part.hi.z; ++z)
    for (int y = part.lo.y; y <= part.hi.y; ++y)
      for (int x = part.lo.x; x <= part.hi.x; ++x)
        if (mine(at(x, y, z))) return false;
  return true;
}

}  // namespace voxvis::detail
