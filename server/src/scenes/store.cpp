// store.cpp — the data directory: atomic, durable scene and positions files.
#include "scenes/store.h"

#include <dirent.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>

#include <nlohmann/json.hpp>

#include "voxvis/mesh.h"
#include "wire/calls.h"

namespace voxvis::server {
namespace fs = std::filesystem;
namespace {

constexpr std::string_view kPositionsFormat = "voxvis-positions/1";
// Temporaries start with '.', which no scene id may, so they can never be
// mistaken for (or collide with) a scene's files, and anything with this
// prefix in scenes/ at start is debris of an interrupted write.
constexpr std::string_view kTempPrefix = ".tmp-";

constexpr const char* kSymlinkReason = "a symbolic link (never followed in the data directory)";

std::string errno_text(int err) { return std::strerror(err); }

std::string scenes_dir(const std::string& dir) { return (fs::path(dir) / "scenes").string(); }
std::string quarantine_dir(const std::string& dir) { return (fs::path(dir) / "quarantine").string(); }

/// A file descriptor, closed at the end of its scope.
class Fd {
 public:
  explicit Fd(int fd = -1) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }
  bool ok() const { return fd_ >= 0; }

 private:
  int fd_;
};

/// Opens a directory of the data directory. The last component must not be a
/// symlink (DIR itself, a command-line argument, may be one: open it with
/// `follow`).
int open_dir(const std::string& path, bool follow = false) {
  return ::open(path.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC | (follow ? 0 : O_NOFOLLOW));
}

/// Opens `path` read-only and fsyncs it: after a rename or unlink, this makes
/// the directory entry itself durable.
Status fsync_dir(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return Status::Error(path, "cannot open directory to fsync: " + errno_text(errno));
  const int rc = ::fsync(fd);
  const int err = errno;
  ::close(fd);
  if (rc != 0) return Status::Error(path, "fsync of directory failed: " + errno_text(err));
  return Status::Ok();
}

std::string unique_temp_name(const std::string& dir, const std::string& name) {
  // The counter keeps two threads of this process writing the same file apart;
  // the pid keeps two processes apart (the second would fail later on its own).
  static std::atomic<unsigned long> counter{0};
  return (fs::path(dir) / (std::string(kTempPrefix) + name + "." + std::to_string(::getpid()) +
                           "." + std::to_string(counter.fetch_add(1))))
      .string();
}

/// renameat that never replaces: fails with EEXIST when `to` exists.
int rename_noreplace(int from_fd, const char* from, int to_fd, const char* to) {
  if (::renameat2(from_fd, from, to_fd, to, RENAME_NOREPLACE) == 0) return 0;
  if (errno != EINVAL && errno != ENOSYS) return -1;
  // A filesystem without RENAME_NOREPLACE: look, then rename. Only one server
  // uses a data directory, so nothing else creates names in quarantine/.
  struct stat st;
  if (::fstatat(to_fd, to, &st, AT_SYMLINK_NOFOLLOW) == 0) {
    errno = EEXIST;
    return -1;
  }
  if (errno != ENOENT) return -1;
  return ::renameat(from_fd, from, to_fd, to);
}

/// Moves the entry `name` of the directory `from_fd` (`from_dir` in messages)
/// into DIR/quarantine/, creating it when missing: under `name` or, when that
/// is taken, `name`.1, `name`.2, ... The entry itself moves (for a symlink,
/// the link). Both directories are fsynced. `moved_to` is the new path.
Status move_to_quarantine(const std::string& dir, int from_fd, const std::string& from_dir,
                          const std::string& name, std::string* moved_to) {
  const std::string quarantine = quarantine_dir(dir);
  Fd parent(open_dir(dir, /*follow=*/true));
  if (!parent.ok()) return Status::Error(dir, "cannot open directory: " + errno_text(errno));
  if (::mkdirat(parent.get(), "quarantine", 0777) == 0) {
    if (::fsync(parent.get()) != 0) {
      return Status::Error(dir, "fsync of directory failed: " + errno_text(errno));
    }
  } else if (errno != EEXIST) {
    return Status::Error(quarantine, "cannot create directory: " + errno_text(errno));
  }
  Fd target_dir(::openat(parent.get(), "quarantine", O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC));
  if (!target_dir.ok()) {
    const int err = errno;
    return Status::Error(quarantine, err == ELOOP || err == ENOTDIR
                                         ? "not a directory (a symlink or a file): move it away"
                                         : "cannot open directory: " + errno_text(err));
  }
  const std::string from = (fs::path(from_dir) / name).string();
  for (unsigned n = 0; n < 10000; ++n) {
    const std::string target = n == 0 ? name : name + "." + std::to_string(n);
    if (rename_noreplace(from_fd, name.c_str(), target_dir.get(), target.c_str()) != 0) {
      if (errno == EEXIST) continue;
      return Status::Error(from, "cannot move into " + quarantine + ": " + errno_text(errno));
    }
    *moved_to = (fs::path(quarantine) / target).string();
    if (::fsync(target_dir.get()) != 0) {
      return Status::Error(quarantine, "fsync of directory failed: " + errno_text(errno));
    }
    if (::fsync(from_fd) != 0) {
      return Status::Error(from_dir, "fsync of directory failed: " + errno_text(errno));
    }
    return Status::Ok();
  }
  return Status::Error(from, "cannot move into " + quarantine + ": every name tried is taken");
}

/// Writes `text` to dir/name through a temporary in the same directory: write,
/// fsync, rename over the old file, fsync the directory. A crash leaves the
/// old or the new file whole, never a mix.
Status write_atomic(const std::string& dir, const std::string& name, std::string_view text) {
  const std::string target = (fs::path(dir) / name).string();
  const std::string temp = unique_temp_name(dir, name);
  // 0666 before the umask, like any file the operator's tools would create.
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd < 0) return Status::Error(temp, "cannot create: " + errno_text(errno));
  auto fail = [&](const std::string& what, int err) {
    ::close(fd);
    ::unlink(temp.c_str());
    return Status::Error(temp, what + ": " + errno_text(err));
  };
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      return fail("write failed", errno);
    }
    done += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) return fail("fsync failed", errno);
  if (::close(fd) != 0) {
    const int err = errno;
    ::unlink(temp.c_str());
    return Status::Error(temp, "close failed: " + errno_text(err));
  }
  if (::rename(temp.c_str(), target.c_str()) != 0) {
    const int err = errno;
    ::unlink(temp.c_str());
    return Status::Error(target, "rename from temporary failed: " + errno_text(err));
  }
  return fsync_dir(dir);
}

