// The nominal sampling period of a stream, from a robust statistic of its time steps.
//
// A single odd step (a stamp 1 ns after its predecessor, a reset followed by a jump, jitter) must
// not fix the block length or the gap threshold: the nominal period is the median of the first
// `startup_steps` positive steps, and it is re-established when the median of the recent steps
// stays away from it (the stream's rate really changed).
#pragma once
#include <array>
#include <cstddef>

namespace pmsm_param_id {

class SamplePeriodEstimator {
 public:
  static constexpr std::size_t kStartupSteps = 8;   ///< steps before the first nominal period
  static constexpr std::size_t kWatchSteps = 32;    ///< recent steps watched for a rate change

  /// configured_period > 0: known in advance (configuration), never estimated.
  explicit SamplePeriodEstimator(double configured_period = 0.0) : configured_(configured_period) { reset(); }
  void reset();
  /// Records a positive step [s]. Returns true when the nominal period changed (first estimate
  /// or a rate change), so that the caller re-blocks the stream.
  bool addStep(double dt);
  bool known() const { return nominal_ > 0; }
  double nominal() const { return nominal_; }  ///< [s]; 0 while unknown

 private:
  double configured_;
  double nominal_ = 0.0;
  std::array<double, kWatchSteps> recent_{};
  std::size_t count_ = 0;
  std::size_t above_ = 0, below_ = 0;  ///< steps of the watch window above 1.3 nominal, below nominal / 1.3
};

}  // namespace pmsm_param_id
