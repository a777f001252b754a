// bench_frame.cpp — Google Benchmark for the per-frame engine cost.
//
//   walkthrough/grid:GXxGYxGZ[/ob:W]
//     The paper-like scene (make_paper_scene: 5,000 spheres in clusters, 200
//     dynamic, bounds 100 x 60 x 100) and its walkthrough (make_walkthrough),
//     on grids 50x30x50, 100x60x100 and 200x120x200, with the occlusion
//     buffer off or W pixels wide. Each iteration is one frame: apply_moves,
//     then frame. The walkthrough is replayed forwards then backwards
//     (ping-pong) with time always increasing, so every move stays within
//     max_speed; a run is one whole cycle (598 frames).
//
//   indoor[/ob:W], voxel_world/surface[/ob:W], voxel_world/cave[/ob:W],
//   city[/ob:W]
//     Static scenes with a 200-frame camera path each, replayed ping-pong:
//     make_indoor_level (6 x 3 rooms, walls of abutting boxes on voxel
//     planes), make_voxel_world (64 x 64 columns of unit blocks with caves;
//     the path over the surface or through a cave), make_city (8 x 8 blocks
//     of box buildings with parked cars, driven through at street level).
//
//   arena[/ob:W]
//     make_arena (4 x 4 rooms on two storeys, 24 players running at 320
//     units/s), its 200-frame first-person walk, ping-pong like the
//     walkthrough (the players' moves replayed backwards on the way back).
//
//   walkthrough|indoor|city|arena/region:Lms[/omni]
//     The same paths with every camera a region (Camera::eye_extent,
//     horizon_s, omnidirectional): what L ms reach at the path's top speed
//     (region_reach), the eye box a quarter as high as wide; the buffer at
//     128 for the point frames' sake (a region does not use it).
//     dynamic_in_pvs_mean counts the moving objects (the arena's players).
//
//   indoor/meshes[/ob:W], city/meshes[/ob:W]
//     The same levels and paths with every static box a mesh of 12
//     triangles (a cube, placed at the box's centre): the mesh layout's cost
//     against the box layout's.
//
//   Counters of both kinds:
//       median_us, p99_us  engine time per frame (FrameStats::time_us)
//       vfc_median_us      plain frustum culling of the same frames (every
//                          object's box against the six planes), timed in
//                          the same run
//       voxels_mean        voxels visited per frame
//       pvs_mean           PVS size per frame (all timed frames)
//       pvs_sub_mean       PVS size over the frames the ray caster sampled
//       exact_mean         exactly visible objects (ray caster, 1024x576 rays)
//       edge_only_mean     (voxel world) blocks of pvs_sub_mean that the eye
//                          can see only along an edge or at a corner: a tie
//                          the ray caster counts as visible but its sampled
//                          rays never find (edge_only_blocks)
//       voxels_sub_mean, in_view_mean (indoor, voxel world, city) voxels
//                          visited and voxels in view (raycast::voxels_in_view,
//                          256x144 rays) on the sampled frames
//       vfc_mean           objects passing view-frustum culling alone (AABB)
//       ob_voxels_mean, ob_objects_mean (with /ob:W) voxels and objects or
//                          TBVs the buffer proved hidden per frame
//       cells_mean, cells_hidden_mean (with /ob:W) cells of the pyramid the
//                          traversal entered, and skipped whole as hidden
//       traverse_us, render_us, retest_us, bookkeeping_us  where time_us
//                          went, means per frame: the traversal, drawing
//                          occluders (within it), the tests beyond the grid
//                          and of the PVS against the finished buffer, and
//                          the rest (TBVs, claims, queues, the answer)
//     exact_mean and vfc_mean are computed once, outside the timed loop, on
//     every 20th frame of the path (they depend on neither grid nor buffer).
//
//   walkthrough/resolution/grid:200x120x200:100x60x100
//     The walkthrough on both grids at the default options, each frame
//     answered on one then the other (BM_Resolution): ratio_of_least (the
//     median over frames of each frame's least time, fine over coarse),
//     ratio_median (per-step ratios) and ratio_of_medians; the issue's
//     resolution target reads ratio_of_least.
//
//   hidden_dynamic/n:N
//     A fixed camera looks at 200 static spheres in front of a wall that
//     fills its view; N = 1,000 / 10,000 / 100,000 small dynamic spheres sit
//     behind the wall (8 are nudged every 64th frame). A warm-up of 120
//     frames at 60 fps puts them under TBVs; then 600 timed frames at 60 fps. Per-frame time should
//     barely depend on N: compare median_us of n:100000 against n:1000
//     (run_bench.sh prints the ratio; the goal is at most +20%). max_us,
//     p99_us and tbvs_expired_total/tbvs_created_total show the cost of TBV
//     expiry waves inside the timed window; other_median_us is the median
//     of the frame's time outside its traversal and retest (TBV
//     renewals, claims, the answer); revealed_total counts TBVs
//     revealed in it (hidden objects woken). With /ob:256 the same with the
//     occlusion buffer at 256 pixels. hidden_dynamic/region/n:N/ob:256: the
//     same frames for a region (eyes 4 wide, every direction, 100 ms).
//     hidden_dynamic/steady[/region]/n:N/ob:256: the same 600 frames after
//     a warm-up of 1,800 (30 s): the renewals' steady rate, past the
//     TBVs' first periods.
//
//   viewers/voxel_world/n:V, viewers/walkthrough[/moves]/n:V
//     V = 1, 2, 4 viewers of one scene, each on its own thread with its own
//     Scratch, 100 frames each per iteration (BM_Viewers); /moves: viewer 0
//     also applies the walkthrough's moves before each of its frames.
//     answers_per_s (all viewers, wall time), median_us, p99_us.
//
//   ticks/walkthrough[/moves]/n:V/ob:128, ticks/indoor/n:24/ob:160
//     The server's Tick without the server (BM_Ticks): each tick, the moves
//     (/moves), then V viewers' frames at one scene time on two worker
//     threads, the next tick when all are done. answers_per_s,
//     tick_median_ms, tick_p99_ms, busy (engine time over both workers' wall
//     time), and per tick the TBVs renewed, created and revealed.
//
//   mesh_move/triangles:5120
//     64 dynamic meshes (icospheres of 5,120 triangles, 6 voxels across)
//     each moved by a voxel and turned per batch, no viewer: us_per_move
//     (BM_MeshMove).
//
//   mesh_build/triangles:N
//     One static mesh of N triangles (a terrain over 256 x 64 x 256 voxels):
//     Scene::estimate and Scene::create's time, the voxels holding it, and a
//     first frame (BM_MeshBuild).
//
// Filter with --benchmark_filter=walkthrough, hidden_dynamic, indoor, voxel_world,
// city, viewers, ticks or mesh_build (a regular expression: 'city/ob:256', 'ob:(128|512)').
#include <benchmark/benchmark.h>

