// bench_frame.cpp — Google Benchmark for the per-frame engine cost.
//
//   walkthrough/grid:GXxGYxGZ
//     The paper-like scene (make_paper_scene: 5,000 spheres in clusters, 200
//     dynamic, bounds 100 x 60 x 100) and its walkthrough (make_walkthrough),
//     on grids 50x30x50, 100x60x100 and 200x120x200. Each iteration is one
//     frame: apply_moves, then frame. The walkthrough is replayed forwards
//     then backwards (ping-pong) with time always increasing, so every move
//     stays within max_speed; a run is one whole cycle (598 frames).
//     Counters:
//       median_us, p99_us  engine time per frame (FrameStats::time_us) over
//                          the timed frames
//       voxels_mean        voxels visited per frame
//       pvs_mean           PVS size per frame (all timed frames)
//       pvs_sub_mean       PVS size over the frames the ray caster sampled
//       exact_mean         exactly visible objects (ray caster, 256x144 rays)
//       vfc_mean           objects passing view-frustum culling alone (AABB)
//     exact_mean and vfc_mean are computed once, outside the timed loop, on
//     every 10th frame of the walkthrough (they do not depend on the grid).
//     The benchmark's own time per iteration is the ns/frame including
//     apply_moves.
//
//   hidden_dynamic/n:N
//     A fixed camera looks at 200 static spheres in front of a wall that
//     fills its view; N = 1,000 / 10,000 / 100,000 small dynamic spheres sit
//     behind the wall (8 are nudged every 64th frame). A warm-up of 120
//     frames at 60 fps puts them under TBVs; then 600 timed frames at 60 fps. Per-frame time should
//     barely depend on N: compare median_us of n:100000 against n:1000
//     (run_bench.sh prints the ratio; the goal is at most +20%). max_us,
//     p99_us and tbvs_expired_total/tbvs_created_total show the cost of TBV
//     expiry waves inside the timed window.
//
//   indoor, voxel_world/surface, voxel_world/cave
//     Static scenes on unit voxels whose faces lie on voxel planes
//     (make_indoor_level: 6 x 3 rooms of walls made of abutting boxes;
//     make_voxel_world: 64 x 64 columns of unit blocks with caves) and a
//     200-frame camera path each, replayed ping-pong. Counters as for
//     walkthrough, with exact_mean and vfc_mean on every 10th frame.
//
//   walkthrough/grid:100x60x100/ob:W
//     The same at 100x60x100 with the occlusion buffer W pixels wide
//     (W = 64, 128, 256); extra counters ob_voxels_mean (voxels the buffer
//     proved hidden per frame) and ob_objects_mean (objects and TBVs).
//
// Filter with --benchmark_filter=walkthrough, hidden_dynamic, indoor or voxel_world.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "raycast.h"
#include "scenes.h"
#include "voxvis/generate.h"
#include "voxvis/scene.h"

