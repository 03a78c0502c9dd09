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
  if (!(step > kPrecision)) {  // standing still (or within the logging precision)
    if (count_ > 0) ++pauses_;  // between moves: a count not yet reached
    return false;
  }
  steps_[count_++] = step;
  if (count_ < kSteps) return false;
  double g = steps_[0];
  for (std::size_t k = 1; k < kSteps; ++k) g = approximateGcd(g, steps_[k], kPrecision);
  // A divisor well above the precision that every step is a whole multiple of (to 1 % of it).
  bool whole = g > 100.0 * kPrecision, distinct = false;
  for (std::size_t k = 0; whole && k < kSteps; ++k) {
    const double n = steps_[k] / g;
    whole = std::abs(n - std::round(n)) < 0.01;
    distinct = distinct || std::abs(steps_[k] - steps_[0]) > 0.5 * g;
  }
  // Steps all of one size say nothing yet: an exact angle at a constant speed has them too (the
  // divisor is then the step itself). An encoder shows its count where the steps differ by whole
  // counts, or where the angle pauses between steps of one count; until then, the next kSteps.
  if (whole && !distinct && pauses_ == 0) {
    count_ = 0;
    return false;
  }
  decided_ = true;
  quantum_ = whole ? g : 0.0;
  return true;
}

double CountLock::Average::spread() const {
  const double m = mean();
  return std::sqrt(std::max(0.0, sum2 / weight - m * m));
}

}  // namespace pmsm_param_id
