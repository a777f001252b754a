#include "serving/serving.h"

#include <string>
#include <utility>
#include <vector>

#include "scenes/env.h"
#include "voxvis/assert.h"
#include "wire/calls.h"

namespace voxvis::server {

Serving::Serving(const ServiceConfig& config, WorkerPool& pool, SceneRegistry& registry, Log log)
    : config_(config),
      pool_(pool),
      registry_(registry),
      log_(std::move(log)),
      fail_scene_(env_text("VOXVIS_TEST_FAIL_SCENE")) {}

grpc::Status Serving::missing(const std::string& id) const {
  if (std::string owner = config_.shard.other_owner(id); !owner.empty()) return config_.shard.refusal(id, owner);
  return no_scene(id);
}

void Serving::set_verifier(Verifier* v) {
  verifier_ = v;
  registry_.keep_objects(v != nullptr);
}

grpc::Status Serving::serve_frame(SceneEntry& e, FrameViewer* viewer, const Camera& camera, double t,
                                  Scratch& scratch, FrameResult* result, bool* check) {
  if (e.deleted.load()) return deleted(e.id);
  Scene& scene = *e.scene;
  // The scene's clock is shared: a time behind it is taken as it, one too
  // far beyond the simulation's as its limit.
  const double at = e.view_time(t, config_.max_view_lead_s);
  const bool cpu = e.metrics && e.metrics->wants_engine_cpu();
  const double cpu0 = cpu ? thread_cpu_seconds() : 0.0;
  const grpc::Status g = guarded(e, "frame", [&] {
    auto frame = [&](ViewerId id) {
      Status s = scene.frame(id, camera, at, scratch, result, Scene::Clock::Latest);
      return s ? grpc::Status::OK : invalid(s);
    };
    if (viewer == nullptr) {
      // A one-frame viewer, removed however the frame ends.
      struct OneFrameViewer {
        Scene& scene;
        const ViewerId id = scene.add_viewer();
        ~OneFrameViewer() { scene.remove_viewer(id); }
      } one{scene};
      return frame(one.id);
    }
    if (!viewer->added) {
      viewer->id = scene.add_viewer();
      viewer->added = true;
    }
    return frame(viewer->id);
  });
  if (cpu) e.metrics->engine_cpu(thread_cpu_seconds() - cpu0);
  if (!g.ok()) return g;
  e.after_frame(*result);
  if (check) *check = verify_sample();
  return grpc::Status::OK;
}

void Serving::release_viewer(const std::string& client, const std::shared_ptr<SceneEntry>& e,
                             const FrameViewer& viewer) {
  if (!viewer.added) return;
  pool_.submit(client, [e, v = viewer.id](Scratch&) {
    if (!e->deleted.load()) e->scene->remove_viewer(v);
  });
}

grpc::Status Serving::apply_batch(SceneEntry& e, double t, const std::vector<Move>& moves,
                                  const std::string& field_prefix, MoveReport* report) {
  // The scene's batches and its simulation clock are its strand's alone.
  VOXVIS_ASSERT(e.strand && e.strand->runs_here());
  // One batch may advance the clock by a bounded step; the first one on a
  // scene adopts the backend's epoch.
  const double step_limit = config_.max_time_step_s;
  const double from = e.sim_time.load(std::memory_order_relaxed);
  if (e.sim_clock_set && t - from > step_limit)
    return invalid(Status::Error(field_prefix + "t", number_text(t) + " is " + number_text(t - from) +
                                                       " s beyond the scene's clock (" + number_text(from) +
                                                       "); one batch may advance it by at most " +
                                                       number_text(step_limit) + " s"));
  Scene& scene = *e.scene;
  const grpc::Status g = guarded(e, "move batch", [&] {
    Status s = scene.apply_moves(t, moves, report, Scene::Clock::Latest);
    return s ? grpc::Status::OK : invalid(Status::Error(field_prefix + s.field, s.message));
  });
  if (!g.ok()) return g;
  e.moves_applied.fetch_add(report->applied, std::memory_order_relaxed);
  e.after_moves(report->t);
  if (report->applied) e.positions_dirty.store(true, std::memory_order_relaxed);
  if (e.metrics) e.metrics->moves(report->applied);
  e.refresh_wake();
  return grpc::Status::OK;
}

void Serving::verify_served(const SceneEntry& e, const std::string& viewer, std::uint64_t frame,
                            const Camera& camera, const FrameResult& result) {
  if (!verifier_ || !e.verify_objects) return;
  std::uint64_t epoch = 0;
  const std::vector<Move> centers = e.scene->dynamic_centers(nullptr, &epoch);
  if (epoch != result.positions_epoch) {
    // A move batch landed between the frame and this read: the positions the
    // frame saw are gone, and checking against newer ones could report
    // misses that were none.
    verifier_->dropped(e.metrics.get());
    return;
  }
  VerifyJob job;
  job.scene = e.id;
  job.viewer = viewer;
  job.frame = frame;
  job.t = result.t;
  job.camera = camera;
  job.pvs = result.pvs;
  job.objects = objects_at(*e.verify_objects, centers);
  job.metrics = e.metrics;
  verifier_->submit(std::move(job));
}

}  // namespace voxvis::server
