// Field-oriented IPMSM drive: speed PI -> i_q reference, i_d reference = injection, decoupled PI
// current loops, voltage limited by the DC bus, plant integrated by RK4 under zero-order hold.
#pragma once
#include <cstdint>
#include <cmath>
#include <random>
#include <vector>

#include "pmsm_param_id/model/motor_model.hpp"
#include "pmsm_param_id/model/sample.hpp"
#include "pmsm_param_id/simulation/scenario.hpp"

namespace pmsm_param_id {

struct SimulatedSample {
  Sample sample;            ///< what a real drive would log (measured currents, applied voltages)
  ParameterVector truth{};  ///< true {R_s, L_d, L_q, psi_f} at sample.t
  double i_d_true = 0.0;    ///< noise-free d-axis current [A]
  double i_q_true = 0.0;    ///< noise-free q-axis current [A]
  double i_d_reference = 0.0;  ///< [A]
  double i_q_reference = 0.0;  ///< [A]
  double load_torque = 0.0;    ///< [N m]
  bool voltage_limited = false;
  double u_d_applied = 0.0;    ///< d-axis voltage the motor received, mean over the period [V]
  double u_q_applied = 0.0;    ///< [V]
  double u_d_ideal = 0.0;      ///< the held vector's mean over the period in the rotor frame: what an inverter without error applies [V]
  double u_q_ideal = 0.0;      ///< [V]
  double inverter_error_voltage = 0.0;  ///< pole-voltage error amplitude V_dc t_dead f_sw + drop [V]
  double winding_temperature = NAN;     ///< true winding temperature [degC] (thermal model only)
  double magnet_temperature = NAN;      ///< true magnet temperature [degC] (thermal model only)
  /// Flux linkages and incremental/secant inductances at the true current (saturation: truth is
  /// then {R_s, L_dd, psi_q / i_q, psi_d(0, i_q)}, what the identifier's estimates stand for).
  MagneticState magnetics;
};

class DriveSimulator {
 public:
  explicit DriveSimulator(const Scenario& scenario);

  /// Samples at t = 0, T_s, 2 T_s, ...; true while t < duration.
  bool done() const;
  /// Measures, runs the controller, then integrates the plant over one sampling period.
  SimulatedSample step();
  std::uint64_t sampleIndex() const { return k_; }
  const PlantState& state() const { return x_; }
  const Scenario& scenario() const { return scenario_; }
  /// True parameters at time t (drift profiles applied).
  MotorParameters trueMotorAt(double t) const;
  /// Maximum phase voltage amplitude [V] the inverter can apply (V_dc / sqrt(3)).
  double voltageLimit() const;

 private:
  double measure(double true_current);
  double busVoltage(double t) const;

  Scenario scenario_;
  PlantState x_;
  std::uint64_t k_ = 0;
  std::uint64_t sample_count_ = 0;
  std::mt19937_64 rng_;
  std::normal_distribution<double> noise_{0.0, 1.0};
  // controller state
  double speed_integral_ = 0.0;  // i_q reference integral part [A]
  double winding_temperature_ = 0.0, magnet_temperature_ = 0.0;  // thermal model state [degC]
  double encoder_previous_ = 0.0;  // last measured mechanical angle [rad]
  double speed_estimate_ = 0.0;    // filtered mechanical speed from the encoder [rad/s]
  std::vector<double> encoder_history_;  // count angles of the speed window's periods [rad]
  // computation delay: the reference computed at the previous sample and its conversion angle
  double pending_u_d_ = 0.0, pending_u_q_ = 0.0, pending_angle_ = 0.0;
  double d_integral_ = 0.0;      // [V]
  double q_integral_ = 0.0;      // [V]
  // controller gains (from nominal parameters)
  double kp_speed_ = 0, ki_speed_ = 0, kp_d_ = 0, kp_q_ = 0, ki_current_ = 0;
};

/// How far two runs of the same scenario are apart in their true currents, sample by sample (the
/// round trip of a learnt flux map, doc/algorithm.md section 12).
struct CurrentDifference {
  double relative_rms = 0.0;  ///< RMS of |i_b - i_a| over the RMS of |i_a| [-] (NaN without current)
  double largest = 0.0;       ///< largest |i_b - i_a| [A]
};
CurrentDifference currentDifference(const std::vector<SimulatedSample>& a, const std::vector<SimulatedSample>& b);

}  // namespace pmsm_param_id
