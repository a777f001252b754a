// store.cpp — the data directory: atomic, durable scene and positions files.
#include "store.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include <nlohmann/json.hpp>

namespace voxvis::server {
namespace fs = std::filesystem;
namespace {

constexpr std::string_view kPositionsFormat = "voxvis-positions/1";
// Temporaries start with '.', which no scene id may, so they can never be
// mistaken for (or collide with) a scene's files, and anything with this
// prefix in scenes/ at start is debris of an interrupted write.
constexpr std::string_view kTempPrefix = ".tmp-";

std::string errno_text(int err) { return std::strerror(err); }

std::string scenes_dir(const std::string& dir) { return (fs::path(dir) / "scenes").string(); }

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

bool read_file(const fs::path& path, std::string& out, std::string& error) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    error = "cannot open: " + errno_text(errno);
    return false;
  }
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) {
    error = "cannot read: " + errno_text(errno);
    return false;
  }
  out = std::move(text).str();
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
  const auto t_it = doc.find("t");
  if (t_it == doc.end() || !t_it->is_number() || !std::isfinite(t_it->get<double>())) {
    return "t: expected a finite number";
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
      if (!c.is_number() || !std::isfinite(c.get<double>())) {
        return where + ".center[" + std::to_string(axis) + "]: expected a finite number";
      }
      move.center[axis] = c.get<double>();
    }
    parsed.push_back(move);
  }
  t = t_it->get<double>();
  moves = std::move(parsed);
  return {};
}

}  // namespace

bool valid_scene_id(std::string_view id) {
  if (id.empty() || id.size() > 64 || id.front() == '.') return false;
  return std::all_of(id.begin(), id.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
           c == '.' || c == '_' || c == '-';
  });
}

Status SceneStore::open(const std::string& dir) {
  const std::string scenes = scenes_dir(dir);
  std::error_code ec;
  fs::create_directories(scenes, ec);
  if (ec) return Status::Error(scenes, "cannot create directory: " + ec.message());
  if (!fs::is_directory(scenes, ec)) return Status::Error(scenes, "not a directory");

  for (fs::directory_iterator it(scenes, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(kTempPrefix, 0) != 0) continue;
    std::error_code remove_ec;
    if (!it->is_regular_file(remove_ec)) continue;
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
  return Status::Ok();
}

std::vector<StoredScene> SceneStore::load_all(
    const std::function<void(const std::string&)>& warn) const {
  std::vector<StoredScene> result;
  const std::string scenes = scenes_dir(dir_);
  std::error_code ec;
  for (fs::directory_iterator it(scenes, ec), end; !ec && it != end; it.increment(ec)) {
    const fs::path& path = it->path();
    if (path.extension() != ".json") continue;
    const std::string id = path.stem().string();
    if (!valid_scene_id(id)) continue;
    std::error_code type_ec;
    if (!it->is_regular_file(type_ec)) continue;

    StoredScene scene;
    scene.id = id;
    scene.json_path = path.string();
    std::string error;
    if (!read_file(path, scene.json, error)) {
      warn(path.string() + ": " + error + "; scene not loaded");
      continue;
    }

    const fs::path positions_path = fs::path(scenes) / (id + ".positions");
    std::error_code exists_ec;
    if (fs::exists(positions_path, exists_ec)) {
      std::string text;
      double t = 0.0;
      if (!read_file(positions_path, text, error) ||
          !(error = parse_positions(text, t, scene.positions)).empty()) {
        warn(positions_path.string() + ": " + error +
             "; positions ignored, the scene starts at its created positions");
        scene.positions.clear();
      } else {
        scene.t = t;
      }
    }
    result.push_back(std::move(scene));
  }
  if (ec) warn(scenes + ": cannot list directory: " + ec.message());
  std::sort(result.begin(), result.end(),
            [](const StoredScene& a, const StoredScene& b) { return a.id < b.id; });
  return result;
}

Status SceneStore::save_scene(const std::string& id, const std::string& json) {
  if (!valid_scene_id(id)) return Status::Error("id", "invalid scene id");
  return write_atomic(scenes_dir(dir_), id + ".json", json);
}

Status SceneStore::save_positions(const std::string& id, double t,
                                  const std::vector<Move>& positions) {
  if (!valid_scene_id(id)) return Status::Error("id", "invalid scene id");
  // JSON has no NaN or infinity (nlohmann would write null), and such a file
  // would then be rejected at load: refuse it now, where the caller can see.
  if (!std::isfinite(t)) return Status::Error("t", "must be finite");
  nlohmann::json moves = nlohmann::json::array();
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const Move& m = positions[i];
    if (!std::isfinite(m.center.x) || !std::isfinite(m.center.y) || !std::isfinite(m.center.z)) {
      return Status::Error("positions[" + std::to_string(i) + "].center", "must be finite");
    }
    moves.push_back({{"id", m.id}, {"center", {m.center.x, m.center.y, m.center.z}}});
  }
  // nlohmann writes doubles in the shortest form that reads back to the same
  // value, so saved centres are exact.
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
