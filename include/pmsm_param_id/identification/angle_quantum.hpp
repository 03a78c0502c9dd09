// The quantum of a logged rotor angle: an encoder's count (2 pi p / counts per revolution of
// electrical angle), or none.
//
// An incremental encoder's angle moves in whole counts, so every step of the logged electrical
// angle is an integer multiple of one quantum (a wrap of the logged angle is an exact 2 pi, which
// the step takes out). The quantum is the approximate greatest common divisor of the first
// kSteps non-zero steps; an angle from an observer or a resolver has no such divisor above the
// logging precision.
#pragma once
#include <array>
#include <cstddef>
#include <limits>

namespace pmsm_param_id {

class AngleQuantum {
 public:
  static constexpr std::size_t kSteps = 64;  ///< non-zero steps seen before deciding
  /// A divisor at or below this is the angle's logging precision (a float32 angle), not a quantum [rad].
  static constexpr double kPrecision = 1e-6;

  void reset();
  /// The logged angle of the next sample [rad] (NaN: not logged; the next step starts afresh).
  /// Returns true at the sample that decides.
  bool add(double theta_e);
  bool decided() const { return decided_; }
  /// The quantum [rad]; 0 = the angle is not quantised (or not decided yet).
  double quantum() const { return quantum_; }

 private:
  double last_ = std::numeric_limits<double>::quiet_NaN();
  std::array<double, kSteps> steps_{};
  std::size_t count_ = 0;
  bool decided_ = false;
  double quantum_ = 0.0;
};

}  // namespace pmsm_param_id
