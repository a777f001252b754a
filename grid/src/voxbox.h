// voxbox.h — an inclusive box of integer voxel (or cell) coordinates.
#pragma once

#include <glm/vec3.hpp>

namespace voxvis::detail {

/// Integer box [lo, hi] (inclusive on every axis), grid indices; empty when
/// hi < lo on some axis.
struct VoxBox {
  glm::ivec3 lo{0}, hi{-1};
  bool empty() const { return hi.x < lo.x || hi.y < lo.y || hi.z < lo.z; }
  bool contains(const glm::ivec3& v) const {
    return v.x >= lo.x && v.x <= hi.x && v.y >= lo.y && v.y <= hi.y && v.z >= lo.z && v.z <= hi.z;
  }
  bool operator==(const VoxBox&) const = default;
};

}  // namespace voxvis::detail
