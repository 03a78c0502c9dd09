// Winding and magnet temperatures from identified R_s and psi_f (doc/algorithm.md section 9).
//   winding: R_s(T) = R_s,ref (1 + alpha (T - T_ref)),   alpha = 3.93e-3 /K for copper
//   magnet:  psi_f(T) = psi_f,ref (1 + beta (T - T_ref)), beta = -1.2e-3 /K for NdFeB
// A temperature exists only while its parameter is identified; its uncertainty is the
// parameter's stated uncertainty divided by the coefficient.
#pragma once
#include <cmath>
#include <limits>

namespace pmsm_param_id {

struct ThermalSettings {
  bool enabled = false;                 ///< a thermal: block was given
  double reference_temperature = NAN;   ///< [degC]
  double R_s_at_reference = 0.0;        ///< [ohm]; 0 = learn from the first identified value
  double psi_f_at_reference = 0.0;      ///< [Wb]; 0 = learn from the first identified value
  double copper_coefficient = 3.93e-3;  ///< alpha [1/K]
  double magnet_coefficient = -1.2e-3;  ///< beta [1/K] (NdFeB; ferrite about -2e-3)
  /// A learnt reference is taken only this long after the first sample [s]: later the motor may
  /// no longer be at reference_temperature, and the temperatures stay unknown.
  double learning_time = 5.0;
};

struct Temperature {
  double value = std::numeric_limits<double>::quiet_NaN();        ///< [degC]; NaN = unknown
  double uncertainty = std::numeric_limits<double>::quiet_NaN();  ///< [K]
};

/// Temperature of a parameter that varies as reference (1 + coefficient (T - T_ref)).
inline Temperature temperatureFrom(double value, double relative_uncertainty, double reference,
                                   double reference_temperature, double coefficient) {
  Temperature t;
  if (!(reference > 0) || !std::isfinite(value) || !std::isfinite(reference_temperature) || coefficient == 0.0) return t;
  t.value = reference_temperature + (value / reference - 1.0) / coefficient;
  t.uncertainty = std::abs(relative_uncertainty * value / reference / coefficient);
  return t;
}

}  // namespace pmsm_param_id
