#include "pmsm_param_id/identification/sample_period.hpp"

#include <algorithm>

namespace pmsm_param_id {

void SamplePeriodEstimator::reset() {
  nominal_ = configured_ > 0 ? configured_ : 0.0;
  count_ = 0;
  above_ = below_ = 0;
}

bool SamplePeriodEstimator::addStep(double dt) {
  if (!(dt > 0)) return false;
  if (configured_ > 0) return false;
  recent_[count_ % kWatchSteps] = dt;
  ++count_;
  const auto medianOf = [this](std::size_t n) {
    std::array<double, kWatchSteps> v = recent_;
    const auto mid = v.begin() + static_cast<long>(n / 2);
    std::nth_element(v.begin(), mid, v.begin() + static_cast<long>(n));
    return *mid;
  };
  if (!known()) {
    if (count_ < kStartupSteps) return false;
    nominal_ = medianOf(kStartupSteps);
    count_ = 0;
    above_ = below_ = 0;
    return true;
  }
  above_ += dt > 1.3 * nominal_;
  below_ += dt < nominal_ / 1.3;
  if (count_ < kWatchSteps) return false;
  // Every kWatchSteps steps: a median more than 30 % away from the nominal period is a new rate.
  // The median (the step of rank n/2 of n) lies above 1.3 nominal only if n - n/2 steps do, and
  // below nominal / 1.3 only if n/2 + 1 steps do; otherwise the window cannot show a new rate and
  // the selection is spared (it was ~1 % of an FBDAPSO update).
  const std::size_t above = above_, below = below_;
  count_ = 0;
  above_ = below_ = 0;
  if (above < kWatchSteps - kWatchSteps / 2 && below < kWatchSteps / 2 + 1) return false;
  const double m = medianOf(kWatchSteps);
  if (m > 1.3 * nominal_ || m < nominal_ / 1.3) {
    nominal_ = m;
    return true;
  }
  return false;
}

}  // namespace pmsm_param_id
