#include "pmsm_param_id/identification/random.hpp"

#include <cstring>

#include "vector_clones.hpp"

namespace pmsm_param_id {

namespace {
std::uint64_t splitmix(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// The four lanes as one GCC/Clang vector: one AVX register, or two SSE2 ones.
typedef std::uint64_t Lanes __attribute__((vector_size(8 * BlockRandom::kLanes)));
typedef double LaneDoubles __attribute__((vector_size(8 * BlockRandom::kLanes)));

PMSM_INTEGER_VECTOR_CLONES
void fillLanes(std::uint64_t* s0p, std::uint64_t* s1p, std::uint64_t* s2p, std::uint64_t* s3p, double* out,
               std::size_t n) {
  Lanes s0, s1, s2, s3;  // held in registers for the whole block
  std::memcpy(&s0, s0p, sizeof s0);
  std::memcpy(&s1, s1p, sizeof s1);
  std::memcpy(&s2, s2p, sizeof s2);
  std::memcpy(&s3, s3p, sizeof s3);
  const Lanes one = Lanes{} + 0x3FF0000000000000ull;  // the bits of 1.0: 52 bits below form a mantissa
  const Lanes low_half = Lanes{} + 0xFFFFFFFFull;
  for (std::size_t k = 0; k < n; k += BlockRandom::kBlock) {
    const Lanes sum = s0 + s3;
    const Lanes r = ((sum << 23) | (sum >> 41)) + s0;  // xoshiro256++: rotl(s0 + s3, 23) + s0
    const Lanes t = s1 << 17;
    s2 ^= s0;
    s3 ^= s1;
    s1 ^= s2;
    s0 ^= s3;
    s2 ^= t;
    s3 = (s3 << 45) | (s3 >> 19);
    // A 32-bit half shifted under the exponent of 1.0 is a number in [1, 2).
    const LaneDoubles upper = reinterpret_cast<LaneDoubles>(((r >> 32) << 20) | one) - 1.0;
    const LaneDoubles lower = reinterpret_cast<LaneDoubles>(((r & low_half) << 20) | one) - 1.0;
    std::memcpy(out + k, &upper, sizeof upper);
    std::memcpy(out + k + BlockRandom::kLanes, &lower, sizeof lower);
  }
  std::memcpy(s0p, &s0, sizeof s0);
  std::memcpy(s1p, &s1, sizeof s1);
  std::memcpy(s2p, &s2, sizeof s2);
  std::memcpy(s3p, &s3, sizeof s3);
}
}  // namespace

void BlockRandom::reseed(std::uint64_t seed) {
  for (std::size_t l = 0; l < kLanes; ++l) {
    s0_[l] = splitmix(seed);
    s1_[l] = splitmix(seed);
    s2_[l] = splitmix(seed);
    s3_[l] = splitmix(seed);
  }
  used_ = kBlock;
}

void BlockRandom::fill(double* out, std::size_t n) { fillLanes(s0_, s1_, s2_, s3_, out, n); }

}  // namespace pmsm_param_id