#include <algorithm>
#include <atomic>
#include <barrier>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <mutex>
#include <thread>
#include <memory>
#include <string>
#include <unordered_set>
#include <vector>

#include <glm/common.hpp>

#include "meshes.h"
#include "scenes.h"
#include "voxvis/generate.h"
#include "voxvis/mesh.h"
#include "voxvis/raycast.h"
#include "voxvis/scene.h"

namespace voxvis::bench {
namespace {

using raycast::RaySampling;

/// A recorded camera path (with moves, for the walkthrough) and its ground
/// truth on every 20th frame, computed once.
struct Recording {
  SceneDesc scene;
  std::vector<FrameInput> frames;
  double dt = 1.0 / 60.0;
  std::vector<int> sampled;  ///< Frame indices.
  double exact_mean = 0.0;
  double vfc_mean = 0.0;
  /// Voxels in view on the sampled frames (raycast::voxels_in_view at
  /// kInViewCols x kInViewRows rays), on the scene's own grid; 0 when the
  /// scene names none.
  std::vector<double> in_view;
};

enum class Path { Walkthrough, Indoor, Surface, Cave, City, IndoorMeshes, CityMeshes, Arena };

/// The exactly visible set is the ray caster's at 1024 x 576 jittered rays
/// (one per cell) on every 20th frame. The caster samples, so this is a
/// lower bound of the visible set; at 256 x 144 it missed a quarter of the
/// voxel world's visible blocks (docs/performance.md, "The reference").
constexpr int kExactCols = 1024, kExactRows = 576, kSampleEvery = 20;
/// Region rows score every this many frames against the sampled region.
constexpr std::size_t kRegionSampleEvery = 30;
/// Rays for the voxels in view (one per cell centre).
constexpr int kInViewCols = 256, kInViewRows = 144;

Recording record(Path which) {
  Recording out;
  if (which == Path::Walkthrough) {
    out.scene = make_paper_scene(PaperSceneParams{});
    out.frames = make_walkthrough(out.scene, WalkthroughParams{});
    if (out.frames.size() >= 2) out.dt = out.frames[1].t - out.frames[0].t;
  } else if (which == Path::Arena) {
    ArenaLevel a = make_arena(4, 24, 200, 3);
    out.scene = std::move(a.scene);
    out.frames = std::move(a.frames);
    if (out.frames.size() >= 2) out.dt = out.frames[1].t - out.frames[0].t;
  } else {
    const bool indoor = which == Path::Indoor || which == Path::IndoorMeshes;
    const bool city = which == Path::City || which == Path::CityMeshes;
    test::ScenePath p = indoor ? test::make_indoor_level(6, 3, 200, 7)
                        : city ? test::make_city(8, 200, 5)
                               : test::make_voxel_world(64, 200, which == Path::Cave, 11);
    out.scene = std::move(p.scene);
    if (which == Path::IndoorMeshes || which == Path::CityMeshes) {
      // The same layout with every box a mesh of 12 triangles.
      for (ObjectDesc& o : out.scene.objects)
        if (o.shape == Shape::Box && !o.dynamic)
          o = test::mesh_object(o.id, test::cube_mesh(o.half_extent), o.center, Quat(1.0, 0.0, 0.0, 0.0), 1.0);
    }
    for (std::size_t k = 0; k < p.cameras.size(); ++k) {
      FrameInput f;
      f.t = static_cast<double>(k) * out.dt;
      f.camera = p.cameras[k];
      out.frames.push_back(std::move(f));
    }
  }
  std::vector<ObjectDesc> objects = out.scene.objects;
  double exact = 0.0, vfc = 0.0;
  const bool grid = out.scene.grid.has_value();
  for (std::size_t k = 0; k < out.frames.size(); ++k) {
    test::apply_moves_to(&objects, out.frames[k].moves);
    if (k % kSampleEvery != 0) continue;
    RaySampling s;
    s.cols = kExactCols;
    s.rows = kExactRows;
    s.seed = k;
    exact += static_cast<double>(raycast::visible_objects(objects, out.frames[k].camera, s).size());
    vfc += static_cast<double>(raycast::frustum_objects(objects, out.frames[k].camera).size());
    RaySampling centres;
    centres.cols = kInViewCols;
    centres.rows = kInViewRows;
    centres.jitter = false;
    out.in_view.push_back(grid ? static_cast<double>(raycast::voxels_in_view(objects, out.frames[k].camera,
                                                                          out.scene.bounds_min, out.scene.bounds_max,
                                                                          *out.scene.grid, centres))
                               : 0.0);
    out.sampled.push_back(static_cast<int>(k));
  }
  const double n = static_cast<double>(std::max<std::size_t>(1, out.sampled.size()));
  out.exact_mean = exact / n;
  out.vfc_mean = vfc / n;
  return out;
}

const Recording& recording(Path which) {
  static std::map<Path, Recording> cache;
  auto it = cache.find(which);
  if (it == cache.end()) it = cache.emplace(which, record(which)).first;
  return it->second;
}

/// For the voxel world: how many of `pvs` are blocks whose every face
/// towards the eye lies against another block, so that the eye can see them
/// only along an edge or at a corner, where a ray meets them and their
/// neighbours at the same depth. The ray caster counts such a tie as
/// visible (voxvis/raycast.h), so the engine must keep them; the caster's sampled
/// rays never land exactly on an edge, so it never finds them. The count
/// shows how much of the gap to exact_mean is that.
int edge_only_blocks(const SceneDesc& scene, const Camera& cam, const std::vector<ObjectId>& pvs) {
  const glm::ivec3 res(scene.bounds_max - scene.bounds_min);
  std::vector<ObjectId> at(static_cast<std::size_t>(res.x) * res.y * res.z, 0);
  auto index = [&](const glm::ivec3& v) -> long {
    if (v.x < 0 || v.y < 0 || v.z < 0 || v.x >= res.x || v.y >= res.y || v.z >= res.z) return -1;
    return v.x + res.x * (v.y + static_cast<long>(res.y) * v.z);
  };
  std::map<ObjectId, glm::ivec3> where;
  for (const ObjectDesc& o : scene.objects) {
    const glm::ivec3 v(glm::floor(o.center - scene.bounds_min));
    if (const long i = index(v); i >= 0) at[static_cast<std::size_t>(i)] = o.id;
    where[o.id] = v;
  }
  int n = 0;
  for (ObjectId id : pvs) {
    const glm::ivec3 v = where.at(id);
    bool covered = true;
    for (int a = 0; a < 3 && covered; ++a) {
      const double e = cam.eye[a] - scene.bounds_min[a];
      if (e >= v[a] && e <= v[a] + 1) continue;  // No face towards the eye along a.
      glm::ivec3 u = v;
      u[a] += e < v[a] ? -1 : 1;
      const long i = index(u);
      covered = i >= 0 && at[static_cast<std::size_t>(i)] != 0;
    }
    n += covered ? 1 : 0;
  }
  return n;
}

/// Frame index of replay step s: 0, 1, ..., n-1, n-2, ..., 1, 0, 1, ...
std::size_t ping_pong(std::size_t s, std::size_t n) {
  if (n <= 1) return 0;
  const std::size_t period = 2 * (n - 1);
  const std::size_t r = s % period;
  return r < n ? r : period - r;
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const std::size_t i = static_cast<std::size_t>(std::floor(pos));
  const std::size_t j = std::min(v.size() - 1, i + 1);
  const double w = pos - static_cast<double>(i);
  return v[i] * (1.0 - w) + v[j] * w;
}

/// Replays a recording ping-pong, one frame per iteration; grid 0 keeps the
/// scene's own.
/// The fastest the camera of a recording moves, units a second.
double path_speed(const Recording& rec) {
  double fastest = 0.0;
  for (std::size_t k = 1; k < rec.frames.size(); ++k)
    fastest = std::max(fastest, glm::length(rec.frames[k].camera.eye - rec.frames[k - 1].camera.eye) / rec.dt);
  return fastest;
}

/// A region over a camera: what `lookahead` seconds at `speed` reach (the
/// eye box a quarter as high as it is wide), every direction when `omni`.
Camera with_region(Camera c, double lookahead, double speed, bool omni) {
  if (lookahead <= 0.0) return c;
  const double r = speed * lookahead;
  c.eye_extent = Vec3(r, 0.25 * r, r);
  c.omnidirectional = omni;
  c.horizon_s = lookahead;
  return c;
}

void BM_Region(benchmark::State& state, Path which, glm::ivec3 grid, int ob, double lookahead_ms, bool omni) {
  const Recording& rec = recording(which);
  if (rec.frames.empty()) {
    state.SkipWithError("empty path");
    return;
  }
  SceneDesc desc = rec.scene;
  if (grid.x > 0) desc.grid = grid;
  std::unique_ptr<Scene> scene;
  SceneOptions options;
  options.occlusion_buffer = ob;
  if (const Status st = Scene::create(desc, options, &scene); !st.ok) {
    state.SkipWithError(("Scene::create: " + st.str()).c_str());
    return;
  }
  Scratch scratch;
  const ViewerId viewer = scene->add_viewer();
  const std::size_t n = rec.frames.size();
  std::size_t step = 0;
  FrameResult result;
  std::vector<ObjectDesc> objects = desc.objects;  // For frustum culling alone.
  const double speed = path_speed(rec), lookahead = lookahead_ms * 1e-3;
  std::unordered_set<ObjectId> dynamic_ids;
  for (const ObjectDesc& o : desc.objects)
    if (o.dynamic) dynamic_ids.insert(o.id);
  auto run_step = [&]() -> bool {
    const std::size_t k = ping_pong(step, n);
    const double t = static_cast<double>(step) * rec.dt;
    ++step;
    if (!rec.frames[k].moves.empty()) {
      if (!scene->apply_moves(t, rec.frames[k].moves).ok) return false;
      test::apply_moves_to(&objects, rec.frames[k].moves);
    }
    return scene->frame(viewer, with_region(rec.frames[k].camera, lookahead, speed, omni), t, scratch, &result).ok;
  };
  // Warm-up: the first frame treats everything as visible.
  for (int i = 0; i < 10; ++i) {
    if (!run_step()) {
      state.SkipWithError("warm-up frame failed");
      return;
    }
  }
  std::vector<double> times, vfc_times;
  double voxels = 0.0, ob_voxels = 0.0, ob_objects = 0.0, pvs = 0.0, cells = 0.0, cells_hidden = 0.0;
  double traverse = 0.0, render = 0.0, retest = 0.0, whole = 0.0, movers = 0.0;
  std::vector<double> pvs_at(n, -1.0), voxels_at(n, -1.0);
  std::vector<int> edge_only(n, 0);
  // Regions: on every kRegionSampleEvery-th frame, the sampled region's
  // visible set (raycast::region_visible) against the answer: misses, and
  // the players (dynamic objects) each holds.
  double region_missed = 0.0, region_seen_players = 0.0, region_pvs_players = 0.0;
  int region_samples = 0;
  for (auto _ : state) {
    const std::size_t k = ping_pong(step, n);
    if (!run_step()) {
      state.SkipWithError("frame failed");
      break;
    }
    times.push_back(result.stats.time_us);
    voxels += static_cast<double>(result.stats.voxels_visited);
    ob_voxels += static_cast<double>(result.stats.ob_voxels_culled);
    ob_objects += static_cast<double>(result.stats.ob_objects_culled);
    cells += static_cast<double>(result.stats.cells_visited);
    cells_hidden += static_cast<double>(result.stats.cells_hidden);
    traverse += result.stats.traverse_us;
    render += result.stats.render_us;
    retest += result.stats.retest_us;
    whole += result.stats.time_us;
    pvs += static_cast<double>(result.pvs.size());
    for (ObjectId id : result.pvs) movers += dynamic_ids.count(id) ? 1.0 : 0.0;
    if (pvs_at[k] < 0.0 && lookahead > 0.0 && k % kRegionSampleEvery == 0) {
      raycast::RegionSampling sampling;
      // 49 eyes and 8 placements: on the arena (omnidirectional, 100 ms) the
      // sampled set grows from 2.86 players (13 eyes, 2 placements) to 4.14,
      // and to 4.57 with 209 eyes and 24 placements (docs/performance.md).
      sampling.random_eyes = 40;
      sampling.placements = 8;
      sampling.rays = raycast::RaySampling{24, 24};
      sampling.seed = k + 1;
      const Camera cam = with_region(rec.frames[k].camera, lookahead, speed, omni);
      for (ObjectId id : raycast::region_visible(objects, cam, sampling)) {
        region_missed += std::binary_search(result.pvs.begin(), result.pvs.end(), id) ? 0.0 : 1.0;
        region_seen_players += dynamic_ids.count(id) ? 1.0 : 0.0;
      }
      for (ObjectId id : result.pvs) region_pvs_players += dynamic_ids.count(id) ? 1.0 : 0.0;
      ++region_samples;
    }
    if (pvs_at[k] < 0.0) {
      pvs_at[k] = static_cast<double>(result.pvs.size());
      voxels_at[k] = static_cast<double>(result.stats.voxels_visited);
      if (k % kSampleEvery == 0 && (which == Path::Surface || which == Path::Cave))
        edge_only[k] = edge_only_blocks(desc, rec.frames[k].camera, result.pvs);
    }
    benchmark::DoNotOptimize(result.pvs.data());
    const auto v0 = std::chrono::steady_clock::now();
    const std::vector<ObjectId> in_frustum = raycast::frustum_objects(objects, rec.frames[k].camera);
    benchmark::DoNotOptimize(in_frustum.data());
    vfc_times.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - v0).count());
  }
  const double frames = static_cast<double>(std::max<std::size_t>(1, times.size()));
  state.counters["median_us"] = percentile(times, 0.5);
  state.counters["p99_us"] = percentile(times, 0.99);
  state.counters["vfc_median_us"] = percentile(vfc_times, 0.5);
  state.counters["voxels_mean"] = voxels / frames;
  state.counters["pvs_mean"] = pvs / frames;
  state.counters["dynamic_in_pvs_mean"] = movers / frames;
  if (lookahead > 0.0) {
    state.counters["region_reach"] = speed * lookahead;
    state.counters["region_missed"] = region_missed;
    state.counters["region_samples"] = region_samples;
    if (region_samples > 0) {
      state.counters["region_seen_players_mean"] = region_seen_players / region_samples;
      state.counters["region_pvs_players_mean"] = region_pvs_players / region_samples;
    }
  }
  state.counters["traverse_us"] = traverse / frames;
  state.counters["render_us"] = render / frames;
  state.counters["retest_us"] = retest / frames;
  state.counters["bookkeeping_us"] = (whole - traverse - retest) / frames;
  if (ob > 0) {
    state.counters["ob_voxels_mean"] = ob_voxels / frames;
    state.counters["ob_objects_mean"] = ob_objects / frames;
    state.counters["cells_mean"] = cells / frames;
    state.counters["cells_hidden_mean"] = cells_hidden / frames;
  }
  double sub = 0.0, sub_edge = 0.0, sub_voxels = 0.0, sub_in_view = 0.0;
  int sub_n = 0;
  for (std::size_t i = 0; i < rec.sampled.size(); ++i) {
    const auto k = static_cast<std::size_t>(rec.sampled[i]);
    if (pvs_at[k] >= 0.0) {
      sub += pvs_at[k];
      sub_edge += edge_only[k];
      sub_voxels += voxels_at[k];
      sub_in_view += rec.in_view[i];
      ++sub_n;
    }
  }
  // Voxels visited against voxels in view, on the same frames and the
  // scene's own grid.
  if (grid.x == 0 && sub_in_view > 0.0) {
    state.counters["voxels_sub_mean"] = sub_voxels / sub_n;
    state.counters["in_view_mean"] = sub_in_view / sub_n;
  }
  state.counters["pvs_sub_mean"] = sub_n ? sub / sub_n : 0.0;
  if (which == Path::Surface || which == Path::Cave) state.counters["edge_only_mean"] = sub_n ? sub_edge / sub_n : 0.0;
  state.counters["exact_mean"] = rec.exact_mean;
  state.counters["vfc_mean"] = rec.vfc_mean;
  state.counters["objects"] = static_cast<double>(desc.objects.size());
  state.SetItemsProcessed(static_cast<std::int64_t>(times.size()));
}

