// refine.cpp — Renderer::refine: the refinement levels of voxvis/refine.h.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <queue>
#include <string>
#include <unordered_map>
#include <vector>

#include "refine_common.h"
#include "renderer_impl.h"
#include "voxvis/refine.h"

namespace voxvis::render {

using detail::Basis;
using detail::Node;
using detail::screen_rect;
using detail::Clock;
using detail::ms_since;

bool parse_level(const std::string& text, Level* out, std::string* message) {
  static const char* kKnown =
      " (known: none, queries, hierarchical, lazy-grid, ternary, near-optimal, near-optimal:T, adaptive:N)";
  // A count after "name:", from lo to hi; false (with the message) otherwise.
  auto count = [&](const std::string& name, std::size_t at, unsigned long lo, unsigned long hi, const char* what,
                   const char* letter, std::uint32_t* value) {
    const std::string n = text.substr(at);
    if (n.empty() || n.size() > 8 || n.find_first_not_of("0123456789") != std::string::npos || std::stoul(n) < lo ||
        std::stoul(n) > hi) {
      *message = "level '" + text + "': " + name + " needs " + what + " from " + std::to_string(lo) + " to " +
                 std::to_string(hi) + ", as " + name + ":" + letter;
      return false;
    }
    *value = static_cast<std::uint32_t>(std::stoul(n));
    return true;
  };
  Level l;
  if (text == "none") {
    l.kind = LevelKind::None;
  } else if (text == "queries") {
    l.kind = LevelKind::Queries;
  } else if (text == "hierarchical") {
    l.kind = LevelKind::Hierarchical;
  } else if (text == "lazy-grid") {
    l.kind = LevelKind::LazyGrid;
  } else if (text == "ternary") {
    l.kind = LevelKind::Ternary;
  } else if (text == "near-optimal") {
    l.kind = LevelKind::NearOptimal;
  } else if (text.rfind("near-optimal:", 0) == 0) {
    l.kind = LevelKind::NearOptimal;
    if (!count("near-optimal", 13, 1, 10000000, "a triangle count T per object", "T", &l.triangles)) return false;
  } else if (text.rfind("adaptive:", 0) == 0) {
    l.kind = LevelKind::Adaptive;
    if (!count("adaptive", 9, 1, 1000000, "a pixel count N", "N", &l.min_pixels)) return false;
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
    case LevelKind::LazyGrid: return "lazy-grid";
    case LevelKind::Ternary: return "ternary";
    case LevelKind::NearOptimal:
      return level.triangles == Level{}.triangles ? "near-optimal" : "near-optimal:" + std::to_string(level.triangles);
    case LevelKind::Adaptive: return "adaptive:" + std::to_string(level.min_pixels);
  }
  return "?";
}

namespace detail {

bool pvs_instances(Renderer::Impl& m, const Basis& b, const std::vector<ObjectDesc>& objects,
                   const std::vector<ObjectId>& pvs, std::vector<glm::dvec3>* lo, std::vector<glm::dvec3>* hi,
                   std::string* error) {
  std::unordered_map<ObjectId, std::size_t> at;
  at.reserve(objects.size());
  for (std::size_t i = 0; i < objects.size(); ++i) at.emplace(objects[i].id, i);
  m.clear_instances();
  m.drawn_ids.clear();
  lo->clear();
  hi->clear();
  for (ObjectId id : pvs) {
    const auto it = at.find(id);
    if (it == at.end()) {
      *error = "pvs: id " + std::to_string(id) + " is not an object of the scene";
      return false;
    }
    // A mesh's box is object_bounds, the box of its placed vertices: the
    // queries of boxes standing for it (query_box, grown far beyond the
    // rounding of its vertices to float) and the screen rectangles built on
    // it hold every pixel its triangles cover, so they stay conservative.
    glm::dvec3 l, h;
    if (!m.add_object(b, objects[it->second], static_cast<std::uint32_t>(m.drawn_ids.size() + 1), &l, &h)) continue;
    m.drawn_ids.push_back(id);
    lo->push_back(l);
    hi->push_back(h);
  }
  return true;
}

Instance query_box(const Basis& b, const glm::dvec3& lo, const glm::dvec3& hi) {
  const glm::dvec3 c = 0.5 * (lo + hi);
  const glm::dvec3 h = 0.5 * (hi - lo);
  const double grow = 1e-5 * glm::length(c - b.eye) + 1e-30;
  return Renderer::Impl::instance(b, c, h * (1.0 + 1e-4) + glm::dvec3(grow), true, 0);
}

std::int32_t build_hierarchy(std::vector<Node>& nodes, std::vector<std::uint32_t>& order,
                             const std::vector<glm::dvec3>& lo, const std::vector<glm::dvec3>& hi,
                             std::uint32_t first, std::uint32_t count) {
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
    const std::int32_t l = build_hierarchy(nodes, order, lo, hi, first, half);
    const std::int32_t r = build_hierarchy(nodes, order, lo, hi, first + half, count - half);
    nodes[static_cast<std::size_t>(index)].left = l;
    nodes[static_cast<std::size_t>(index)].right = r;
  }
  return index;
}


std::vector<std::size_t> node_instances(Renderer::Impl& m, const Basis& b, const std::vector<Node>& nodes) {
  std::vector<std::size_t> at(nodes.size());
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    at[k] = m.instances.size();
    m.instances.push_back(query_box(b, nodes[k].lo, nodes[k].hi));
  }
  return at;
}

