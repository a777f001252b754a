// numeric.h — small numeric helpers shared by the engine's sources.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#if defined(__x86_64__) || defined(__i386__)
#include <x86intrin.h>
#endif

#include "voxvis/types.h"

namespace voxvis::detail {

/// A cheap monotonic tick count for splitting a frame's time into parts
/// (FrameStats::render_us): the time stamp counter on x86, else the steady
/// clock in nanoseconds. Ticks are only ever compared with ticks of the same
/// frame; the frame's clock reads (two, as every timed method makes) turn
/// their ratio into microseconds.
inline std::uint64_t ticks() {
#if defined(__x86_64__) || defined(__i386__)
  return __rdtsc();
#else
  return static_cast<std::uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count());
#endif
}

/// One unit in the last place of 1.0.
/// std::fmin(a, b) and std::fmax(a, b) where `a` is not NaN (a NaN `b`
/// leaves `a`, as they do), without the library call they make at -O3 for
/// their NaN rule. For the buffer's per-box and per-occluder loops.
inline double least(double a, double b) { return b < a ? b : a; }
inline double greatest(double a, double b) { return b > a ? b : a; }

inline constexpr double kUlp = std::numeric_limits<double>::epsilon();

/// Clamps a grid coordinate to [lo, hi] before converting it, so huge or
/// far-away values never overflow the integer.
inline int clamp_floor(double g, int lo, int hi) {
  if (!(g >= lo)) return lo;
  if (g >= hi) return hi;
  return static_cast<int>(std::floor(g));
}

inline bool finite3(const Vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

/// Largest absolute component.
inline double max_abs(const Vec3& v) {
  return std::max(std::fabs(v.x), std::max(std::fabs(v.y), std::fabs(v.z)));
}

}  // namespace voxvis::detail