/// A path of point cameras.
void BM_Path(benchmark::State& state, Path which, glm::ivec3 grid, int ob) {
  BM_Region(state, which, grid, ob, 0.0, false);
}

/// The walkthrough on two grids at once, the default options: each step
/// applies the frame's moves to both scenes and answers it on both, in
/// turn (which goes first alternates), so that the host's noise falls on
/// both alike. Reports each grid's median frame time, the median over steps
/// of the per-step ratio fine / coarse, and the ratio of the medians, over
/// frame indices, of each index's least time (the steadiest figure on a
/// shared machine). An iteration is one step; 1,794 steps are three
/// ping-pong cycles, six visits of each frame.
void BM_Resolution(benchmark::State& state, glm::ivec3 coarse, glm::ivec3 fine) {
  const Recording& rec = recording(Path::Walkthrough);
  std::unique_ptr<Scene> scenes[2];
  for (int i = 0; i < 2; ++i) {
    SceneDesc desc = rec.scene;
    desc.grid = i == 0 ? coarse : fine;
    if (const Status st = Scene::create(desc, SceneOptions{}, &scenes[i]); !st.ok) {
      state.SkipWithError(("Scene::create: " + st.str()).c_str());
      return;
    }
  }
  Scratch scratch[2];
  const ViewerId viewer[2] = {scenes[0]->add_viewer(), scenes[1]->add_viewer()};
  const std::size_t n = rec.frames.size();
  std::size_t step = 0;
  FrameResult result;
  double last[2] = {0.0, 0.0};
  auto run_step = [&]() -> bool {
    const std::size_t k = ping_pong(step, n);
    const double t = static_cast<double>(step) * rec.dt;
    for (int j = 0; j < 2; ++j) {
      const int i = (j + static_cast<int>(step & 1)) & 1;
      if (!rec.frames[k].moves.empty() && !scenes[i]->apply_moves(t, rec.frames[k].moves).ok) return false;
      if (!scenes[i]->frame(viewer[i], rec.frames[k].camera, t, scratch[i], &result).ok) return false;
      last[i] = result.stats.time_us;
    }
    ++step;
    return true;
  };
  for (int i = 0; i < 10; ++i) {
    if (!run_step()) {
      state.SkipWithError("warm-up frame failed");
      return;
    }
  }
  std::vector<double> times[2], ratios;
  std::vector<double> least[2] = {std::vector<double>(n, HUGE_VAL), std::vector<double>(n, HUGE_VAL)};
  for (auto _ : state) {
    const std::size_t k = ping_pong(step, n);
    if (!run_step()) {
      state.SkipWithError("frame failed");
      break;
    }
    for (int i = 0; i < 2; ++i) {
      times[i].push_back(last[i]);
      least[i][k] = std::min(least[i][k], last[i]);
    }
    if (last[0] > 0.0) ratios.push_back(last[1] / last[0]);
  }
  for (auto& v : least) v.erase(std::remove(v.begin(), v.end(), HUGE_VAL), v.end());
  const double m0 = percentile(times[0], 0.5), m1 = percentile(times[1], 0.5);
  const double l0 = percentile(least[0], 0.5), l1 = percentile(least[1], 0.5);
  state.counters["coarse_median_us"] = m0;
  state.counters["fine_median_us"] = m1;
  state.counters["ratio_of_medians"] = m0 > 0.0 ? m1 / m0 : 0.0;
  state.counters["ratio_median"] = percentile(ratios, 0.5);
  state.counters["coarse_least_us"] = l0;
  state.counters["fine_least_us"] = l1;
  state.counters["ratio_of_least"] = l0 > 0.0 ? l1 / l0 : 0.0;
  state.SetItemsProcessed(static_cast<std::int64_t>(times[0].size()));
}