bool pvs_depth_pass(Renderer::Impl& m, const Basis& b, int width, int height, std::size_t n, RefineStats* stats,
                    std::string* error) {
  const auto t0 = Clock::now();
  m.upload();
  m.depth_pass(b, width, height, static_cast<std::ptrdiff_t>(n));
  glFinish();
  stats->draw_ms += ms_since(t0);
  ++stats->draw_calls;
  return m.gl_ok("the depth pass", error);
}

void query_round(Renderer::Impl& m, const std::vector<std::size_t>& probes, std::vector<GLuint>* passed,
                 RefineStats* stats) {
  auto t = Clock::now();
  m.begin_probes(probes.size());
  for (std::size_t q = 0; q < probes.size(); ++q) m.probe(GL_SAMPLES_PASSED, q, probes[q]);
  glFlush();
  stats->query_ms += ms_since(t);
  t = Clock::now();
  m.read_queries(probes.size(), passed);
  for (const GLuint p : *passed) stats->pixels += p;
  stats->wait_ms += ms_since(t);
  stats->queries += static_cast<std::uint32_t>(probes.size());
  stats->draw_calls += static_cast<std::uint32_t>(probes.size());
  ++stats->levels;
}

bool screen_rect(const Basis& b, int width, int height, const glm::dvec3& lo, const glm::dvec3& hi, int* x0, int* y0,
                 int* x1, int* y1, float* znear) {
  double zmin = std::numeric_limits<double>::infinity();
  double xmin = zmin, ymin = zmin, xmax = -zmin, ymax = -zmin;
  bool behind = false;
  for (int c = 0; c < 8; ++c) {
    const glm::dvec3 p = glm::dvec3(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z) - b.eye;
    const double z = glm::dot(p, b.f);
    zmin = std::min(zmin, z);
    if (!(z > b.near * 0.5)) {
      behind = true;  // Projection unbounded: the whole image.
      continue;
    }
    const double x = glm::dot(p, b.right) / (z * b.tanx), y = glm::dot(p, b.up) / (z * b.tany);
    xmin = std::min(xmin, x);
    xmax = std::max(xmax, x);
    ymin = std::min(ymin, y);
    ymax = std::max(ymax, y);
  }
  // Stored depths are single precision: a margin keeps the comparison
  // conservative for a box whose nearest point is a hit point.
  *znear = static_cast<float>(std::max(zmin, b.near) / b.far * (1.0 - 1e-5));
  if (behind) {
    *x0 = *y0 = 0;
    *x1 = width - 1;
    *y1 = height - 1;
    return true;
  }
  // Pixel i samples x = -1 + (2i+1)/W: the centres inside [xmin, xmax], one
  // pixel of margin each side for rounding.
  const double fx0 = (xmin + 1.0) * 0.5 * width - 0.5, fx1 = (xmax + 1.0) * 0.5 * width - 0.5;
  const double fy0 = (ymin + 1.0) * 0.5 * height - 0.5, fy1 = (ymax + 1.0) * 0.5 * height - 0.5;
  if (fx1 < -1.0 || fy1 < -1.0 || fx0 > width || fy0 > height) return false;
  *x0 = static_cast<int>(std::max(0.0, std::floor(fx0) - 1.0));
  *y0 = static_cast<int>(std::max(0.0, std::floor(fy0) - 1.0));
  *x1 = static_cast<int>(std::min(width - 1.0, std::ceil(fx1) + 1.0));
  *y1 = static_cast<int>(std::min(height - 1.0, std::ceil(fy1) + 1.0));
  return *x0 <= *x1 && *y0 <= *y1;
}

}  // namespace detail

