// Small, fast, seedable generator for the swarm's r1, r2 and Metropolis draws.
// xoshiro256+ (Blackman & Vigna), seeded by splitmix64: a few ns per draw, far cheaper than
// std::mt19937_64 + std::uniform_real_distribution, and bit-identical on every platform.
#pragma once
#include <cstdint>

namespace pmsm_param_id {

class FastRandom {
 public:
  explicit FastRandom(std::uint64_t seed = 1) { reseed(seed); }
  void reseed(std::uint64_t seed) {
    for (std::uint64_t& s : s_) {
      seed += 0x9E3779B97F4A7C15ull;
      std::uint64_t z = seed;
      z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
      z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
      s = z ^ (z >> 31);
    }
  }
  /// Two independent uniforms in [0, 1) with 26-bit resolution from one draw (Eq. 4's r1, r2).
  void uniformPair(double& a, double& b) {
    const std::uint64_t x = next();
    a = static_cast<double>(x >> 38) * 0x1.0p-26;
    b = static_cast<double>((x >> 12) & 0x3FFFFFFull) * 0x1.0p-26;
  }
  /// Uniform in [0, 1) with 53-bit resolution.
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }

 private:
  std::uint64_t next() {
    const std::uint64_t result = s_[0] + s_[3];
    const std::uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = (s_[3] << 45) | (s_[3] >> 19);
    return result;
  }
  std::uint64_t s_[4];
};

}  // namespace pmsm_param_id