/// The fixed-PVS scene of hidden_dynamic: bounds 100 x 60 x 100 on a
/// 100x60x100 grid (unit voxels); a wall filling z in [45, 50] (and reaching
/// far beyond the bounds); 200 static spheres at z in [55, 85]; n dynamic
/// spheres (radius 0.2, max_speed 1) behind the wall; the camera at
/// (50, 30, 95) looking down -z.
struct HiddenScene {
  SceneDesc desc;
  Camera cam;
  std::vector<ObjectId> hidden;
};

HiddenScene make_hidden_scene(int n) {
  HiddenScene h;
  h.desc.bounds_min = Vec3(0.0);
  h.desc.bounds_max = Vec3(100.0, 60.0, 100.0);
  h.desc.grid = glm::ivec3(100, 60, 100);
  ObjectDesc wall;
  wall.id = 1;
  wall.shape = Shape::Box;
  wall.center = Vec3(50.0, 30.0, 47.5);
  wall.half_extent = Vec3(150.0, 130.0, 2.5);
  h.desc.objects.push_back(wall);
  test::Rng rng(4242);
  ObjectId id = 2;
  for (int i = 0; i < 200; ++i) {
    ObjectDesc o;
    o.id = id++;
    o.shape = Shape::Sphere;
    o.radius = rng.uniform(0.3, 1.5);
    o.center = rng.in_box(Vec3(25.0, 10.0, 55.0), Vec3(75.0, 50.0, 85.0));
    h.desc.objects.push_back(o);
  }
  for (int i = 0; i < n; ++i) {
    ObjectDesc o;
    o.id = id++;
    o.shape = Shape::Sphere;
    o.radius = 0.2;
    o.center = rng.in_box(Vec3(1.0, 1.0, 1.0), Vec3(99.0, 59.0, 43.0));
    o.dynamic = true;
    o.max_speed = 1.0;
    h.desc.objects.push_back(o);
    h.hidden.push_back(o.id);
  }
  h.cam.eye = Vec3(50.0, 30.0, 95.0);
  h.cam.dir = Vec3(0.0, 0.0, -1.0);
  h.cam.up = Vec3(0.0, 1.0, 0.0);
  h.cam.fov_y_deg = 60.0;
  h.cam.aspect = 16.0 / 9.0;
  h.cam.near = 0.05;
  h.cam.far = 1000.0;
  return h;
}

