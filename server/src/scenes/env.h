// env.h — reading the environment (the server's test hooks and settings).
#pragma once

#include <cstdlib>
#include <string>

namespace voxvis::server {

/// An environment variable's value; empty when unset.
inline std::string env_text(const char* name) {
  const char* v = std::getenv(name);
  return v ? v : "";
}

}  // namespace voxvis::server
