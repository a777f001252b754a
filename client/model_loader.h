// model_loader.h — the scene files' model references for the `voxvis`
// commands that read scene files: the importer's loader (voxvis/import.h),
// run in a child process so that a model reader that crashes or hangs on a
// malformed file becomes an error naming it.
#pragma once

#include <string>

#include "voxvis/format.h"

namespace voxvis::cli {

/// Reader options for the scene file `scene_path`: relative model paths
/// resolve against its directory; models load through the importer, each in
/// a child process given at most `timeout_s` seconds (0: no limit).
/// `*loaded` (may be null) counts the models loaded.
SceneReadOptions scene_read_options(const std::string& scene_path, int* loaded = nullptr, double timeout_s = 600.0);

}  // namespace voxvis::cli
