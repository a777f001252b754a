// child_process.h — running a piece of work in a child process with a
// deadline, reading what it writes to a pipe: how the CLI reads model files
// (voxvis import, models by reference), so that a reader that crashes or
// loops forever on a malformed file becomes an error naming the file.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>

namespace voxvis::cli {

struct ChildOutcome {
  std::string error;       ///< Not empty: the child could not be started (pipe or fork failed).
  pid_t pid = -1;
  bool timed_out = false;  ///< Killed (SIGKILL) at the deadline.
  int status = 0;          ///< waitpid's status when not timed out.
  bool exited() const { return error.empty() && !timed_out && WIFEXITED(status); }
  int exit_code() const { return WEXITSTATUS(status); }
  /// The signal that ended it, 0 if none.
  int signal() const { return error.empty() && !timed_out && WIFSIGNALED(status) ? WTERMSIG(status) : 0; }
};

/// Forks: the child runs work(fd) (fd: the pipe's writing end) and exits
/// with its result; the parent passes every chunk the child writes to
/// `on_data` until the pipe closes, or kills the child once `timeout_s`
/// seconds have passed (0: no deadline), and reaps it. The child may take
/// `memory_bytes` of address space beyond what it was forked with (0: no
/// limit; RLIMIT_AS, so that an allocation past it fails as out of memory
/// in the child alone). Sanitizer builds set no limit: their shadow memory
/// is address space too.
ChildOutcome run_in_child(const std::function<int(int fd)>& work, double timeout_s,
                          const std::function<void(std::string_view)>& on_data, std::uint64_t memory_bytes = 0);

/// The default limit of a model reader's memory: half the machine's
/// memory, at least 1 GiB.
std::uint64_t default_child_memory_bytes();

/// Whether run_in_child can limit memory in this build (not under the
/// sanitizers).
bool child_memory_limits();

/// "signal 11 (SIGSEGV)".
std::string signal_text(int sig);

}  // namespace voxvis::cli