void BM_HiddenDynamic(benchmark::State& state, int n, int ob, bool region, int warmup) {
  HiddenScene h = make_hidden_scene(n);
  if (region) {  // Eyes 4 wide, every direction, 100 ms ahead.
    h.cam.eye_extent = Vec3(2.0);
    h.cam.omnidirectional = true;
    h.cam.horizon_s = 0.1;
  }
  std::unique_ptr<Scene> scene;
  SceneOptions options;
  options.occlusion_buffer = ob;
  if (const Status st = Scene::create(h.desc, options, &scene); !st.ok) {
    state.SkipWithError(("Scene::create: " + st.str()).c_str());
    return;
  }
  Scratch scratch;
  const ViewerId viewer = scene->add_viewer();
  const double dt = 1.0 / 60.0;
  std::size_t step = 0;
  FrameResult result;
  // Rare small moves: every 64th frame, 8 distinct hidden objects move
  // 0.9 * max_speed * dt (far below their speed limit over 64 frames).
  std::vector<Vec3> centers;
  for (std::size_t i = 0; i < h.hidden.size(); ++i) centers.push_back(h.desc.objects[201 + i].center);
  std::size_t next_mover = 0;
  std::vector<Move> moves;
  double t = 0.0;
  auto run_step = [&]() -> bool {
    t += dt;
    if (step % 64 == 63 && !h.hidden.empty()) {
      moves.clear();
      for (std::size_t j = 0; j < std::min<std::size_t>(8, h.hidden.size()); ++j) {
        const std::size_t i = next_mover++ % h.hidden.size();
        centers[i].x += (centers[i].x < 50.0 ? 0.9 : -0.9) * dt;
        moves.push_back({h.hidden[i], centers[i]});
      }
      if (!scene->apply_moves(t, moves).ok) return false;
    }
    ++step;
    return scene->frame(viewer, h.cam, t, scratch, &result).ok;
  };
  // Warm-up: the first frame sees everything; then hidden objects get TBVs
  // (2 s of scene time at 60 fps). The timed window then covers the TBVs'
  // first expiry-and-renewal cycles (automatic periods start at 2 s and
  // double, or at 11.5-15.3 s deep in unseen space, most of the objects
  // here);
  // median_us is the steady per-frame cost, p99_us/max_us show the frames
  // where many TBVs expire together.
  for (int i = 0; i < warmup; ++i) {
    if (!run_step()) {
      state.SkipWithError("warm-up frame failed");
      return;
    }
  }
  std::vector<double> times, others;
  double pvs = 0.0;
  double voxels = 0.0;
  double tbvs = 0.0;
  double expired = 0.0;
  double created = 0.0;
  double revealed = 0.0;
  double woken = 0.0;
  double hidden_in_pvs = 0.0;
  const ObjectId first_hidden = h.hidden.empty() ? 0 : h.hidden.front();
  for (auto _ : state) {
    if (!run_step()) {
      state.SkipWithError("frame failed");
      break;
    }
    times.push_back(result.stats.time_us);
    const FrameStats& fs = result.stats;
    others.push_back(fs.time_us - fs.traverse_us - fs.retest_us);  // render_us is within traverse_us.
    pvs += static_cast<double>(result.pvs.size());
    voxels += static_cast<double>(result.stats.voxels_visited);
    tbvs += static_cast<double>(result.stats.tbvs_active);
    expired += static_cast<double>(result.stats.tbvs_expired);
    created += static_cast<double>(result.stats.tbvs_created);
    revealed += static_cast<double>(result.stats.tbvs_revealed);
    woken += static_cast<double>(result.wake.size());
    hidden_in_pvs += static_cast<double>(
        std::count_if(result.pvs.begin(), result.pvs.end(), [&](ObjectId id) { return id >= first_hidden; }));
    benchmark::DoNotOptimize(result.pvs.data());
  }
  const double frames = static_cast<double>(std::max<std::size_t>(1, times.size()));
  state.counters["median_us"] = percentile(times, 0.5);
  state.counters["p99_us"] = percentile(times, 0.99);
  state.counters["other_median_us"] = percentile(others, 0.5);
  state.counters["pvs_mean"] = pvs / frames;
  state.counters["voxels_mean"] = voxels / frames;
  state.counters["tbvs_active_mean"] = tbvs / frames;
  state.counters["max_us"] = times.empty() ? 0.0 : *std::max_element(times.begin(), times.end());
  state.counters["tbvs_expired_total"] = expired;
  state.counters["tbvs_created_total"] = created;
  state.counters["revealed_total"] = revealed;
  state.counters["woken_total"] = woken;
  state.counters["hidden_in_pvs_total"] = hidden_in_pvs;
  state.counters["hidden"] = static_cast<double>(n);
  state.SetItemsProcessed(static_cast<std::int64_t>(times.size()));
}

