// refine_near_optimal.cpp — the `near-optimal` level (voxvis/refine.h), after
// Guthe, Balázs, Klein and Klein, "Near optimal hierarchical culling"
// (../shared/papers/near-optimal-hierarchical-culling.txt).
//
// After a depth pass of the PVS's objects, the bounding-box hierarchy over
// them (refine_common.h) is walked from the root and each node and object is
// queried only where the paper's test says a query is reasonable (its
// figure 5), from:
//  - the chance it is hidden (section 3.1): its box's screen coverage c_bb
//    against c_scr, the expected coverage of everything nearer (objects
//    sorted by their nearest depth, c_scr(i+1) = c_scr(i) + (1 - c_scr(i))
//    c(i), with c = c_bb for a box and pi/4 c_bb for a ball), p_cov =
//    (sqrt(c_scr) - sqrt(c_bb))^2 when c_bb < c_scr; then by last frame's
//    state: hidden 1, kept p_cov^2 / 2, not a candidate p_cov;
//  - the time a query takes, t_o = T_o^s + fragments T_o^f, and the time
//    drawing its objects would take, t_r = max(T_r^s, T T_r^tri, 2 c wh
//    T_r^f) per object of T triangles, from the machine's cost model
//    (cost_model.cpp);
//  - cost C = t_o and benefit B = p (t_r - t_o) / log2(N + 1), the benefit
//    of a node kept last frame amortised over the frames since its last
//    query (C <= frames B), a node not a candidate last frame queried when
//    t_o + (1 - p) t_r < t_r, a node hidden last frame always queried;
//    granularity: no query where its children's queries cost less in all,
//    and an inner node's only where its benefit beats its children's and
//    T_o^o times its objects exceeds its query's time, or a child is
//    cheaper drawn than queried.
// Latency (section 4.3): the children of a node hidden last frame wait for
// its answer (the next round of queries) when the queries that may save pay
// for the latency T_o^l; the others are walked at once, in the same round.
// An object with no query of its own or of a node above it is kept: the
// level spends queries only where they are expected to pay, so it lies
// between `none` and `queries` in tightness, and is conservative.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <string>
#include <unordered_map>
#include <vector>

#include "refine_common.h"
#include "renderer_impl.h"

