// Small, fast, seedable generator for the swarm's r1, r2 and Metropolis draws.
// Four xoshiro256++ streams (Blackman & Vigna) advanced in lock step and stored lane by lane, so
// that one swarm iteration's uniforms come from vector instructions in one call. (One serial
// stream is a chain of dependent xors: about three cycles per draw whatever the machine's width.)
// Seeded by splitmix64; the same numbers on every platform and instruction set.
#pragma once
#include <cstddef>
#include <cstdint>

namespace pmsm_param_id {

class BlockRandom {
 public:
  static constexpr std::size_t kLanes = 4;
  /// fill() writes uniforms in multiples of this (two per lane and step).
  static constexpr std::size_t kBlock = 2 * kLanes;

  explicit BlockRandom(std::uint64_t seed = 1) { reseed(seed); }
  void reseed(std::uint64_t seed);
  /// A count of uniforms rounded up to what fill() writes.
  static constexpr std::size_t blockCount(std::size_t n) { return (n + kBlock - 1) / kBlock * kBlock; }
  /// Fills out[0, blockCount(n)) with uniforms in [0, 1) of 32-bit resolution: each 64-bit output
  /// gives two, from its upper and its lower half.
  void fill(double* out, std::size_t n);
  /// One uniform in [0, 1) from the same streams (initial positions, restarts).
  double uniform() {
    if (used_ == kBlock) {
      fill(buffer_, kBlock);
      used_ = 0;
    }
    return buffer_[used_++];
  }

 private:
  alignas(32) std::uint64_t s0_[kLanes], s1_[kLanes], s2_[kLanes], s3_[kLanes];
  double buffer_[kBlock];
  std::size_t used_ = kBlock;
};

}  // namespace pmsm_param_id
