// Thresholds of the condition monitor (monitor.hpp), read from the identifier YAML's alarms: block.
#pragma once

namespace pmsm_param_id {

struct AlarmSettings {
  double winding_max_temperature = 155.0;  ///< [degC] (insulation class F)
  double winding_hysteresis = 5.0;         ///< the alarm clears this far below [K]
  double magnet_above_winding = 25.0;      ///< magnet "hotter" than the winding by more: demagnetisation [K]
  double demagnetisation_drop = 0.02;      ///< psi_f falling by more than this within jump_window [-]
  double confirm_time = 0.05;              ///< a condition must hold this long [s]
  double jump_fraction = 0.05;             ///< R_s, L_d or L_q changing by more than this ... [-]
  double jump_window = 1.0;                ///< ... between identified values this close is a jump [s]
  double drift_rate = 0.5;                 ///< relative change per second sustained over drift_window [1/s]
  double drift_window = 1.0;               ///< [s]
};

}  // namespace pmsm_param_id
