// voxvis/vdb.h — a scene's voxels and one frame's culling written as
// OpenVDB grids (`voxvis export --vdb`), so that they open in Houdini,
// Blender or any tool that reads .vdb files. docs/formats.md ("VDB export")
// is the contract: the grids, their values, transform and metadata.
//
// The only module that includes OpenVDB (in its one source file): the
// engine (voxvis::grid) knows nothing of it and gives what is written
// through voxvis/inspect.h.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "voxvis/inspect.h"
#include "voxvis/scene.h"

namespace voxvis::vdb {

/// One frame's culling, written beside the scene's grids.
struct FrameGrids {
  std::uint64_t index = 0;  ///< 0-based index of the frame in its frames file.
  double t = 0.0;           ///< Scene time of the frame, seconds.
  Camera camera;
  int occlusion_buffer = 0;  ///< The buffer's width that frame, pixels (FrameStats::ob_width); 0: off.
  const FrameTrace* trace = nullptr;           ///< What the frame's traversal did; required.
  const std::vector<ObjectId>* pvs = nullptr;  ///< The frame's PVS, ids; required.
};

/// Active voxels of each grid written (tiles counted by their voxels).
struct ExportSummary {
  std::uint64_t opaque = 0;
  std::uint64_t objects = 0;
  std::uint64_t visited = 0;   ///< With a frame only, as the two below.
  std::uint64_t occluded = 0;
  std::uint64_t pvs = 0;
};

/// Whether OpenVDB can hold the scene's grid: its transform refuses voxels
/// whose volume (the product of voxel_size's components) is below 3e-15
/// cubic world units. The error names the voxel size.
Status check_grid(const GridSpec& grid);

/// Writes `opaque` and `objects` for the scene as it stands (dynamic
/// objects at their current centres) and, with `frame`, `visited`,
/// `occluded` and `pvs`, to `path` (created or overwritten) with
/// openvdb::io::File. `source` (the scene file's name) is recorded in the
/// file's metadata. Not atomic: a caller that must never leave a partial
/// file writes to a temporary path and renames it. Errors (the grid
/// refused by check_grid, OpenVDB failing to write) come back as a Status
/// whose message says what failed. The file is read back to check that
/// every grid is there, unless `read_back` is false (a device or a FIFO,
/// which cannot be read back). Reads the scene under its shared lock
/// (inspect_grid).
Status write_vdb(const std::string& path, const Scene& scene, const std::string& source, const FrameGrids* frame,
                 ExportSummary* summary = nullptr, bool read_back = true);

}  // namespace voxvis::vdb