/// The recording's scene on `grid` (its own when grid.x is 0) with the
/// occlusion buffer `ob` pixels wide (0: off); null, the benchmark skipped
/// with the engine's error, when it cannot be built.
std::unique_ptr<Scene> recording_scene(benchmark::State& state, const Recording& rec, glm::ivec3 grid, int ob) {
  SceneDesc desc = rec.scene;
  if (grid.x > 0) desc.grid = grid;
  SceneOptions options;
  options.occlusion_buffer = ob;
  std::unique_ptr<Scene> scene;
  if (const Status st = Scene::create(desc, options, &scene); !st.ok) {
    state.SkipWithError(("Scene::create: " + st.str()).c_str());
    return nullptr;
  }
  return scene;
}

/// Frames of `viewers` viewers of one scene, each on its own thread with its
/// own Scratch, walking the recording from its own start; with `moves`,
/// viewer 0 also applies the recording's moves before each of its frames, as
/// a simulation backend would (without, the dynamic objects stand still, but
/// their TBVs still expire and are revealed). One iteration: 100 frames a
/// viewer. Reports answers per second of wall time (all viewers) and the
/// median frame time.
void BM_Viewers(benchmark::State& state, Path which, glm::ivec3 grid, int viewers, bool moves, int ob) {
  constexpr int kFrames = 100;
  const Recording& rec = recording(which);
  // The buffer off (the names without /ob:, as in docs/performance.md's
  // first table, measured before the buffer became the default) or at `ob`.
  const std::unique_ptr<Scene> scene = recording_scene(state, rec, grid, ob);
  if (!scene) return;
  const std::size_t n = rec.frames.size();
  std::vector<ViewerId> ids;
  std::vector<Scratch> scratch(static_cast<std::size_t>(viewers));
  for (int v = 0; v < viewers; ++v) ids.push_back(scene->add_viewer());
  std::size_t round = 0;
  std::mutex times_mu;
  std::vector<double> times;
  bool failed = false;
  auto run_viewer = [&](int v, std::size_t first) {
    FrameResult result;
    std::vector<double> own;
    for (int i = 0; i < kFrames; ++i) {
      const std::size_t step = first + static_cast<std::size_t>(i);
      const std::size_t k = ping_pong(step + static_cast<std::size_t>(v) * n / static_cast<std::size_t>(viewers), n);
      const double t = static_cast<double>(step) * rec.dt;
      if (v == 0 && moves && !rec.frames[k].moves.empty() &&
          !scene->apply_moves(t, rec.frames[k].moves, nullptr, Scene::Clock::Latest).ok) {
        std::lock_guard<std::mutex> lock(times_mu);
        failed = true;
        return;
      }
      if (!scene->frame(ids[static_cast<std::size_t>(v)], rec.frames[k].camera, t,
                        scratch[static_cast<std::size_t>(v)], &result, Scene::Clock::Latest)
               .ok) {
        std::lock_guard<std::mutex> lock(times_mu);
        failed = true;
        return;
      }
      own.push_back(result.stats.time_us);
    }
    std::lock_guard<std::mutex> lock(times_mu);
    times.insert(times.end(), own.begin(), own.end());
  };
  run_viewer(0, 0);  // Warm-up: the first frames treat everything as visible.
  times.clear();
  double wall = 0.0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    ++round;
    std::vector<std::thread> threads;
    for (int v = 0; v < viewers; ++v) threads.emplace_back(run_viewer, v, round * kFrames);
    for (std::thread& th : threads) th.join();
    wall += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (failed) {
      state.SkipWithError("a frame or move failed");
      break;
    }
  }
  state.counters["answers_per_s"] = wall > 0.0 ? static_cast<double>(times.size()) / wall : 0.0;
  state.counters["median_us"] = percentile(times, 0.5);
  state.counters["p99_us"] = percentile(times, 0.99);
  state.counters["viewers"] = viewers;
}

/// Ticks as the server runs them: every tick, the moves (with `moves`),
/// then the frames of `viewers` viewers of one scene at the same scene time,
/// shared by two worker threads (the 2-core machine's pool), and the next
/// tick only when all are answered. Each viewer walks the recording from its
/// own start. One iteration: 100 ticks. Reports answers per second of wall
/// time, the median tick, the workers' busy share (engine time over 2 x
/// wall), and per tick the TBVs renewed, created and revealed.
void BM_Ticks(benchmark::State& state, Path which, glm::ivec3 grid, int viewers, bool moves, int ob) {
  constexpr int kTicks = 100;
  constexpr int kWorkers = 2;
  const Recording& rec = recording(which);
  const std::unique_ptr<Scene> scene = recording_scene(state, rec, grid, ob);
  if (!scene) return;
  const std::size_t n = rec.frames.size();
  std::vector<ViewerId> ids;
  for (int v = 0; v < viewers; ++v) ids.push_back(scene->add_viewer());
  std::vector<Scratch> scratch(kWorkers);
  std::vector<FrameResult> results(static_cast<std::size_t>(viewers));
  std::atomic<int> next{0};
  std::atomic<bool> failed{false}, stop{false};
  std::size_t step = 0;
  std::barrier sync(kWorkers + 1);
  auto worker = [&](int k) {
    for (;;) {
      sync.arrive_and_wait();  // A tick starts (or the run ends).
      if (stop.load()) return;
      for (int v; (v = next.fetch_add(1)) < viewers;) {
        const std::size_t f = ping_pong(step + static_cast<std::size_t>(v) * n / static_cast<std::size_t>(viewers), n);
        if (!scene->frame(ids[static_cast<std::size_t>(v)], rec.frames[f].camera, static_cast<double>(step) * rec.dt,
                          scratch[static_cast<std::size_t>(k)], &results[static_cast<std::size_t>(v)])
                 .ok)
          failed = true;
      }
      sync.arrive_and_wait();  // The tick's frames are done.
    }
  };
  std::vector<std::thread> threads;
  for (int k = 0; k < kWorkers; ++k) threads.emplace_back(worker, k);
  std::vector<double> tick_ms, frame_us;
  double wall = 0.0, engine_us = 0.0;
  std::uint64_t renewed = 0, created = 0, revealed = 0;
  auto tick = [&](bool timed) {
    const double t = static_cast<double>(step) * rec.dt;
    const auto t0 = std::chrono::steady_clock::now();
    if (moves && !rec.frames[ping_pong(step, n)].moves.empty() &&
        !scene->apply_moves(t, rec.frames[ping_pong(step, n)].moves, nullptr).ok)
      failed = true;
    next = 0;
    sync.arrive_and_wait();
    sync.arrive_and_wait();
    const double dt = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ++step;
    if (!timed) return;
    wall += dt;
    tick_ms.push_back(dt * 1e3);
    for (const FrameResult& r : results) {
      frame_us.push_back(r.stats.time_us);
      engine_us += r.stats.time_us;
      renewed += r.stats.tbvs_expired;
      created += r.stats.tbvs_created;
      revealed += r.stats.tbvs_revealed;
    }
  };
  for (int i = 0; i < kTicks; ++i) tick(false);  // Warm-up: the first frames treat everything as visible.
  for (auto _ : state)
    for (int i = 0; i < kTicks && !failed; ++i) tick(true);
  stop = true;
  sync.arrive_and_wait();
  for (std::thread& th : threads) th.join();
  if (failed) {
    state.SkipWithError("a frame or move failed");
    return;
  }
  const double ticks = static_cast<double>(tick_ms.size());
  state.counters["answers_per_s"] = wall > 0.0 ? static_cast<double>(frame_us.size()) / wall : 0.0;
  state.counters["tick_median_ms"] = percentile(tick_ms, 0.5);
  state.counters["tick_p99_ms"] = percentile(tick_ms, 0.99);
  state.counters["frame_median_us"] = percentile(frame_us, 0.5);
  state.counters["busy"] = wall > 0.0 ? engine_us * 1e-6 / (kWorkers * wall) : 0.0;
  state.counters["renewed_per_tick"] = static_cast<double>(renewed) / ticks;
  state.counters["created_per_tick"] = static_cast<double>(created) / ticks;
  state.counters["revealed_per_tick"] = static_cast<double>(revealed) / ticks;
  state.counters["viewers"] = viewers;
}

