// cells.h — the cell pyramid over the voxel grid.
//
// Level 0 is the voxels; a cell of level l is 4^l voxels a side (4 x 4 x 4
// cells of level l-1), cut at the grid's far faces; level 1 is the 4^3-voxel
// brick. The top level has a single cell covering the grid (4^7 = 16384 is
// beyond the largest resolution, 8192).
//
// Why. An object is stored in every voxel its box touches, so an object
// covering the grid costs the grid's voxel count, and a thousand such objects
// a thousand times that (27-66 s and 1.3 GB for 1,000 spheres over an 84^3
// grid). Stored instead in the coarsest cells whose voxels it all touches,
// and in voxels only where its surface cuts a brick, it costs about its
// surface: `decompose` below finds those cells.
//
// Convexity is what makes a cell's test cheap: the voxels a ball or a box
// touches (or contains) are, by their lower corners, a convex set of the
// grid's integer points, so a box of voxels lies in it when its 8 corner
// voxels do. A rounding that lets the corners pass while an inner voxel
// would fail by an ulp stores the object where it nearly touches: that only
// adds it to a collection, never removes it.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include <glm/common.hpp>
#include <glm/vec3.hpp>

#include "voxbox.h"
#include "voxvis/assert.h"

namespace voxvis::detail {

inline constexpr int kCellShift = 2;   ///< 4 children per axis, 64 in all.
inline constexpr int kMaxLevels = 8;   ///< Voxels, bricks, ..., 4^7 = 16384 voxels a side.

struct Pyramid {
  int levels = 1;                         ///< Levels 0 .. levels - 1; the top has one cell.
  std::array<glm::ivec3, kMaxLevels> res{};  ///< Cells per axis; res[0] is the grid.

  /// At least the voxels and the bricks (levels >= 2, so that the top is a
  /// cell, never a voxel, even for a grid of one voxel).
  static Pyramid make(const glm::ivec3& voxels) {
    Pyramid p;
    p.res[0] = voxels;
    while ((p.res[p.levels - 1] != glm::ivec3(1) || p.levels < 2) && p.levels < kMaxLevels) {
      p.res[p.levels] = (p.res[p.levels - 1] + ((1 << kCellShift) - 1)) >> kCellShift;
      ++p.levels;
    }
    return p;
  }
  std::size_t cells(int l) const {
    return static_cast<std::size_t>(res[l].x) * static_cast<std::size_t>(res[l].y) *
           static_cast<std::size_t>(res[l].z);
  }
  std::size_t index(int l, const glm::ivec3& c) const {
    VOXVIS_ASSERT(l >= 0 && l < levels && c.x >= 0 && c.y >= 0 && c.z >= 0 && c.x < res[l].x && c.y < res[l].y &&
                  c.z < res[l].z);
    return static_cast<std::size_t>(c.x) +
           static_cast<std::size_t>(res[l].x) *
               (static_cast<std::size_t>(c.y) + static_cast<std::size_t>(res[l].y) * static_cast<std::size_t>(c.z));
  }
  /// The level-`base` cells of cell c of level l (l >= base), clipped to the grid.
  VoxBox span(int l, const glm::ivec3& c, int base) const {
    const int sh = kCellShift * (l - base);
    VoxBox b{c << sh, ((c + 1) << sh) - 1};
    b.hi = glm::min(b.hi, res[base] - 1);
    return b;
  }
};

/// Splits the box `box` of level-`base` cells into the coarsest cells
/// (levels >= base) that lie wholly inside it and whose every base cell
/// satisfies `whole(VoxBox corners)` — called with the box of base cells
/// whose 8 corners it must test (the set it tests must be convex) — and
/// calls emit(level, cell) for each. A base cell inside the box that fails
/// `whole` is emitted when `keep_partial` says so, else dropped. A cell one
/// level above base that is not whole is handed to `leaf(in)` (`in`: its
/// base cells inside the box), which may emit the base cells itself and
/// return true (faster than one `whole` test each), or return false.
/// `tick(n)` counts work and returns false to abandon (decompose then
/// returns false).
template <class Whole, class Leaf, class Emit, class Tick>
bool decompose(const Pyramid& p, int base, const VoxBox& box, Whole&& whole, Leaf&& leaf, bool keep_partial,
               Emit&& emit, Tick&& tick) {
  if (box.empty()) return true;
  struct Frame {
    int level, x, y, z;
  };
  // Depth-first: at most 63 siblings pending per level. Left uninitialized
  // (a plain array of ints): decompose runs for every move.
  Frame stack[64 * kMaxLevels];
  int top = 0;
  stack[top++] = Frame{p.levels - 1, 0, 0, 0};
  while (top > 0) {
    const Frame fr = stack[--top];
    const struct {
      int level;
      glm::ivec3 c;
    } f{fr.level, glm::ivec3(fr.x, fr.y, fr.z)};
    const VoxBox r = f.level == base ? VoxBox{f.c, f.c} : p.span(f.level, f.c, base);
    const VoxBox in{glm::max(r.lo, box.lo), glm::min(r.hi, box.hi)};
    if (in.empty()) continue;
    if (!tick(1)) return false;
    if (in == r && whole(r)) {
      emit(f.level, f.c);
      continue;
    }
    if (f.level == base) {
      if (keep_partial) emit(f.level, f.c);
      continue;
    }
    if (f.level == base + 1) {
      if (!tick(static_cast<std::uint64_t>(in.hi.x - in.lo.x + 1) * static_cast<std::uint64_t>(in.hi.y - in.lo.y + 1) *
                static_cast<std::uint64_t>(in.hi.z - in.lo.z + 1)))
        return false;
      if (leaf(in)) continue;
    }
    // The children meeting the box.
    const int sh = kCellShift * (f.level - 1 - base);
    const glm::ivec3 first = f.c << kCellShift;
    const glm::ivec3 lo = glm::max(first, in.lo >> sh);
    const glm::ivec3 hi = glm::min(glm::min(first + ((1 << kCellShift) - 1), p.res[f.level - 1] - 1), in.hi >> sh);
    for (int z = hi.z; z >= lo.z; --z)
      for (int y = hi.y; y >= lo.y; --y)
        for (int x = hi.x; x >= lo.x; --x) stack[top++] = Frame{f.level - 1, x, y, z};
  }
  return true;
}

/// Whether the 8 corner cells of `b` all satisfy `test(x, y, z)`.
/// (Each distinct corner once: a single cell is one test, not eight.)
template <class Test>
bool corners_pass(const VoxBox& b, Test&& test) {
  for (int z = b.lo.z;; z = b.hi.z) {
    for (int y = b.lo.y;; y = b.hi.y) {
      for (int x = b.lo.x;; x = b.hi.x) {
        if (!test(x, y, z)) return false;
        if (x == b.hi.x) break;
      }
      if (y == b.hi.y) break;
    }
    if (z == b.hi.z) break;
  }
  return true;
}

}  // namespace voxvis::detail
