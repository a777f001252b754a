// voxvis/rng.h — seeded random numbers that are the same on every platform,
// for the scene generators (generate.h) and the tests.
//
// Determinism: only std::mt19937_64, whose output sequence the standard
// fixes, and our own mappings below. The standard distributions
// (uniform_real_distribution, uniform_int_distribution, ...) are
// implementation defined and would make scenes differ between standard
// libraries, so they are never used.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>

#include "voxvis/types.h"

namespace voxvis {

/// Seeded random numbers with portable mappings.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : gen_(seed) {}
  /// The next 64 raw bits of the mt19937_64 stream.
  std::uint64_t bits() { return gen_(); }
  /// Uniform in [0, 1), 53 random bits.
  double uniform() { return static_cast<double>(gen_() >> 11) * 0x1.0p-53; }
  /// Uniform in [a, b).
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  /// exp(uniform(log a, log b)); a, b > 0.
  double log_uniform(double a, double b) { return std::exp(uniform(std::log(a), std::log(b))); }
  /// Uniform integer in [lo, hi] (lo <= hi), unbiased.
  int uniform_int(int lo, int hi) {
    const std::uint64_t range =
        static_cast<std::uint64_t>(static_cast<std::int64_t>(hi) - static_cast<std::int64_t>(lo)) + 1;
    const std::uint64_t limit = (~std::uint64_t{0} / range) * range;  // Reject the biased tail.
    std::uint64_t r = gen_();
    while (r >= limit) r = gen_();
    return static_cast<int>(static_cast<std::int64_t>(lo) + static_cast<std::int64_t>(r % range));
  }
  bool chance(double p) { return uniform() < p; }
  /// Uniform in the box [lo, hi), drawn x, then y, then z.
  Vec3 in_box(const Vec3& lo, const Vec3& hi) {
    const double x = uniform(lo.x, hi.x);
    const double y = uniform(lo.y, hi.y);
    const double z = uniform(lo.z, hi.z);
    return {x, y, z};
  }
  /// Uniform on the unit sphere (Archimedes: z uniform in [-1, 1]).
  Vec3 unit_vector() {
    const double z = uniform(-1.0, 1.0);
    const double phi = uniform(0.0, 2.0 * std::numbers::pi);
    const double s = std::sqrt(std::max(0.0, 1.0 - z * z));
    return {s * std::cos(phi), s * std::sin(phi), z};
  }

 private:
  std::mt19937_64 gen_;
};

}  // namespace voxvis
