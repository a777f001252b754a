// frame.cpp — Scene::frame: one viewer's frame as named phases.
//
//  1. begin     the clock and the pending counters, under `book`; then,
//               only when a TBV has expired, `mu` exclusive to renew it.
//  2. traverse  `mu` shared: the traversal (traverse.h), or frustum culling
//               alone when the camera leaves the occlusion tests no
//               precision; then what lies beyond the grid, and the PVS
//               tested once more against the whole buffer.
//  3. commit    still shared, under `book`: reveals and new TBVs queued,
//               claims updated, the answer written.
//  4. apply     `mu` exclusive if free: the queue applied now, else by the
//               next holder.
// docs/design.md ("A frame", "Thread-safety") says why each step is where
// it is.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <shared_mutex>

#include <glm/vector_relational.hpp>

#include "numeric.h"
#include "region.h"
#include "region_candidates.h"
#include "traverse.h"
#include "voxvis/inspect.h"

namespace voxvis {

using detail::Obj;

namespace {

/// While frames of other viewers run, a frame renews TBVs expiring within
/// this many seconds of it along with the expired ones.
constexpr double kRenewAhead = 0.1;

/// One frame's state, passed from phase to phase.
struct FrameRun {
  Scene::Impl& s;
  Scratch::Impl& w;
  const detail::WorldFrustum wf;
  const detail::RegionReach reach;  ///< Whether, and what, a region reaches (region.h).
  ViewerId viewer;
  double t;
  FrameStats st{};
  std::vector<std::uint32_t>& wake;  ///< Slots; the Scratch's buffer (w.wake).
};

/// Phase 1: the clock, under `book`; whether a TBV has expired.
Status begin(FrameRun& f, Scene::Clock clock, bool* expired) {
  Scene::Impl& s = f.s;
  std::lock_guard<std::mutex> book(s.book);
  if (clock == Scene::Clock::Latest && s.time_set) f.t = std::fmax(f.t, s.time);
  if (s.time_set && f.t < s.time)
    return Status::Error("t", "time goes backwards: " + number_text(f.t) + " < " + number_text(s.time));
  if (s.viewers.find(f.viewer) == s.viewers.end())
    return Status::Error("viewer", "unknown viewer " + std::to_string(f.viewer));
  s.time = f.t;
  s.time_set = true;
  if (!std::isfinite(s.first_frame_time)) s.first_frame_time = f.t;
  f.st = s.pending;
  s.pending = FrameStats{};
  // The scene takes this Scratch's emptied buffer in exchange: both keep
  // their capacity, so a frame allocates nothing here.
  f.wake.clear();
  f.wake.swap(s.pending_wake);
  // Only an expired TBV makes a frame wait: it no longer bounds its object.
  // The queue is conservative as it stands (queued TBVs still bound their
  // objects, unclaimed objects are in the grid where they are), so it waits
  // for a free moment (phase 4) or the next change. The expiry queue
  // changes only under `mu` exclusive and `book`, and a TBV made after this
  // point expires after s.time >= t, so the check holds until the traversal.
  *expired = s.expiry.any_due(f.t);
  return Status::Ok();
}

/// Asks for the cache lines of an object that a TBV's renewal reads: its
/// fields up to the TBV's (the mesh's, after them, are not read).
void prefetch_obj(const Obj& o) {
  const char* p = reinterpret_cast<const char*>(&o);
  const char* end = reinterpret_cast<const char*>(&o.tbv_coarse + 1);
  for (; p < end; p += 64) __builtin_prefetch(p);
  __builtin_prefetch(end - 1);
}

/// Phase 1, exclusive: the queue other frames left, and expired TBVs given
/// a new validity period around the object's current position (paper 4.1,
/// criterion 2); an object hidden through a whole period gets twice as long
/// the next time. While other frames run, those expiring within kRenewAhead
/// are renewed too (early is as sound: the new period starts now), so that
/// frames wait for this lock about once per kRenewAhead; a frame alone
/// renews only what expired, spreading the work over frames. Each is
/// renewed once: a new period shorter than kRenewAhead must not bring it
/// straight back.
void renew(FrameRun& f) {
  Scene::Impl& s = f.s;
  std::unique_lock<detail::GridMutex> lock(s.mu);
  std::lock_guard<std::mutex> book(s.book);
  s.apply_queue(f.st, s.claims_made);
  const double ahead = s.frames_in_flight.load(std::memory_order_relaxed) > 1 ? kRenewAhead : 0.0;
  std::vector<detail::ExpiryEntry> due;
  s.expiry.pop_due(f.t + ahead, &due);
  // The objects are scattered over the scene's memory (a cache miss each,
  // most of a renewal's time at 100,000 hidden objects): fetched a few ahead.
  constexpr std::size_t kAhead = 4;
  for (std::size_t k = 0; k < std::min(kAhead, due.size()); ++k) prefetch_obj(s.objs[due[k].slot]);
  for (std::size_t k = 0; k < due.size(); ++k) {
    const detail::ExpiryEntry& e = due[k];
    if (k + kAhead < due.size()) prefetch_obj(s.objs[due[k + kAhead].slot]);
    Obj& o = s.objs[e.slot];
    if (!o.under_tbv || o.tbv_epoch != e.epoch) continue;
    o.tbv_period = std::fmin(2.0 * o.tbv_period, s.max_period(o));
    s.renew_tbv(e.slot, f.t);
    ++f.st.tbvs_expired;
    f.wake.push_back(e.slot);
  }
}

void put_in_pvs(FrameRun& f, std::uint32_t slot) {
  if (f.w.obj_mark[slot] == f.w.frame) return;
  f.w.obj_mark[slot] = f.w.frame;
  f.w.pvs.push_back(slot);
}

/// Levels of halving a moving object's box (or the eyes') when no one
/// occluder hides it from a region (RegionOcclusion::hides): up to 16 pairs
/// of pieces. Static objects are tested whole: there are many, and they are
/// not what a game server hides (halving them too costs 2.4x the frame on
/// the arena for 7% fewer objects kept, none of them players).
constexpr int kRegionSplitLevels = 4;

/// The voxels the box [lo, hi] may touch, clipped to the grid; `inside`:
/// whether the box lies within the grid box, rounding allowed for.
detail::VoxBox grid_range(const Scene::Impl& s, const Vec3& lo, const Vec3& hi, bool* inside) {
  const double slop = s.slop(detail::max_abs(lo) + detail::max_abs(hi));
  const Vec3 glo = s.to_grid(lo) - slop * s.inv_vs, ghi = s.to_grid(hi) + slop * s.inv_vs;
  *inside = glm::all(glm::greaterThanEqual(glo, Vec3(0.0))) && glm::all(glm::lessThanEqual(ghi, Vec3(s.res)));
  return s.touch_range(lo, hi, slop);
}

/// The free space the region's eyes are shut in (region_cavity.h): the eye
/// box grown by what the near plane may clip (omnidirectional: a cube of
/// `near` about each eye, a cube face's depth; a frustum: the distance to
/// its near rectangle's corners).
detail::RegionCavity eyes_cavity(const Scene::Impl& s, const detail::WorldFrustum& wf, const detail::RegionEyes& eyes) {
  const double reach = eyes.omnidirectional ? eyes.near
                                            : eyes.near * std::sqrt(1.0 + wf.tan_x * wf.tan_x + wf.tan_y * wf.tan_y);
  bool inside = false;
  detail::VoxBox range;
  if (std::isfinite(reach)) range = grid_range(s, eyes.lo - Vec3(reach), eyes.hi + Vec3(reach), &inside);
  return detail::RegionCavity(s.free_space, s.res, range, inside && std::isfinite(reach));
}

/// Phase 2 for a region (region.h, region_occlusion.h): every object and
/// TBV the region can reach, less those static occluders hide from every
/// eye of the box wherever the object goes within the horizon
/// (docs/design.md, "Regions"). The static objects are tested all; the
/// dynamic ones and TBVs only where their cells can hold a candidate
/// (region_candidates.h), so that movers hidden far away cost nothing.
void reach_region(FrameRun& f, const Camera& camera) {
  Scene::Impl& s = f.s;
  f.st.region = true;
  f.w.ob.begin(f.wf, 0);
  f.st.ob_width = 0;
  if (f.w.region_mark.size() < s.region_occ.occ.size()) f.w.region_mark.assign(s.region_occ.occ.size(), 0u);
  detail::RegionEyes eyes;
  eyes.lo = camera.eye - camera.eye_extent;
  eyes.hi = camera.eye + camera.eye_extent;
  eyes.omnidirectional = camera.omnidirectional;
  eyes.f = f.wf.f;
  eyes.near = camera.near;
  const detail::RegionOcclusion occ(s.region_occ, eyes, f.w.region_mark, f.w.region_stamp);
  const detail::RegionCavity cavity = eyes_cavity(s, f.wf, eyes);
  // Hidden wherever the object goes within the horizon (a TBV: from
  // anywhere in it): outside the eyes' free space, or behind a static
  // occluder.
  auto hidden = [&](const Vec3& lo, const Vec3& hi, double speed) {
    const Vec3 grow(speed * f.reach.horizon);
    if (!detail::finite3(grow)) return false;
    const Vec3 glo = lo - grow, ghi = hi + grow;
    bool inside = false;
    const bool out_of_space = cavity.on() && cavity.hides(grid_range(s, glo, ghi, &inside), inside);
    const int levels = speed > 0.0 ? kRegionSplitLevels : 0;
    if (!out_of_space && !occ.hides(glo, ghi, levels)) return false;
    ++f.st.ob_objects_culled;
    return true;
  };
  auto test = [&](std::uint32_t slot) {
    const Obj& o = s.objs[slot];
    const double speed = o.dynamic ? o.max_speed : 0.0;
    if (o.under_tbv && f.reach.may_reach(f.wf, o.tbv_lo, o.tbv_hi, speed)) {
      // Every position the object can reach before the TBV expires is
      // hidden: nothing to reveal, and the object (inside it) is hidden too.
      if (hidden(o.tbv_lo, o.tbv_hi, speed)) return;
      f.w.deferred.push_back(slot);
    }
    if (f.reach.may_reach(f.wf, o.box_lo(), o.box_hi(), speed) && !hidden(o.box_lo(), o.box_hi(), speed))
      put_in_pvs(f, slot);
  };
  for (const std::uint32_t slot : s.static_slots) test(slot);
  const detail::RegionVisit visit = detail::region_visit(s, f.reach, f.wf, cavity);
  detail::see_region(s, f.w, visit.seen);
  if (visit.all) {
    for (const std::uint32_t slot : s.dynamic_slots) test(slot);
    return;
  }
  auto test_once = [&](std::uint32_t slot) {
    // (The outside list holds static objects too: tested above.)
    if (!s.objs[slot].dynamic || f.w.obj_seen[slot] == f.w.frame) return;
    f.w.obj_seen[slot] = f.w.frame;
    test(slot);
  };
  f.st.cells_visited = detail::for_each_entry(s, visit.range, test_once);
  if (visit.outside) {
    for (const std::uint32_t slot : s.outside_objs) test_once(slot);
    for (const std::uint32_t slot : s.outside_tbvs) test_once(slot);
    f.st.outside_tested += static_cast<std::uint32_t>(s.outside_objs.size() + s.outside_tbvs.size());
  }
}

/// Phase 2: the traversal. An eye so far away that shell indices lose
/// precision, or a camera whose basis came out unusable (validation should
/// make that impossible), falls back to frustum culling of everything,
/// which is always conservative.
void traverse(FrameRun& f) {
  Scene::Impl& s = f.s;
  detail::FrameGeometry g;
  f.st.frustum_fallback = detail::eye_too_far(s.to_grid(f.wf.eye)) || !f.wf.sane();
  f.w.ob.begin(f.wf, f.st.frustum_fallback ? 0 : s.options.occlusion_buffer);
  f.st.ob_width = static_cast<std::uint32_t>(f.w.ob.width());
  if (!f.st.frustum_fallback) {
    if (!detail::make_frame_geometry(s, f.wf, &g)) return;  // The grid is wholly out of view.
    FrameTrace* trace = f.w.trace;
    if (f.w.ob.on()) {
      if (trace != nullptr) trace->traversal = FrameTrace::Traversal::Cells;
      detail::traverse_cells(s, f.w, f.wf, f.st, g);
    } else {
      f.w.begin_voxels(static_cast<std::size_t>(s.spec.voxel_count()));
      detail::traverse_voxels(s, f.w, f.wf, f.st, g);
      if (trace != nullptr) {
        trace->traversal = FrameTrace::Traversal::Voxels;
        detail::trace_voxels(s, f.w, *trace);
      }
    }
    return;
  }
  for (std::uint32_t slot = 0; slot < s.objs.size(); ++slot) {
    const Obj& o = s.objs[slot];
    if (o.under_tbv && f.wf.may_intersect_box(o.tbv_lo, o.tbv_hi)) f.w.deferred.push_back(slot);
    if (f.wf.may_intersect_box(o.box_lo(), o.box_hi())) put_in_pvs(f, slot);
  }
}

/// Whether any part of the box [lo, hi] beyond the grid box may lie in the
/// frustum. Parts inside the grid are the traversal's business.
bool outside_part_visible(const detail::WorldFrustum& wf, const GridSpec& g, Vec3 lo, Vec3 hi) {
  for (int a = 0; a < 3; ++a) {
    if (lo[a] < g.bounds_min[a]) {
      Vec3 h = hi;
      h[a] = std::fmin(hi[a], g.bounds_min[a]);
      if (wf.may_intersect_box(lo, h)) return true;
    }
    if (hi[a] > g.bounds_max[a]) {
      Vec3 l = lo;
      l[a] = std::fmax(lo[a], g.bounds_max[a]);
      if (wf.may_intersect_box(l, hi)) return true;
    }
  }
  return false;
}

/// Phase 2: TBVs and objects reaching beyond the grid, whose outer parts no
/// cell stands for. Tested under the same lock as the traversal, so that a
/// TBV another viewer's frame made since phase 1 is seen by one or the other.
void beyond_grid(FrameRun& f) {
  Scene::Impl& s = f.s;
  for (std::uint32_t slot : s.outside_tbvs) {
    ++f.st.outside_tested;
    const Obj& o = s.objs[slot];
    if (!o.under_tbv || !outside_part_visible(f.wf, s.spec, o.tbv_lo, o.tbv_hi)) continue;
    if (detail::ob_hides_tbv(f.w.ob, o)) {
      ++f.st.ob_objects_culled;
      continue;
    }
    f.w.deferred.push_back(slot);
    if (f.wf.may_intersect_box(o.box_lo(), o.box_hi())) put_in_pvs(f, slot);
  }
  for (std::uint32_t slot : s.outside_objs) {
    if (f.w.obj_mark[slot] == f.w.frame) continue;
    ++f.st.outside_tested;
    const Obj& o = s.objs[slot];
    if (!outside_part_visible(f.wf, s.spec, o.box_lo(), o.box_hi())) continue;
    if (detail::ob_hides_object(f.w.ob, o)) {
      ++f.st.ob_objects_culled;
      continue;
    }
    put_in_pvs(f, slot);
  }
}

/// Phase 2: objects found early were tested against a buffer that did not
/// yet hold the occluders found after them; the PVS and the reveals are
/// tested once more against the whole buffer, fine (over each pixel at the
/// object's own depth there) since this is the last word on them. Sound in any order: a bound
/// says only that some object (in the PVS or not) hides what lies behind it.
void retest(FrameRun& f) {
  detail::OcclusionBuffer& ob = f.w.ob;
  if (ob.on()) {
    const Scene::Impl& s = f.s;
    auto hidden = [&](std::uint32_t slot) { return detail::ob_hides_object(ob, s.objs[slot], true); };
    const std::size_t before = f.w.pvs.size();
    f.w.pvs.erase(std::remove_if(f.w.pvs.begin(), f.w.pvs.end(), hidden), f.w.pvs.end());
    auto tbv_hidden = [&](std::uint32_t slot) { return detail::ob_hides_tbv(ob, s.objs[slot]); };
    f.w.deferred.erase(std::remove_if(f.w.deferred.begin(), f.w.deferred.end(), tbv_hidden), f.w.deferred.end());
    f.st.ob_objects_culled += static_cast<std::uint32_t>(before - f.w.pvs.size());
    f.st.ob_pixels_written = ob.writes();
  }
  ob.end();
}

/// Phase 3, under `book` (`mu` still shared): claims. A dynamic object is
/// claimed by every viewer whose last PVS holds it; one no viewer claims is
/// hidden from all of them and is queued for a TBV (Scene::Impl::apply_queue).
void update_claims(Scene::Impl& s, const std::vector<std::uint32_t>& last, const std::vector<std::uint32_t>& pvs) {
  auto a = last.begin();
  auto b = pvs.begin();
  while (a != last.end() || b != pvs.end()) {
    if (b == pvs.end() || (a != last.end() && *a < *b)) {
      Obj& o = s.objs[*a];
      if (o.dynamic && --o.claims == 0 && !o.pending_unclaimed) {
        o.pending_unclaimed = true;
        s.unclaimed.push_back(*a);
      }
      ++a;
    } else if (a == last.end() || *b < *a) {
      Obj& o = s.objs[*b];
      if (o.dynamic) ++o.claims;
      ++b;
    } else {
      ++a, ++b;
    }
  }
  s.claims_made = true;
}

/// Phase 3: reveals and new TBVs are queued for the next holder of `mu`
/// exclusive; claims and the answer are made here. Nothing changes the grid
/// while this frame holds `mu` shared, so what the traversal read still holds.
Status commit(FrameRun& f, FrameResult* out) {
  Scene::Impl& s = f.s;
  std::lock_guard<std::mutex> book(s.book);
  auto vit = s.viewers.find(f.viewer);
  if (vit == s.viewers.end()) return Status::Error("viewer", "unknown viewer " + std::to_string(f.viewer));
  // A reveal another frame queued already is that frame's to report.
  auto queue_reveal = [&](std::uint32_t slot) {
    Obj& o = s.objs[slot];
    if (!o.under_tbv || o.reveal_queued) return;
    o.reveal_queued = true;
    s.queued_reveals.push_back(slot);
    ++s.wake_epoch;
    ++f.st.tbvs_revealed;
    f.wake.push_back(slot);
  };
  for (std::uint32_t slot : f.w.deferred) queue_reveal(slot);
  f.w.deferred.clear();
  // Sorted in the Scratch's buffer, which then trades places with the
  // viewer's last PVS (capacity goes round, nothing is allocated).
  std::vector<std::uint32_t>& pvs = f.w.sorted_pvs;
  pvs.assign(f.w.pvs.begin(), f.w.pvs.end());
  std::sort(pvs.begin(), pvs.end());
  // Objects under a TBV put in the PVS (beyond the grid, or the far-eye
  // fallback): this viewer may see them, so they are revealed.
  for (std::uint32_t slot : pvs) queue_reveal(slot);
  detail::ViewerState& vs = vit->second;
  s.mark_seen(f.w, f.t);
  update_claims(s, vs.last_pvs, pvs);
  out->t = f.t;
  out->pvs.clear();
  out->wake.clear();
  out->pvs.reserve(pvs.size());
  for (std::uint32_t slot : pvs) {
    out->pvs.push_back(s.objs[slot].id);
    if (s.objs[slot].dynamic) f.wake.push_back(slot);
  }
  vs.last_pvs.swap(pvs);
  out->wake.reserve(f.wake.size());
  for (std::uint32_t slot : f.wake) out->wake.push_back(s.objs[slot].id);
  std::sort(out->pvs.begin(), out->pvs.end());
  std::sort(out->wake.begin(), out->wake.end());
  out->wake.erase(std::unique(out->wake.begin(), out->wake.end()), out->wake.end());
  f.st.objects_discretized += s.pending.objects_discretized;
  s.pending.objects_discretized = 0;
  f.st.pvs_size = static_cast<std::uint32_t>(out->pvs.size());
  f.st.tbvs_active = s.tbv_count;
  return Status::Ok();
}

/// Phase 4: the queue applied now if no traversal is running; otherwise the
/// next frame (or move) that holds `mu` exclusive does. Until then queued
/// TBVs keep bounding their objects and unclaimed objects stay in the grid
/// at their positions, both conservative.
void apply_if_free(FrameRun& f) {
  Scene::Impl& s = f.s;
  std::unique_lock<detail::GridMutex> lock(s.mu, std::try_to_lock);
  if (!lock.owns_lock()) return;
  std::lock_guard<std::mutex> book(s.book);
  if (!s.queued(true)) return;
  s.apply_queue(f.st);
  f.st.objects_discretized += s.pending.objects_discretized;
  s.pending.objects_discretized = 0;
  f.st.tbvs_active = s.tbv_count;
}

}  // namespace

Status Scene::frame(ViewerId viewer, const Camera& camera, double t, Scratch& scratch, FrameResult* out, Clock clock) {
  Impl& s = *impl_;
  if (Status st = validate_camera(camera); !st) return st;
  if (Status st = validate_time("t", t); !st) return st;
  const auto start = std::chrono::steady_clock::now();
  const std::uint64_t tick0 = detail::ticks();
  s.frames_in_flight.fetch_add(1, std::memory_order_relaxed);
  struct InFlight {
    std::atomic<int>& n;
    ~InFlight() { n.fetch_sub(1, std::memory_order_relaxed); }
  } in_flight{s.frames_in_flight};
  Scratch::Impl& w = scratch.impl();
  if (w.trace != nullptr) w.trace->clear();
  w.begin(s.objs.size(), s.opaque_boxes.size(), s.bricks.size(), s.cell_base[static_cast<std::size_t>(s.pyr.levels)],
          s.static_triangles);
  FrameRun f{s, w, detail::make_world_frustum(camera), detail::make_region_reach(camera), viewer, t, FrameStats{},
             w.wake};
  std::uint64_t tick_split[2] = {0, 0};  // Traversal; beyond the grid and retest.
  bool expired = false;
  if (Status st = begin(f, clock, &expired); !st) return st;
  if (expired) renew(f);
  {
    std::shared_lock<detail::GridMutex> lock(s.mu);
    out->positions_epoch = s.moves_epoch;
    const std::uint64_t t0 = detail::ticks();
    w.render_ticks = 0;
    if (f.reach.on) {
      reach_region(f, camera);  // Beyond the grid included.
    } else {
      traverse(f);
    }
    const std::uint64_t t1 = detail::ticks();
    if (!f.reach.on) beyond_grid(f);
    retest(f);
    tick_split[0] = t1 - t0;
    tick_split[1] = detail::ticks() - t1;
    if (Status st = commit(f, out); !st) return st;
  }
  apply_if_free(f);
  f.st.time_us = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count();
  // The split, in the frame's ticks scaled to its time: two clock reads a
  // frame, whatever clock a timing tool puts behind steady_clock.
  const double ticks_total = static_cast<double>(detail::ticks() - tick0);
  if (ticks_total > 0.0) {
    const double us_per_tick = f.st.time_us / ticks_total;
    f.st.traverse_us = static_cast<double>(tick_split[0]) * us_per_tick;
    f.st.retest_us = static_cast<double>(tick_split[1]) * us_per_tick;
    f.st.render_us = static_cast<double>(w.render_ticks) * us_per_tick;
  }
  out->stats = f.st;
  return Status::Ok();
}

}  // namespace voxvis
