// store.h — the data directory: scenes and dynamic positions on disk.
//
// Layout under DIR:
//   scenes/<id>.json        the scene as created (voxvis-scene/1), written
//                           once, before CreateScene answers OK
//   scenes/<id>.positions   JSON {"format": "voxvis-positions/1", "t": T,
//                           "moves": [{"id": N, "center": [x,y,z]}, ...]}:
//                           last centres of the dynamic objects (a mesh's
//                           with "rotation": [w,x,y,z], its rotation as last
//                           given), rewritten every save period and at
//                           shutdown; doubles written exactly
//   quarantine/             what could not be loaded, moved aside (created
//                           when first needed)
//
// Every write goes to a temporary file in the same directory, is fsynced, and
// is renamed over the old file; the directory is fsynced after the rename. A
// crash at any point leaves either the old or the new file, never a partial
// one; stray temporaries are removed at start.
//
// Nothing inside DIR is trusted (DIR itself may be a symlink): symlinks there
// are never followed, and any entry of scenes/ that cannot be loaded is moved
// into quarantine/ (the entry itself: for a symlink, the link) so that the
// rest can be served.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "voxvis/types.h"

namespace voxvis::server {

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
  /// Creates DIR and DIR/scenes when missing, and removes stray temporaries.
  /// A DIR/scenes that is not a directory (a symlink, a file) is moved into
  /// quarantine/ and a fresh one created; load_all reports it. Errors name the
  /// path.
  Status open(const std::string& dir);

  /// Every stored scene, ascending id. Whatever else scenes/ holds is moved
  /// into quarantine/, one line through `warn` each naming the entry, the
  /// reason and where it went: symlinks, directories and other non-files,
  /// unexpected names, unreadable scene files (with their positions),
  /// positions files of no scene, and positions files that do not parse or
  /// are out of range (t beyond ±kMaxSceneTime, centres beyond
  /// ±kMaxCoordinate, a rotation not a unit quaternion; the scene then loads
  /// at its created positions). A scene file is returned as it is: the caller
  /// parses it, and quarantine()s it when it is refused.
  std::vector<StoredScene> load_all(const std::function<void(const std::string&)>& warn);

  /// One stored scene's files (read anew): its scene file, and its
  /// positions when a positions file exists. Errors name the path: a
  /// missing or unreadable scene file, a positions file that does not parse.
  Status read(const std::string& id, StoredScene* out);

  /// Moves both files of a scene (those that exist) into quarantine/, under
  /// their names or, when taken, with a ".N" suffix; both directories are
  /// fsynced. Errors name the path.
  Status quarantine(const std::string& id);

  /// Writes scenes/<id>.json atomically and durably.
  Status save_scene(const std::string& id, const std::string& json);
  /// Writes scenes/<id>.positions atomically and durably. `t`, the centres
  /// and the rotations (those of moves with has_rotation) must be finite and
  /// within what load_all accepts.
  Status save_positions(const std::string& id, double t, const std::vector<Move>& positions);
  /// Removes both files of a scene (durably: the directory is fsynced).
  Status remove_scene(const std::string& id);

  const std::string& dir() const { return dir_; }

 private:
  std::string dir_;
  /// What open() moved aside, reported by the next load_all.
  std::vector<std::string> open_warnings_;
};

}  // namespace voxvis::server
