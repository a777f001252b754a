// describe.h — helpers of the tests' failure messages and set checks:
// round-trippable descriptions of cameras, objects and id lists, and the
// ids a PVS misses.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "voxvis/types.h"

namespace voxvis::test {

/// Ids in `visible` missing from `pvs` (both ascending).
std::vector<ObjectId> missing_ids(const std::vector<ObjectId>& pvs,
                                  const std::vector<ObjectId>& visible);

/// Human-readable, round-trippable (%.17g) descriptions for failure messages.
std::string describe(const Camera& cam);
std::string describe(const ObjectDesc& obj);
std::string describe_ids(const std::vector<ObjectId>& ids, std::size_t max_count = 40);

}  // namespace voxvis::test