/// The names in the directory `dir_fd`, but "." and "..", ascending.
bool list_names(int dir_fd, std::vector<std::string>& names, std::string& error) {
  const int copy = ::fcntl(dir_fd, F_DUPFD_CLOEXEC, 0);
  if (copy < 0) {
    error = "cannot list directory: " + errno_text(errno);
    return false;
  }
  ::DIR* listing = ::fdopendir(copy);
  if (listing == nullptr) {
    error = "cannot list directory: " + errno_text(errno);
    ::close(copy);
    return false;
  }
  errno = 0;
  while (const ::dirent* entry = ::readdir(listing)) {
    const std::string name = entry->d_name;
    if (name != "." && name != "..") names.push_back(name);
    errno = 0;
  }
  const int err = errno;
  ::closedir(listing);
  if (err != 0) {
    error = "cannot list directory: " + errno_text(err);
    return false;
  }
  std::sort(names.begin(), names.end());
  return true;
}

/// Reads the regular file `name` of the directory `dir_fd`, never through a
/// symlink (one swapped in since the listing is refused) and never waiting on
/// a FIFO.
bool read_entry(int dir_fd, const std::string& name, std::string& out, std::string& error) {
  Fd fd(::openat(dir_fd, name.c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC));
  if (!fd.ok()) {
    error = errno == ELOOP ? kSymlinkReason : "cannot open: " + errno_text(errno);
    return false;
  }
  struct stat st;
  if (::fstat(fd.get(), &st) != 0) {
    error = "cannot stat: " + errno_text(errno);
    return false;
  }
  if (!S_ISREG(st.st_mode)) {
    error = "not a regular file";
    return false;
  }
  std::string text;
  char buf[1 << 16];
  for (;;) {
    const ssize_t n = ::read(fd.get(), buf, sizeof buf);
    if (n < 0) {
      if (errno == EINTR) continue;
      error = "cannot read: " + errno_text(errno);
      return false;
    }
    if (n == 0) break;
    text.append(buf, static_cast<std::size_t>(n));
  }
  out = std::move(text);
  return true;
}

