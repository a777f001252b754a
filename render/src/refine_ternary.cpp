// refine_ternary.cpp — the `ternary` level (voxvis/refine.h), after Kovalčík
// and Sochor, "Occlusion culling with statistically optimized occlusion
// queries" (../shared/papers/ternary-tree-occlusion-queries.txt):
//
//  - a ternary tree: a node's cell splits at its middle into the objects
//    below the plane, those above it, and a third child for those across it
//    (never split further), so no object is left on an inner node;
//  - tight boxes: every node is queried by the box of the objects it holds
//    this frame, not by its cell;
//  - an additional query per node counts its pixels with no depth test; the
//    ratio of visible to all pixels splits a leaf (>= R_split = 0.25 with
//    >= O_split = 12 objects) or merges sibling leaves (all <= R_merge = 0.75
//    with <= O_merge = 5 objects) for the next frame, the paper's constants;
//    a split's plane is across the cell's axis closest to the view direction
//    (among the axes at least half the cell's longest), so that front and
//    back come apart;
//  - colliding queries: the traversal goes front to back drawing what shows
//    into the depth buffer, keeps many queries in flight, and holds a query
//    back while a pending one covers an overlapping screen rectangle, whose
//    objects, once drawn, may hide it.
//
// Where the paper renders a visible leaf's objects, this level queries each
// of them (an object here is one box, ball or mesh: a query costs no more
// than drawing it, and keeping it would cost tightness). What is tested against is
// only what was drawn before, so a dropped object is hidden by drawn objects
// of the PVS: conservative at pixel level, less tight than `queries`.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <deque>
#include <functional>
#include <limits>
#include <queue>
#include <string>
#include <vector>

#include "refine_common.h"
#include "renderer_impl.h"
#include "voxvis/mesh.h"

