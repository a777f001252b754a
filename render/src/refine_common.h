// refine_common.h — what the refinement levels (refine.cpp,
// refine_ternary.cpp, refine_near_optimal.cpp) share: the PVS's objects as
// instances, a bounding-box hierarchy over them, boxes grown for queries and
// the screen rectangle of a box.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "renderer_impl.h"
#include "voxvis/refine.h"

namespace voxvis::render::detail {

/// The PVS's objects that may meet the frustum, as m.instances (numbered
/// from 1, m.drawn_ids[k] the id of instance k) with their boxes. False, with
/// `error`, for an id that is not an object of the scene.
bool pvs_instances(Renderer::Impl& m, const Basis& b, const std::vector<ObjectDesc>& objects,
                   const std::vector<ObjectId>& pvs, std::vector<glm::dvec3>* lo, std::vector<glm::dvec3>* hi,
                   std::string* error);

/// A box instance for a query standing for the objects inside [lo, hi]:
/// grown by more than single-precision rounding, so that on every ray the box
/// is entered no later than any object inside it (else the box could hide in
/// the depth buffer behind its own visible object).
Instance query_box(const Basis& b, const glm::dvec3& lo, const glm::dvec3& hi);

/// A node of the hierarchy over the PVS's objects: a box around its
/// children, or (leaf) around at most kLeafObjects objects.
struct Node {
  glm::dvec3 lo, hi;
  std::uint32_t first = 0, count = 0;  // Objects [first, first + count) of the ordering.
  std::int32_t left = -1, right = -1;  // Children; -1 for a leaf.
};

constexpr std::uint32_t kLeafObjects = 4;

/// Median split on the longest axis of the centres, recursively; node 0 is
/// the root. `order` holds the object numbers, permuted.
std::int32_t build_hierarchy(std::vector<Node>& nodes, std::vector<std::uint32_t>& order,
                             const std::vector<glm::dvec3>& lo, const std::vector<glm::dvec3>& hi,
                             std::uint32_t first, std::uint32_t count);

/// The pixels a box may cover, [x0, x1] x [y0, y1] (clamped to the image),
/// and its least depth as the depth buffer stores it (t / far, hits clipped
/// to near). False when the box lies wholly outside the image.
bool screen_rect(const Basis& b, int width, int height, const glm::dvec3& lo, const glm::dvec3& hi, int* x0, int* y0,
                 int* x1, int* y1, float* znear);

/// Appends a query box (query_box) per node to m.instances; returns each
/// node's instance number.
std::vector<std::size_t> node_instances(Renderer::Impl& m, const Basis& b, const std::vector<Node>& nodes);

/// Uploads m.instances and draws the first n (the PVS's objects) into the
/// depth and id buffers, waiting for it: stats' draw_ms and draw_calls.
bool pvs_depth_pass(Renderer::Impl& m, const Basis& b, int width, int height, std::size_t n, RefineStats* stats,
                    std::string* error);

/// One round of queries: instance probes[q] drawn in query q against the
/// depth buffer, all issued before any is read; `passed` gets their sample
/// counts, `stats` the queries, draw calls, samples, a round and the times.
void query_round(Renderer::Impl& m, const std::vector<std::size_t>& probes, std::vector<GLuint>* passed,
                 RefineStats* stats);

/// The levels in their own files.
bool refine_ternary(Renderer::Impl& m, const Basis& b, int width, int height, const std::vector<ObjectDesc>& objects,
                    const std::vector<ObjectId>& pvs, std::vector<ObjectId>* out, RefineStats* stats,
                    std::string* error);
bool refine_near_optimal(Renderer::Impl& m, const Level& level, const Basis& b, int width, int height,
                         const std::vector<ObjectDesc>& objects, const std::vector<ObjectId>& pvs,
                         std::vector<ObjectId>* out, RefineStats* stats, std::string* error);

}  // namespace voxvis::render::detail
