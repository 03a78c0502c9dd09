// The drive as it is built: the switching-level PWM inverter, the timing conventions (angle
// prediction, computation delay, what the log holds) and the encoder's count-difference speed,
// each against its theory.
#include <gtest/gtest.h>

#include <cmath>

#include "pmsm_param_id/model/frames.hpp"
#include "test_helpers.hpp"

using namespace pmsm_param_id;
using test_helpers::run;
using test_helpers::scenario;

namespace {
// The switching-level industrial drive with ideal sensors, at one steady operating point.
Scenario steadySwitchingDrive() {
  Scenario s = scenario("industrial_pwm_steady.yaml");
  s.sensors = {};
  s.d_current_injection = Profile::constant(0.0);
  s.duration = 0.5;
  return s;
}
// Mean over whole electrical turns from t_from on of the applied error along and across the current.
struct ErrorAlongCurrent {
  double along = 0, across = 0;
};
ErrorAlongCurrent meanError(const std::vector<SimulatedSample>& data, double t_from) {
  ErrorAlongCurrent out;
  double turn_start = NAN, angle = 0, along = 0, across = 0;
  int n = 0, n_whole = 0;
  double last_theta = NAN;
  for (const SimulatedSample& x : data) {
    if (x.sample.t < t_from) continue;
    const double ed = x.u_d_applied - x.u_d_ideal, eq = x.u_q_applied - x.u_q_ideal;
    const double magnitude = std::hypot(x.i_d_true, x.i_q_true);
    along += (ed * x.i_d_true + eq * x.i_q_true) / magnitude;
    across += (eq * x.i_d_true - ed * x.i_q_true) / magnitude;
    ++n;
    if (std::isfinite(last_theta)) angle += std::abs(std::remainder(x.sample.theta_e - last_theta, 2 * M_PI));
    last_theta = x.sample.theta_e;
    if (!std::isfinite(turn_start)) turn_start = x.sample.t;
    if (angle >= 2 * M_PI) {  // a whole turn: keep the sums up to here
      out.along = along / n;
      out.across = across / n;
      n_whole = n;
      angle -= 2 * M_PI;
    }
  }
  EXPECT_GT(n_whole, 0);
  return out;
}
}  // namespace

TEST(SwitchingInverter, WithoutDeadTimeOrDropsAppliesTheReferenceOnAverage) {
  Scenario s = steadySwitchingDrive();
  s.inverter.dead_time = 0.0;
  s.inverter.device_drop = 0.0;
  const auto data = run(s);
  // Volt-second balance: per period the pulses' mean is the held vector (second-order terms of the
  // rotor's turn within the period aside).
  double worst = 0, scale = 0;
  for (const SimulatedSample& x : data) {
    if (x.sample.t < 0.2) continue;
    worst = std::max(worst, std::hypot(x.u_d_applied - x.u_d_ideal, x.u_q_applied - x.u_q_ideal));
    scale = std::max(scale, std::hypot(x.u_d_ideal, x.u_q_ideal));
  }
  EXPECT_LT(worst, 2e-3 * scale) << "largest period-mean error " << worst << " V of " << scale << " V";
}

TEST(SwitchingInverter, DeadTimeAndDropsCostFourOverPiTimesTheErrorVoltageAlongTheCurrent) {
  // Theory: each pole loses V_err = V_dc t_dead f_sw + V_on against its current's sign; in d-q the
  // mean over a turn is (4 / pi) V_err along the current, nothing across it (doc/simulator.md).
  // The current's ripple near each zero crossing takes a little off (measured ~3 % here).
  const Scenario s = steadySwitchingDrive();
  const auto data = run(s);
  const double v_err = s.drive.dc_bus_voltage * s.inverter.dead_time / s.drive.sample_period + s.inverter.device_drop;
  const ErrorAlongCurrent e = meanError(data, 0.25);
  EXPECT_NEAR(-e.along, 4.0 / M_PI * v_err, 0.06 * 4.0 / M_PI * v_err) << "theory " << 4.0 / M_PI * v_err << " V";
  EXPECT_LT(-e.along, 4.0 / M_PI * v_err * 1.01);  // the ripple can only take off
  EXPECT_NEAR(e.across, 0.0, 0.05 * v_err);
  EXPECT_NEAR(data.back().inverter_error_voltage, v_err, 1e-9);
}

