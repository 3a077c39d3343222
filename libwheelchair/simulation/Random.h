// Portable, reproducible random numbers for the simulator.
//
// std::normal_distribution (and the other std distributions) are implementation-defined:
// the same std::mt19937_64 seed gives different numbers on libstdc++ and libc++. The
// simulator therefore draws only raw 64-bit words from std::mt19937_64 (whose output IS
// specified by the standard) and turns them into uniforms (53-bit mantissa) and normals
// (Box-Muller) itself. The only remaining platform dependence is the last bit of
// std::log/std::cos/std::sin of the C library, which does not change any decision the
// simulator makes in practice.
//
// Every consumer (each sensor's noise, each sensor's timestamp jitter, dropouts, outliers,
// the Pozyx anchor frame, scenario randomness) gets its own stream derived from (seed,
// stream id) with SplitMix64, so switching one effect on does not shift the noise of any
// other stream: a run with gyro_bias differs from the run without it in the gyro only.
//
// Example:
//   Rng gyro(seed, "imu.noise");
//   double n = 0.005 * gyro.normal();
#pragma once

#include <cmath>
#include <cstdint>
#include <random>
#include <string>

namespace wheelchair::simulation {

/// SplitMix64 finaliser: a good 64-bit mix, used to derive independent stream seeds.
inline uint64_t splitMix64(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

/// FNV-1a of a stream name (stable across platforms).
inline uint64_t streamHash(const std::string& name) {
  uint64_t h = 0xcbf29ce484222325ull;
  for (unsigned char c : name) {
    h ^= c;
    h *= 0x100000001b3ull;
  }
  return h;
}

class Rng {
 public:
  Rng(uint64_t seed, const std::string& stream)
      : eng_(splitMix64(seed ^ splitMix64(streamHash(stream)))) {}

  /// Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(eng_() >> 11) * 0x1.0p-53; }
  /// Uniform in [a, b).
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  /// Standard normal (Box-Muller, both values used).
  double normal() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    double u1 = uniform();
    while (u1 <= 0.0) u1 = uniform();
    const double u2 = uniform();
    const double rad = std::sqrt(-2.0 * std::log(u1));
    const double ang = 2.0 * M_PI * u2;
    spare_ = rad * std::sin(ang);
    has_spare_ = true;
    return rad * std::cos(ang);
  }
  /// true with probability p.
  bool bernoulli(double p) { return uniform() < p; }

 private:
  std::mt19937_64 eng_;
  bool has_spare_ = false;
  double spare_ = 0;
};

}  // namespace wheelchair::simulation
