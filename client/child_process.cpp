// child_process.cpp — see child_process.h.
#include "child_process.h"

#include <poll.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>

namespace voxvis::cli {

ChildOutcome run_in_child(const std::function<int(int fd)>& work, double timeout_s,
                          const std::function<void(std::string_view)>& on_data) {
  ChildOutcome out;
  int fds[2];
  if (::pipe(fds) != 0) {
    out.error = std::string("cannot create a pipe: ") + std::strerror(errno);
    return out;
  }
  std::fflush(nullptr);
  out.pid = ::fork();
  if (out.pid < 0) {
    out.error = std::string("cannot start a child process: ") + std::strerror(errno);
    ::close(fds[0]);
    ::close(fds[1]);
    return out;
  }
  if (out.pid == 0) {
    ::close(fds[0]);
    const int code = work(fds[1]);
    std::fflush(nullptr);
    ::_exit(code);
  }
  ::close(fds[1]);
  const auto start = std::chrono::steady_clock::now();
  for (;;) {
    int wait_ms = -1;
    if (timeout_s > 0.0) {
      const double left = timeout_s - std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      if (left <= 0.0) {
        out.timed_out = true;
        break;
      }
      wait_ms = static_cast<int>(std::min(left * 1000.0 + 1.0, 60'000.0));
    }
    pollfd p{fds[0], POLLIN, 0};
    if (::poll(&p, 1, wait_ms) <= 0) continue;  // EINTR or the deadline, checked above.
    char buf[1 << 16];
    const ssize_t n = ::read(fds[0], buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;  // The child is done (or closed the pipe in dying).
    on_data(std::string_view(buf, static_cast<std::size_t>(n)));
  }
  ::close(fds[0]);
  if (out.timed_out) ::kill(out.pid, SIGKILL);
  while (::waitpid(out.pid, &out.status, 0) < 0 && errno == EINTR) {
  }
  return out;
}

std::string signal_text(int sig) {
  const char* name = sig == SIGSEGV ? "SIGSEGV" : sig == SIGABRT ? "SIGABRT" : sig == SIGBUS ? "SIGBUS"
                     : sig == SIGFPE ? "SIGFPE" : sig == SIGILL ? "SIGILL" : sig == SIGKILL ? "SIGKILL" : nullptr;
  return "signal " + std::to_string(sig) + (name != nullptr ? std::string(" (") + name + ")" : std::string());
}

}  // namespace voxvis::cli