namespace {

constexpr int kCell = 16;  // Pixels a side of a cell of the lazy grid.

/// Hey et al.'s lazy occlusion grid (z-buffer variant) over the PVS's
/// objects, whose instances are uploaded and whose hierarchy is `nodes`.
bool lazy_grid(Renderer::Impl& m, const Basis& b, int width, int height, const std::vector<Node>& nodes,
               const std::vector<std::uint32_t>& order, const std::vector<glm::dvec3>& lo,
               const std::vector<glm::dvec3>& hi, std::vector<ObjectId>* out, RefineStats* stats, std::string* error) {
  auto t0 = Clock::now();
  m.upload();
  m.depth_pass(b, width, height, 0);  // Cleared to the far depth; nothing drawn yet.
  stats->draw_ms += ms_since(t0);
  if (nodes.empty()) return m.gl_ok("the lazy grid", error);
  const int gx = (width + kCell - 1) / kCell, gy = (height + kCell - 1) / kCell;
  std::vector<float> zfar(static_cast<std::size_t>(gx) * static_cast<std::size_t>(gy), 1.0f);
  std::vector<char> outdated(zfar.size(), 0);
  std::vector<float> pixels(static_cast<std::size_t>(kCell) * kCell);
  ++stats->levels;

  // Whether the rectangle may show something at depth >= znear: cells known
  // to be free enough first, then the outdated ones, each read back once.
  auto occluded = [&](int x0, int y0, int x1, int y1, float znear) {
    const int c0 = x0 / kCell, c1 = x1 / kCell, r0 = y0 / kCell, r1 = y1 / kCell;
    for (int r = r0; r <= r1; ++r)
      for (int c = c0; c <= c1; ++c) {
        const std::size_t i = static_cast<std::size_t>(r) * static_cast<std::size_t>(gx) + static_cast<std::size_t>(c);
        if (!outdated[i] && zfar[i] >= znear) return false;
      }
    for (int r = r0; r <= r1; ++r)
      for (int c = c0; c <= c1; ++c) {
        const std::size_t i = static_cast<std::size_t>(r) * static_cast<std::size_t>(gx) + static_cast<std::size_t>(c);
        if (!outdated[i]) continue;
        const auto t = Clock::now();
        const int px = c * kCell, py = r * kCell;
        const int cw = std::min(kCell, width - px), ch = std::min(kCell, height - py);
        glReadPixels(px, py, cw, ch, GL_DEPTH_COMPONENT, GL_FLOAT, pixels.data());
        float far_depth = 0.0f;
        for (int k = 0; k < cw * ch; ++k) far_depth = std::max(far_depth, pixels[static_cast<std::size_t>(k)]);
        zfar[i] = far_depth;
        outdated[i] = 0;
        ++stats->queries;
        stats->pixels += static_cast<std::uint64_t>(cw * ch);
        stats->wait_ms += ms_since(t);
        if (zfar[i] >= znear) return false;
      }
    return true;
  };

  // Front to back by least depth: boxes of the hierarchy and objects in one
  // queue; a box not occluded opens its children, an object not occluded is
  // drawn (depth and id) and kept, and the cells under it go out of date.
  struct Entry {
    float znear;
    std::int32_t node;    // >= 0: a box of the hierarchy.
    std::uint32_t object;  // When node < 0: the object's instance.
    int x0, y0, x1, y1;
    bool operator>(const Entry& o) const { return znear > o.znear; }
  };
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> queue;
  auto push = [&](std::int32_t node, std::uint32_t object) {
    const glm::dvec3& l = node >= 0 ? nodes[static_cast<std::size_t>(node)].lo : lo[object];
    const glm::dvec3& h = node >= 0 ? nodes[static_cast<std::size_t>(node)].hi : hi[object];
    Entry e{0.0f, node, object, 0, 0, 0, 0};
    if (screen_rect(b, width, height, l, h, &e.x0, &e.y0, &e.x1, &e.y1, &e.znear)) queue.push(e);
  };
  push(0, 0);
  glDepthMask(GL_TRUE);
  glDepthFunc(GL_LESS);
  while (!queue.empty()) {
    const Entry e = queue.top();
    queue.pop();
    if (occluded(e.x0, e.y0, e.x1, e.y1, e.znear)) continue;
    if (e.node >= 0) {
      const Node& nd = nodes[static_cast<std::size_t>(e.node)];
      if (nd.left >= 0) {
        push(nd.left, 0);
        push(nd.right, 0);
      } else {
        for (std::uint32_t i = nd.first; i < nd.first + nd.count; ++i) push(-1, order[i]);
      }
      continue;
    }
    const auto t = Clock::now();
    m.draw_instance(e.object);
    ++stats->draw_calls;
    stats->draw_ms += ms_since(t);
    out->push_back(m.drawn_ids[e.object]);
    for (int r = e.y0 / kCell; r <= e.y1 / kCell; ++r)
      for (int c = e.x0 / kCell; c <= e.x1 / kCell; ++c)
        outdated[static_cast<std::size_t>(r) * static_cast<std::size_t>(gx) + static_cast<std::size_t>(c)] = 1;
  }
  if (!m.gl_ok("the lazy grid", error)) return false;
  std::sort(out->begin(), out->end());
  return true;
}

}  // namespace

