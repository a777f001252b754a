// output_file.h — all-or-nothing output: data goes to a temporary file next
// to the target, renamed over it only by commit(). A run that fails (or is
// interrupted by SIGINT/SIGTERM/SIGHUP) removes the temporary file and leaves
// any earlier target untouched, so a file at the target path is always complete.
#pragma once

#include <cstdio>
#include <string>
#include <string_view>

namespace voxvis::cli {

class OutputFile {
 public:
  OutputFile() = default;
  ~OutputFile();  ///< Discards the data unless committed.
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  /// Starts writing `path`, or standard output when `path` is empty or "-".
  /// On failure returns false and sets `message`.
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
  /// The temporary file, for a library that writes a file by name (OpenVDB)
  /// instead of through write(): commit() renames it into place all the
  /// same. Empty for standard output.
  const std::string& temp_path() const { return temp_path_; }

 private:
  std::FILE* file_ = nullptr;
  bool is_stdout_ = false;
  std::string path_;
  std::string temp_path_;
};

}  // namespace voxvis::cli
