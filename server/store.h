// store.h — the data directory: scenes and dynamic positions on disk.
//
// Layout under DIR:
//   scenes/<id>.json        the scene as created (voxvis-scene/1), written
//                           once, before CreateScene answers OK
//   scenes/<id>.positions   JSON {"format": "voxvis-positions/1", "t": T,
//                           "moves": [{"id": N, "center": [x,y,z]}, ...]}:
//                           last centres of the dynamic objects, rewritten
//                           every save period and at shutdown
//
// Every write goes to a temporary file in the same directory, is fsynced, and
// is renamed over the old file; the directory is fsynced after the rename. A
// crash at any point leaves either the old or the new file, never a partial
// one; stray temporaries are removed at start.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "voxvis/types.h"

namespace voxvis::server {

/// Scene ids: 1-64 characters from [A-Za-z0-9._-], not starting with '.'.
bool valid_scene_id(std::string_view id);

struct StoredScene {
  std::string id;
  std::string json;  ///< voxvis-scene/1 text.
  std::string json_path;
  /// Saved positions, when a positions file exists and parses.
  std::optional<double> t;
  std::vector<Move> positions;
};

class SceneStore {
 public:
  /// Creates DIR and DIR/scenes when missing. Errors name the path.
  Status open(const std::string& dir);

  /// Every stored scene, ascending id. A positions file that does not parse is
  /// reported through `warn` and ignored (the scene loads at its created
  /// positions); a scene file is returned as it is (the caller parses it).
  std::vector<StoredScene> load_all(const std::function<void(const std::string&)>& warn) const;

  /// Writes scenes/<id>.json atomically and durably.
  Status save_scene(const std::string& id, const std::string& json);
  /// Writes scenes/<id>.positions atomically and durably.
  Status save_positions(const std::string& id, double t, const std::vector<Move>& positions);
  /// Removes both files of a scene (durably: the directory is fsynced).
  Status remove_scene(const std::string& id);

  const std::string& dir() const { return dir_; }

 private:
  std::string dir_;
};

}  // namespace voxvis::server