bool Renderer::refine(const Level& level, const std::vector<ObjectDesc>& objects, const Camera& cam, int width,
                      int height, const std::vector<ObjectId>& pvs, std::vector<ObjectId>* out, RefineStats* stats,
                      std::string* error) {
  Impl& m = *impl_;
  *stats = RefineStats{};
  out->clear();
  if (level.kind == LevelKind::NearOptimal && !m.refine.model) {
    // Measured (or loaded) before the frame's camera takes the framebuffer.
    std::string note;
    if (!m.egl->make_current(error) || !m.ensure_model(&note, error)) return false;
  }
  Basis b;
  if (!m.begin(cam, width, height, &b, error)) return false;
  if (level.kind == LevelKind::None) {
    *out = pvs;
    return true;
  }

  if (level.kind == LevelKind::Ternary) return detail::refine_ternary(m, b, width, height, objects, pvs, out, stats, error);
  if (level.kind == LevelKind::NearOptimal)
    return detail::refine_near_optimal(m, level, b, width, height, objects, pvs, out, stats, error);

  // The PVS's objects that may meet the frustum: the occluders, and the
  // candidates. The others cannot show.
  std::vector<glm::dvec3> lo, hi;
  if (!detail::pvs_instances(m, b, objects, pvs, &lo, &hi, error)) return false;
  const std::size_t n = m.instances.size();

  // Hierarchical: the boxes of the inner nodes go after the objects (query
  // boxes, grown).
  std::vector<Node> nodes;
  std::vector<std::uint32_t> order;
  std::vector<std::size_t> node_instance;
  if ((level.kind == LevelKind::Hierarchical || level.kind == LevelKind::LazyGrid) && n > 0) {
    order.resize(n);
    for (std::uint32_t i = 0; i < n; ++i) order[i] = i;
    build_hierarchy(nodes, order, lo, hi, 0, static_cast<std::uint32_t>(n));
  }
  if (level.kind == LevelKind::LazyGrid) return lazy_grid(m, b, width, height, nodes, order, lo, hi, out, stats, error);
  if (level.kind == LevelKind::Hierarchical && n > 0) node_instance = detail::node_instances(m, b, nodes);

  // The depth of the PVS's objects, then rounds of queries against it.
  if (!detail::pvs_depth_pass(m, b, width, height, n, stats, error)) return false;
  std::vector<GLuint> passed;
  auto round = [&](const std::vector<std::size_t>& probes) { detail::query_round(m, probes, &passed, stats); };

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