/// Parses a voxvis-positions/1 document into `t` and `moves`; on error returns
/// a message naming the offending field.
std::string parse_positions(const std::string& text, double& t, std::vector<Move>& moves) {
  const nlohmann::json doc = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) return "not valid JSON";
  if (!doc.is_object()) return "expected a JSON object";
  const auto format = doc.find("format");
  if (format == doc.end() || !format->is_string() || format->get<std::string>() != kPositionsFormat) {
    return "format: expected \"" + std::string(kPositionsFormat) + "\"";
  }
  // The engine refuses scene times beyond ±kMaxSceneTime: such a clock would
  // make the scene unloadable.
  const auto t_it = doc.find("t");
  if (t_it == doc.end() || !t_it->is_number() || !std::isfinite(t_it->get<double>()) ||
      std::fabs(t_it->get<double>()) > kMaxSceneTime) {
    return "t: expected a finite number of seconds within ±" + number_text(kMaxSceneTime);
  }
  const auto list = doc.find("moves");
  if (list == doc.end() || !list->is_array()) return "moves: expected an array";
  std::vector<Move> parsed;
  parsed.reserve(list->size());
  for (std::size_t i = 0; i < list->size(); ++i) {
    const nlohmann::json& entry = (*list)[i];
    const std::string where = "moves[" + std::to_string(i) + "]";
    if (!entry.is_object()) return where + ": expected an object";
    const auto id = entry.find("id");
    if (id == entry.end() || !id->is_number_unsigned() ||
        id->get<std::uint64_t>() > std::numeric_limits<ObjectId>::max()) {
      return where + ".id: expected an unsigned 32-bit integer";
    }
    const auto center = entry.find("center");
    if (center == entry.end() || !center->is_array() || center->size() != 3) {
      return where + ".center: expected [x, y, z]";
    }
    Move move;
    move.id = static_cast<ObjectId>(id->get<std::uint64_t>());
    for (int axis = 0; axis < 3; ++axis) {
      const nlohmann::json& c = (*center)[static_cast<std::size_t>(axis)];
      if (!c.is_number() || !std::isfinite(c.get<double>()) ||
          std::fabs(c.get<double>()) > kMaxCoordinate) {
        return where + ".center[" + std::to_string(axis) + "]: expected a finite number within ±" +
               number_text(kMaxCoordinate);
      }
      move.center[axis] = c.get<double>();
    }
    // A mesh's rotation, as the engine reports it (Scene::dynamic_centers):
    // four numbers, a unit quaternion by validate_rotation's rule.
    if (const auto rotation = entry.find("rotation"); rotation != entry.end()) {
      if (!rotation->is_array() || rotation->size() != 4) return where + ".rotation: expected [w, x, y, z]";
      double q[4];
      for (std::size_t k = 0; k < 4; ++k) {
        const nlohmann::json& c = (*rotation)[k];
        if (!c.is_number()) return where + ".rotation[" + std::to_string(k) + "]: expected a number";
        q[k] = c.get<double>();
      }
      move.rotation = Quat(q[0], q[1], q[2], q[3]);
      if (const Status st = validate_rotation(move.rotation, where + ".rotation"); !st) return st.str();
      move.has_rotation = true;
    }
    parsed.push_back(move);
  }
  t = t_it->get<double>();
  moves = std::move(parsed);
  return {};
}

}  // namespace

