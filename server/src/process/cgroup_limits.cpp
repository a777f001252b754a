#include "process/cgroup_limits.h"

#include <cmath>
#include <fstream>
#include <sstream>
#include <vector>

namespace voxvis::server {
namespace {

/// The first line of a file, or empty.
std::string first_line(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  if (in) std::getline(in, line);
  return line;
}

/// The cgroup paths of /proc/self/cgroup: for v2 ("0::/path") the path under
/// "" ; for v1 ("N:memory:/path", "N:cpu,cpuacct:/path") under each
/// controller it lists.
std::vector<std::pair<std::string, std::string>> cgroup_paths(const std::string& self) {
  std::vector<std::pair<std::string, std::string>> out;
  std::ifstream in(self);
  std::string line;
  while (std::getline(in, line)) {
    const std::size_t a = line.find(':');
    const std::size_t b = a == std::string::npos ? a : line.find(':', a + 1);
    if (b == std::string::npos) continue;
    std::string controllers = line.substr(a + 1, b - a - 1);
    std::string path = line.substr(b + 1);
    if (controllers.empty()) {
      out.emplace_back("", path);
      continue;
    }
    std::stringstream list(controllers);
    std::string c;
    while (std::getline(list, c, ',')) out.emplace_back(c, path);
  }
  return out;
}

std::optional<std::uint64_t> number(const std::string& text) {
  if (text.empty() || text == "max") return std::nullopt;
  try {
    std::size_t used = 0;
    const unsigned long long v = std::stoull(text, &used);
    if (used != text.size()) return std::nullopt;
    return v;
  } catch (...) {
    return std::nullopt;
  }
}

/// The file `name` of the controller's cgroup, or of the root when the
/// process's own path is not mounted there (inside a container the
/// namespace's root is its own cgroup).
std::string value(const std::string& root, const std::string& mount, const std::string& path,
                  const std::string& name) {
  const std::string base = mount.empty() ? root : root + "/" + mount;
  std::string v = first_line(base + path + "/" + name);
  if (v.empty()) v = first_line(base + "/" + name);
  return v;
}

}  // namespace

std::optional<std::uint64_t> cgroup_memory_limit(const std::string& root, const std::string& self) {
  for (const auto& [controller, path] : cgroup_paths(self)) {
    std::optional<std::uint64_t> limit;
    if (controller.empty()) limit = number(value(root, "", path, "memory.max"));
    if (controller == "memory") limit = number(value(root, "memory", path, "memory.limit_in_bytes"));
    // cgroup v1 says "no limit" with a huge page-rounded number.
    if (limit && *limit < (std::uint64_t{1} << 62)) return limit;
  }
  return std::nullopt;
}

std::optional<unsigned> cgroup_cpu_limit(const std::string& root, const std::string& self) {
  for (const auto& [controller, path] : cgroup_paths(self)) {
    std::optional<std::uint64_t> quota, period;
    if (controller.empty()) {
      std::stringstream ss(value(root, "", path, "cpu.max"));  // "QUOTA PERIOD" or "max PERIOD"
      std::string q, p;
      ss >> q >> p;
      quota = number(q);
      period = number(p);
    } else if (controller == "cpu") {
      const std::string q = value(root, "cpu", path, "cpu.cfs_quota_us");  // -1: none
      if (q.empty() || q[0] == '-') continue;
      quota = number(q);
      period = number(value(root, "cpu", path, "cpu.cfs_period_us"));
    }
    if (quota && period && *period > 0 && *quota > 0)
      return static_cast<unsigned>(std::max(1.0, std::ceil(double(*quota) / double(*period))));
  }
  return std::nullopt;
}

}  // namespace voxvis::server
