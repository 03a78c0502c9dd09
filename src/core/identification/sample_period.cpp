#include "pmsm_param_id/identification/sample_period.hpp"

#include <algorithm>

namespace pmsm_param_id {

void SamplePeriodEstimator::reset() {
  nominal_ = configured_ > 0 ? configured_ : 0.0;
  count_ = 0;
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
    return true;
  }
  if (count_ < kWatchSteps) return false;
  // Every kWatchSteps steps: a median more than 30 % away from the nominal period is a new rate.
  const double m = medianOf(kWatchSteps);
  count_ = 0;
  if (m > 1.3 * nominal_ || m < nominal_ / 1.3) {
    nominal_ = m;
    return true;
  }
  return false;
}

}  // namespace pmsm_param_id