Status SceneStore::open(const std::string& dir) {
  const std::string scenes = scenes_dir(dir);
  std::vector<std::string> warnings;
  struct stat st;
  if (::lstat(scenes.c_str(), &st) == 0 && !S_ISDIR(st.st_mode)) {
    // Through a symlink every scene would be read and written outside DIR.
    const std::string reason = S_ISLNK(st.st_mode) ? kSymlinkReason : "not a directory";
    Fd parent(open_dir(dir, /*follow=*/true));
    if (!parent.ok()) return Status::Error(dir, "cannot open directory: " + errno_text(errno));
    std::string moved_to;
    if (Status s = move_to_quarantine(dir, parent.get(), dir, "scenes", &moved_to); !s) {
      return Status::Error(scenes, reason + "; cannot move it into quarantine: " + s.str());
    }
    warnings.push_back(scenes + ": " + reason + "; moved to " + moved_to +
                       ", an empty one is created");
  }
  std::error_code ec;
  const bool created = fs::create_directories(scenes, ec);
  if (ec) return Status::Error(scenes, "cannot create directory: " + ec.message());
  if (::lstat(scenes.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) {
    return Status::Error(scenes, "not a directory");
  }
  if (created) {
    if (Status s = fsync_dir(dir); !s) return s;
  }

  for (fs::directory_iterator it(scenes, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(kTempPrefix, 0) != 0) continue;
    // Only what an interrupted write leaves: anything else with the prefix is
    // quarantined by load_all.
    std::error_code remove_ec;
    if (!fs::is_regular_file(it->symlink_status(remove_ec))) continue;
    fs::remove(it->path(), remove_ec);
    if (remove_ec) {
      return Status::Error(it->path().string(), "cannot remove stale temporary: " + remove_ec.message());
    }
  }
  if (ec) return Status::Error(scenes, "cannot list directory: " + ec.message());

  // Permission bits do not tell the whole story (read-only mounts, ACLs,
  // root), so find out whether saves will work by making one.
  const std::string probe = unique_temp_name(scenes, "probe");
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd < 0) return Status::Error(scenes, "directory is not writable: " + errno_text(errno));
  ::close(fd);
  if (::unlink(probe.c_str()) != 0) {
    return Status::Error(probe, "cannot remove probe file: " + errno_text(errno));
  }
  dir_ = dir;
  open_warnings_ = std::move(warnings);
  return Status::Ok();
}