namespace voxvis::render::detail {

namespace {

enum class Was : std::uint8_t { Unknown, Kept, Hidden };

/// What the model says of a node or an object.
struct Estimate {
  double cbb = 0.0;        // Screen fraction of its box.
  double p = 0.0;          // Chance it is hidden.
  double t_render = 0.0;   // ms to draw its objects.
  double t_query = 0.0;    // ms to query it.
  double benefit = 0.0;    // B.
  double frames = 0.0;     // Frames since its last query.
  Was was = Was::Unknown;
  bool outside = false;    // Its box misses the image.
};

double p_cov(double cscr, double cbb) {
  if (!(cbb < cscr)) return 0.0;
  const double d = std::sqrt(cscr) - std::sqrt(cbb);
  return d * d;
}

double p_hidden(Was was, double pcov) {
  switch (was) {
    case Was::Hidden: return 1.0;
    case Was::Kept: return 0.5 * pcov * pcov;
    case Was::Unknown: return pcov;
  }
  return pcov;
}

}  // namespace

bool refine_near_optimal(Renderer::Impl& m, const Level& level, const Basis& b, int width, int height,
                         const std::vector<ObjectDesc>& objects, const std::vector<ObjectId>& pvs,
                         std::vector<ObjectId>* out, RefineStats* stats, std::string* error) {
  const CostModel& cm = *m.refine.model;
  NearOptimalState& state = m.refine.near_optimal;
  ++state.frame;
  std::vector<glm::dvec3> lo, hi;
  if (!pvs_instances(m, b, objects, pvs, &lo, &hi, error)) return false;
  const std::size_t n = lo.size();
  if (n == 0) {
    state.last.clear();
    return true;
  }
  std::vector<Node> nodes;
  std::vector<std::uint32_t> order(n);
  for (std::uint32_t i = 0; i < n; ++i) order[i] = i;
  build_hierarchy(nodes, order, lo, hi, 0, static_cast<std::uint32_t>(n));
  const std::vector<std::size_t> node_instance = node_instances(m, b, nodes);
  if (!pvs_depth_pass(m, b, width, height, n, stats, error)) return false;

  // The model's estimates, objects first (front to back for c_scr).
  const double wh = static_cast<double>(width) * height;
  const double log_nodes = std::log2(static_cast<double>(nodes.size() + n) + 1.0);
  auto rect = [&](const glm::dvec3& l, const glm::dvec3& h, Estimate* e, float* znear) {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    if (!screen_rect(b, width, height, l, h, &x0, &y0, &x1, &y1, znear)) {
      e->outside = true;
      return;
    }
    e->cbb = std::min(1.0, (x1 - x0 + 1.0) * (y1 - y0 + 1.0) / wh);
  };
  std::vector<Estimate> obj(n);
  std::vector<float> zobj(n);
  std::vector<double> cover(n);  // c(O): the object's own coverage.
  for (std::size_t k = 0; k < n; ++k) {
    rect(lo[k], hi[k], &obj[k], &zobj[k]);
    cover[k] = obj[k].cbb * (m.instances[k].kind < 0.5f ? 0.78539816339744831 : 1.0);
    const auto it = state.last.find(m.drawn_ids[k]);
    if (it != state.last.end()) {
      obj[k].was = it->second.visible ? Was::Kept : Was::Hidden;
      obj[k].frames = it->second.last_query == 0 ? 1e9 : static_cast<double>(state.frame - it->second.last_query);
    } else {
      obj[k].frames = 1e9;
    }
    obj[k].t_render = cm.render_ms(level.triangles, 2.0 * wh * cover[k]);
    obj[k].t_query = cm.query_ms(wh * obj[k].cbb);
  }
  std::vector<std::uint32_t> by_depth(n);
  for (std::uint32_t k = 0; k < n; ++k) by_depth[k] = k;
  std::sort(by_depth.begin(), by_depth.end(), [&](std::uint32_t a, std::uint32_t c) { return zobj[a] < zobj[c]; });
  std::vector<float> zsorted(n);
  std::vector<double> cscr(n + 1, 0.0);  // cscr[i]: expected coverage of the i nearest objects.
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t k = by_depth[i];
    zsorted[i] = zobj[k];
    cscr[i + 1] = cscr[i] + (1.0 - cscr[i]) * cover[k];
    obj[k].p = p_hidden(obj[k].was, p_cov(cscr[i], obj[k].cbb));
    obj[k].benefit = obj[k].p * (obj[k].t_render - obj[k].t_query) / log_nodes;
  }
  auto cscr_at = [&](float z) {
    return cscr[static_cast<std::size_t>(std::lower_bound(zsorted.begin(), zsorted.end(), z) - zsorted.begin())];
  };
  std::vector<Estimate> est(nodes.size());
  for (std::size_t k = nodes.size(); k-- > 0;) {
    const Node& nd = nodes[k];
    Estimate& e = est[k];
    float z = 0.0f;
    rect(nd.lo, nd.hi, &e, &z);
    bool any_kept = false, all_hidden = true;
    double last = 0.0;
    for (std::uint32_t i = nd.first; i < nd.first + nd.count; ++i) {
      const Estimate& o = obj[order[i]];
      e.t_render += o.t_render;
      any_kept = any_kept || o.was == Was::Kept;
      all_hidden = all_hidden && o.was == Was::Hidden;
      last = std::max(last, o.frames > 1e8 ? 0.0 : static_cast<double>(state.frame) - o.frames);
    }
    e.was = any_kept ? Was::Kept : all_hidden ? Was::Hidden : Was::Unknown;
    e.frames = last == 0.0 ? 1e9 : static_cast<double>(state.frame) - last;
    e.t_query = cm.query_ms(wh * e.cbb);
    e.p = p_hidden(e.was, p_cov(e.outside ? 0.0 : cscr_at(z), e.cbb));
    e.benefit = e.p * (e.t_render - e.t_query) / log_nodes;
  }