TEST(SwitchingInverter, OnStateResistanceActsAsAResistanceInSeriesWithEveryPhase) {
  // Theory: each pole loses R_on times its phase current whichever device conducts (a MOSFET's
  // channel both ways), so the period's mean applied voltage is the reference less R_on i in d-q,
  // with no zero-crossing shape: the inverter's terminals see R_s + R_on, and the truth says so.
  // Measured (R_on 5 % of R_s): -0.25 % / -0.05 % in R_on, the largest period 0.35 % / 0.14 % of
  // R_on |i| beside it (industrial_pwm_steady / robot_joint_pwm).
  for (const char* name : {"industrial_pwm_steady.yaml", "robot_joint_pwm.yaml"}) {
    Scenario s = scenario(name);
    s.sensors = {};
    s.d_current_injection = Profile::constant(0.0);
    s.duration = 0.3;
    s.inverter.dead_time = 0.0;
    s.inverter.device_drop = 0.0;
    s.inverter.device_resistance = 0.05 * s.motor.R_s;
    const double r = s.inverter.device_resistance;
    const auto data = run(s);
    double ei = 0, ii = 0, worst = 0, largest = 0;
    for (std::size_t k = 0; k + 1 < data.size(); ++k) {
      const SimulatedSample& x = data[k];
      if (x.sample.t < 0.1) continue;
      // The period's mean current: the trapezoid between the period's two samples.
      const double i_d = 0.5 * (x.i_d_true + data[k + 1].i_d_true), i_q = 0.5 * (x.i_q_true + data[k + 1].i_q_true);
      const double ed = x.u_d_applied - x.u_d_ideal, eq = x.u_q_applied - x.u_q_ideal;
      ei += ed * i_d + eq * i_q;
      ii += i_d * i_d + i_q * i_q;
      worst = std::max(worst, std::hypot(ed + r * i_d, eq + r * i_q));
      largest = std::max(largest, r * std::hypot(i_d, i_q));
    }
    EXPECT_NEAR(data.back().truth[kRs], s.motor.R_s + r, 1e-12 * s.motor.R_s) << name;
    EXPECT_NEAR(-ei / ii, r, 0.01 * r) << name;
    EXPECT_LT(worst, 0.02 * largest) << name << ": largest period error beside -R_on i " << worst << " V";
  }
}

TEST(SwitchingInverter, DeadTimeFollowsTheActualCurrentNotTheSampledOne) {
  // At a light load the ripple makes the phase current change sign within a period near every
  // zero crossing: there the pulse-width loss is partial, so the mean error is below the average
  // model's (which follows the sampled current). It must still be a loss, and smaller than at load.
  Scenario light = steadySwitchingDrive();
  light.load_torque = Profile::constant(0.3);
  const Scenario loaded = steadySwitchingDrive();
  const double v_err = light.drive.dc_bus_voltage * light.inverter.dead_time / light.drive.sample_period +
                       light.inverter.device_drop;
  const double light_loss = -meanError(run(light), 0.25).along, loaded_loss = -meanError(run(loaded), 0.25).along;
  EXPECT_GT(light_loss, 0.2 * v_err);
  EXPECT_LT(light_loss, loaded_loss);
}

TEST(SwitchingInverter, ACurrentTheDeadTimeDrivesThroughZeroStaysThereAtAnyStepSize) {
  // The robot joint (48 V, 40/60 uH, 0.75 us, its devices' loss a 0.05 V threshold, which changes
  // sign with the current as the diodes do): within one dead time the current moves about 0.5 A,
  // so near the ripple's zero crossings a dead leg's diode drives its current to zero, and where
  // the other diode would drive it back neither conducts: it stays at zero until the switch turns
  // on. Located as an event, the period's applied voltage is the same with 10 integration steps
  // per period as with 400: measured 0.26 % of the error voltage's RMS apart. (The sign taken at
  // each Runge-Kutta stage instead averaged the two diodes across the crossing: 4.6 % apart.)
  Scenario s = scenario("robot_joint_pwm_threshold.yaml");
  s.sensors = {};
  s.duration = 0.1;
  Scenario fine = s;
  fine.drive.integration_substeps = 400;
  const auto coarse_run = run(s), fine_run = run(fine);
  double difference = 0, error = 0;
  for (std::size_t k = 0; k < coarse_run.size(); ++k) {
    const SimulatedSample &a = coarse_run[k], &b = fine_run[k];
    difference += std::pow(a.u_d_applied - b.u_d_applied, 2) + std::pow(a.u_q_applied - b.u_q_applied, 2);
    error += std::pow(b.u_d_applied - b.u_d_ideal, 2) + std::pow(b.u_q_applied - b.u_q_ideal, 2);
  }
  EXPECT_LT(std::sqrt(difference / error), 0.01);
}

