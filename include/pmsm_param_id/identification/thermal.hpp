// Winding and magnet temperatures from identified R_s and psi_f (doc/algorithm.md section 9).
//   winding: R_s(T) = R_s,ref (1 + alpha (T - T_ref)),   alpha = 3.93e-3 /K for copper
//   magnet:  psi_f(T) = psi_f,ref (1 + beta (T - T_ref)), beta = -1.2e-3 /K for NdFeB
// A temperature exists where its parameter's estimate states it to max_uncertainty; its
// uncertainty is the parameter's stated uncertainty (with a learnt reference's) divided by the
// coefficient.
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
  /// A temperature is reported where its stated uncertainty is at most this [K]: from the slow
  /// estimate (R_s, psi_f over slow_time_constant) or the fast one, whichever states less. 10 K:
  /// an over-temperature alarm (class F, 155 degC, 5 K hysteresis) needs no finer, and behind a
  /// real inverter R_s at light load is worth +-5-8 K; lower it to hide coarser values.
  double max_uncertainty = 10.0;
};

/// The references a declared cold start learnt, as kept across restarts (io/thermal_state.hpp): a
/// node restarted on a hot motor takes them instead of learning the hot values as cold.
struct LearntReferences {
  double reference_temperature = std::numeric_limits<double>::quiet_NaN();  ///< [degC]
  double R_s = 0.0;                       ///< R_s at reference_temperature [ohm]; 0 = not learnt
  double R_s_relative_uncertainty = 0.0;  ///< [-]
  double psi_f = 0.0;                     ///< psi_f at reference_temperature [Wb]; 0 = not learnt
  double psi_f_relative_uncertainty = 0.0;  ///< [-]
  double R_s_learnt_at = std::numeric_limits<double>::quiet_NaN();    ///< stamp of the data it came from [s]
  double psi_f_learnt_at = std::numeric_limits<double>::quiet_NaN();  ///< [s]
  bool any() const { return R_s > 0 || psi_f > 0; }
  bool operator==(const LearntReferences& o) const {
    return R_s == o.R_s && psi_f == o.psi_f && R_s_relative_uncertainty == o.R_s_relative_uncertainty &&
           psi_f_relative_uncertainty == o.psi_f_relative_uncertainty;
  }
  bool operator!=(const LearntReferences& o) const { return !(*this == o); }
};

struct Temperature {
  double value = std::numeric_limits<double>::quiet_NaN();        ///< [degC]; NaN = unknown
  double uncertainty = std::numeric_limits<double>::quiet_NaN();  ///< [K]
};

/// Temperature of a parameter that varies as reference (1 + coefficient (T - T_ref)).
/// reference_relative_uncertainty: a learnt reference's own (0 for a declared one) [-].
inline Temperature temperatureFrom(double value, double relative_uncertainty, double reference,
                                   double reference_temperature, double coefficient,
                                   double reference_relative_uncertainty = 0.0) {
  Temperature t;
  if (!(reference > 0) || !std::isfinite(value) || !std::isfinite(reference_temperature) || coefficient == 0.0) return t;
  t.value = reference_temperature + (value / reference - 1.0) / coefficient;
  t.uncertainty = std::abs(std::hypot(relative_uncertainty, reference_relative_uncertainty) * value / reference / coefficient);
  return t;
}

}  // namespace pmsm_param_id
