// One synchronous drive sample, the unit every identifier consumes.
#pragma once
#include <limits>

namespace pmsm_param_id {

/// Row k of a drive log. The voltages are the ones applied from t to t + T_s (zero-order hold,
/// commanded by the controller at t); the currents and the speed are sampled at t.
struct Sample {
  double t = 0.0;        ///< time stamp [s]
  double u_d = 0.0;      ///< d-axis stator voltage [V]
  double u_q = 0.0;      ///< q-axis stator voltage [V]
  double i_d = 0.0;      ///< measured d-axis current [A]
  double i_q = 0.0;      ///< measured q-axis current [A]
  double omega_e = 0.0;  ///< electrical speed [rad/s] (= pole pairs x mechanical speed)
  double theta_e = std::numeric_limits<double>::quiet_NaN();  ///< electrical angle [rad]; NaN = not logged
  /// DC-bus voltage measured at t [V]; NaN = not logged. The inverter's dead-time error scales with
  /// it (doc/algorithm.md section 8).
  double v_dc = std::numeric_limits<double>::quiet_NaN();
};

}  // namespace pmsm_param_id
