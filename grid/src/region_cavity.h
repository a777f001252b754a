// region_cavity.h — the free space a region's eyes are shut in (docs/design.md,
// "Regions"): what lies outside it is hidden from every eye of the box,
// however many walls meet around it.
//
// The argument. Label the 26-connected components of the voxels that are not
// static opaque. Let the eye box, grown by what the near plane clips, lie in
// free voxels of a set C of components, and let a box X touch no voxel of C
// (and, when a component of C reaches the grid's boundary, lie inside the
// grid). Follow a segment from an eye to a point x of X through the closed
// voxels it meets: at the last point p where it is in a voxel of C, every
// voxel holding the points just beyond p holds p too, so is a 26-neighbour of
// a voxel of C; a free one would be in C, so all are opaque, and the points
// just beyond p lie inside the union of opaque voxels — inside the static
// objects, strictly before x and beyond the near plane. So no point of X is a
// first hit from any eye of the box, at any time X's box covers. Opaque
// voxels are static, so the labels are made once, when the scene is built.
#pragma once

#include <algorithm>
#include <cstdint>
#include <functional>
#include <vector>

#include <glm/vec3.hpp>

#include "voxbox.h"
#include "voxvis/types.h"

namespace voxvis::detail {

/// Per voxel, its free-space component: kOpaqueLabel for a static opaque
/// voxel, 1 .. kMaxLabel, or kUnlabelled past that many components (eyes in
/// one get no test; the pockets of a voxel cave are many and small).
inline constexpr std::uint16_t kOpaqueLabel = 0, kMaxLabel = 1023, kUnlabelled = 0xffff;

struct FreeSpace {
  std::vector<std::uint16_t> label;  ///< Per voxel, x fastest.
  std::vector<std::uint8_t> open;    ///< Per label: the component reaches the grid's boundary.
  std::vector<VoxBox> box;           ///< Per label: the voxels' bounding box.
  bool built() const { return !label.empty(); }
};

/// Grids of more voxels get no free space (its labels would cost more than
/// 4 MiB; the automatic resolution aims at 600,000 voxels).
inline constexpr std::uint64_t kMaxFreeSpaceVoxels = std::uint64_t{1} << 21;
/// The bytes the labels of a grid of `voxels` voxels keep (0: none made).
inline std::uint64_t free_space_bytes(std::uint64_t voxels) {
  if (voxels > kMaxFreeSpaceVoxels) return 0;
  return 2 * voxels + (1 + sizeof(VoxBox)) * std::min<std::uint64_t>(voxels + 1, kMaxLabel + 1);
}

/// Labels the voxels of a grid of `res` (flags per voxel, x fastest;
/// `opaque` the static-opaque bit). `keep_going` is asked once a row of
/// voxels; false stops and leaves `out` empty. Uses a queue of up to one
/// entry a voxel (4 bytes).
bool label_free_space(const glm::ivec3& res, const std::vector<std::uint8_t>& flags, std::uint8_t opaque,
                      const std::function<bool()>& keep_going, FreeSpace* out);

/// One frame's test: the components the eye box lies in.
class RegionCavity {
 public:
  /// Voxels the eyes' cell range may span before the test is not worth
  /// its set-up (a box of eyes that large is in the open anyway).
  static constexpr std::int64_t kMaxEyeVoxels = 4096;
  /// Voxels of an object's range within the eyes' components' box that
  /// may be read before the object is left untested.
  static constexpr std::int64_t kMaxObjectVoxels = 4096;

  /// `eyes`: the voxel range the eye box, grown by the near plane's reach,
  /// may touch; `inside`: whether that box lies inside the grid box.
  RegionCavity(const FreeSpace& space, const glm::ivec3& res, const VoxBox& eyes, bool inside);
  bool on() const { return on_; }
  /// Whether the object whose box may touch voxels `range` (clipped to the
  /// grid; `inside`: the box lies within the grid box) is hidden.
  bool hides(const VoxBox& range, bool inside) const;
  /// The voxel box around the eyes' components (when on()).
  const VoxBox& box() const { return box_; }

 private:
  std::uint16_t at(int x, int y, int z) const {
    return space_.label[static_cast<std::size_t>(x) +
                        static_cast<std::size_t>(res_.x) * (static_cast<std::size_t>(y) + static_cast<std::size_t>(res_.y) * z)];
  }
  bool mine(std::uint16_t l) const;

  const FreeSpace& space_;
  glm::ivec3 res_;
  bool on_ = false;
  bool open_ = false;  ///< A component of the eyes reaches the grid's boundary.
  std::uint16_t labels_[8] = {};
  int count_ = 0;
  VoxBox box_;  ///< Around the eyes' components.
};

}  // namespace voxvis::detail
