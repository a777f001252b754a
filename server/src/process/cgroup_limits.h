// cgroup_limits.h — the memory and CPU a container may use, for the
// server's defaults (--memory-budget-mib, --workers). In a container the
// machine's figures are the node's: a pod limited to 2 GiB on a 64 GiB node
// would otherwise take a 32 GiB budget and be killed by the kernel where it
// should refuse a scene with RESOURCE_EXHAUSTED.
//
// Read from the process's own cgroup (/proc/self/cgroup) under
// /sys/fs/cgroup: cgroup v2's memory.max and cpu.max, or v1's
// memory.limit_in_bytes and cpu.cfs_quota_us / cpu.cfs_period_us. Anything
// missing or unreadable means no limit.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace voxvis::server {

/// The cgroup's memory limit in bytes; empty when there is none.
std::optional<std::uint64_t> cgroup_memory_limit(const std::string& root = "/sys/fs/cgroup",
                                                 const std::string& self = "/proc/self/cgroup");

/// The cgroup's CPU quota in cores, rounded up (at least 1); empty when there
/// is none.
std::optional<unsigned> cgroup_cpu_limit(const std::string& root = "/sys/fs/cgroup",
                                         const std::string& self = "/proc/self/cgroup");

}  // namespace voxvis::server
