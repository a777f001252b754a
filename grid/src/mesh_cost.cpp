// mesh_cost.cpp — see mesh_cost.h.
#include "mesh_cost.h"

#include <cmath>
#include <unordered_set>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "tri_box.h"

namespace voxvis::detail {
namespace {

double norm1(const Vec3& v) { return std::fabs(v.x) + std::fabs(v.y) + std::fabs(v.z); }

/// The volume of triangle (a, b, c) grown by an axis-aligned cube of side w.
double grown_volume(const Vec3& a, const Vec3& b, const Vec3& c, double w) {
  const double faces = 0.5 * w * norm1(glm::cross(b - a, c - a));
  const double edges = 0.5 * w * w * (norm1(b - a) + norm1(c - b) + norm1(a - c));
  return faces + edges + w * w * w;
}

/// A bound from a volume: rounded up, with a part in a million for the
/// volume's own roundings.
double whole_cells(double volume) { return std::ceil(volume * (1.0 + 1e-6)); }

}  // namespace

double cells_touched_bound(const Vec3& a, const Vec3& b, const Vec3& c, double side, double grow) {
  return whole_cells(grown_volume(a / side, b / side, c / side, 2.0 * (1.0 + grow / side)));
}

namespace {

struct Key {
  std::int64_t x, y, z;
  bool operator==(const Key&) const = default;
};
struct KeyHash {
  std::size_t operator()(const Key& k) const {
    return static_cast<std::size_t>(k.x * 73856093 ^ k.y * 19349663 ^ k.z * 83492791);
  }
};

/// Adds to `leaves` every leaf (a unit cell in leaf units) of the cube
/// [lo, lo + size) that triangle (a, b, c), in leaf units, meets grown by
/// `grow`, descending by halves from the cube. False when the set passes
/// `max` or `steps` passes `max_steps`.
bool descend(const Vec3& a, const Vec3& b, const Vec3& c, const Key& lo, std::int64_t size, double grow,
             std::unordered_set<Key, KeyHash>& leaves, std::uint64_t max, std::uint64_t& steps) {
  ++steps;
  const Vec3 corner(static_cast<double>(lo.x), static_cast<double>(lo.y), static_cast<double>(lo.z));
  const double half = 0.5 * static_cast<double>(size);
  // Grown a little more at each level than the leaves below it, so that no
  // leaf the finest test keeps is in a cube a coarser one drops.
  const double margin = 1e-9 * (norm1(a) + norm1(b) + norm1(c) + norm1(corner) + static_cast<double>(size));
  if (!triangle_meets_box(a, b, c, corner + half, Vec3(half + grow + margin))) return true;
  if (size == 1) {
    leaves.insert(lo);
    return leaves.size() <= max;
  }
  const std::int64_t h = size / 2;
  for (int k = 0; k < 8; ++k) {
    const Key child{lo.x + ((k & 1) ? h : 0), lo.y + ((k & 2) ? h : 0), lo.z + ((k & 4) ? h : 0)};
    if (!descend(a, b, c, child, h, grow, leaves, max, steps)) return false;
  }
  return true;
}

}  // namespace

bool level_set_nodes(const std::vector<Vec3>& g, const Mesh& mesh, double distance, std::uint64_t max_leaves,
                     const std::function<bool(std::uint64_t)>& tick, LevelSetNodes* out) {
  constexpr double kLeaf = 8.0;
  std::unordered_set<Key, KeyHash> leaves;
  const double grow = distance / kLeaf;
  bool within = true;
  for (const auto& t : mesh.triangles) {
    const Vec3 a = g[t[0]] / kLeaf, b = g[t[1]] / kLeaf, c = g[t[2]] / kLeaf;
    const Vec3 lo = glm::floor(glm::min(a, glm::min(b, c)) - grow) - 1.0;
    const Vec3 hi = glm::ceil(glm::max(a, glm::max(b, c)) + grow) + 1.0;
    const double span = std::fmax(hi.x - lo.x, std::fmax(hi.y - lo.y, hi.z - lo.z));
    // A triangle whose box alone holds more than the leaves allowed in one
    // direction is past the limit however thin it is.
    if (!(span <= static_cast<double>(max_leaves))) {
      within = false;
      break;
    }
    std::int64_t size = 1;
    while (static_cast<double>(size) < span) size *= 2;
    std::uint64_t steps = 0;
    within = descend(a, b, c, Key{static_cast<std::int64_t>(lo.x), static_cast<std::int64_t>(lo.y),
                                  static_cast<std::int64_t>(lo.z)},
                     size, grow, leaves, max_leaves, steps);
    if (!within || (tick && !tick(steps))) break;
  }
  std::unordered_set<Key, KeyHash> internal, top;
  for (const Key& k : leaves) {
    internal.insert(Key{k.x >> 4, k.y >> 4, k.z >> 4});
    top.insert(Key{k.x >> 9, k.y >> 9, k.z >> 9});
  }
  *out = LevelSetNodes{leaves.size(), internal.size(), top.size()};
  return within && leaves.size() <= max_leaves;
}

double cells_of(const glm::ivec3& lo, const glm::ivec3& hi) {
  if (hi.x < lo.x || hi.y < lo.y || hi.z < lo.z) return 0.0;
  return static_cast<double>(hi.x - lo.x + 1) * static_cast<double>(hi.y - lo.y + 1) *
         static_cast<double>(hi.z - lo.z + 1);
}

}  // namespace voxvis::detail
