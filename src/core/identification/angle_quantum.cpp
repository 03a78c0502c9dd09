#include "pmsm_param_id/identification/angle_quantum.hpp"
#include "pmsm_param_id/model/frames.hpp"

#include <algorithm>
#include <cmath>

namespace pmsm_param_id {

namespace {
// Euclid's algorithm on positive reals, a remainder within `tolerance` of zero or of the divisor
// counting as zero.
double approximateGcd(double a, double b, double tolerance) {
  if (a < b) std::swap(a, b);
  while (b > tolerance) {
    double r = std::fmod(a, b);
    if (r > b - tolerance) r = 0.0;
    a = b;
    b = r;
  }
  return a;
}
}  // namespace

void AngleQuantum::reset() { *this = AngleQuantum{}; }

bool AngleQuantum::add(double theta_e) {
  if (decided_) return false;
  if (!std::isfinite(theta_e)) {
    last_ = theta_e;
    return false;
  }
  const double previous = last_;
  last_ = theta_e;
  if (!std::isfinite(previous)) return false;
  const double step = std::abs(wrappedAngle(theta_e - previous));
  if (!(step > kPrecision)) return false;  // standing still (or within the logging precision)
  steps_[count_++] = step;
  if (count_ < kSteps) return false;
  decided_ = true;
  double g = steps_[0];
  for (std::size_t k = 1; k < kSteps; ++k) g = approximateGcd(g, steps_[k], kPrecision);
  // A divisor well above the precision that every step is a whole multiple of (to 1 % of it).
  bool whole = g > 100.0 * kPrecision;
  for (std::size_t k = 0; whole && k < kSteps; ++k) {
    const double n = steps_[k] / g;
    whole = std::abs(n - std::round(n)) < 0.01;
  }
  quantum_ = whole ? g : 0.0;
  return true;
}

}  // namespace pmsm_param_id
