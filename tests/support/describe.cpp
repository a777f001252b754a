// describe.cpp — see describe.h.
#include "describe.h"

#include <algorithm>
#include <cstdio>
#include <iterator>

namespace voxvis::test {

std::vector<ObjectId> missing_ids(const std::vector<ObjectId>& pvs,
                                  const std::vector<ObjectId>& visible) {
  std::vector<ObjectId> out;
  std::set_difference(visible.begin(), visible.end(), pvs.begin(), pvs.end(),
                      std::back_inserter(out));
  return out;
}

namespace {
std::string vec_str(const Vec3& v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "{%.17g, %.17g, %.17g}", v.x, v.y, v.z);
  return buf;
}
}  // namespace

std::string describe(const Camera& cam) {
  char buf[128];
  std::snprintf(buf, sizeof buf, ", fov_y_deg=%.17g, aspect=%.17g, near=%.17g, far=%.17g}",
                cam.fov_y_deg, cam.aspect, cam.near, cam.far);
  return "Camera{eye=" + vec_str(cam.eye) + ", dir=" + vec_str(cam.dir) + ", up=" + vec_str(cam.up) +
         buf;
}

std::string describe(const ObjectDesc& obj) {
  std::string s = "Object{id=" + std::to_string(obj.id);
  if (obj.shape == Shape::Sphere) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "%.17g", obj.radius);
    s += ", sphere, center=" + vec_str(obj.center) + ", radius=" + buf;
  } else if (obj.shape == Shape::Box) {
    s += ", box, center=" + vec_str(obj.center) + ", half_extent=" + vec_str(obj.half_extent);
  } else {
    char buf[160];
    std::snprintf(buf, sizeof buf, ", rotation={%.17g, %.17g, %.17g, %.17g}, scale=%.17g", obj.rotation.w,
                  obj.rotation.x, obj.rotation.y, obj.rotation.z, obj.scale);
    s += ", mesh of " + (obj.mesh ? std::to_string(obj.mesh->triangles.size()) : std::string("no")) +
         " triangles, center=" + vec_str(obj.center) + buf;
  }
  if (obj.dynamic) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "%.17g", obj.max_speed);
    s += std::string(", dynamic, max_speed=") + buf;
  }
  return s + "}";
}

std::string describe_ids(const std::vector<ObjectId>& ids, std::size_t max_count) {
  std::string s = "[";
  for (std::size_t i = 0; i < ids.size() && i < max_count; ++i) {
    if (i) s += ", ";
    s += std::to_string(ids[i]);
  }
  if (ids.size() > max_count) s += ", ... (" + std::to_string(ids.size()) + " in all)";
  return s + "]";
}

}  // namespace voxvis::test
