// scene_registry.h — the scenes a server serves: creating (building within
// the memory budget, storing), loading at start, deleting, saving the
// dynamic objects' positions, finding them by id, and keeping the scenes of
// the data directory that other shards own.
//
// A scene's id is taken from the moment its build is admitted until its
// deletion has removed its files and metrics: a CreateScene and a
// DeleteScene of one id never interleave. The budget counts every scene's
// estimated bytes (Scene::estimate, and each worker's scratch) and the bytes
// reserved by builds under way.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "scenes/metrics.h"
#include "scenes/pool.h"
#include "scenes/scene_entry.h"
#include "scenes/store.h"
#include "voxvis/scene.h"

namespace voxvis::server {

/// The registry's part of the server's settings (ServiceConfig).
struct RegistryConfig {
  SceneOptions scene_options;
  std::uint64_t memory_budget_bytes = 0;  ///< Sum of scenes' estimated bytes allowed.
  /// Workers of the frame pool: each one's scratch is counted for every scene.
  unsigned workers = 1;
};

/// Where a scene starts when it is not at its created positions: a
/// restart's saved positions, or another server's (ExportScene).
struct StartPositions {
  double t = 0.0;           ///< Sets the scene's clocks.
  std::vector<Move> moves;  ///< Saved with the scene when it is persisted.
};

/// Places the dynamic objects of `desc` that `moves` name at their centres
/// (a mesh's rotation too); their ids are unique (the callers' parsers
/// check). Strict (positions from the wire): every id must be a dynamic
/// object of the scene, only meshes may carry a rotation, and a mesh's new
/// placement must pass validate_mesh_object's rules; errors name `field`[i]
/// (".center" or ".rotation" for a placement beyond the limit). Not strict (the data directory's
/// files, checked when written): other ids are ignored.
Status place_dynamic(SceneDesc* desc, const std::vector<Move>& moves, bool strict, const std::string& field);

class SceneRegistry {
 public:
  using Log = std::function<void(const std::string&)>;
  /// `pool` runs the scenes' strands; `stopping` is true once the server is
  /// shutting down (a build stopped then answers UNAVAILABLE, not CANCELLED).
  /// With VOXVIS_TEST_FAIL_BUILD=<id> in the environment, every build of
  /// scene <id> throws once its grid is built (the tests' injected fault).
  SceneRegistry(RegistryConfig config, WorkerPool& pool, SceneStore& store, Metrics& metrics, Log log,
                const std::atomic<bool>& stopping);
  SceneRegistry(const SceneRegistry&) = delete;
  SceneRegistry& operator=(const SceneRegistry&) = delete;

  /// The scene, or null.
  std::shared_ptr<SceneEntry> find(const std::string& id) const;
  /// Every scene, ascending ids.
  std::vector<std::shared_ptr<SceneEntry>> list() const;
  /// Verify mode: scenes built from now on keep their objects as created
  /// (SceneEntry::verify_objects).
  void keep_objects(bool on) { keep_objects_ = on; }

  /// Checks the budget, builds, persists (when `persist`) and registers a
  /// scene. INVALID_ARGUMENT, ALREADY_EXISTS, ABORTED (the id is being
  /// deleted), RESOURCE_EXHAUSTED or INTERNAL. The cost comes from
  /// Scene::estimate (the objects' footprints) before anything large is
  /// allocated; `control` (may be null) cancels the build (CANCELLED, or
  /// UNAVAILABLE when the server is stopping). `json`: the scene as stored;
  /// `from_json` says errors are to name its lines (a scene_json request or
  /// a file) rather than a description's fields. `start` (may be null):
  /// the clocks' time, set before the scene is registered, and the positions
  /// (already placed in `desc`) saved with it when `persist`.
  grpc::Status create(const std::string& id, SceneDesc desc, const std::string& json, bool from_json, bool persist,
                      const BuildControl* control = nullptr, const StartPositions* start = nullptr);
  /// Loads a scene at start (data directory or --scene file), before the
  /// server accepts calls. `positions`, when given, replace the centres of
  /// the dynamic objects they name; `t` sets the scene's clocks. Errors
  /// start with `source`.
  Status load(const std::string& id, const std::string& json, const std::string& source,
              const std::vector<Move>* positions, std::optional<double> t, bool persist);
  /// Deletes scene `id`: unregisters it, gives its bytes back, marks it
  /// deleted and removes its files, then runs `end_streams` (which ends the
  /// calls on it) and removes its metrics before the id is free again.
  /// NOT_FOUND, or INTERNAL when its files remain (it is deleted all the same).
  grpc::Status remove(const std::string& id, const std::function<void(SceneEntry&)>& end_streams);
  /// Writes the positions of every scene whose dynamic objects moved since
  /// the last save.
  void save_positions();

  /// Records a scene of the data directory that another shard owns: kept on
  /// disk, not served; listed, exported and deleted (ListScenes,
  /// ExportScene, DeleteScene) so that `voxvis rebalance` can move it. Call
  /// before serving.
  void add_misplaced(const std::string& id, const std::string& owner);
  /// The scenes kept for other shards: id -> owner.
  std::map<std::string, std::string> misplaced() const;
  bool is_misplaced(const std::string& id) const;
  /// Deletes a scene kept for another shard with its files: NOT_FOUND when
  /// none has the id, INTERNAL when its files remain (it stays kept then).
  grpc::Status remove_misplaced(const std::string& id);

 private:
  /// OK when no scene has or is taking the id: else ALREADY_EXISTS, or
  /// ABORTED while it is being deleted.
  grpc::Status id_free_locked(const std::string& id) const;

  const RegistryConfig config_;
  WorkerPool& pool_;
  SceneStore& store_;
  Metrics& metrics_;
  Log log_;
  const std::atomic<bool>& stopping_;
  const std::string fail_build_;  // VOXVIS_TEST_FAIL_BUILD: builds of that id throw once built.
  std::atomic<bool> keep_objects_{false};

  mutable std::mutex mu_;
  std::map<std::string, std::shared_ptr<SceneEntry>> scenes_;  // Guarded by mu_.
  std::map<std::string, std::uint64_t> reserved_;  // Guarded by mu_: ids being created.
  std::set<std::string> deleting_;                 // Guarded by mu_: ids being deleted.
  std::uint64_t bytes_in_use_ = 0;                 // Guarded by mu_ (scenes and reserved).

  std::mutex store_mu_;  // Serializes position saves with scene deletion.

  mutable std::mutex misplaced_mu_;
  std::map<std::string, std::string> misplaced_;  // Guarded by misplaced_mu_: id -> owner.
};

}  // namespace voxvis::server