/// A static level of `triangles` triangles: a rolling terrain heightfield
/// over a 256 x 64 x 256 grid, one mesh. Reports the time of
/// Scene::create (validation, placement, the triangles' voxels, the
/// lists), of Scene::estimate, the voxels holding the mesh, and a first
/// frame's time from above the terrain.
void BM_MeshBuild(benchmark::State& state, int triangles) {
  const int side = static_cast<int>(std::sqrt(triangles / 2.0));
  auto mesh = std::make_shared<Mesh>();
  mesh->vertices.reserve(static_cast<std::size_t>(side + 1) * static_cast<std::size_t>(side + 1));
  for (int j = 0; j <= side; ++j)
    for (int i = 0; i <= side; ++i) {
      const double x = 256.0 * i / side, z = 256.0 * j / side;
      mesh->vertices.push_back(Vec3(x, 20.0 + 8.0 * std::sin(x / 17.0) * std::cos(z / 23.0), z));
    }
  for (int j = 0; j < side; ++j)
    for (int i = 0; i < side; ++i) {
      const auto v = static_cast<std::uint32_t>(j * (side + 1) + i), w = v + static_cast<std::uint32_t>(side + 1);
      mesh->triangles.push_back({v, v + 1, w});
      mesh->triangles.push_back({v + 1, w + 1, w});
    }
  SceneDesc desc;
  desc.bounds_min = Vec3(0.0);
  desc.bounds_max = Vec3(256.0, 64.0, 256.0);
  desc.grid = glm::ivec3(256, 64, 256);
  ObjectDesc o;
  o.id = 1;
  o.shape = Shape::Mesh;
  o.mesh = mesh;
  desc.objects.push_back(o);
  double estimate_s = 0.0, frame_us = 0.0;
  std::uint64_t entries = 0;
  for (auto _ : state) {
    auto t0 = std::chrono::steady_clock::now();
    SceneCost cost;
    if (!Scene::estimate(desc, {}, &cost).ok) {
      state.SkipWithError("estimate failed");
      return;
    }
    estimate_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    entries = cost.id_entries;
    std::unique_ptr<Scene> scene;
    if (!Scene::create(desc, {}, &scene).ok) {
      state.SkipWithError("create failed");
      return;
    }
    Scratch scratch;
    FrameResult r;
    Camera cam;
    cam.eye = Vec3(10.0, 40.0, 10.0);
    cam.dir = Vec3(1.0, -0.3, 1.0);
    cam.far = 1000.0;
    if (!scene->frame(scene->add_viewer(), cam, 0.0, scratch, &r).ok) {
      state.SkipWithError("frame failed");
      return;
    }
    frame_us = r.stats.time_us;
  }
  state.counters["triangles"] = static_cast<double>(mesh->triangles.size());
  state.counters["estimate_s"] = estimate_s;
  state.counters["voxel_entries"] = static_cast<double>(entries);
  state.counters["first_frame_us"] = frame_us;
}

/// Moves of dynamic meshes of about `triangles` triangles (an icosphere of
/// radius 3 voxels): 64 of them in a 128^3 grid, each moved by one voxel per
/// batch, back and forth, turning as it goes, with no viewer (so every one
/// stays discretized: the costly case, no TBV absorbs the move).
void BM_MeshMove(benchmark::State& state, int levels) {
  const std::shared_ptr<const Mesh> mesh = test::icosphere(levels);
  SceneDesc desc;
  desc.bounds_min = Vec3(0.0);
  desc.bounds_max = Vec3(128.0);
  desc.grid = glm::ivec3(128);
  for (int k = 0; k < 64; ++k) {
    ObjectDesc o = test::mesh_object(static_cast<ObjectId>(k + 1), mesh,
                                     Vec3(12.0 + 14.0 * (k % 8), 64.0, 12.0 + 14.0 * (k / 8)), Quat(1.0, 0.0, 0.0, 0.0),
                                     3.0);
    o.dynamic = true;
    o.max_speed = 100.0;
    desc.objects.push_back(o);
  }
  std::unique_ptr<Scene> scene;
  if (!Scene::create(desc, {}, &scene).ok) {
    state.SkipWithError("create failed");
    return;
  }
  std::vector<Move> moves(desc.objects.size());
  double t = 0.0;
  int step = 0;
  for (auto _ : state) {
    t += 0.05;
    ++step;
    for (std::size_t k = 0; k < moves.size(); ++k) {
      moves[k].id = desc.objects[k].id;
      moves[k].center = desc.objects[k].center + Vec3((step & 1) ? 1.0 : 0.0, 0.0, 0.0);
      moves[k].has_rotation = true;
      moves[k].rotation = test::rotation_about(Vec3(0.0, 1.0, 0.0), 0.1 * step);
    }
    MoveReport report;
    if (!scene->apply_moves(t, moves, &report).ok) {
      state.SkipWithError("apply_moves failed");
      return;
    }
  }
  state.counters["triangles"] = static_cast<double>(mesh->triangles.size());
  state.counters["us_per_move"] =
      benchmark::Counter(static_cast<double>(moves.size()), benchmark::Counter::kIsIterationInvariantRate |
                                                                benchmark::Counter::kInvert);
}

