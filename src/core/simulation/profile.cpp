#include "pmsm_param_id/simulation/profile.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace pmsm_param_id {

Profile Profile::constant(double value) {
  Profile p;
  p.type_ = Type::Constant;
  p.a_ = value;
  return p;
}
Profile Profile::step(double initial, double final_value, double time) {
  Profile p;
  p.type_ = Type::Step;
  p.a_ = initial;
  p.b_ = final_value;
  p.c_ = time;
  return p;
}
Profile Profile::ramp(double initial, double final_value, double start, double end) {
  if (!(end > start)) throw std::invalid_argument("ramp end must be after start");
  Profile p;
  p.type_ = Type::Ramp;
  p.a_ = initial;
  p.b_ = final_value;
  p.c_ = start;
  p.d_ = end;
  return p;
}
Profile Profile::sine(double offset, double amplitude, double frequency_hz, double phase_rad) {
  Profile p;
  p.type_ = Type::Sine;
  p.a_ = offset;
  p.b_ = amplitude;
  p.c_ = frequency_hz;
  p.d_ = phase_rad;
  return p;
}
Profile Profile::square(double offset, double amplitude, double frequency_hz) {
  Profile p;
  p.type_ = Type::Square;
  p.a_ = offset;
  p.b_ = amplitude;
  p.c_ = frequency_hz;
  return p;
}
Profile Profile::piecewise(std::vector<double> times, std::vector<double> values) {
  if (times.empty() || times.size() != values.size())
    throw std::invalid_argument("piecewise needs equally many times and values (at least one)");
  for (size_t i = 1; i < times.size(); ++i)
    if (!(times[i] > times[i - 1])) throw std::invalid_argument("piecewise times must increase");
  Profile p;
  p.type_ = Type::Piecewise;
  p.times_ = std::move(times);
  p.values_ = std::move(values);
  return p;
}

double Profile::operator()(double t) const {
  switch (type_) {
    case Type::Constant:
      return a_;
    case Type::Step:
      return t < c_ ? a_ : b_;
    case Type::Ramp:
      if (t <= c_) return a_;
      if (t >= d_) return b_;
      return a_ + (b_ - a_) * (t - c_) / (d_ - c_);
    case Type::Sine:
      return a_ + b_ * std::sin(2.0 * M_PI * c_ * t + d_);
    case Type::Square: {
      const double phase = c_ * t - std::floor(c_ * t);
      return a_ + (phase < 0.5 ? b_ : -b_);
    }
    case Type::Piecewise: {
      if (t <= times_.front()) return values_.front();
      if (t >= times_.back()) return values_.back();
      const auto it = std::upper_bound(times_.begin(), times_.end(), t);
      const size_t i = static_cast<size_t>(it - times_.begin());
      const double f = (t - times_[i - 1]) / (times_[i] - times_[i - 1]);
      return values_[i - 1] + f * (values_[i] - values_[i - 1]);
    }
  }
  return a_;
}

}  // namespace pmsm_param_id
