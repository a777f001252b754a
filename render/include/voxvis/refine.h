// voxvis/refine.h — refinement levels: ways of spending GPU occlusion
// queries to make a CPU PVS tighter, each returning a subset of its input
// with what it cost (docs/accuracy.md). Every level but `adaptive` keeps every
// object of the PVS that shows at pixel level (render.h's definition), so a
// conservative PVS stays conservative at that resolution.
//
//   none          the PVS as it is
//   queries       one occlusion query per PVS object against the depth of
//                 the PVS's objects, all issued before any is read
//   hierarchical  Bartz et al.: queries on the bounding boxes of a hierarchy
//                 over the PVS's objects first, level by level, descending
//                 only into boxes that show; objects of hidden boxes are
//                 dropped without a query of their own
//   lazy-grid     Hey et al.: the PVS's objects front to back through the
//                 same hierarchy, each box and object tested against a coarse
//                 grid of the depth buffer's farthest depth per cell (16x16
//                 pixels), a cell read back only when a test needs it after
//                 something was drawn over it; what is not occluded is drawn
//                 and kept. Few readbacks, no per-object query.
//   adaptive:N    Bartz et al.'s approximate culling: objects with fewer than
//                 N visible pixels are dropped too. The only level that may
//                 drop a visible object (one under N pixels), and says so.
//
// Occluders are the PVS's own objects: an object outside a conservative PVS
// is hidden, and leaving a hidden object out of the depth buffer can only
// make others look more visible.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "voxvis/render.h"

namespace voxvis::render {

enum class LevelKind { None, Queries, Hierarchical, LazyGrid, Adaptive };

struct Level {
  LevelKind kind = LevelKind::None;
  std::uint32_t min_pixels = 0;  ///< Adaptive: objects with fewer visible pixels are dropped.
};

/// "none", "queries", "hierarchical", "lazy-grid" or "adaptive:N" (N
/// pixels, 1 to 1e6);
/// on error sets `message` (naming the known levels).
bool parse_level(const std::string& text, Level* out, std::string* message);
std::string level_name(const Level& level);
/// Whether the level may drop a visible object (adaptive only).
inline bool level_may_miss(const Level& level) { return level.kind == LevelKind::Adaptive; }

/// What a refinement cost. Times are wall-clock milliseconds on the calling
/// thread: issuing the depth pass and the queries, and waiting for results.
struct RefineStats {
  std::uint32_t queries = 0;      ///< Occlusion queries issued (lazy-grid: cells read back).
  std::uint32_t draw_calls = 0;   ///< Draw calls, the depth pass's included.
  std::uint64_t pixels = 0;       ///< Samples the queries counted as passing.
  std::uint32_t levels = 0;       ///< Rounds of queries (hierarchical: tree levels).
  double draw_ms = 0.0;
  double query_ms = 0.0;
  double wait_ms = 0.0;
};

}  // namespace voxvis::render
