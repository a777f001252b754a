// refine.cpp — Renderer::refine: the refinement levels of voxvis/refine.h.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <unordered_map>
#include <vector>

#include "renderer_impl.h"
#include "voxvis/refine.h"

namespace voxvis::render {

using detail::Basis;
using detail::Clock;
using detail::ms_since;

bool parse_level(const std::string& text, Level* out, std::string* message) {
  static const char* kKnown = " (known: none, queries, hierarchical, adaptive:N)";
  Level l;
  if (text == "none") {
    l.kind = LevelKind::None;
  } else if (text == "queries") {
    l.kind = LevelKind::Queries;
  } else if (text == "hierarchical") {
    l.kind = LevelKind::Hierarchical;
  } else if (text.rfind("adaptive:", 0) == 0) {
    const std::string n = text.substr(9);
    if (n.empty() || n.size() > 7 || n.find_first_not_of("0123456789") != std::string::npos ||
        std::stoul(n) < 1 || std::stoul(n) > 1000000) {
      *message = "level '" + text + "': adaptive needs a pixel count N from 1 to 1000000, as adaptive:N";
      return false;
    }
    l.kind = LevelKind::Adaptive;
    l.min_pixels = static_cast<std::uint32_t>(std::stoul(n));
  } else {
    *message = "unknown level '" + text + "'" + kKnown;
    return false;
  }
  *out = l;
  return true;
}

std::string level_name(const Level& level) {
  switch (level.kind) {
    case LevelKind::None: return "none";
    case LevelKind::Queries: return "queries";
    case LevelKind::Hierarchical: return "hierarchical";
    case LevelKind::Adaptive: return "adaptive:" + std::to_string(level.min_pixels);
  }
  return "?";
}

namespace {

/// A node of the hierarchy over the PVS's objects: a box around its
/// children, or (first == last - 1 and leaf) one object.
struct Node {
  glm::dvec3 lo, hi;
  std::uint32_t first = 0, count = 0;  // Objects [first, first + count) of the ordering.
  std::int32_t left = -1, right = -1;  // Children; -1 for a leaf.
};

constexpr std::uint32_t kLeafObjects = 4;  // Below this, a node's children are its objects.

/// Median split on the longest axis of the centres, recursively.
std::int32_t build(std::vector<Node>& nodes, std::vector<std::uint32_t>& order, const std::vector<glm::dvec3>& lo,
                   const std::vector<glm::dvec3>& hi, std::uint32_t first, std::uint32_t count) {
  Node n;
  n.first = first;
  n.count = count;
  n.lo = glm::dvec3(std::numeric_limits<double>::infinity());
  n.hi = -n.lo;
  glm::dvec3 clo = n.lo, chi = n.hi;
  for (std::uint32_t i = first; i < first + count; ++i) {
    n.lo = glm::min(n.lo, lo[order[i]]);
    n.hi = glm::max(n.hi, hi[order[i]]);
    const glm::dvec3 c = 0.5 * (lo[order[i]] + hi[order[i]]);
    clo = glm::min(clo, c);
    chi = glm::max(chi, c);
  }
  const auto index = static_cast<std::int32_t>(nodes.size());
  nodes.push_back(n);
  if (count > kLeafObjects) {
    const glm::dvec3 ext = chi - clo;
    const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
    const std::uint32_t half = count / 2;
    std::nth_element(order.begin() + first, order.begin() + first + half, order.begin() + first + count,
                     [&](std::uint32_t a, std::uint32_t b) { return lo[a][axis] + hi[a][axis] < lo[b][axis] + hi[b][axis]; });
    const std::int32_t l = build(nodes, order, lo, hi, first, half);
    const std::int32_t r = build(nodes, order, lo, hi, first + half, count - half);
    nodes[static_cast<std::size_t>(index)].left = l;
    nodes[static_cast<std::size_t>(index)].right = r;
  }
  return index;
}

}  // namespace

bool Renderer::refine(const Level& level, const std::vector<ObjectDesc>& objects, const Camera& cam, int width,
                      int height, const std::vector<ObjectId>& pvs, std::vector<ObjectId>* out, RefineStats* stats,
                      std::string* error) {
  Impl& m = *impl_;
  *stats = RefineStats{};
  out->clear();
  Basis b;
  if (!m.begin(cam, width, height, &b, error)) return false;
  if (level.kind == LevelKind::None) {
    *out = pvs;
    return true;
  }

  // The PVS's objects that may meet the frustum: the occluders, and the
  // candidates. The others cannot show.
  std::unordered_map<ObjectId, std::size_t> at;
  at.reserve(objects.size());
  for (std::size_t i = 0; i < objects.size(); ++i) at.emplace(objects[i].id, i);
  m.instances.clear();
  m.drawn_ids.clear();
  std::vector<glm::dvec3> lo, hi;
  for (ObjectId id : pvs) {
    const auto it = at.find(id);
    if (it == at.end()) {
      *error = "pvs: id " + std::to_string(id) + " is not an object of the scene";
      return false;
    }
    const ObjectDesc& o = objects[it->second];
    if (!detail::may_meet_frustum(b, o)) continue;
    const Vec3 half = o.shape == Shape::Sphere ? Vec3(o.radius) : o.half_extent;
    m.drawn_ids.push_back(id);
    m.instances.push_back(Impl::instance(b, o.center, half, o.shape == Shape::Box,
                                         static_cast<std::uint32_t>(m.drawn_ids.size())));
    lo.push_back(o.center - half);
    hi.push_back(o.center + half);
  }
  const std::size_t n = m.instances.size();

  // Hierarchical: the boxes of the inner nodes go after the objects, grown
  // by more than single-precision rounding, so that a box is entered no
  // later than any object inside it on every ray (else a box could hide in
  // the depth buffer behind its own visible object).
  std::vector<Node> nodes;
  std::vector<std::uint32_t> order;
  std::vector<std::size_t> node_instance;
  if (level.kind == LevelKind::Hierarchical && n > 0) {
    order.resize(n);
    for (std::uint32_t i = 0; i < n; ++i) order[i] = i;
    build(nodes, order, lo, hi, 0, static_cast<std::uint32_t>(n));
    node_instance.resize(nodes.size());
    for (std::size_t k = 0; k < nodes.size(); ++k) {
      const Node& nd = nodes[k];
      const glm::dvec3 c = 0.5 * (nd.lo + nd.hi);
      const glm::dvec3 h = 0.5 * (nd.hi - nd.lo);
      const double grow = 1e-5 * glm::length(c - b.eye) + 1e-30;
      node_instance[k] = m.instances.size();
      m.instances.push_back(Impl::instance(b, c, h * (1.0 + 1e-4) + glm::dvec3(grow), true, 0));
    }
  }

  // The depth of the PVS's objects.
  auto t0 = Clock::now();
  m.upload();
  m.depth_pass(b, width, height, static_cast<std::ptrdiff_t>(n));
  glFinish();
  stats->draw_ms = ms_since(t0);
  stats->draw_calls = 1;
  if (!m.gl_ok("the depth pass", error)) return false;

  // One round of probes: every instance of `probes` in a query, all issued
  // before any is read; `passed` gets their sample counts.
  std::vector<GLuint> passed;
  auto round = [&](const std::vector<std::size_t>& probes) {
    auto t = Clock::now();
    m.begin_probes(probes.size());
    for (std::size_t q = 0; q < probes.size(); ++q) m.probe(GL_SAMPLES_PASSED, q, probes[q]);
    glFlush();
    stats->query_ms += ms_since(t);
    t = Clock::now();
    passed.assign(probes.size(), 0);
    for (std::size_t q = 0; q < probes.size(); ++q) {
      glGetQueryObjectuiv(m.queries[q], GL_QUERY_RESULT, &passed[q]);
      stats->pixels += passed[q];
    }
    stats->wait_ms += ms_since(t);
    stats->queries += static_cast<std::uint32_t>(probes.size());
    stats->draw_calls += static_cast<std::uint32_t>(probes.size());
    ++stats->levels;
  };

  if (level.kind == LevelKind::Queries || level.kind == LevelKind::Adaptive) {
    std::vector<std::size_t> probes(n);
    for (std::size_t k = 0; k < n; ++k) probes[k] = k;
    if (n > 0) round(probes);
    const GLuint need = level.kind == LevelKind::Adaptive ? level.min_pixels : 1;
    for (std::size_t k = 0; k < n; ++k)
      if (passed[k] >= need) out->push_back(m.drawn_ids[k]);
  } else if (n > 0) {
    // Level by level from the root: a box that shows opens its children
    // (boxes, or a small node's objects), a hidden one drops its objects.
    std::vector<std::int32_t> frontier = {0};
    std::vector<std::size_t> objects_next;  // Objects to probe with the next round.
    while (!frontier.empty() || !objects_next.empty()) {
      std::vector<std::size_t> probes;
      for (std::int32_t k : frontier) probes.push_back(node_instance[static_cast<std::size_t>(k)]);
      const std::size_t boxes = probes.size();
      probes.insert(probes.end(), objects_next.begin(), objects_next.end());
      round(probes);
      for (std::size_t q = boxes; q < probes.size(); ++q)
        if (passed[q] > 0) out->push_back(m.drawn_ids[probes[q]]);
      std::vector<std::int32_t> next;
      objects_next.clear();
      for (std::size_t q = 0; q < boxes; ++q) {
        if (passed[q] == 0) continue;
        const Node& nd = nodes[static_cast<std::size_t>(frontier[q])];
        if (nd.left >= 0) {
          next.push_back(nd.left);
          next.push_back(nd.right);
        } else {
          for (std::uint32_t i = nd.first; i < nd.first + nd.count; ++i) objects_next.push_back(order[i]);
        }
      }
      frontier.swap(next);
    }
  }
  m.end_probes();
  if (!m.gl_ok("the refinement queries", error)) return false;
  std::sort(out->begin(), out->end());
  return true;
}

}  // namespace voxvis::render
