// output_file.h — all-or-nothing output: data goes to a temporary file next
// to the target, renamed over it only by commit(). A run that fails (or is
// interrupted by SIGINT/SIGTERM/SIGHUP) removes the temporary file and leaves
// any earlier target untouched, so a file at the target path is always complete.
//
// A symbolic link is followed: the file it names is replaced, the link
// kept. A target that exists and is not a regular file is never replaced: a
// character device or a FIFO (/dev/null, /dev/stdout, a named pipe) is
// written to directly, as a shell's `>` would, and so not all or nothing; a
// directory, a socket or a block device is refused, naming what it is. Every
// command that writes a file writes it through OutputFile.
#pragma once

#include <cstdio>
#include <string>
#include <string_view>

namespace voxvis::cli {

/// Whether `path` is a character device or a FIFO (written in place).
bool is_device_or_fifo(const std::string& path);

/// The file a regular output at `path` replaces: `path`, or for a symbolic
/// link the file it names (all links resolved), so that the link stays
/// (`/dev/stdout` redirected to a file: that file). Its temporary file is
/// this path + ".tmp-<pid>".
std::string renamed_path(const std::string& path);

class OutputFile {
 public:
  OutputFile() = default;
  ~OutputFile();  ///< Discards the data unless committed.
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  /// Starts writing `path`, or standard output when `path` is empty or "-";
  /// a character device or FIFO at `path` directly. On failure (a directory
  /// or another kind of file that is not a regular one there, a temporary
  /// file that cannot be made) returns false and sets `message`.
  bool open(const std::string& path, std::string* message);
  bool write(std::string_view data) {
    return std::fwrite(data.data(), 1, data.size(), file_) == data.size();
  }
  /// Flushes, closes and renames into place. On failure removes the
  /// temporary file, returns false and sets `message`.
  bool commit(std::string* message);
  /// Closes and removes the temporary file (no-op for stdout).
  void discard();
  const std::string& path() const { return path_; }
  /// A character device or FIFO, written in place (it cannot be read back).
  bool direct() const { return direct_; }
  /// The file to write, for a library that writes a file by name (OpenVDB)
  /// instead of through write(): the temporary file, which commit() renames
  /// into place all the same, or the device or FIFO itself. Empty for
  /// standard output.
  const std::string& temp_path() const { return direct_ ? path_ : temp_path_; }

 private:
  std::FILE* file_ = nullptr;
  bool is_stdout_ = false;
  bool direct_ = false;  // A character device or FIFO, written to in place.
  std::string path_;       // As named.
  std::string target_;     // What the rename replaces (renamed_path).
  std::string temp_path_;
};

}  // namespace voxvis::cli