TEST(TimingConventions, AnglePredictionTurnsTheAppliedVectorByItsMismatch) {
  // Average model, no inverter error, exact angle: the voltage computed at t_k acts over
  // [t_k+1, t_k+2) turned at theta_k + k_p omega_e T_s and held in the stator frame. Its mean in the
  // rotor frame is the reference turned by (k_p - 1.5) omega_e T_s (times sinc(omega_e T_s / 2)).
  for (double k_p : {0.0, 0.5, 1.0, 1.5}) {
    Scenario s = scenario("wc1_drive.yaml");
    s.sensors = {};
    s.inverter = {};
    s.inverter.stationary_hold = true;
    s.inverter.computation_delay = 1;
    s.inverter.angle_prediction = k_p;
    s.duration = 0.4;
    const auto data = run(s);
    double worst = 0;
    for (std::size_t k = 1; k < data.size(); ++k) {
      if (data[k].sample.t < 0.2) continue;
      const Sample& computed = data[k - 1].sample;
      const double wT = computed.omega_e * s.drive.sample_period;
      const double sinc = std::sin(0.5 * wT) / (0.5 * wT);
      const Vec2 expected = rotate({computed.u_d * sinc, computed.u_q * sinc}, (k_p - 1.5) * wT);
      worst = std::max(worst, std::hypot(data[k].u_d_applied - expected.x, data[k].u_q_applied - expected.y) /
                                  std::hypot(expected.x, expected.y));
    }
    EXPECT_LT(worst, 1e-4) << "k_p = " << k_p;
  }
}

TEST(TimingConventions, AnAppliedVoltageLogHoldsTheVoltageOfItsOwnPeriod) {
  Scenario s = scenario("wc1_drive.yaml");
  s.sensors = {};
  s.inverter = {};
  s.inverter.stationary_hold = true;
  s.inverter.computation_delay = 1;
  s.inverter.angle_prediction = 1.5;
  s.inverter.log_applied_voltage = true;
  s.duration = 0.3;
  const auto data = run(s);
  double worst = 0;
  for (const SimulatedSample& x : data)
    if (x.sample.t > 0.1) {
      const double wT = x.sample.omega_e * s.drive.sample_period, sinc = std::sin(0.5 * wT) / (0.5 * wT);
      worst = std::max(worst, std::hypot(x.u_d_applied - sinc * x.sample.u_d, x.u_q_applied - sinc * x.sample.u_q) /
                                  std::hypot(x.u_d_applied, x.u_q_applied));
    }
  EXPECT_LT(worst, 1e-4);
}

TEST(Encoder, CountDifferenceSpeedIsQuantisedAndLagsByHalfItsWindow) {
  // A dyno holds the speed on a ramp: the count difference over N periods is the true speed half a
  // window back, within one count per window.
  Scenario s = scenario("wc1_drive.yaml");
  s.sensors = {};
  s.sensors.encoder_lines = 4000;
  s.sensors.speed_window_periods = 10;
  s.drive.torque_control = true;
  s.q_current_reference = Profile::constant(2.0);
  s.speed_reference_rpm = Profile::ramp(0.0, 1000.0, 0.0, 0.05);
  s.duration = 0.1;
  const auto data = run(s);
  const int p = s.motor.pole_pairs;
  const double Ts = s.drive.sample_period, window = 10 * Ts;
  const double quantum = p * 2 * M_PI / (4.0 * 4000) / window;  // one count per window, electrical [rad/s]
  const auto true_speed = [&](double t) { return p * s.speed_reference_rpm(t) * 2 * M_PI / 60; };
  int n = 0;
  for (const SimulatedSample& x : data) {
    if (x.sample.t < 0.01) continue;
    const double counts = x.sample.omega_e / quantum;
    EXPECT_NEAR(counts, std::round(counts), 1e-6) << "t = " << x.sample.t;
    // (The dyno holds each period's speed from its start: the window's mean is half a period older.)
    const double lagged = x.sample.t < 0.05 ? true_speed(x.sample.t - 0.5 * window - 0.5 * Ts)
                                            : x.sample.t > 0.05 + window ? true_speed(0.05) : x.sample.omega_e;
    EXPECT_NEAR(x.sample.omega_e, lagged, quantum + 1e-9) << "t = " << x.sample.t;
    if (x.sample.t < 0.05 && std::abs(x.sample.omega_e - true_speed(x.sample.t)) > 2 * quantum) ++n;  // lagging
  }
  EXPECT_GT(n, 0) << "the speed should visibly lag the ramp";
}