std::vector<StoredScene> SceneStore::load_all(
    const std::function<void(const std::string&)>& warn) {
  for (const std::string& w : open_warnings_) warn(w);
  open_warnings_.clear();
  std::vector<StoredScene> result;
  const std::string scenes = scenes_dir(dir_);
  // Everything below goes through this descriptor, so scenes/ cannot be
  // swapped for a symlink halfway.
  const Fd scenes_fd(open_dir(scenes));
  if (!scenes_fd.ok()) {
    warn(scenes + ": cannot open directory: " + errno_text(errno));
    return result;
  }
  std::vector<std::string> names;
  std::string error;
  if (!list_names(scenes_fd.get(), names, error)) {
    warn(scenes + ": " + error);
    return result;
  }

  // Moves scenes/<name> into quarantine/, with one line: the entry, `reason`,
  // where it went, and `outcome` (what that means for the scene).
  const auto quarantine_entry = [&](const std::string& name, const std::string& reason,
                                    const std::string& outcome) {
    const std::string path = (fs::path(scenes) / name).string();
    std::string moved_to;
    if (Status s = move_to_quarantine(dir_, scenes_fd.get(), scenes, name, &moved_to); !s) {
      warn(path + ": " + reason + "; left in place, cannot quarantine it: " + s.str() + outcome);
    } else {
      warn(path + ": " + reason + "; moved to " + moved_to + outcome);
    }
  };

  struct Files {
    bool json = false;
    bool positions = false;
  };
  std::map<std::string, Files> by_id;  // Ascending id.
  for (const std::string& name : names) {
    struct stat st;
    if (::fstatat(scenes_fd.get(), name.c_str(), &st, AT_SYMLINK_NOFOLLOW) != 0) {
      if (errno != ENOENT) warn((fs::path(scenes) / name).string() + ": cannot stat: " + errno_text(errno));
      continue;
    }
    if (S_ISLNK(st.st_mode)) {
      quarantine_entry(name, kSymlinkReason, "");
    } else if (S_ISDIR(st.st_mode)) {
      quarantine_entry(name, "a directory where a file should be", "");
    } else if (!S_ISREG(st.st_mode)) {
      quarantine_entry(name, "not a regular file", "");
    } else if (name.rfind(kTempPrefix, 0) == 0) {
      // A temporary of a write in progress: open() removed those of earlier runs.
    } else {
      const std::size_t dot = name.rfind('.');
      const std::string id = dot == std::string::npos ? name : name.substr(0, dot);
      const std::string ext = dot == std::string::npos ? "" : name.substr(dot);
      if (valid_scene_id(id) && ext == ".json") {
        by_id[id].json = true;
      } else if (valid_scene_id(id) && ext == ".positions") {
        by_id[id].positions = true;
      } else {
        quarantine_entry(name,
                         "unexpected name (expected <id>.json or <id>.positions, the id 1-64 "
                         "characters of [A-Za-z0-9._-] not starting with '.')",
                         "");
      }
    }
  }

  for (const auto& [id, files] : by_id) {
    const std::string json_name = id + ".json";
    const std::string positions_name = id + ".positions";
    if (!files.json) {
      quarantine_entry(positions_name, "positions of no scene (no loadable " + json_name + ")", "");
      continue;
    }
    StoredScene scene;
    scene.id = id;
    scene.json_path = (fs::path(scenes) / json_name).string();
    if (!read_entry(scenes_fd.get(), json_name, scene.json, error)) {
      quarantine_entry(json_name, error, "; scene not loaded");
      if (files.positions) {
        quarantine_entry(positions_name, "positions of a scene not loaded (" + json_name + ")", "");
      }
      continue;
    }
    if (files.positions) {
      std::string text;
      double t = 0.0;
      if (!read_entry(scenes_fd.get(), positions_name, text, error) ||
          !(error = parse_positions(text, t, scene.positions)).empty()) {
        scene.positions.clear();
        quarantine_entry(positions_name, error, "; the scene starts at its created positions");
      } else {
        scene.t = t;
      }
    }
    result.push_back(std::move(scene));
  }
  return result;
}

Status SceneStore::read(const std::string& id, StoredScene* out) {
  *out = StoredScene();
  if (!valid_scene_id(id)) return Status::Error("scene_id", "not a scene id");
  const std::string scenes = scenes_dir(dir_);
  const Fd scenes_fd(open_dir(scenes));
  if (!scenes_fd.ok()) return Status::Error(scenes, "cannot open directory: " + errno_text(errno));
  std::string error;
  const std::string json_name = id + ".json";
  out->id = id;
  out->json_path = (fs::path(scenes) / json_name).string();
  if (!read_entry(scenes_fd.get(), json_name, out->json, error)) return Status::Error(out->json_path, error);
  const std::string positions_name = id + ".positions";
  struct stat st;
  if (::fstatat(scenes_fd.get(), positions_name.c_str(), &st, AT_SYMLINK_NOFOLLOW) != 0) {
    if (errno == ENOENT) return Status::Ok();
    return Status::Error(positions_name, "cannot stat: " + errno_text(errno));
  }
  std::string text;
  double t = 0.0;
  if (!read_entry(scenes_fd.get(), positions_name, text, error) ||
      !(error = parse_positions(text, t, out->positions)).empty()) {
    return Status::Error((fs::path(scenes) / positions_name).string(), error);
  }
  out->t = t;
  return Status::Ok();
}

