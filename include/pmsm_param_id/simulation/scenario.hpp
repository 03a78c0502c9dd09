// A simulated drive run: motor, inverter/controller settings, input profiles and sensors.
#pragma once
#include <array>
#include <cstdint>
#include <cmath>
#include <limits>
#include <memory>
#include <string>

#include "pmsm_param_id/model/magnetics.hpp"
#include "pmsm_param_id/model/motor_model.hpp"
#include "pmsm_param_id/simulation/profile.hpp"

namespace pmsm_param_id {

struct DriveSettings {
  double sample_period = 1e-4;          ///< controller and sampling period T_s [s]
  int integration_substeps = 10;        ///< RK4 steps per sampling period
  double dc_bus_voltage = 400.0;        ///< [V]; voltage vector limited to V_dc/sqrt(3) (SVPWM)
  double max_current = 30.0;            ///< current reference limit [A]
  double current_loop_bandwidth_hz = 1000.0;  ///< PI current loops, pole-zero cancellation [Hz]
  double speed_loop_bandwidth_hz = 20.0;      ///< PI speed loop [Hz]
  /// false: the speed loop sets i_q (speed control); true: i_q follows the q_current_reference
  /// profile and the speed is imposed by a load machine (a dyno), following speed_rpm exactly.
  bool torque_control = false;
};

/// What a real inverter does to the commanded voltage (all off by default: the paper tier).
struct InverterSettings {
  double dead_time = 0.0;              ///< [s]; the pole-voltage error is V_dc t_dead f_sw + device_drop
  double switching_frequency = 0.0;    ///< [Hz]; 0 = 1 / sample_period
  double device_drop = 0.0;            ///< on-state threshold voltage of a switch or diode [V] (IGBTs, diodes)
  /// On-state slope resistance of the conducting switch or diode [ohm]: each pole loses it times its
  /// phase current. A MOSFET bridge's loss (its channel conducts both ways: R_ds,on i, no threshold).
  /// In series with every phase at every instant, it adds to the winding's resistance as the
  /// inverter's terminals see it.
  double device_resistance = 0.0;
  double zero_crossing_current = 0.1;  ///< the error passes zero smoothly, tanh(i / this) [A]
  bool stationary_hold = false;        ///< hold the voltage vector in the stator (alpha-beta) frame
  int computation_delay = 0;           ///< periods between computing a voltage and applying it: 0 or 1
  double dc_ripple = 0.0;              ///< relative amplitude of a sinusoidal DC-bus ripple [-]
  double dc_ripple_frequency = 300.0;  ///< [Hz]
  /// false: the average model (each pole voltage loses the error voltage times tanh of its current);
  /// true: switching level. Centre-aligned carrier comparison at one PWM period per sample (the
  /// carrier's valley at the sample instants, where the currents are sampled), min-max zero sequence
  /// (SVPWM), dead time at every commutation with the leg voltage set by the sign of the actual phase
  /// current during it, device drops against the current (doc/simulator.md).
  bool switching = false;
  /// The reference computed at t_k is turned into the stator frame at the predicted angle
  /// theta_k + angle_prediction omega_e T_s [periods]; NaN = computation_delay (0 or 1).
  double angle_prediction = std::numeric_limits<double>::quiet_NaN();
  /// false: the log holds the reference computed at t_k; true: the d-q voltage applied over
  /// [t_k, t_k+1) (the acting vector in the rotor frame at the measured mid-period angle).
  bool log_applied_voltage = false;
  double anglePrediction() const { return std::isfinite(angle_prediction) ? angle_prediction : computation_delay; }
  /// Pole-voltage error amplitude [V] at bus voltage v_dc.
  double errorVoltage(double v_dc, double sample_period) const {
    const double f = switching_frequency > 0 ? switching_frequency : 1.0 / sample_period;
    return dead_time > 0 || device_drop > 0 ? v_dc * dead_time * f + device_drop : 0.0;
  }
  bool active() const {
    return dead_time > 0 || device_drop > 0 || device_resistance > 0 || stationary_hold || computation_delay > 0 ||
           dc_ripple > 0 || switching || anglePrediction() != computation_delay || log_applied_voltage;
  }
};

/// First-order thermal models of winding and magnets (off by default): R_s and psi_f follow them.
///   C_w dT_w/dt = 1.5 R_s(T_w) |i|^2 - (T_w - T_a)/R_wa - (T_w - T_m)/R_wm
///   C_m dT_m/dt = k_m omega_m^2 + (T_w - T_m)/R_wm - (T_m - T_a)/R_ma
///   R_s = R_s,ref (1 + alpha (T_w - T_ref)),  psi_f = psi_f,ref (1 + beta (T_m - T_ref))
struct ThermalModelSettings {
  bool enabled = false;
  double reference_temperature = 20.0;   ///< the motor block's R_s and psi_f hold here [degC]
  double ambient_temperature = 20.0;     ///< [degC]; also the initial temperature of both
  double winding_capacity = 500.0;       ///< C_w [J/K]
  double winding_to_ambient = 0.5;       ///< R_wa [K/W]
  double winding_to_magnet = 1.0;        ///< R_wm [K/W]
  double magnet_capacity = 1000.0;       ///< C_m [J/K]
  double magnet_to_ambient = 1.0;        ///< R_ma [K/W]
  double magnet_loss_coefficient = 0.0;  ///< k_m [W s^2/rad^2] (eddy losses grow with speed squared)
  double copper_coefficient = 3.93e-3;   ///< alpha [1/K]
  double magnet_coefficient = -1.2e-3;   ///< beta [1/K] (NdFeB)
};

struct SensorSettings {
  double current_noise_sigma = 0.0;  ///< white Gaussian noise on each measured current [A]
  int adc_bits = 0;                  ///< quantisation of measured currents; 0 = none
  double adc_range = 50.0;           ///< full scale +-adc_range [A]
  bool phase_currents = false;       ///< errors act on the phase currents a, b, c (else on d, q)
  std::array<double, 3> phase_offset{0, 0, 0};  ///< per-phase offset [A] (phase_currents only)
  std::array<double, 3> phase_gain{1, 1, 1};    ///< per-phase gain [-] (phase_currents only)
  int encoder_lines = 0;             ///< 0: exact angle and speed; else an incremental encoder (4x counts)
  double speed_filter_hz = 1000.0;   ///< speed = filtered position difference, first-order cut-off [Hz]
  /// > 0: the speed is the count difference over this many periods instead (quantised to one count
  /// per window, lagging by half the window); 0: the filter above.
  int speed_window_periods = 0;
};

struct Scenario {
  std::string name;
  MotorParameters motor;
  DriveSettings drive;
  InverterSettings inverter;
  ThermalModelSettings thermal;
  SaturationSettings saturation;  ///< saturating magnetics (off: the linear model of Eq. 1)
  SensorSettings sensors;
  double duration = 0.5;  ///< [s]
  uint64_t seed = 1;
  Profile speed_reference_rpm = Profile::constant(0.0);  ///< mechanical speed reference [rpm]
  Profile load_torque = Profile::constant(0.0);          ///< [N m]
  Profile d_current_injection = Profile::constant(0.0);  ///< i_d reference [A]
  Profile q_current_reference = Profile::constant(0.0);  ///< i_q reference in torque control [A]
  Profile R_s_scale = Profile::constant(1.0);    ///< true R_s = motor.R_s * scale(t) [-]
  Profile psi_f_scale = Profile::constant(1.0);  ///< true psi_f = motor.psi_f * scale(t) [-]
  Profile L_d_scale = Profile::constant(1.0);    ///< true L_d = motor.L_d * scale(t) [-] (e.g. an inter-turn fault)
  Profile L_q_scale = Profile::constant(1.0);    ///< true L_q = motor.L_q * scale(t) [-]
};

/// Reads a scenario YAML file. Throws ConfigError with one line "FILE: key 'k': problem".
Scenario loadScenario(const std::string& path);

/// The same scenario with the plant's magnetics from a flux map instead of its own model (the map
/// of the motor's round trip, doc/algorithm.md section 12).
Scenario withFluxMap(Scenario s, std::shared_ptr<const FluxTable> map);

}  // namespace pmsm_param_id
