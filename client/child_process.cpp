// child_process.cpp — see child_process.h.
#include "child_process.h"

#include <poll.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>

namespace voxvis::cli {
namespace {

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kSanitized = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif
#else
constexpr bool kSanitized = false;
#endif

/// In the child: its address space limited to what it has plus `bytes`.
void limit_memory(std::uint64_t bytes) {
  if (kSanitized) return;
  unsigned long long pages = 0;
  if (std::FILE* f = std::fopen("/proc/self/statm", "r")) {
    if (std::fscanf(f, "%llu", &pages) != 1) pages = 0;
    std::fclose(f);
  }
  const std::uint64_t now = static_cast<std::uint64_t>(pages) * static_cast<std::uint64_t>(::sysconf(_SC_PAGESIZE));
  const rlimit lim{static_cast<rlim_t>(now + bytes), static_cast<rlim_t>(now + bytes)};
  (void)::setrlimit(RLIMIT_AS, &lim);
}

}  // namespace

bool child_memory_limits() { return !kSanitized; }

std::uint64_t default_child_memory_bytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), size = ::sysconf(_SC_PAGESIZE);
  const std::uint64_t half = pages > 0 && size > 0 ? static_cast<std::uint64_t>(pages) * static_cast<std::uint64_t>(size) / 2 : 0;
  return std::max<std::uint64_t>(half, std::uint64_t{1} << 30);
}

ChildOutcome run_in_child(const std::function<int(int fd)>& work, double timeout_s,
                          const std::function<void(std::string_view)>& on_data, std::uint64_t memory_bytes) {
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
    if (memory_bytes > 0) limit_memory(memory_bytes);
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
