// files.h — whole-file helpers for tests that run the binaries.
#pragma once

#include <string>
#include <vector>

namespace voxvis::test {

/// The file's bytes; empty when it cannot be read.
std::string slurp(const std::string& path);
/// Writes `text` as the whole file.
void spit(const std::string& path, const std::string& text);
/// The lines of `text`, without their newlines.
std::vector<std::string> lines_of(const std::string& text);

}  // namespace voxvis::test
