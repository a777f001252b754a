#include "output_file.h"

#include <cerrno>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <string>
#include <system_error>

#include <sys/stat.h>
#include <unistd.h>

namespace voxvis::cli {
namespace {

// Temporary files to remove if a signal ends the process. Fixed storage: the
// handler may only use async-signal-safe calls (unlink, signal, raise).
constexpr int kMaxTemps = 4;
constexpr std::size_t kMaxPath = 4096;
char g_temps[kMaxTemps][kMaxPath];
volatile std::sig_atomic_t g_temp_used[kMaxTemps];

extern "C" void remove_temps_and_reraise(int sig) {
  for (int i = 0; i < kMaxTemps; ++i) {
    if (g_temp_used[i] != 0) ::unlink(g_temps[i]);
  }
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

void install_handlers_once() {
  static bool installed = false;
  if (installed) return;
  installed = true;
  for (const int sig : {SIGINT, SIGTERM, SIGHUP}) {
    if (std::signal(sig, remove_temps_and_reraise) == SIG_IGN) std::signal(sig, SIG_IGN);
  }
}

int register_temp(const std::string& path) {
  if (path.size() >= kMaxPath) return -1;
  for (int i = 0; i < kMaxTemps; ++i) {
    if (g_temp_used[i] == 0) {
      std::memcpy(g_temps[i], path.c_str(), path.size() + 1);
      g_temp_used[i] = 1;
      return i;
    }
  }
  return -1;
}

void unregister_temp(const std::string& path) {
  for (int i = 0; i < kMaxTemps; ++i) {
    if (g_temp_used[i] != 0 && path == g_temps[i]) g_temp_used[i] = 0;
  }
}

std::string errno_text() { return std::strerror(errno); }

/// "a directory", "a socket", ...: what a file that is not a regular one is.
std::string kind_of(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISSOCK(mode)) return "a socket";
  if (S_ISBLK(mode)) return "a block device";
  return "a special file";
}

}  // namespace

std::string renamed_path(const std::string& path) {
  struct stat st{};
  if (::lstat(path.c_str(), &st) != 0 || !S_ISLNK(st.st_mode)) return path;
  std::error_code ec;
  const std::filesystem::path target = std::filesystem::weakly_canonical(path, ec);
  return ec || target.empty() ? path : target.string();
}

bool is_device_or_fifo(const std::string& path) {
  struct stat st{};
  return ::stat(path.c_str(), &st) == 0 && (S_ISCHR(st.st_mode) || S_ISFIFO(st.st_mode));
}

OutputFile::~OutputFile() { discard(); }

bool OutputFile::open(const std::string& path, std::string* message) {
  discard();
  if (path.empty() || path == "-") {
    file_ = stdout;
    is_stdout_ = true;
    path_ = "<stdout>";
    return true;
  }
  path_ = path;
  struct stat st{};
  if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) {
    if (S_ISCHR(st.st_mode) || S_ISFIFO(st.st_mode)) {
      // Written in place: renaming a file over a device node would replace it.
      file_ = std::fopen(path.c_str(), "wb");
      if (file_ == nullptr) {
        *message = "cannot open " + path + " for writing: " + errno_text();
        return false;
      }
      direct_ = true;
      return true;
    }
    *message = "is " + kind_of(st.st_mode) + ", not a file to write; give a file's path";
    return false;
  }
  install_handlers_once();
  // A link is followed: the file it names is replaced, the link kept.
  target_ = renamed_path(path);
  // Same directory as the target, so that rename() is atomic.
  temp_path_ = target_ + ".tmp-" + std::to_string(static_cast<long>(::getpid()));
  register_temp(temp_path_);
  file_ = std::fopen(temp_path_.c_str(), "wb");
  if (file_ == nullptr) {
    *message = "cannot create " + temp_path_ + ": " + errno_text();
    unregister_temp(temp_path_);
    temp_path_.clear();
    return false;
  }
  std::setvbuf(file_, nullptr, _IOFBF, std::size_t{1} << 20);
  return true;
}

bool OutputFile::commit(std::string* message) {
  if (file_ == nullptr) {
    *message = "no output open";
    return false;
  }
  if (is_stdout_) {
    const bool ok = std::fflush(file_) == 0 && std::ferror(file_) == 0;
    file_ = nullptr;
    if (!ok) *message = "cannot write to standard output: " + errno_text();
    return ok;
  }
  if (direct_) {
    bool ok = std::fflush(file_) == 0 && std::ferror(file_) == 0;
    if (!ok) *message = "cannot write " + path_ + ": " + errno_text();
    if (std::fclose(file_) != 0 && ok) {
      ok = false;
      *message = "cannot write " + path_ + ": " + errno_text();
    }
    file_ = nullptr;
    direct_ = false;
    return ok;
  }
  bool ok = std::fflush(file_) == 0 && std::ferror(file_) == 0;
  if (!ok) *message = "cannot write " + temp_path_ + ": " + errno_text();
  if (std::fclose(file_) != 0 && ok) {
    ok = false;
    *message = "cannot write " + temp_path_ + ": " + errno_text();
  }
  file_ = nullptr;
  if (ok && std::rename(temp_path_.c_str(), target_.c_str()) != 0) {
    ok = false;
    *message = "cannot rename " + temp_path_ + " to " + target_ + ": " + errno_text();
  }
  if (!ok) std::remove(temp_path_.c_str());
  unregister_temp(temp_path_);
  temp_path_.clear();
  return ok;
}

void OutputFile::discard() {
  if (file_ != nullptr && !is_stdout_) std::fclose(file_);
  if (is_stdout_ && file_ != nullptr) std::fflush(file_);
  file_ = nullptr;
  is_stdout_ = false;
  direct_ = false;
  if (!temp_path_.empty()) {
    std::remove(temp_path_.c_str());
    unregister_temp(temp_path_);
    temp_path_.clear();
  }
}

}  // namespace voxvis::cli
