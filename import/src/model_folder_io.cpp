// model_folder_io.cpp — see model_folder_io.h.
#include "model_folder_io.h"

#include <system_error>

namespace voxvis::import {
namespace {

/// `p` made absolute with every "..", "." and symbolic link resolved (as
/// far as it exists).
std::filesystem::path resolved(const std::filesystem::path& p) {
  std::error_code ec;
  std::filesystem::path r = std::filesystem::weakly_canonical(std::filesystem::absolute(p, ec), ec);
  return ec ? std::filesystem::path() : r;
}

/// Whether `p` is `folder` or lies below it (both resolved).
bool within(const std::filesystem::path& p, const std::filesystem::path& folder) {
  auto f = folder.begin(), q = p.begin();
  for (; f != folder.end(); ++f, ++q)
    if (q == p.end() || *f != *q) return false;
  return true;
}

}  // namespace

ModelFolderIO::ModelFolderIO(const std::string& model) : model_(resolved(model)) {
  folder_ = model_.parent_path();
}

bool ModelFolderIO::allowed(const char* file) const {
  if (file == nullptr || *file == '\0') return false;
  const std::filesystem::path p = resolved(file);
  std::string why;
  if (p.empty()) {
    why = "cannot be resolved";
  } else if (p != model_ && !within(p, folder_)) {
    why = "lies outside the model's folder (" + folder_.string() + "); only files in it or below it are read";
  } else {
    std::error_code ec;
    const auto st = std::filesystem::status(p, ec);
    if (!ec && std::filesystem::exists(st) && !std::filesystem::is_regular_file(st))
      why = "is not a regular file (a device, a FIFO or a directory); only regular files are read";
  }
  if (why.empty()) return true;
  if (refused_.empty()) refused_ = "the model refers to '" + std::string(file) + "', which " + why;
  return false;
}

bool ModelFolderIO::Exists(const char* file) const { return allowed(file) && DefaultIOSystem::Exists(file); }

Assimp::IOStream* ModelFolderIO::Open(const char* file, const char* mode) {
  // Reading only: a model is never written.
  if (mode == nullptr || mode[0] != 'r' || !allowed(file)) return nullptr;
  return DefaultIOSystem::Open(file, mode);
}

}  // namespace voxvis::import