namespace voxvis::render::detail {
namespace {

constexpr double kSplitRatio = 0.25;
constexpr std::size_t kSplitObjects = 12;
constexpr double kMergeRatio = 0.75;
constexpr std::uint32_t kMergeObjects = 5;
constexpr int kMaxDepth = 24;
constexpr int kFlushQueries = 16;  // Queries issued between flushes, so that results come in.

/// What the tree holds this frame.
struct Frame {
  std::vector<std::vector<std::uint32_t>> members;  // Per leaf: its objects.
  std::vector<glm::dvec3> cell_lo, cell_hi;          // Per node: its cell.
  std::vector<glm::dvec3> box_lo, box_hi;            // Per node: the tight box of its objects.
  std::vector<std::uint32_t> count;                  // Per node: objects below it.
  std::vector<double> ratio;                          // Visible / all pixels; -1 when not queried.
};

void assign(const TernaryTree& t, const glm::dvec3& region_lo, const glm::dvec3& region_hi,
            const std::vector<glm::dvec3>& lo, const std::vector<glm::dvec3>& hi, Frame* f) {
  const std::size_t nn = t.nodes.size();
  const glm::dvec3 inf(std::numeric_limits<double>::infinity());
  f->members.assign(nn, {});
  f->cell_lo.assign(nn, region_lo);
  f->cell_hi.assign(nn, region_hi);
  f->box_lo.assign(nn, inf);
  f->box_hi.assign(nn, -inf);
  f->count.assign(nn, 0);
  f->ratio.assign(nn, -1.0);
  // Cells top down (children always come after their parent).
  for (std::size_t i = 0; i < nn; ++i) {
    const TernaryNode& nd = t.nodes[i];
    if (nd.axis < 0) continue;
    const int a = nd.axis;
    const double mid = 0.5 * (f->cell_lo[i][a] + f->cell_hi[i][a]);
    for (int c = 0; c < 3; ++c) {
      const auto k = static_cast<std::size_t>(nd.child[c]);
      f->cell_lo[k] = f->cell_lo[i];
      f->cell_hi[k] = f->cell_hi[i];
    }
    f->cell_hi[static_cast<std::size_t>(nd.child[0])][a] = mid;
    f->cell_lo[static_cast<std::size_t>(nd.child[1])][a] = mid;
  }
  for (std::uint32_t k = 0; k < lo.size(); ++k) {
    std::size_t i = 0;
    while (t.nodes[i].axis >= 0) {
      const TernaryNode& nd = t.nodes[i];
      const int a = nd.axis;
      const double mid = 0.5 * (f->cell_lo[i][a] + f->cell_hi[i][a]);
      i = static_cast<std::size_t>(hi[k][a] <= mid ? nd.child[0] : lo[k][a] >= mid ? nd.child[1] : nd.child[2]);
    }
    f->members[i].push_back(k);
  }
  // Tight boxes and counts bottom up.
  for (std::size_t i = nn; i-- > 0;) {
    const TernaryNode& nd = t.nodes[i];
    if (nd.axis < 0) {
      for (std::uint32_t k : f->members[i]) {
        f->box_lo[i] = glm::min(f->box_lo[i], lo[k]);
        f->box_hi[i] = glm::max(f->box_hi[i], hi[k]);
      }
      f->count[i] = static_cast<std::uint32_t>(f->members[i].size());
      continue;
    }
    for (std::int32_t c : nd.child) {
      const auto k = static_cast<std::size_t>(c);
      f->box_lo[i] = glm::min(f->box_lo[i], f->box_lo[k]);
      f->box_hi[i] = glm::max(f->box_hi[i], f->box_hi[k]);
      f->count[i] += f->count[k];
    }
  }
}

bool splittable(const TernaryNode& nd) { return nd.axis < 0 && !nd.across && nd.depth < kMaxDepth; }

/// Splits leaf i across the axis of its cell closest to the view direction
/// among those at least half the longest. False for a cell with no extent.
bool split(TernaryTree& t, std::size_t i, const glm::dvec3& cell_lo, const glm::dvec3& cell_hi,
           const glm::dvec3& view) {
  const glm::dvec3 ext = cell_hi - cell_lo;
  const double longest = std::max(ext.x, std::max(ext.y, ext.z));
  if (!(longest > 0.0) || !std::isfinite(longest)) return false;
  int axis = -1;
  for (int a = 0; a < 3; ++a)
    if (ext[a] >= 0.5 * longest && (axis < 0 || std::abs(view[a]) > std::abs(view[axis]))) axis = a;
  const std::uint8_t depth = static_cast<std::uint8_t>(t.nodes[i].depth + 1);
  for (int c = 0; c < 3; ++c) {
    TernaryNode child;
    child.depth = depth;
    child.across = c == 2;
    t.nodes[i].child[c] = static_cast<std::int32_t>(t.nodes.size());
    t.nodes.push_back(child);
  }
  t.nodes[i].axis = static_cast<std::int8_t>(axis);
  return true;
}

/// Drops the nodes no longer reachable from the root, keeping parents
/// before children.
void compact(TernaryTree& t) {
  std::vector<TernaryNode> kept;
  kept.reserve(t.nodes.size());
  kept.push_back(t.nodes[0]);
  for (std::size_t i = 0; i < kept.size(); ++i) {
    if (kept[i].axis < 0) continue;
    for (int c = 0; c < 3; ++c) {
      const TernaryNode child = t.nodes[static_cast<std::size_t>(kept[i].child[c])];
      kept[i].child[c] = static_cast<std::int32_t>(kept.size());
      kept.push_back(child);  // May move kept: no reference into it is held.
    }
  }
  t.nodes.swap(kept);
}

}  // namespace

bool refine_ternary(Renderer::Impl& m, const Basis& b, int width, int height, const std::vector<ObjectDesc>& objects,
                    const std::vector<ObjectId>& pvs, std::vector<ObjectId>* out, RefineStats* stats,
                    std::string* error) {
  std::vector<glm::dvec3> lo, hi;
  if (!pvs_instances(m, b, objects, pvs, &lo, &hi, error)) return false;
  const std::size_t n = lo.size();
  if (n == 0) return true;

  // The tree's region: every object of the scene, so that it stays put while
  // the view moves.
  glm::dvec3 region_lo(std::numeric_limits<double>::infinity()), region_hi = -region_lo;
  for (const ObjectDesc& o : objects) {
    if (o.shape == Shape::Mesh && !o.mesh) continue;
    Vec3 l, h;
    object_bounds(o, &l, &h);  // A mesh's: the box of its placed vertices.
    region_lo = glm::min(region_lo, l);
    region_hi = glm::max(region_hi, h);
  }
  TernaryTree& tree = m.refine.ternary;
  Frame f;
  if (tree.nodes.empty()) {
    // A first tree: leaves split until they hold fewer than O_split objects.
    tree.nodes.emplace_back();
    for (int round = 0; round < kMaxDepth; ++round) {
      assign(tree, region_lo, region_hi, lo, hi, &f);
      bool any = false;
      const std::size_t nn = tree.nodes.size();
      for (std::size_t i = 0; i < nn; ++i)
        if (splittable(tree.nodes[i]) && f.members[i].size() >= kSplitObjects)
          any = split(tree, i, f.cell_lo[i], f.cell_hi[i], b.f) || any;
      if (!any) break;
    }
  }
  assign(tree, region_lo, region_hi, lo, hi, &f);
  const std::size_t nn = tree.nodes.size();

  // Query boxes of the nodes holding two objects or more, after the objects.
  std::vector<std::size_t> node_instance(nn, 0);
  for (std::size_t i = 0; i < nn; ++i) {
    if (f.count[i] < 2) continue;
    node_instance[i] = m.instances.size();
    m.instances.push_back(query_box(b, f.box_lo[i], f.box_hi[i]));
  }
  auto t0 = Clock::now();
  m.upload();
  m.depth_pass(b, width, height, 0);  // Cleared; nothing drawn yet.
  m.begin_probes(0);
  stats->draw_ms += ms_since(t0);

  // Query objects from the renderer's pool, all free between frames.
  std::vector<std::size_t> free_queries(m.queries.size());
  for (std::size_t q = 0; q < free_queries.size(); ++q) free_queries[q] = free_queries.size() - 1 - q;
  auto acquire = [&]() {
    if (free_queries.empty()) {
      const std::size_t old = m.queries.size(), grown = std::max<std::size_t>(64, 2 * old);
      m.queries.resize(grown);
      glGenQueries(static_cast<GLsizei>(grown - old), m.queries.data() + old);
      for (std::size_t q = grown; q-- > old;) free_queries.push_back(q);
    }
    const std::size_t q = free_queries.back();
    free_queries.pop_back();
    return q;
  };
  auto draw_in_query = [&](std::size_t q, std::size_t instance) {
    glBeginQuery(GL_SAMPLES_PASSED, m.queries[q]);
    m.draw_instance(instance);
    glEndQuery(GL_SAMPLES_PASSED);
    ++stats->draw_calls;
    ++stats->queries;
  };

  struct Entry {
    float znear = 0.0f;
    std::int32_t node = -1;    // >= 0: a node of the tree.
    std::uint32_t object = 0;  // When node < 0.
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    bool operator>(const Entry& o) const { return znear > o.znear; }
  };
  struct Pending {
    Entry e;
    std::size_t visible_q = 0, all_q = 0;  // all_q for nodes only.
  };
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> queue;
  std::deque<Pending> pending;

  // A node holding one object is that object.
  auto single = [&](std::size_t i) {
    while (tree.nodes[i].axis >= 0)
      for (std::int32_t c : tree.nodes[i].child)
        if (f.count[static_cast<std::size_t>(c)] > 0) {
          i = static_cast<std::size_t>(c);
          break;
        }
    return f.members[i].front();
  };
  auto push_object = [&](std::uint32_t k) {
    Entry e;
    e.object = k;
    if (screen_rect(b, width, height, lo[k], hi[k], &e.x0, &e.y0, &e.x1, &e.y1, &e.znear)) queue.push(e);
  };
  auto push_node = [&](std::size_t i) {
    if (f.count[i] == 0) return;
    if (f.count[i] == 1) return push_object(single(i));
    Entry e;
    e.node = static_cast<std::int32_t>(i);
    if (screen_rect(b, width, height, f.box_lo[i], f.box_hi[i], &e.x0, &e.y0, &e.x1, &e.y1, &e.znear)) queue.push(e);
  };

  // A pending query's answer: a node that shows opens its children (or its
  // objects), an object that shows is drawn and kept.
  auto resolve = [&]() {
    const Pending p = pending.front();
    pending.pop_front();
    GLuint available = 0;
    glGetQueryObjectuiv(m.queries[p.visible_q], GL_QUERY_RESULT_AVAILABLE, &available);
    auto t = Clock::now();
    GLuint visible = 0, all = 0;
    glGetQueryObjectuiv(m.queries[p.visible_q], GL_QUERY_RESULT, &visible);
    free_queries.push_back(p.visible_q);
    if (p.e.node >= 0) {
      glGetQueryObjectuiv(m.queries[p.all_q], GL_QUERY_RESULT, &all);
      free_queries.push_back(p.all_q);
    }
    if (!available) {
      stats->wait_ms += ms_since(t);
      ++stats->levels;
    }
    stats->pixels += visible;
    if (p.e.node >= 0) {
      const auto i = static_cast<std::size_t>(p.e.node);
      f.ratio[i] = all > 0 ? static_cast<double>(visible) / all : 0.0;
      if (visible == 0) return;
      if (tree.nodes[i].axis >= 0) {
        for (std::int32_t c : tree.nodes[i].child) push_node(static_cast<std::size_t>(c));
      } else {
        for (std::uint32_t k : f.members[i]) push_object(k);
      }
      return;
    }
    if (visible == 0) return;
    t = Clock::now();
    glDepthMask(GL_TRUE);
    glColorMaski(0, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glDepthFunc(GL_LESS);
    m.draw_instance(p.e.object);
    m.begin_probes(0);
    ++stats->draw_calls;
    stats->draw_ms += ms_since(t);
    out->push_back(m.drawn_ids[p.e.object]);
  };
  auto collides = [&](const Entry& e) {
    for (const Pending& p : pending)
      if (e.x0 <= p.e.x1 && p.e.x0 <= e.x1 && e.y0 <= p.e.y1 && p.e.y0 <= e.y1) return true;
    return false;
  };

  push_node(0);
  int unflushed = 0;
  while (!queue.empty() || !pending.empty()) {
    // Answers already in.
    while (!pending.empty()) {
      GLuint available = 0;
      glGetQueryObjectuiv(m.queries[pending.front().visible_q], GL_QUERY_RESULT_AVAILABLE, &available);
      if (!available) break;
      resolve();
    }
    if (queue.empty() || collides(queue.top())) {
      if (!pending.empty()) resolve();  // Wait for the oldest.
      continue;
    }
    const Entry e = queue.top();
    queue.pop();
    const auto t = Clock::now();
    Pending p{e, acquire(), 0};
    if (e.node >= 0) {
      const std::size_t inst = node_instance[static_cast<std::size_t>(e.node)];
      draw_in_query(p.visible_q, inst);
      p.all_q = acquire();
      glDepthFunc(GL_ALWAYS);
      draw_in_query(p.all_q, inst);
      glDepthFunc(GL_LEQUAL);
    } else {
      draw_in_query(p.visible_q, e.object);
    }
    pending.push_back(p);
    if (++unflushed == kFlushQueries) {
      glFlush();
      unflushed = 0;
    }
    stats->query_ms += ms_since(t);
  }
  m.end_probes();
  if (!m.gl_ok("the ternary tree's queries", error)) return false;
  std::sort(out->begin(), out->end());

  // The tree for the next frame: merges decided on the nodes that were inner
  // nodes this frame, then splits.
  bool merged = false;
  for (std::size_t i = 0; i < nn; ++i) {
    TernaryNode& nd = tree.nodes[i];
    if (nd.axis < 0) continue;
    bool merge = true;
    for (std::int32_t c : nd.child) {
      const auto k = static_cast<std::size_t>(c);
      merge = merge && tree.nodes[k].axis < 0 && f.ratio[k] <= kMergeRatio && f.count[k] <= kMergeObjects;
    }
    if (merge) {
      nd.axis = -1;
      merged = true;
    }
  }
  for (std::size_t i = 0; i < nn; ++i)
    if (splittable(tree.nodes[i]) && f.ratio[i] >= kSplitRatio && f.members[i].size() >= kSplitObjects)
      split(tree, i, f.cell_lo[i], f.cell_hi[i], b.f);
  if (merged) compact(tree);
  stats->tree_nodes = static_cast<std::uint32_t>(tree.nodes.size());
  return true;
}

}  // namespace voxvis::render::detail
