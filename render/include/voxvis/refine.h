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
//   ternary       Kovalcik & Sochor's ternary tree: a spatial tree kept on
//                 the renderer from frame to frame, whose nodes split in two
//                 halves and a third child for the objects across the plane;
//                 traversed front to back with queries on the nodes' tight
//                 boxes, drawing what shows, a query held back while a nearer
//                 pending one covers the same screen rectangle (colliding
//                 queries); a second query per node counts its pixels with no
//                 depth test, and the ratio of visible to all pixels splits
//                 and merges the tree's leaves for the next frame.
//   near-optimal  Guthe et al.: the hierarchy's nodes are queried only where
//   near-optimal:T the model says a query pays: the chance a node is hidden
//                 (its screen coverage against that of what lies in front,
//                 and its objects' state last frame) against the time a query
//                 takes and the time drawing its objects would take, from a
//                 model of this machine's GPU calibrated once and saved
//                 (CostModel). T: triangles per object of the meshes a client
//                 draws (default 1,000). Objects it does not query are kept.
//   adaptive:N    Bartz et al.'s approximate culling: objects with fewer than
//                 N visible pixels are dropped too. The only level that may
//                 drop a visible object (one under N pixels), and says so.
//
// Occluders are the PVS's own objects: an object outside a conservative PVS
// is hidden, and leaving a hidden object out of the depth buffer can only
// make others look more visible. queries, hierarchical, near-optimal and
// adaptive test against the depth of all of them; lazy-grid and ternary
// against those drawn so far, front to back, as the papers render.
//
// ternary and near-optimal keep state on the Renderer from one frame to the
// next (the tree; each object's last state): call
// Renderer::reset_refinement() before a sequence of frames that does not
// continue the last one.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "voxvis/render.h"

namespace voxvis::render {

enum class LevelKind { None, Queries, Hierarchical, LazyGrid, Ternary, NearOptimal, Adaptive };

struct Level {
  LevelKind kind = LevelKind::None;
  std::uint32_t min_pixels = 0;  ///< Adaptive: objects with fewer visible pixels are dropped.
  std::uint32_t triangles = 1000;  ///< NearOptimal: triangles per object of the client's meshes.
};

/// "none", "queries", "hierarchical", "lazy-grid", "ternary",
/// "near-optimal", "near-optimal:T" (T triangles, 1 to 1e7) or "adaptive:N"
/// (N pixels, 1 to 1e6);
/// on error sets `message` (naming the known levels).
bool parse_level(const std::string& text, Level* out, std::string* message);
std::string level_name(const Level& level);
/// Whether the level may drop a visible object (adaptive only).
inline bool level_may_miss(const Level& level) { return level.kind == LevelKind::Adaptive; }

/// What a refinement cost. Times are wall-clock milliseconds on the calling
/// thread: issuing the depth pass and the queries, and waiting for results.
struct RefineStats {
  std::uint32_t queries = 0;      ///< Occlusion queries issued (lazy-grid: cells read back).
  std::uint32_t kept_unqueried = 0;  ///< near-optimal: objects kept with no query of theirs.
  std::uint32_t tree_nodes = 0;   ///< ternary: nodes of the tree for the next frame.
  std::uint32_t draw_calls = 0;   ///< Draw calls, the depth pass's included.
  std::uint64_t pixels = 0;       ///< Samples the queries counted as passing.
  std::uint32_t levels = 0;       ///< Rounds of queries (hierarchical: tree levels; ternary: waits).
  double draw_ms = 0.0;
  double query_ms = 0.0;
  double wait_ms = 0.0;
};

/// Near-optimal's model of the GPU (Guthe et al., table 2), measured on the
/// renderer's own context: microseconds per call, nanoseconds per triangle
/// or fragment.
struct CostModel {
  /// GL_RENDERER and GL_VERSION it was measured on, and " | query buffer"
  /// when query results are read a round at once (ContextOptions).
  std::string device;
  double render_setup_us = 0.0;       ///< T_r^s: a draw call.
  double render_triangle_ns = 0.0;    ///< T_r^tri: a triangle drawn.
  double render_fragment_ns = 0.0;    ///< T_r^f: a fragment shaded and written.
  double query_setup_us = 0.0;        ///< T_o^s: a query of a small box, issued and read.
  double query_fragment_ns = 0.0;     ///< T_o^f: a fragment tested by a query.
  double query_latency_us = 0.0;      ///< T_o^l: the longest wait from issuing a query to its result.
  double query_overhead_us = 0.0;     ///< T_o^o: a query around a draw, over the draw alone.
  double calibration_ms = 0.0;        ///< How long measuring took.

  /// Estimated milliseconds to draw an object of `triangles` triangles
  /// shading `fragments` fragments, and to query a box of `fragments`.
  double render_ms(double triangles, double fragments) const;
  double query_ms(double fragments) const;
};

/// Where the cost model is kept: $XDG_CACHE_HOME/voxvis/cost-model.json, else
/// $HOME/.cache/voxvis/cost-model.json; empty when neither is set.
std::string default_cost_model_path();

}  // namespace voxvis::render