Status SceneStore::quarantine(const std::string& id) {
  if (!valid_scene_id(id)) return Status::Error("id", "invalid scene id");
  const std::string scenes = scenes_dir(dir_);
  const Fd scenes_fd(open_dir(scenes));
  if (!scenes_fd.ok()) return Status::Error(scenes, "cannot open directory: " + errno_text(errno));
  // Positions first, as in remove_scene.
  for (const char* ext : {".positions", ".json"}) {
    const std::string name = id + ext;
    struct stat st;
    if (::fstatat(scenes_fd.get(), name.c_str(), &st, AT_SYMLINK_NOFOLLOW) != 0) {
      if (errno == ENOENT) continue;
      return Status::Error((fs::path(scenes) / name).string(), "cannot stat: " + errno_text(errno));
    }
    std::string moved_to;
    if (Status s = move_to_quarantine(dir_, scenes_fd.get(), scenes, name, &moved_to); !s) return s;
  }
  return Status::Ok();
}

Status SceneStore::save_scene(const std::string& id, const std::string& json) {
  if (!valid_scene_id(id)) return Status::Error("id", "invalid scene id");
  return write_atomic(scenes_dir(dir_), id + ".json", json);
}

Status SceneStore::save_positions(const std::string& id, double t,
                                  const std::vector<Move>& positions) {
  if (!valid_scene_id(id)) return Status::Error("id", "invalid scene id");
  // JSON has no NaN or infinity (nlohmann would write null), and such a file,
  // like one out of range, would then be quarantined at load: refuse it now,
  // where the caller can see.
  if (!std::isfinite(t) || std::fabs(t) > kMaxSceneTime) {
    return Status::Error("t", "must be finite and within ±" + number_text(kMaxSceneTime));
  }
  nlohmann::json moves = nlohmann::json::array();
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const Move& m = positions[i];
    for (int axis = 0; axis < 3; ++axis) {
      if (!std::isfinite(m.center[axis]) || std::fabs(m.center[axis]) > kMaxCoordinate) {
        return Status::Error("positions[" + std::to_string(i) + "].center",
                             "must be finite and within ±" + number_text(kMaxCoordinate));
      }
    }
    nlohmann::json entry = {{"id", m.id}, {"center", {m.center.x, m.center.y, m.center.z}}};
    if (m.has_rotation) {
      if (const Status st = validate_rotation(m.rotation, "positions[" + std::to_string(i) + "].rotation"); !st)
        return st;
      entry["rotation"] = {m.rotation.w, m.rotation.x, m.rotation.y, m.rotation.z};
    }
    moves.push_back(std::move(entry));
  }
  // nlohmann writes doubles in the shortest form that reads back to the same
  // value, so saved centres and rotations are exact.
  const nlohmann::json doc = {{"format", kPositionsFormat}, {"t", t}, {"moves", std::move(moves)}};
  return write_atomic(scenes_dir(dir_), id + ".positions", doc.dump() + "\n");
}

Status SceneStore::remove_scene(const std::string& id) {
  if (!valid_scene_id(id)) return Status::Error("id", "invalid scene id");
  const std::string scenes = scenes_dir(dir_);
  // Positions first: a crash in between then leaves a scene without saved
  // positions (it loads at its created ones), never positions without a scene.
  for (const char* ext : {".positions", ".json"}) {
    const fs::path path = fs::path(scenes) / (id + ext);
    std::error_code ec;
    fs::remove(path, ec);  // false without error when missing: fine.
    if (ec) return Status::Error(path.string(), "cannot remove: " + ec.message());
  }
  return fsync_dir(scenes);
}

}  // namespace voxvis::server
