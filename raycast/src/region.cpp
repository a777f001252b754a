// region.cpp — region_visible (voxvis/raycast.h): a region camera sampled
// as point cameras, eyes by views by placements of the moving objects.
#include <algorithm>
#include <array>
#include <cmath>
#include <unordered_map>
#include <utility>
#include <vector>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "voxvis/mesh.h"
#include "voxvis/raycast.h"
#include "voxvis/rng.h"
#include "voxvis/scene.h"

namespace voxvis::raycast {
namespace {

/// The sampled eyes of the box eye ± h: centre, corners, random points.
std::vector<Vec3> sample_eyes(const Camera& cam, int random_eyes, Rng& rng) {
  std::vector<Vec3> eyes = {cam.eye};
  const Vec3 h = cam.eye_extent;
  if (h == Vec3(0.0)) return eyes;
  for (int k = 0; k < 8; ++k)
    eyes.push_back(cam.eye + Vec3((k & 1) ? h.x : -h.x, (k & 2) ? h.y : -h.y, (k & 4) ? h.z : -h.z));
  for (int k = 0; k < random_eyes; ++k)
    eyes.push_back(cam.eye + Vec3(rng.uniform(-h.x, h.x), rng.uniform(-h.y, h.y), rng.uniform(-h.z, h.z)));
  return eyes;
}

/// The views from one eye: the camera's own, or six cube faces.
std::vector<Camera> views(const Camera& cam, const Vec3& eye) {
  Camera base = cam;
  base.eye = eye;
  base.eye_extent = Vec3(0.0);
  base.omnidirectional = false;
  base.horizon_s = 0.0;
  if (!cam.omnidirectional) return {base};
  static const std::array<std::pair<Vec3, Vec3>, 6> kFaces = {{{Vec3(1, 0, 0), Vec3(0, 1, 0)},
                                                               {Vec3(-1, 0, 0), Vec3(0, 1, 0)},
                                                               {Vec3(0, 0, 1), Vec3(0, 1, 0)},
                                                               {Vec3(0, 0, -1), Vec3(0, 1, 0)},
                                                               {Vec3(0, 1, 0), Vec3(0, 0, 1)},
                                                               {Vec3(0, -1, 0), Vec3(0, 0, 1)}}};
  std::vector<Camera> out;
  for (const auto& [dir, up] : kFaces) {
    Camera c = base;
    c.dir = dir;
    c.up = up;
    c.fov_y_deg = 90.0;
    c.aspect = 1.0;
    out.push_back(c);
  }
  return out;
}

/// The objects placed as at the horizon's placement `k` (0: where they are).
std::vector<ObjectDesc> placement(const std::vector<ObjectDesc>& objects, double horizon, int k, int count,
                                  Rng& rng) {
  std::vector<ObjectDesc> out = objects;
  if (k == 0) return out;
  for (ObjectDesc& o : out) {
    if (!o.dynamic) continue;
    const double reach = o.max_speed * horizon * (k + 1 == count ? 1.0 : rng.uniform());
    if (!(reach > 0.0) || !std::isfinite(reach)) continue;
    o.center += rng.unit_vector() * std::min(reach, kMaxCoordinate);
  }
  return out;
}

}  // namespace

std::vector<ObjectId> region_visible(const std::vector<ObjectDesc>& objects, const Camera& cam,
                                     const RegionSampling& sampling) {
  if (!validate_camera(cam).ok) return {};
  if (!is_region(cam)) return visible_objects(objects, cam, sampling.rays);
  Rng rng(sampling.seed);
  const bool moving = cam.horizon_s > 0.0 && std::any_of(objects.begin(), objects.end(), [](const ObjectDesc& o) {
                        return o.dynamic && o.max_speed > 0.0;
                      });
  const int placements = moving ? 1 + std::max(0, sampling.placements) : 1;
  std::vector<ObjectId> seen;
  for (int k = 0; k < placements; ++k) {
    const std::vector<ObjectDesc> placed = placement(objects, cam.horizon_s, k, placements, rng);
    // Omnidirectional, far bounds distance (a sphere), where a cube face's
    // far plane reaches sqrt(3) times as far in its corners: a sighting of
    // an object wholly farther than `far` from the eye is not one.
    std::unordered_map<ObjectId, std::pair<Vec3, Vec3>> box;
    if (cam.omnidirectional)
      for (const ObjectDesc& o : placed) object_bounds(o, &box[o.id].first, &box[o.id].second);
    const auto beyond_far = [&](ObjectId id, const Vec3& eye) {
      const auto& [lo, hi] = box.at(id);
      const Vec3 nearest = glm::max(glm::max(lo - eye, eye - hi), Vec3(0.0));
      return glm::length(nearest) > cam.far * (1.0 + 1e-9);
    };
    for (const Vec3& eye : sample_eyes(cam, std::max(0, sampling.random_eyes), rng))
      for (const Camera& view : views(cam, eye)) {
        if (!validate_camera(view).ok) continue;  // An eye beyond the coordinates' limit.
        for (ObjectId id : visible_objects(placed, view, sampling.rays))
          if (!cam.omnidirectional || !beyond_far(id, eye)) seen.push_back(id);
      }
  }
  std::sort(seen.begin(), seen.end());
  seen.erase(std::unique(seen.begin(), seen.end()), seen.end());
  return seen;
}

}  // namespace voxvis::raycast
