// The container limits behind the server's defaults (cgroup_limits.h), read
// from a fake /sys/fs/cgroup and /proc/self/cgroup: cgroup v2 and v1, the
// process's own cgroup or the namespace's root, and "no limit" spelled each
// way.
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "process/cgroup_limits.h"
#include "server_process.h"

namespace voxvis::server {
namespace {

namespace fs = std::filesystem;
using servertest::make_temp_dir;
using servertest::spit;

void write(const std::string& path, const std::string& text) {
  fs::create_directories(fs::path(path).parent_path());
  spit(path, text);
}

TEST(CgroupLimits, V2OwnCgroupAndNamespaceRoot) {
  const std::string root = make_temp_dir("cgroup");
  const std::string self = root + "/self";
  write(self, "0::/kubepods/pod1/c1\n");
  EXPECT_FALSE(cgroup_memory_limit(root, self));
  EXPECT_FALSE(cgroup_cpu_limit(root, self));
  write(root + "/kubepods/pod1/c1/memory.max", "2147483648\n");
  write(root + "/kubepods/pod1/c1/cpu.max", "150000 100000\n");
  EXPECT_EQ(cgroup_memory_limit(root, self), std::uint64_t{2147483648});
  EXPECT_EQ(cgroup_cpu_limit(root, self), 2u);  // 1.5 cores, rounded up
  // Inside the container's namespace its own cgroup is the root.
  const std::string ns = make_temp_dir("cgroup");
  write(ns + "/self", "0::/\n");
  write(ns + "/memory.max", "max\n");
  write(ns + "/cpu.max", "max 100000\n");
  EXPECT_FALSE(cgroup_memory_limit(ns, ns + "/self"));
  EXPECT_FALSE(cgroup_cpu_limit(ns, ns + "/self"));
  write(ns + "/memory.max", "536870912\n");
  write(ns + "/cpu.max", "50000 100000\n");
  EXPECT_EQ(cgroup_memory_limit(ns, ns + "/self"), std::uint64_t{536870912});
  EXPECT_EQ(cgroup_cpu_limit(ns, ns + "/self"), 1u);
  write(ns + "/memory.max", "garbage\n");
  EXPECT_FALSE(cgroup_memory_limit(ns, ns + "/self"));
}

TEST(CgroupLimits, V1Controllers) {
  const std::string root = make_temp_dir("cgroup");
  const std::string self = root + "/self";
  write(self, "12:memory:/docker/abc\n4:cpu,cpuacct:/docker/abc\n1:name=systemd:/docker/abc\n");
  write(root + "/memory/docker/abc/memory.limit_in_bytes", "9223372036854771712\n");  // no limit
  write(root + "/cpu/docker/abc/cpu.cfs_quota_us", "-1\n");
  write(root + "/cpu/docker/abc/cpu.cfs_period_us", "100000\n");
  EXPECT_FALSE(cgroup_memory_limit(root, self));
  EXPECT_FALSE(cgroup_cpu_limit(root, self));
  write(root + "/memory/docker/abc/memory.limit_in_bytes", "1073741824\n");
  write(root + "/cpu/docker/abc/cpu.cfs_quota_us", "400000\n");
  EXPECT_EQ(cgroup_memory_limit(root, self), std::uint64_t{1073741824});
  EXPECT_EQ(cgroup_cpu_limit(root, self), 4u);
}

}  // namespace
}  // namespace voxvis::server
