// engine_check.h — drives the engine through its public API (voxvis/scene.h)
// and checks every frame against the ray-cast ground truth (raycast.h) and
// the result invariants:
//   * zero misses: PVS ⊇ visible_objects(current positions, camera);
//   * pvs and wake ascending and unique, pvs ids exist, stats.pvs_size matches;
//   * wake ⊆ dynamic ids, and every dynamic object in the PVS is in wake;
//   * stats finite and plausible (time_us finite and >= 0, counts bounded).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "raycast.h"
#include "voxvis/scene.h"

namespace voxvis::test {

/// Options with the occlusion buffer off: the object-space culling alone,
/// for the tests whose claims are about it (the engine's default renders a
/// buffer 160 pixels wide, which would hide what those tests look for).
inline SceneOptions buffer_off(SceneOptions options = {}) {
  options.occlusion_buffer = 0;
  return options;
}

/// Checks one frame; returns "" when fine, else a full description (scene
/// label, frame, camera, missed ids with their objects). `label` should carry
/// the seed.
std::string check_frame(const std::string& label, int frame, const std::vector<ObjectDesc>& objects,
                        const Camera& cam, const FrameResult& result, const RaySampling& sampling);

/// "" when every field of `s` is finite and plausible for a scene of
/// `objects` objects; else what is wrong.
std::string check_stats(const FrameStats& s, std::size_t objects);

/// One scene, its viewers, one Scratch, and the objects' true positions.
class EngineHarness {
 public:
  EngineHarness(const SceneDesc& desc, const SceneOptions& options = {}, std::string label = "");
  /// The result of Scene::create.
  const Status& status() const { return status_; }
  Scene& scene() { return *scene_; }
  Scratch& scratch() { return scratch_; }
  /// The viewer added at construction.
  ViewerId viewer() const { return viewer_; }
  const std::vector<ObjectDesc>& objects() const { return objects_; }
  const FrameResult& last() const { return last_; }
  int frames() const { return frames_; }

  /// Scene::apply_moves; on success also moves the harness's copy.
  Status move(double t, const std::vector<Move>& moves, MoveReport* report = nullptr);
  /// Scene::frame for the default viewer and the full check. Returns "" when
  /// fine; a failed Scene::frame is reported as an error too. Sampling
  /// defaults to 96x96 jittered rays plus the cell corners (down to 48x48
  /// when VOXVIS_TEST_SCALE < 1).
  std::string frame(const Camera& cam, double t, const RaySampling* sampling = nullptr) {
    return frame_viewer(viewer_, cam, t, sampling);
  }
  /// The same for another viewer of the scene.
  std::string frame_viewer(ViewerId viewer, const Camera& cam, double t,
                           const RaySampling* sampling = nullptr);

 private:
  std::string label_;
  Status status_;
  std::unique_ptr<Scene> scene_;
  Scratch scratch_;
  ViewerId viewer_ = 0;
  std::vector<ObjectDesc> objects_;
  FrameResult last_;
  int frames_ = 0;
};

}  // namespace voxvis::test
