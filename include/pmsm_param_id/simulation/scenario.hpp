// A simulated drive run: motor, inverter/controller settings, input profiles and sensors.
#pragma once
#include <cstdint>
#include <string>

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
};

struct SensorSettings {
  double current_noise_sigma = 0.0;  ///< white Gaussian noise on measured i_d, i_q [A]
  int adc_bits = 0;                  ///< quantisation of measured currents; 0 = none
  double adc_range = 50.0;           ///< full scale +-adc_range [A]
};

struct Scenario {
  std::string name;
  MotorParameters motor;
  DriveSettings drive;
  SensorSettings sensors;
  double duration = 0.5;  ///< [s]
  uint64_t seed = 1;
  Profile speed_reference_rpm = Profile::constant(0.0);  ///< mechanical speed reference [rpm]
  Profile load_torque = Profile::constant(0.0);          ///< [N m]
  Profile d_current_injection = Profile::constant(0.0);  ///< i_d reference [A]
  Profile R_s_scale = Profile::constant(1.0);    ///< true R_s = motor.R_s * scale(t) [-]
  Profile psi_f_scale = Profile::constant(1.0);  ///< true psi_f = motor.psi_f * scale(t) [-]
};

/// Reads a scenario YAML file. Throws ConfigError with one line "FILE: key 'k': problem".
Scenario loadScenario(const std::string& path);

}  // namespace pmsm_param_id
