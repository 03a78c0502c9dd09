// The quantum of a logged rotor angle: an encoder's count (2 pi p / counts per revolution of
// electrical angle), or none.
//
// An incremental encoder's angle moves in whole counts, so every step of the logged electrical
// angle is an integer multiple of one quantum (a wrap of the logged angle is an exact 2 pi, which
// the step takes out). The quantum is the approximate greatest common divisor of the first
// kSteps non-zero steps; an angle from an observer or a resolver has no such divisor above the
// logging precision. Steps all of one size (a constant speed) decide nothing, since an exact angle
// has them too (the divisor is then the step itself): the quantum waits for steps of different
// counts or for the angle pausing between steps.
#pragma once
#include <array>
#include <cmath>
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
  std::size_t pauses_ = 0;  // steps of no count between non-zero ones
  bool decided_ = false;
  double quantum_ = 0.0;
};

/// Whether an encoder's count is locked to the sampling: the counted angle steps by the same whole
/// number of counts period after period (a speed of exactly n counts per period, held there by a
/// speed loop that reads the same counts). The quantisation error then stays where it is instead
/// of sweeping through the count, so the rotor's motion within a count is not seen at all: a d-axis
/// injection shakes the rotor through the reluctance torque by a fraction of a count, and the
/// drive's frame wobbles against the rotor in phase with i_d, which reads as a resistance
/// (doc/algorithm.md section 8, "An encoder's count locked to the sampling").
class CountLock {
 public:
  /// Consecutive steps of the same number of counts, as a share of the steps over the fitness
  /// window's time constant, at or above which the count is locked. Measured on the switching-level
  /// industrial drive (10 000 counts, 8 kHz): 0.96 at 1200 rpm (25 counts every period), 0.58 at
  /// 1190 rpm, 0.33 at 800 rpm.
  static constexpr double kLockedShare = 0.9;

  void reset() { *this = CountLock{}; }
  /// The stream broke: the next step has no predecessor (the averages are kept).
  void breakContinuity() { have_step_ = false; }
  /// One period: the logged angle's step [rad] (wrapped), the quantum [rad], the nominal period [s], the
  /// time constants [s] of the lock's detection (the fitness window's) and of the window whose
  /// locked share and d current are tracked (the slow window's), the sample's i_d [A].
  void add(double angle_step, double quantum, double dt, double detection_time_constant, double window_time_constant,
           double i_d);
  /// The count is locked now.
  bool locked() const { return fast_.weight > 0.5 && fast_.mean() >= kLockedShare; }
  /// Over one of the two time constants: the share of the data taken while the count was locked
  /// [-], and the d current's mean and standard deviation [A].
  struct Window {
    double locked_share = 0.0, i_d_mean = 0.0, i_d_spread = 0.0;
  };
  Window detectionWindow() const { return of(locked() ? 1.0 : 0.0, fast_i_d_); }
  Window window() const { return of(window_.weight > 0 ? window_.mean() : 0.0, i_d_); }

 private:
  // An exponentially weighted mean, its weight rising to 1 (the mean is sum / weight).
  struct Average {
    double weight = 0.0, sum = 0.0, sum2 = 0.0, alpha = 0.0, alpha_dt = 0.0, alpha_tau = 0.0;
    void add(double x, double dt, double tau);
    double mean() const { return sum / weight; }
    double spread() const;  ///< standard deviation
  };
  static Window of(double locked_share, const Average& i_d) {
    return i_d.weight > 0 ? Window{locked_share, i_d.mean(), i_d.spread()} : Window{locked_share, 0.0, 0.0};
  }
  bool have_step_ = false;
  long last_counts_ = 0;
  Average fast_, window_, i_d_, fast_i_d_;
};

// Defined here, not in angle_quantum.cpp: BlockStatistics::add calls it every sample from its
// AVX2 clone (PMSM_VECTOR_CLONES), and a call into code built without AVX paid a transition every
// time (measured: 2 us of a 6 us sample on industrial_pwm).
inline void CountLock::Average::add(double x, double dt, double tau) {
  if (dt != alpha_dt || tau != alpha_tau) {  // the period rarely changes: one exp per change
    alpha = 1.0 - std::exp(-dt / tau);
    alpha_dt = dt;
    alpha_tau = tau;
  }
  weight += alpha * (1.0 - weight);
  sum += alpha * (x - sum);
  sum2 += alpha * (x * x - sum2);
}

inline void CountLock::add(double angle_step, double quantum, double dt, double detection_time_constant,
                           double window_time_constant, double i_d) {
  if (!(quantum > 0) || !std::isfinite(angle_step) || !(dt > 0) || !(detection_time_constant > 0) ||
      !(window_time_constant > 0)) {
    have_step_ = false;
    return;
  }
  const long counts = std::lround(angle_step / quantum);
  const bool had = have_step_;
  const bool same = had && counts == last_counts_;
  last_counts_ = counts;
  have_step_ = true;
  if (!had) return;
  fast_.add(same ? 1.0 : 0.0, dt, detection_time_constant);
  window_.add(locked() ? 1.0 : 0.0, dt, window_time_constant);
  i_d_.add(i_d, dt, window_time_constant);
  fast_i_d_.add(i_d, dt, detection_time_constant);
}

}  // namespace pmsm_param_id
