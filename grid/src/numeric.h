// numeric.h — small numeric helpers shared by the engine's sources.
#pragma once

#include <algorithm>
#include <bit>
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

/// std::fmin(a, b) and std::fmax(a, b) where `a` is not NaN (a NaN `b`
/// leaves `a`, as they do), without the library call they make at -O3 for
/// their NaN rule. For the buffer's per-box and per-occluder loops.
inline double least(double a, double b) { return b < a ? b : a; }
inline double greatest(double a, double b) { return b > a ? b : a; }

/// Whether this CPU runs AVX2 (and the build has the engine's AVX2 kernels,
/// written for x86-64 with GCC or Clang); asked once.
inline bool cpu_has_avx2() {
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
  static const bool has = __builtin_cpu_supports("avx2");
  return has;
#else
  return false;
#endif
}

/// One unit in the last place of 1.0.
inline constexpr double kUlp = std::numeric_limits<double>::epsilon();

/// The largest float not above d (NaN for NaN): for every float m,
/// static_cast<double>(m) > d exactly when m > float_at_or_below(d), so a
/// loop over floats compares them with d in float (the occludee test's scan
/// of tile bounds).
inline float float_at_or_below(double d) {
  constexpr double kMax = std::numeric_limits<float>::max();
  constexpr float kInfF = std::numeric_limits<float>::infinity();
  if (std::isnan(d)) return std::numeric_limits<float>::quiet_NaN();
  if (d >= kMax) return d == std::numeric_limits<double>::infinity() ? kInfF : std::numeric_limits<float>::max();
  if (d < -kMax) return -kInfF;
  const float f = static_cast<float>(d);  // In range: rounds to one of its two neighbours.
  if (!(static_cast<double>(f) > d)) return f;
  // The float below f (finite, above -FLT_MAX), without a library call:
  // one step of the magnitude's bits, and below a zero the least negative.
  const std::uint32_t u = std::bit_cast<std::uint32_t>(f);
  return std::bit_cast<float>(f > 0.0f ? u - 1u : f < 0.0f ? u + 1u : 0x80000001u);
}

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
