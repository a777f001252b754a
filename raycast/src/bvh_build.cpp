// bvh_build.cpp — see bvh_build.h. Binned SAH (16 bins on the longest axis of
// the centres, as in Wald, "On fast Construction of SAH-based Bounding Volume
// Hierarchies", 2007), at most 4 items a leaf.
#include "bvh_build.h"

#include <algorithm>
#include <array>
#include <limits>

namespace voxvis::raycast::detail {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kBins = 16;
constexpr std::uint32_t kLeafMax = 4;
/// Below this depth the build splits by the surface-area heuristic; beyond
/// it (degenerate distributions) at the median, which bounds the depth.
constexpr int kSahDepth = 40;

double half_area(const double* lo, const double* hi) {
  const double x = hi[0] - lo[0];
  const double y = hi[1] - lo[1];
  const double z = hi[2] - lo[2];
  return x * y + y * z + z * x;
}

void grow(double* lo, double* hi, const double* blo, const double* bhi) {
  for (int i = 0; i < 3; ++i) {
    lo[i] = std::min(lo[i], blo[i]);
    hi[i] = std::max(hi[i], bhi[i]);
  }
}

/// Builds node `at` over items [begin, end).
void build(std::vector<BvhNode>& nodes, std::vector<BvhItem>& items, std::uint32_t at, std::uint32_t begin,
           std::uint32_t end, int depth) {
  double lo[3] = {kInf, kInf, kInf};
  double hi[3] = {-kInf, -kInf, -kInf};
  double clo[3] = {kInf, kInf, kInf};
  double chi[3] = {-kInf, -kInf, -kInf};
  for (std::uint32_t k = begin; k < end; ++k) {
    grow(lo, hi, items[k].lo, items[k].hi);
    grow(clo, chi, items[k].c, items[k].c);
  }
  BvhNode& node = nodes[at];
  std::copy(lo, lo + 3, node.lo);
  std::copy(hi, hi + 3, node.hi);
  const std::uint32_t count = end - begin;
  int axis = 0;
  for (int a = 1; a < 3; ++a)
    if (chi[a] - clo[a] > chi[axis] - clo[axis]) axis = a;
  const double extent = chi[axis] - clo[axis];
  if (count <= 1 || (count <= kLeafMax && !(extent > 0.0))) {
    node.first = begin;
    node.count = count;
    return;
  }
  std::uint32_t mid = begin + count / 2;
  bool split = true;
  if (!(extent > 0.0) || depth >= kSahDepth) {
    // Identical centres, or too deep: halves by centre.
    std::nth_element(items.begin() + begin, items.begin() + mid, items.begin() + end,
                     [axis](const BvhItem& a, const BvhItem& b) { return a.c[axis] < b.c[axis]; });
  } else {
    struct Bin {
      double lo[3] = {kInf, kInf, kInf};
      double hi[3] = {-kInf, -kInf, -kInf};
      std::uint32_t n = 0;
    };
    std::array<Bin, kBins> bins;
    const double scale = kBins / extent;
    auto bin_of = [&](const BvhItem& it) {
      return std::clamp(static_cast<int>((it.c[axis] - clo[axis]) * scale), 0, kBins - 1);
    };
    for (std::uint32_t k = begin; k < end; ++k) {
      Bin& bn = bins[static_cast<std::size_t>(bin_of(items[k]))];
      grow(bn.lo, bn.hi, items[k].lo, items[k].hi);
      ++bn.n;
    }
    // Cost of splitting after bin s: area-weighted counts of both sides.
    std::array<double, kBins> right_cost{};
    {
      double rlo[3] = {kInf, kInf, kInf};
      double rhi[3] = {-kInf, -kInf, -kInf};
      std::uint32_t rn = 0;
      for (int s = kBins - 1; s > 0; --s) {
        grow(rlo, rhi, bins[static_cast<std::size_t>(s)].lo, bins[static_cast<std::size_t>(s)].hi);
        rn += bins[static_cast<std::size_t>(s)].n;
        right_cost[static_cast<std::size_t>(s)] = rn > 0 ? rn * half_area(rlo, rhi) : 0.0;
      }
    }
    double llo[3] = {kInf, kInf, kInf};
    double lhi[3] = {-kInf, -kInf, -kInf};
    std::uint32_t ln = 0;
    double best_cost = kInf;
    int best_split = -1;
    for (int s = 1; s < kBins; ++s) {
      grow(llo, lhi, bins[static_cast<std::size_t>(s - 1)].lo, bins[static_cast<std::size_t>(s - 1)].hi);
      ln += bins[static_cast<std::size_t>(s - 1)].n;
      if (ln == 0 || ln == count) continue;
      const double cost = ln * half_area(llo, lhi) + right_cost[static_cast<std::size_t>(s)];
      if (cost < best_cost) {
        best_cost = cost;
        best_split = s;
      }
    }
    if (count <= kLeafMax && !(best_cost < count * half_area(lo, hi))) split = false;
    if (split && best_split > 0) {
      const auto it = std::partition(items.begin() + begin, items.begin() + end,
                                     [&](const BvhItem& x) { return bin_of(x) < best_split; });
      mid = static_cast<std::uint32_t>(it - items.begin());
    } else if (split) {
      std::nth_element(items.begin() + begin, items.begin() + mid, items.begin() + end,
                       [axis](const BvhItem& a, const BvhItem& b) { return a.c[axis] < b.c[axis]; });
    }
  }
  if (!split) {
    node.first = begin;
    node.count = count;
    return;
  }
  const auto children = static_cast<std::uint32_t>(nodes.size());
  nodes[at].first = children;
  nodes[at].count = 0;
  nodes.emplace_back();
  nodes.emplace_back();
  build(nodes, items, children, begin, mid, depth + 1);
  build(nodes, items, children + 1, mid, end, depth + 1);
}

}  // namespace

void build_bvh(std::vector<BvhItem>& items, std::vector<BvhNode>* nodes) {
  nodes->clear();
  nodes->reserve(2 * items.size());
  nodes->emplace_back();
  build(*nodes, items, 0, 0, static_cast<std::uint32_t>(items.size()), 0);
}

}  // namespace voxvis::raycast::detail
