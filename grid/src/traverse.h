// traverse.h — the two traversals of a frame. Both only read the scene
// (frames of different viewers run them in parallel), put what may be
// visible into the worker's Scratch (w.pvs, and the TBVs to reveal in
// w.deferred), record the voxels they saw, and count their work in `st`.
//
//  * traverse_voxels (traverse_shells.cpp): the paper's chess-metric shells of
//    voxels front to back, with occluder fusion in object space; the
//    traversal with the occlusion buffer off.
//  * traverse_cells (traverse_cells.cpp): the cell pyramid front to back,
//    empty cells skipped by their masks, cells the occlusion buffer hides
//    skipped whole, objects tested one by one; the traversal with the
//    buffer on (the default).
#pragma once

#include "collect.h"

namespace voxvis::detail {

void traverse_voxels(const Scene::Impl& s, Scratch::Impl& w, const WorldFrustum& wf, FrameStats& st,
                     const FrameGeometry& g);
void traverse_cells(const Scene::Impl& s, Scratch::Impl& w, const WorldFrustum& wf, FrameStats& st,
                    const FrameGeometry& g);
/// The frame's record (voxvis/inspect.h) of the voxel traversal that just
/// ran with `w`, read from its stamps; the cell traversal writes its own
/// as it goes (w.trace).
void trace_voxels(const Scene::Impl& s, const Scratch::Impl& w, FrameTrace& trace);

}  // namespace voxvis::detail
