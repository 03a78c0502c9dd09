#include "pmsm_param_id/simulation/drive_simulator.hpp"

#include <algorithm>
#include <cmath>

namespace pmsm_param_id {

DriveSimulator::DriveSimulator(const Scenario& scenario) : scenario_(scenario), rng_(scenario.seed) {
  const MotorParameters& m = scenario_.motor;
  const double Ts = scenario_.drive.sample_period;
  sample_count_ = static_cast<std::uint64_t>(std::floor(scenario_.duration / Ts + 1e-9));
  // Current loops: PI zero cancels the R/L pole, crossover at the requested bandwidth.
  const double wc = 2.0 * M_PI * scenario_.drive.current_loop_bandwidth_hz;
  kp_d_ = wc * m.L_d;
  kp_q_ = wc * m.L_q;
  ki_current_ = wc * m.R_s;
  // Speed loop: J dw/dt = k_t i_q; crossover ws, integral zero at ws/4.
  const double ws = 2.0 * M_PI * scenario_.drive.speed_loop_bandwidth_hz;
  const double k_t = 1.5 * m.pole_pairs * m.psi_f;
  kp_speed_ = m.inertia * ws / k_t;
  ki_speed_ = kp_speed_ * ws / 4.0;
}

bool DriveSimulator::done() const { return k_ >= sample_count_; }

double DriveSimulator::voltageLimit() const { return scenario_.drive.dc_bus_voltage / std::sqrt(3.0); }

MotorParameters DriveSimulator::trueMotorAt(double t) const {
  MotorParameters m = scenario_.motor;
  m.R_s *= scenario_.R_s_scale(t);
  m.psi_f *= scenario_.psi_f_scale(t);
  return m;
}

double DriveSimulator::measure(double true_current) {
  double v = true_current;
  if (scenario_.sensors.current_noise_sigma > 0) v += scenario_.sensors.current_noise_sigma * noise_(rng_);
  if (scenario_.sensors.adc_bits > 0) {
    const double range = scenario_.sensors.adc_range;
    const double lsb = 2.0 * range / std::ldexp(1.0, scenario_.sensors.adc_bits);
    v = std::clamp(std::round(v / lsb) * lsb, -range, range);
  }
  return v;
}

SimulatedSample DriveSimulator::step() {
  const Scenario& s = scenario_;
  const double Ts = s.drive.sample_period;
  const double t = static_cast<double>(k_) * Ts;
  const MotorParameters nominal = s.motor;
  const MotorParameters plant = trueMotorAt(t);

  SimulatedSample out;
  out.truth = plant.electrical();
  out.i_d_true = x_.i_d;
  out.i_q_true = x_.i_q;
  const double i_d = measure(x_.i_d);
  const double i_q = measure(x_.i_q);
  const double omega_e = nominal.pole_pairs * x_.omega_m;

  // Speed loop -> i_q reference, limited so that |i_ref| <= max_current (conditional integration).
  const double i_d_ref = s.d_current_injection(t);
  const double i_q_limit = std::sqrt(std::max(0.0, s.drive.max_current * s.drive.max_current - i_d_ref * i_d_ref));
  const double speed_error = s.speed_reference_rpm(t) * 2.0 * M_PI / 60.0 - x_.omega_m;
  double i_q_ref = kp_speed_ * speed_error + speed_integral_ + ki_speed_ * Ts * speed_error;
  if (std::abs(i_q_ref) < i_q_limit) {
    speed_integral_ += ki_speed_ * Ts * speed_error;
  } else {
    i_q_ref = std::copysign(i_q_limit, i_q_ref);
  }

  // Current loops with decoupling feed-forward from the nominal (controller's) parameters.
  const double e_d = i_d_ref - i_d, e_q = i_q_ref - i_q;
  const double ff_d = -omega_e * nominal.L_q * i_q;
  const double ff_q = omega_e * (nominal.L_d * i_d + nominal.psi_f);
  double u_d = kp_d_ * e_d + d_integral_ + ki_current_ * Ts * e_d + ff_d;
  double u_q = kp_q_ * e_q + q_integral_ + ki_current_ * Ts * e_q + ff_q;
  const double limit = voltageLimit();
  const double magnitude = std::hypot(u_d, u_q);
  if (magnitude > limit) {
    u_d *= limit / magnitude;
    u_q *= limit / magnitude;
    out.voltage_limited = true;  // anti-windup: hold both integrators
  } else {
    d_integral_ += ki_current_ * Ts * e_d;
    q_integral_ += ki_current_ * Ts * e_q;
  }

  out.sample = Sample{t, u_d, u_q, i_d, i_q, omega_e};
  out.sample.theta_e = std::remainder(x_.theta_e, 2.0 * M_PI);  // exact angle, in (-pi, pi]
  out.i_d_reference = i_d_ref;
  out.i_q_reference = i_q_ref;
  out.load_torque = s.load_torque(t);

  // Plant over [t, t + Ts] with the voltages held (zero-order hold).
  const int n = s.drive.integration_substeps;
  const double h = Ts / n;
  for (int j = 0; j < n; ++j) x_ = rk4Step(plant, x_, u_d, u_q, out.load_torque, h);
  ++k_;
  return out;
}

}  // namespace pmsm_param_id