  // An item of the walk: a node (>= 0) or object k (-1 - k).
  auto estimate = [&](std::int64_t item) -> const Estimate& {
    return item >= 0 ? est[static_cast<std::size_t>(item)] : obj[static_cast<std::size_t>(-1 - item)];
  };
  auto children = [&](std::int64_t item) {
    std::vector<std::int64_t> c;
    if (item < 0) return c;
    const Node& nd = nodes[static_cast<std::size_t>(item)];
    if (nd.left >= 0) {
      c = {nd.left, nd.right};
    } else {
      for (std::uint32_t i = nd.first; i < nd.first + nd.count; ++i) c.push_back(-1 - static_cast<std::int64_t>(order[i]));
    }
    return c;
  };
  const double overhead_ms = cm.query_overhead_us * 1e-3, latency_ms = cm.query_latency_us * 1e-3;
  // Figure 5 of the paper.
  auto reasonable = [&](std::int64_t item, const std::vector<std::int64_t>& kids) {
    const Estimate& e = estimate(item);
    if (e.t_render < e.t_query) return false;
    double kids_cost = 0.0, kids_benefit = 0.0;
    bool kid_cheaper_drawn = false;
    for (std::int64_t c : kids) {
      const Estimate& k = estimate(c);
      kids_cost += k.outside ? 0.0 : k.t_query;
      kids_benefit += k.benefit;
      kid_cheaper_drawn = kid_cheaper_drawn || k.t_render < k.t_query;
    }
    if (!kids.empty() && kids_cost < e.t_query) return false;
    if (e.was == Was::Hidden) return true;
    if (e.was == Was::Unknown) return e.t_query + (1.0 - e.p) * e.t_render < e.t_render;
    if (e.t_query > e.frames * e.benefit) return false;
    if (kids.empty() || kid_cheaper_drawn) return true;
    const Node& nd = nodes[static_cast<std::size_t>(item)];
    return e.benefit > kids_benefit && overhead_ms * nd.count > e.t_query;
  };

  // The walk, in rounds of queries all issued before any is read.
  std::vector<char> dropped(n, 0), covered(n, 0), own(n, 0);
  auto drop = [&](std::int64_t item) {
    if (item < 0) {
      dropped[static_cast<std::size_t>(-1 - item)] = 1;
      return;
    }
    const Node& nd = nodes[static_cast<std::size_t>(item)];
    for (std::uint32_t i = nd.first; i < nd.first + nd.count; ++i) dropped[order[i]] = 1;
  };
  auto cover_all = [&](std::int64_t item) {
    if (item < 0) {
      covered[static_cast<std::size_t>(-1 - item)] = 1;
      return;
    }
    const Node& nd = nodes[static_cast<std::size_t>(item)];
    for (std::uint32_t i = nd.first; i < nd.first + nd.count; ++i) covered[order[i]] = 1;
  };
  std::vector<std::int64_t> probes, frontier = {0};
  std::vector<char> held;  // Per probe: its children wait for its answer.
  std::vector<GLuint> passed;
  std::vector<std::size_t> instances;  // The probes' instance numbers.
  std::function<void(std::int64_t)> visit = [&](std::int64_t item) {
    const Estimate& e = estimate(item);
    if (e.outside) {
      drop(item);  // Its box covers no pixel of the image.
      return;
    }
    const std::vector<std::int64_t> kids = children(item);
    if (reasonable(item, kids)) {
      probes.push_back(item);
      cover_all(item);
      if (item < 0) own[static_cast<std::size_t>(-1 - item)] = 1;
      double saved = 0.0;
      for (std::int64_t c : kids) saved += estimate(c).t_query;
      held.push_back(!kids.empty() && e.was == Was::Hidden && e.p * saved > latency_ms);
      if (held.back()) return;
    }
    for (std::int64_t c : kids) visit(c);
  };
  while (!frontier.empty()) {
    probes.clear();
    held.clear();
    for (std::int64_t item : frontier) visit(item);
    frontier.clear();
    if (probes.empty()) break;
    instances.resize(probes.size());
    for (std::size_t q = 0; q < probes.size(); ++q)
      instances[q] = probes[q] >= 0 ? node_instance[static_cast<std::size_t>(probes[q])]
                                    : static_cast<std::size_t>(-1 - probes[q]);
    query_round(m, instances, &passed, stats);
    for (std::size_t q = 0; q < probes.size(); ++q)
      if (passed[q] == 0) drop(probes[q]);
    for (std::size_t q = 0; q < probes.size(); ++q) {
      if (passed[q] == 0 || !held[q]) continue;
      for (std::int64_t c : children(probes[q])) frontier.push_back(c);
    }
  }
  m.end_probes();
  if (!m.gl_ok("the near-optimal queries", error)) return false;

  // Kept objects, and each candidate's state for the next frame.
  std::unordered_map<ObjectId, ObjectHistory> next;
  next.reserve(n);
  for (std::size_t k = 0; k < n; ++k) {
    ObjectHistory h;
    h.visible = !dropped[k];
    const auto it = state.last.find(m.drawn_ids[k]);
    h.last_query = covered[k] ? state.frame : (it != state.last.end() ? it->second.last_query : 0);
    next.emplace(m.drawn_ids[k], h);
    if (dropped[k]) continue;
    out->push_back(m.drawn_ids[k]);
    if (!own[k]) ++stats->kept_unqueried;
  }
  state.last.swap(next);
  std::sort(out->begin(), out->end());
  return true;
}

}  // namespace voxvis::render::detail
