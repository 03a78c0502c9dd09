// Time profiles for scenario inputs (speed reference, load, injection, parameter drift).
#pragma once
#include <string>
#include <vector>

namespace pmsm_param_id {

/// A scalar function of time [s]. Units are those of the quantity it drives.
class Profile {
 public:
  enum class Type { Constant, Step, Ramp, Sine, Square, Piecewise };

  static Profile constant(double value);
  static Profile step(double initial, double final_value, double time);
  static Profile ramp(double initial, double final_value, double start, double end);
  static Profile sine(double offset, double amplitude, double frequency_hz, double phase_rad = 0.0);
  static Profile square(double offset, double amplitude, double frequency_hz);
  /// Linear interpolation through (times[i], values[i]); held constant outside. times increasing.
  static Profile piecewise(std::vector<double> times, std::vector<double> values);

  double operator()(double t) const;
  Type type() const { return type_; }

 private:
  Type type_ = Type::Constant;
  double a_ = 0, b_ = 0, c_ = 0, d_ = 0;  // meaning depends on type_
  std::vector<double> times_, values_;
};

}  // namespace pmsm_param_id
