// assert.h — VOXVIS_ASSERT: invariants checked in Debug and sanitizer builds.
//
// On when VOXVIS_ASSERTS is defined (CMake defines it for Debug builds and
// with VOXVIS_SANITIZE, so that the sanitizer stage of the tests checks
// them), off in Release: there the condition is not evaluated. A failed
// invariant prints where and what, then aborts (the sanitizers' own report
// follows under them). For the hot loops' invariants: indices within their
// tables, counts that never go below zero, spans within the buffer.
#pragma once

#include <cstdio>
#include <cstdlib>

namespace voxvis::detail {

[[noreturn]] inline void assert_failed(const char* what, const char* file, int line) {
  std::fprintf(stderr, "%s:%d: invariant failed: %s\n", file, line, what);
  std::abort();
}

}  // namespace voxvis::detail

#if defined(VOXVIS_ASSERTS)
#define VOXVIS_ASSERT(cond) ((cond) ? static_cast<void>(0) : ::voxvis::detail::assert_failed(#cond, __FILE__, __LINE__))
#else
#define VOXVIS_ASSERT(cond) static_cast<void>(sizeof(cond))
#endif
