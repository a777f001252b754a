// refine_state.h — what the ternary and near-optimal levels keep on the
// renderer from one frame to the next.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "voxvis/refine.h"
#include "voxvis/types.h"

namespace voxvis::render::detail {

/// A node of the ternary tree: a leaf, or a split of its cell at the middle
/// of `axis` into the objects below the plane, those above it and those
/// across it (child 2, a leaf never split further).
struct TernaryNode {
  std::int8_t axis = -1;  ///< -1 for a leaf.
  bool across = false;    ///< Child 2 of its parent.
  std::uint8_t depth = 0;
  std::int32_t child[3] = {-1, -1, -1};
};

/// The tree's shape only: which objects lie in which node is worked out
/// anew every frame from their positions, so moving objects and a changing
/// PVS need nothing more.
struct TernaryTree {
  std::vector<TernaryNode> nodes;  ///< nodes[0] is the root once built.
};

/// An object's state after the last frame, for near-optimal's estimate of
/// its chance to be hidden.
struct ObjectHistory {
  bool visible = false;             ///< Kept (shown by its query, or kept with none).
  std::uint32_t last_query = 0;     ///< Frame number of the last query that covered it (0: none).
};

struct NearOptimalState {
  std::uint32_t frame = 0;
  std::unordered_map<ObjectId, ObjectHistory> last;  ///< Last frame's candidates.
};

struct RefineState {
  TernaryTree ternary;
  NearOptimalState near_optimal;
  std::unique_ptr<CostModel> model;  ///< Once measured or loaded.
  std::string model_path;            ///< Where it is kept (set on first use).
  bool model_path_set = false;
};

}  // namespace voxvis::render::detail