namespace voxvis::bench {
namespace {

using test::RaySampling;

struct Walkthrough {
  SceneDesc scene;
  std::vector<FrameInput> frames;
  double dt = 1.0 / 60.0;
  // Ground truth on every 10th frame, computed once.
  std::vector<int> sampled;  ///< Frame indices.
  double exact_mean = 0.0;
  double vfc_mean = 0.0;
};

const Walkthrough& walkthrough() {
  static const Walkthrough w = [] {
    Walkthrough out;
    out.scene = make_paper_scene(PaperSceneParams{});
    out.frames = make_walkthrough(out.scene, WalkthroughParams{});
    if (out.frames.size() >= 2) out.dt = out.frames[1].t - out.frames[0].t;
    std::vector<ObjectDesc> objects = out.scene.objects;
    double exact = 0.0;
    double vfc = 0.0;
    for (std::size_t k = 0; k < out.frames.size(); ++k) {
      test::apply_moves_to(&objects, out.frames[k].moves);
      if (k % 10 != 0) continue;
      RaySampling s;
      s.cols = 256;
      s.rows = 144;
      s.seed = k;
      exact += static_cast<double>(test::visible_objects(objects, out.frames[k].camera, s).size());
      vfc += static_cast<double>(test::frustum_objects(objects, out.frames[k].camera).size());
      out.sampled.push_back(static_cast<int>(k));
    }
    if (!out.sampled.empty()) {
      out.exact_mean = exact / static_cast<double>(out.sampled.size());
      out.vfc_mean = vfc / static_cast<double>(out.sampled.size());
    }
    return out;
  }();
  return w;
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

void BM_Walkthrough(benchmark::State& state, int gx, int gy, int gz, int ob) {
  const Walkthrough& w = walkthrough();
  if (w.frames.empty()) {
    state.SkipWithError("empty walkthrough");
    return;
  }
  SceneDesc desc = w.scene;
  desc.grid = glm::ivec3(gx, gy, gz);
  std::unique_ptr<Scene> scene;
  SceneOptions options;
  options.occlusion_buffer = ob;
  if (const Status st = Scene::create(desc, options, &scene); !st.ok) {
    state.SkipWithError(("Scene::create: " + st.str()).c_str());
    return;
  }
  Scratch scratch;
  const ViewerId viewer = scene->add_viewer();
  const std::size_t n = w.frames.size();
  std::size_t step = 0;
  FrameResult result;
  auto run_step = [&]() -> bool {
    const std::size_t k = ping_pong(step, n);
    const double t = static_cast<double>(step) * w.dt;
    ++step;
    if (!scene->apply_moves(t, w.frames[k].moves).ok) return false;
    return scene->frame(viewer, w.frames[k].camera, t, scratch, &result).ok;
  };
  // Warm-up: the first frame treats everything as visible.
  for (int i = 0; i < 10; ++i) {
    if (!run_step()) {
      state.SkipWithError("warm-up frame failed");
      return;
    }
  }
  std::vector<double> times;
  double voxels = 0.0;
  double ob_voxels = 0.0, ob_objects = 0.0;
  double pvs = 0.0;
  std::vector<double> pvs_at(n, -1.0);
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
    pvs += static_cast<double>(result.pvs.size());
    if (pvs_at[k] < 0.0) pvs_at[k] = static_cast<double>(result.pvs.size());
    benchmark::DoNotOptimize(result.pvs.data());
  }
  const double frames = static_cast<double>(std::max<std::size_t>(1, times.size()));
  state.counters["median_us"] = percentile(times, 0.5);
  state.counters["p99_us"] = percentile(times, 0.99);
  state.counters["voxels_mean"] = voxels / frames;
  state.counters["pvs_mean"] = pvs / frames;
  if (ob > 0) {
    state.counters["ob_voxels_mean"] = ob_voxels / frames;
    state.counters["ob_objects_mean"] = ob_objects / frames;
  }
  double sub = 0.0;
  int sub_n = 0;
  for (int k : w.sampled) {
    if (pvs_at[static_cast<std::size_t>(k)] >= 0.0) {
      sub += pvs_at[static_cast<std::size_t>(k)];
      ++sub_n;
    }
  }
  state.counters["pvs_sub_mean"] = sub_n ? sub / sub_n : 0.0;
  state.counters["exact_mean"] = w.exact_mean;
  state.counters["vfc_mean"] = w.vfc_mean;
  state.counters["objects"] = static_cast<double>(desc.objects.size());
  state.SetItemsProcessed(static_cast<std::int64_t>(times.size()));
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

void BM_HiddenDynamic(benchmark::State& state, int n) {
  const HiddenScene h = make_hidden_scene(n);
  std::unique_ptr<Scene> scene;
  if (const Status st = Scene::create(h.desc, SceneOptions{}, &scene); !st.ok) {
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
  // double); median_us is the steady per-frame cost, p99_us/max_us show the
  // frames where many TBVs expire together.
  for (int i = 0; i < 120; ++i) {
    if (!run_step()) {
      state.SkipWithError("warm-up frame failed");
      return;
    }
  }
  std::vector<double> times;
  double pvs = 0.0;
  double voxels = 0.0;
  double tbvs = 0.0;
  double expired = 0.0;
  double created = 0.0;
  for (auto _ : state) {
    if (!run_step()) {
      state.SkipWithError("frame failed");
      break;
    }
    times.push_back(result.stats.time_us);
    pvs += static_cast<double>(result.pvs.size());
    voxels += static_cast<double>(result.stats.voxels_visited);
    tbvs += static_cast<double>(result.stats.tbvs_active);
    expired += static_cast<double>(result.stats.tbvs_expired);
    created += static_cast<double>(result.stats.tbvs_created);
    benchmark::DoNotOptimize(result.pvs.data());
  }
  const double frames = static_cast<double>(std::max<std::size_t>(1, times.size()));
  state.counters["median_us"] = percentile(times, 0.5);
  state.counters["p99_us"] = percentile(times, 0.99);
  state.counters["pvs_mean"] = pvs / frames;
  state.counters["voxels_mean"] = voxels / frames;
  state.counters["tbvs_active_mean"] = tbvs / frames;
  state.counters["max_us"] = times.empty() ? 0.0 : *std::max_element(times.begin(), times.end());
  state.counters["tbvs_expired_total"] = expired;
  state.counters["tbvs_created_total"] = created;
  state.counters["hidden"] = static_cast<double>(n);
  state.SetItemsProcessed(static_cast<std::int64_t>(times.size()));
}

struct StaticPath {
  test::ScenePath path;
  std::vector<int> sampled;
  double exact_mean = 0.0;
  double vfc_mean = 0.0;
};

const StaticPath& static_path(int which) {
  static std::map<int, StaticPath> cache;
  auto it = cache.find(which);
  if (it != cache.end()) return it->second;
  StaticPath out;
  out.path = which == 0 ? test::make_indoor_level(6, 3, 200, 7)
                        : test::make_voxel_world(64, 200, which == 2, 11);
  double exact = 0.0, vfc = 0.0;
  for (std::size_t k = 0; k < out.path.cameras.size(); k += 10) {
    RaySampling s;
    s.cols = 256;
    s.rows = 144;
    s.seed = k;
    exact += static_cast<double>(test::visible_objects(out.path.scene.objects, out.path.cameras[k], s).size());
    vfc += static_cast<double>(test::frustum_objects(out.path.scene.objects, out.path.cameras[k]).size());
    out.sampled.push_back(static_cast<int>(k));
  }
  out.exact_mean = exact / static_cast<double>(std::max<std::size_t>(1, out.sampled.size()));
  out.vfc_mean = vfc / static_cast<double>(std::max<std::size_t>(1, out.sampled.size()));
  return cache.emplace(which, std::move(out)).first->second;
}

void BM_StaticPath(benchmark::State& state, int which) {
  const StaticPath& sp = static_path(which);
  std::unique_ptr<Scene> scene;
  if (const Status st = Scene::create(sp.path.scene, SceneOptions{}, &scene); !st.ok) {
    state.SkipWithError(("Scene::create: " + st.str()).c_str());
    return;
  }
  Scratch scratch;
  const ViewerId viewer = scene->add_viewer();
  const std::size_t n = sp.path.cameras.size();
  std::vector<double> times;
  double voxels = 0.0, pvs = 0.0;
  std::vector<double> pvs_at(n, -1.0);
  std::size_t step = 0;
  FrameResult result;
  for (auto _ : state) {
    const std::size_t k = ping_pong(step, n);
    if (!scene->frame(viewer, sp.path.cameras[k], static_cast<double>(step) / 60.0, scratch, &result).ok) {
      state.SkipWithError("frame failed");
      break;
    }
    ++step;
    times.push_back(result.stats.time_us);
    voxels += static_cast<double>(result.stats.voxels_visited);
    pvs += static_cast<double>(result.pvs.size());
    if (pvs_at[k] < 0.0) pvs_at[k] = static_cast<double>(result.pvs.size());
    benchmark::DoNotOptimize(result.pvs.data());
  }
  const double frames = static_cast<double>(std::max<std::size_t>(1, times.size()));
  double sub = 0.0;
  int sub_n = 0;
  for (int k : sp.sampled) {
    if (pvs_at[static_cast<std::size_t>(k)] >= 0.0) {
      sub += pvs_at[static_cast<std::size_t>(k)];
      ++sub_n;
    }
  }
  state.counters["median_us"] = percentile(times, 0.5);
  state.counters["p99_us"] = percentile(times, 0.99);
  state.counters["voxels_mean"] = voxels / frames;
  state.counters["pvs_mean"] = pvs / frames;
  state.counters["pvs_sub_mean"] = sub_n ? sub / sub_n : 0.0;
  state.counters["exact_mean"] = sp.exact_mean;
  state.counters["vfc_mean"] = sp.vfc_mean;
  state.counters["objects"] = static_cast<double>(sp.path.scene.objects.size());
  state.SetItemsProcessed(static_cast<std::int64_t>(times.size()));
}

void register_all() {
  const char* paths[] = {"indoor", "voxel_world/surface", "voxel_world/cave"};
  for (int i = 0; i < 3; ++i)
    benchmark::RegisterBenchmark(paths[i], BM_StaticPath, i)->Iterations(398)->Unit(benchmark::kMicrosecond);
  const int grids[][3] = {{50, 30, 50}, {100, 60, 100}, {200, 120, 200}};
  for (const auto& g : grids) {
    const std::string name = "walkthrough/grid:" + std::to_string(g[0]) + "x" +
                             std::to_string(g[1]) + "x" + std::to_string(g[2]);
    // One whole ping-pong cycle of the 300-frame walkthrough per run.
    benchmark::RegisterBenchmark(name.c_str(), BM_Walkthrough, g[0], g[1], g[2], 0)
        ->Iterations(598)
        ->Unit(benchmark::kMicrosecond);
  }
  // The occlusion buffer at three widths (SceneOptions::occlusion_buffer).
  for (int ob : {64, 128, 256}) {
    const std::string name = "walkthrough/grid:100x60x100/ob:" + std::to_string(ob);
    benchmark::RegisterBenchmark(name.c_str(), BM_Walkthrough, 100, 60, 100, ob)
        ->Iterations(598)
        ->Unit(benchmark::kMicrosecond);
  }
  for (int n : {1000, 10000, 100000}) {
    const std::string name = "hidden_dynamic/n:" + std::to_string(n);
    // 600 frames: 10 s of scene time at 60 fps.
    benchmark::RegisterBenchmark(name.c_str(), BM_HiddenDynamic, n)
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
