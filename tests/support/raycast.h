// raycast.h — the tests' ground truth is the product's CPU ray caster
// (raycast/include/voxvis/raycast.h, namespace voxvis::raycast, which says
// what "visible" means); this header brings its names into voxvis::test,
// next to the helpers of failure messages (describe.h). Nothing is defined
// here: there is one ray caster.
#pragma once

#include "describe.h"
#include "voxvis/raycast.h"

namespace voxvis::test {

using raycast::CastOptions;
using raycast::CastStats;
using raycast::first_hit;
using raycast::frustum_objects;
using raycast::intersect;
using raycast::make_basis;
using raycast::pixel_centres;
using raycast::project;
using raycast::RaySampling;
using raycast::ViewBasis;
using raycast::visible_objects;
using raycast::voxels_in_view;

}  // namespace voxvis::test