void register_all() {
  // The occlusion buffer's widths (SceneOptions::occlusion_buffer), 0 = off.
  const int widths[] = {0, 64, 128, 256, 512};
  auto suffix = [](int ob) { return ob ? "/ob:" + std::to_string(ob) : std::string(); };
  const std::pair<const char*, Path> paths[] = {{"indoor", Path::Indoor},
                                                {"voxel_world/surface", Path::Surface},
                                                {"voxel_world/cave", Path::Cave},
                                                {"city", Path::City},
                                                {"arena", Path::Arena},
                                                {"indoor/meshes", Path::IndoorMeshes},
                                                {"city/meshes", Path::CityMeshes}};
  for (const auto& [name, which] : paths)
    for (int ob : widths)
      benchmark::RegisterBenchmark((name + suffix(ob)).c_str(), BM_Path, which, glm::ivec3(0), ob)
          ->Iterations(398)
          ->Unit(benchmark::kMicrosecond);
  // Regions (docs/design.md, "Regions"): the eye box and horizon of a 50,
  // 100 and 150 ms lookahead at the path's own top speed, in the camera's
  // frustum and in every direction; beside the point rows above.
  const std::pair<const char*, Path> region_paths[] = {
      {"walkthrough", Path::Walkthrough}, {"indoor", Path::Indoor}, {"city", Path::City}, {"arena", Path::Arena}};
  for (const auto& [name, which] : region_paths)
    for (int ms : {50, 100, 150})
      for (bool omni : {false, true}) {
        const std::string n = std::string(name) + "/region:" + std::to_string(ms) + "ms" + (omni ? "/omni" : "");
        const glm::ivec3 grid = which == Path::Walkthrough ? glm::ivec3(100, 60, 100) : glm::ivec3(0);
        benchmark::RegisterBenchmark(n.c_str(), BM_Region, which, grid, 128, static_cast<double>(ms), omni)
            ->Iterations(which == Path::Walkthrough ? 598 : 398)
            ->Unit(benchmark::kMicrosecond);
      }
  const int grids[][3] = {{50, 30, 50}, {100, 60, 100}, {200, 120, 200}};
  for (const auto& g : grids)
    for (int ob : widths) {
      const std::string name = "walkthrough/grid:" + std::to_string(g[0]) + "x" + std::to_string(g[1]) +
                               "x" + std::to_string(g[2]) + suffix(ob);
      // One whole ping-pong cycle of the 300-frame walkthrough per run.
      benchmark::RegisterBenchmark(name.c_str(), BM_Path, Path::Walkthrough, glm::ivec3(g[0], g[1], g[2]), ob)
          ->Iterations(598)
          ->Unit(benchmark::kMicrosecond);
    }
  // The resolution target: the finer grid against the coarser, interleaved.
  benchmark::RegisterBenchmark("walkthrough/resolution/grid:200x120x200:100x60x100", BM_Resolution,
                               glm::ivec3(100, 60, 100), glm::ivec3(200, 120, 200))
      ->Iterations(1794)
      ->Unit(benchmark::kMicrosecond);
  // One scene, several viewers, each frame on its own thread; the buffer
  // off, and at the default width.
  for (int ob : {0, 128})
    for (int v : {1, 2, 4}) {
      const std::string n = "/n:" + std::to_string(v) + suffix(ob);
      benchmark::RegisterBenchmark(("viewers/voxel_world" + n).c_str(), BM_Viewers, Path::Surface,
                                   glm::ivec3(0), v, false, ob)
          ->Iterations(3)
          ->UseRealTime()
          ->Unit(benchmark::kMillisecond);
      benchmark::RegisterBenchmark(("viewers/walkthrough" + n).c_str(), BM_Viewers, Path::Walkthrough,
                                   glm::ivec3(100, 60, 100), v, false, ob)
          ->Iterations(3)
          ->UseRealTime()
          ->Unit(benchmark::kMillisecond);
      benchmark::RegisterBenchmark(("viewers/walkthrough/moves" + n).c_str(), BM_Viewers, Path::Walkthrough,
                                   glm::ivec3(100, 60, 100), v, true, ob)
          ->Iterations(3)
          ->UseRealTime()
          ->Unit(benchmark::kMillisecond);
    }
  // Ticks: the viewers of one scene answered together at one scene time.
  for (int v : {1, 2, 4})
    for (bool moves : {false, true}) {
      const std::string n = std::string(moves ? "/moves" : "") + "/n:" + std::to_string(v) + "/ob:128";
      benchmark::RegisterBenchmark(("ticks/walkthrough" + n).c_str(), BM_Ticks, Path::Walkthrough,
                                   glm::ivec3(100, 60, 100), v, moves, 128)
          ->Iterations(3)
          ->UseRealTime()
          ->Unit(benchmark::kMillisecond);
    }
  // The indoor target's shape: 24 viewers a tick, at the server's default width.
  benchmark::RegisterBenchmark("ticks/indoor/n:24/ob:160", BM_Ticks, Path::Indoor, glm::ivec3(0), 24, false, 160)
      ->Iterations(3)
      ->UseRealTime()
      ->Unit(benchmark::kMillisecond);
  benchmark::RegisterBenchmark("mesh_move/triangles:5120", BM_MeshMove, 4)->Unit(benchmark::kMicrosecond);
  for (int n : {100000, 1000000})
    benchmark::RegisterBenchmark(("mesh_build/triangles:" + std::to_string(n)).c_str(), BM_MeshBuild, n)
        ->Iterations(1)
        ->Unit(benchmark::kMillisecond);
  for (int ob : {0, 256})
    for (int n : {1000, 10000, 100000}) {
      const std::string name = "hidden_dynamic/n:" + std::to_string(n) + suffix(ob);
      // 600 frames: 10 s of scene time at 60 fps.
      benchmark::RegisterBenchmark(name.c_str(), BM_HiddenDynamic, n, ob, false, 120)
          ->Iterations(600)
          ->Unit(benchmark::kMicrosecond);
    }
  for (int n : {1000, 10000, 100000}) {
    const std::string name = "hidden_dynamic/region/n:" + std::to_string(n) + suffix(256);
    benchmark::RegisterBenchmark(name.c_str(), BM_HiddenDynamic, n, 256, true, 120)
        ->Iterations(600)
        ->Unit(benchmark::kMicrosecond);
  }
  // The same after 30 s of frames, when every TBV is past its first
  // periods: the steady rate of renewals rather than the first ones.
  for (const bool region : {false, true})
    for (int n : {1000, 100000}) {
      const std::string name =
          std::string("hidden_dynamic/steady") + (region ? "/region" : "") + "/n:" + std::to_string(n) + suffix(256);
      benchmark::RegisterBenchmark(name.c_str(), BM_HiddenDynamic, n, 256, region, 1800)
          ->Iterations(600)
          ->Unit(benchmark::kMicrosecond);
    }
}

}  // namespace
}  // namespace voxvis::bench

int main(int argc, char** argv) {
  voxvis::bench::register_all();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
