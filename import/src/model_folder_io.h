// model_folder_io.h — what a model file may make the importer read: itself,
// and the files it refers to (a glTF's buffers and images, an OBJ's
// materials, ...) only when they lie in the model's folder or below it once
// ".." and symbolic links are resolved, and are regular files. A model from
// elsewhere must not read what its reader's user can ("../secret.bin",
// "/etc/shadow", a link to /dev/zero, a FIFO that never ends). assimp reads
// every file through this IOSystem; the first file refused is kept for the
// error, which names it.
#pragma once

#include <filesystem>
#include <string>

#include <assimp/DefaultIOSystem.h>

namespace voxvis::import {

class ModelFolderIO : public Assimp::DefaultIOSystem {
 public:
  /// For the model file `model` (any path; resolved here).
  explicit ModelFolderIO(const std::string& model);

  bool Exists(const char* file) const override;
  Assimp::IOStream* Open(const char* file, const char* mode = "rb") override;

  /// The first file refused, and why ("" when none was).
  const std::string& refused() const { return refused_; }

 private:
  /// Whether `file` may be read; when not, the reason is kept in refused_.
  bool allowed(const char* file) const;

  std::filesystem::path folder_;  // The model's folder, resolved.
  std::filesystem::path model_;   // The model file, resolved.
  mutable std::string refused_;
};

}  // namespace voxvis::import
