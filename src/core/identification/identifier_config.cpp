#include "pmsm_param_id/identification/identifier_config.hpp"

#include "pmsm_param_id/io/yaml_reader.hpp"

#include <cmath>

namespace pmsm_param_id {

const std::string& methodList() {
  static const std::string list = "fbdapso, sapso, pso, ekf, rls, wls";
  return list;
}
bool isSwarmMethod(const std::string& m) { return m == "fbdapso" || m == "sapso" || m == "pso"; }
bool isKnownMethod(const std::string& m) { return isSwarmMethod(m) || m == "ekf" || m == "rls" || m == "wls"; }

void validate(const IdentifierConfig& c, const std::string& source) {
  const auto fail = [&](const std::string& key, const std::string& msg) {
    throw ConfigError(source + ": key '" + key + "': " + msg);
  };
  if (!isKnownMethod(c.method)) fail("method", "unknown method '" + c.method + "' (expected " + methodList() + ")");
  if (!(c.map.cell_fraction > 0.0 && c.map.cell_fraction < 1.0)) fail("map.cell_fraction", "must be in (0, 1) [-]");
  if (c.window.sensor_gains && !c.window.sensor_offsets)
    fail("current_sensors.gains", "estimate needs current_sensors.offsets: estimate (the same projection)");
  if (c.magnetics.cross_saturation && c.inverter.estimate_voltage)
    fail("magnetics.cross_saturation", "not together with inverter.model: estimate (not supported yet)");
  if (c.magnetics.cross_saturation && c.window.estimate_voltage_angle)
    fail("magnetics.cross_saturation", "not together with time.voltage_angle: estimate (not supported yet)");
  for (int p = 0; p < kParameterCount; ++p) {
    const std::string name = parameterNames()[p];
    if (c.search.fixed_bounds) {
      if (!(c.search.lower[p] > 0)) fail("bounds." + name, "lower bound must be > 0");
      if (!(c.search.lower[p] < c.search.upper[p])) fail("bounds." + name, "lower bound must be < upper bound");
      if (c.search.has_initial && !(c.search.initial[p] >= c.search.lower[p] && c.search.initial[p] <= c.search.upper[p]))
        fail("initial." + name, "must lie inside bounds." + name);
    }
    if (c.search.has_initial && !(c.search.initial[p] > 0)) fail("initial." + name, "must be > 0");
  }
  if (!(c.search.span_factor > 1)) fail("search.span_factor", "must be > 1");
  if (c.swarm.particles < 2) fail("swarm.particles", "population must be >= 2");
  if (c.swarm.reset_iterations < 1) fail("swarm.reset_iterations", "must be >= 1");
  if (!(c.swarm.v_max > 0 && c.swarm.v_max <= 1)) fail("swarm.v_max", "must be in (0, 1]");
  if (!(c.swarm.restart_velocity >= 0 && c.swarm.restart_velocity <= c.swarm.v_max))
    fail("swarm.restart_velocity", "must be in [0, v_max]");
  if (!(c.swarm.w_min >= 0 && c.swarm.w_min <= c.swarm.w_max)) fail("swarm.w_min", "must be in [0, w_max]");
  if (!(c.sapso_C1 > 0 && c.sapso_C1 < 1)) fail("sapso.C1", "must be in (0, 1)");
  if (!(c.fbdapso_C1 > 0 && c.fbdapso_C1 < 1)) fail("fbdapso.C1", "must be in (0, 1)");
  if (!(c.fbdapso_C2 > 0 && c.fbdapso_C2 < 1)) fail("fbdapso.C2", "must be in (0, 1)");
  if (!(c.sapso_T1 > 0)) fail("sapso.T1", "must be > 0");
  if (!(c.fbdapso_T1 > 0)) fail("fbdapso.T1", "must be > 0");
  if (!(c.fbdapso_T2 >= 0)) fail("fbdapso.T2", "must be >= 0");
  if (c.iterations_per_sample < 1) fail("swarm.iterations_per_sample", "must be >= 1");
  if (!(c.window.block_length >= 0)) fail("window.block_length", "must be >= 0 (0 = automatic)");
  if (!(c.window.forgetting_time_constant >= 0)) fail("window.forgetting_time_constant", "must be >= 0 (0 = automatic)");
  if (c.window.forgetting_time_constant > 0 && c.window.block_length > 0 &&
      !(c.window.forgetting_time_constant > c.window.block_length))
    fail("window.forgetting_time_constant", "must be longer than window.block_length");
  if (!(c.window.long_difference_spacing >= 0) || !std::isfinite(c.window.long_difference_spacing))
    fail("window.long_difference_spacing", "must be a finite number >= 0 (0 = consecutive blocks only)");
  if (!(c.window.long_time_constant >= c.window.forgetting_time_constant))
    fail("window.long_time_constant", "must be at least window.forgetting_time_constant");
  if (!(c.window.slow_time_constant >= c.window.forgetting_time_constant) || !std::isfinite(c.window.slow_time_constant))
    fail("window.slow_time_constant", "must be finite and at least window.forgetting_time_constant");
  if (c.window.voltage_delay_samples < 0 || c.window.voltage_delay_samples > 1)
    fail("time.voltage_delay_samples", "must be 0 or 1");
  if (!(c.time.max_gap_periods > 1)) fail("time.max_gap_periods", "must be > 1");
  if (!(c.time.sample_period >= 0)) fail("time.sample_period", "must be >= 0 (0 = from the stamps)");
  if (!(c.assessment.max_relative_uncertainty > 0)) fail("assessment.max_relative_uncertainty", "must be > 0");
  if (!(c.assessment.max_fit_ratio > 1)) fail("assessment.max_fit_ratio", "must be > 1");
}

IdentifierConfig loadIdentifierConfig(const std::string& path) {
  const YamlReader y = YamlReader::fromFile(path);
  IdentifierConfig c;
  c.method = y.text("method", c.method);
  c.seed = static_cast<std::uint64_t>(y.integer("seed", 1, 0, 1L << 53));
  int bounds_given = 0, initial_given = 0;
  for (int p = 0; p < kParameterCount; ++p) {
    const std::string name = parameterNames()[p];
    if (y.has("bounds." + name)) {
      const std::vector<double> b = y.numbers("bounds." + name);
      if (b.size() != 2) y.fail("bounds." + name, "expected [lower, upper]");
      c.search.lower[p] = b[0];
      c.search.upper[p] = b[1];
      ++bounds_given;
    }
    if (y.has("initial." + name)) {
      c.search.initial[p] = y.positive("initial." + name);
      ++initial_given;
    }
  }
  if (bounds_given != 0 && bounds_given != kParameterCount)
    y.fail("bounds", "give all four of R_s, L_d, L_q, psi_f or none (none: a data-driven search box)");
  if (initial_given != 0 && initial_given != kParameterCount)
    y.fail("initial", "give all four of R_s, L_d, L_q, psi_f or none (none: a data-driven start)");
  c.search.fixed_bounds = bounds_given == kParameterCount;
  c.search.has_initial = initial_given == kParameterCount;
  c.search.span_factor = y.number("search.span_factor", c.search.span_factor);
  c.window.block_length = y.number("window.block_length", c.window.block_length);
  c.window.forgetting_time_constant = y.number("window.forgetting_time_constant", c.window.forgetting_time_constant);
  c.window.long_time_constant = y.positive("window.long_time_constant", c.window.long_time_constant);
  c.window.long_difference_spacing = y.number("window.long_difference_spacing", c.window.long_difference_spacing);
  c.window.slow_time_constant = y.positive("window.slow_time_constant", c.window.slow_time_constant);
  c.pole_pairs = static_cast<int>(y.integer("motor.pole_pairs", c.pole_pairs, 0, 1000));
  c.swarm.particles = static_cast<int>(y.integer("swarm.particles", c.swarm.particles, 2, 100000));
  c.swarm.c1 = y.number("swarm.c1", c.swarm.c1);
  c.swarm.c2 = y.number("swarm.c2", c.swarm.c2);
  c.swarm.w_max = y.number("swarm.w_max", c.swarm.w_max);
  c.swarm.w_min = y.number("swarm.w_min", c.swarm.w_min);
  c.swarm.reset_iterations = static_cast<int>(y.integer("swarm.reset_iterations", c.swarm.reset_iterations, 1, 1000000));
  c.swarm.v_max = y.number("swarm.v_max", c.swarm.v_max);
  c.swarm.restart_velocity = y.number("swarm.restart_velocity", c.swarm.restart_velocity);
  c.iterations_per_sample =
      static_cast<int>(y.integer("swarm.iterations_per_sample", c.iterations_per_sample, 1, 10000));
  c.magnetics.cross_saturation = y.flag("magnetics.cross_saturation", c.magnetics.cross_saturation);
  c.map.cell_fraction = y.number("map.cell_fraction", c.map.cell_fraction);
  c.map.max_cells = static_cast<int>(y.integer("map.max_cells", c.map.max_cells, 1, 1000000));
  fitnessKindFrom(y.oneOf("fitness", toString(c.fitness), {"block", "paper", "paper_one_step"}), c.fitness);
  c.fitness_window_samples =
      static_cast<int>(y.integer("fitness_window_samples", c.fitness_window_samples, 2, 1000000));
  c.sapso_T1 = y.number("sapso.T1", c.sapso_T1);
  c.sapso_C1 = y.number("sapso.C1", c.sapso_C1);
  c.fbdapso_T1 = y.number("fbdapso.T1", c.fbdapso_T1);
  c.fbdapso_T2 = y.number("fbdapso.T2", c.fbdapso_T2);
  c.fbdapso_C1 = y.number("fbdapso.C1", c.fbdapso_C1);
  c.fbdapso_C2 = y.number("fbdapso.C2", c.fbdapso_C2);
  c.fbdapso_zero_delta = y.positive("fbdapso.zero_delta", c.fbdapso_zero_delta);
  c.ekf.measurement_sigma = y.nonNegative("ekf.measurement_sigma", c.ekf.measurement_sigma, " (0 = from the data)");
  c.ekf.process_current_sigma = y.nonNegative("ekf.process_current_sigma", c.ekf.process_current_sigma, " (0 = automatic)");
  c.ekf.parameter_drift = y.positive("ekf.parameter_drift", c.ekf.parameter_drift);
  c.ekf.initial_relative_std = y.positive("ekf.initial_relative_std", c.ekf.initial_relative_std);
  c.rls.time_constant = y.nonNegative("rls.time_constant", c.rls.time_constant, " (0 = the fitness window's)");
  c.rls.initial_covariance = y.positive("rls.initial_covariance", c.rls.initial_covariance);
  c.assessment.max_relative_uncertainty =
      y.positive("assessment.max_relative_uncertainty", c.assessment.max_relative_uncertainty);
  c.assessment.confidence_sigmas = y.positive("assessment.confidence_sigmas", c.assessment.confidence_sigmas);
  c.assessment.variance_inflation = y.positive("assessment.variance_inflation", c.assessment.variance_inflation);
  c.assessment.max_fit_ratio = y.positive("assessment.max_fit_ratio", c.assessment.max_fit_ratio);
  c.assessment.fit_floor_relative = y.positive("assessment.fit_floor_relative", c.assessment.fit_floor_relative);
  c.assessment.min_relative_uncertainty =
      y.positive("assessment.min_relative_uncertainty", c.assessment.min_relative_uncertainty);
  c.assessment.observer_settling_time_constants = y.nonNegative(
      "assessment.observer_settling_time_constants", c.assessment.observer_settling_time_constants, " (0 = at once)");
  c.time.sample_period = y.number("time.sample_period", c.time.sample_period);
  c.time.max_gap_periods = y.number("time.max_gap_periods", c.time.max_gap_periods);
  c.window.voltage_delay_samples = static_cast<int>(y.integer("time.voltage_delay_samples", 0, 0, 1));
  const std::string hold = y.oneOf("time.voltage_hold", "dq", {"dq", "stationary"});
  c.window.stationary_hold = hold == "stationary";
  c.window.estimate_voltage_angle = y.oneOf("time.voltage_angle", "none", {"none", "estimate"}) == "estimate";
  if (y.has("time.angle_prediction")) {
    // The drive's declared prediction k_p against the one the delay and hold model already carry: the
    // vector aligned with the rotor at the start of its period (k_p = delay) under the stationary
    // hold, at mid-period (k_p = delay + 1/2) under the rotor-frame hold.
    const double k_p = y.number("time.angle_prediction");
    if (!(std::abs(k_p) <= 4.0)) y.fail("time.angle_prediction", "must be in [-4, 4] periods of omega_e T_s");
    const double own = c.window.voltage_delay_samples + (c.window.stationary_hold ? 0.0 : 0.5);
    c.window.declared_voltage_angle = k_p - own;
  }
  const std::string model = y.oneOf("inverter.model", "none", {"none", "estimate"});
  c.inverter.estimate_voltage = model == "estimate";
  // "auto": measured from the data (doc/algorithm.md section 8), as where no drive is declared.
  c.window.inverter_zero_crossing_current =
      y.has("inverter.zero_crossing_current") && y.text("inverter.zero_crossing_current", "") == "auto"
          ? -1.0
          : y.nonNegative("inverter.zero_crossing_current", 0.0, " [A] (0 = sign, auto = from the data)");
  c.window.inverter_shape_observer_gain = y.nonNegative("inverter.shape_observer_gain", c.window.inverter_shape_observer_gain,
                                                        " (0 or 1 = the measured currents)");
  if (c.window.inverter_shape_observer_gain > 1)
    y.fail("inverter.shape_observer_gain", "must be in [0, 1] (0 or 1 = the shape from the measured currents)");
  c.inverter.max_relative_uncertainty =
      y.positive("inverter.max_relative_uncertainty", c.inverter.max_relative_uncertainty);
  c.window.sensor_offsets = y.oneOf("current_sensors.offsets", "none", {"none", "estimate"}) == "estimate";
  c.window.sensor_gains = y.oneOf("current_sensors.gains", "none", {"none", "estimate"}) == "estimate";
  c.window.angle_smoothing_samples = static_cast<int>(
      y.integer("angle_sensor.smoothing_samples", c.window.angle_smoothing_samples, -1, 100000));
  // The drive model: chosen from the data unless something about the drive is declared.
  const std::string drive_model = y.oneOf("drive_model", "auto", {"auto", "declared"});
  bool drive_declared = false;
  for (const char* key : {"time.voltage_delay_samples", "time.voltage_hold", "time.voltage_angle", "time.angle_prediction",
                          "inverter.model", "current_sensors.offsets", "current_sensors.gains"})
    drive_declared = drive_declared || y.has(key);
  c.automatic_drive_model = drive_model == "auto" && !drive_declared && !c.magnetics.cross_saturation;
  bool thermal_reference_missing = false;
  if (y.has("thermal")) {
    ThermalSettings& t = c.thermal;
    t.enabled = true;
    thermal_reference_missing = !y.has("thermal.reference_temperature");  // reported after a typo is
    t.reference_temperature = y.number("thermal.reference_temperature", 20.0);  // named by its nearest key
    if (t.reference_temperature < -60 || t.reference_temperature > 250)
      y.fail("thermal.reference_temperature", "must be in [-60, 250] degC");
    t.R_s_at_reference = y.number("thermal.R_s_at_reference", 0.0);
    if (t.R_s_at_reference < 0) y.fail("thermal.R_s_at_reference", "must be > 0 [ohm] (or absent: learnt at the start)");
    t.psi_f_at_reference = y.number("thermal.psi_f_at_reference", 0.0);
    if (t.psi_f_at_reference < 0) y.fail("thermal.psi_f_at_reference", "must be > 0 [Wb] (or absent: learnt at the start)");
    t.copper_coefficient = y.positive("thermal.copper_coefficient", t.copper_coefficient);
    t.magnet_coefficient = y.number("thermal.magnet_coefficient", t.magnet_coefficient);
    if (!(t.magnet_coefficient < 0)) y.fail("thermal.magnet_coefficient", "must be < 0 [1/K] (magnets weaken when hot)");
    t.learning_time = y.positive("thermal.learning_time", t.learning_time);
    t.max_uncertainty = y.positive("thermal.max_uncertainty", t.max_uncertainty);
  }
  AlarmSettings& al = c.alarms;
  al.winding_max_temperature = y.number("alarms.winding_max_temperature", al.winding_max_temperature);
  al.winding_hysteresis = y.positive("alarms.winding_hysteresis", al.winding_hysteresis);
  al.magnet_above_winding = y.positive("alarms.magnet_above_winding", al.magnet_above_winding);
  al.demagnetisation_drop = y.positive("alarms.demagnetisation_drop", al.demagnetisation_drop);
  al.confirm_time = y.positive("alarms.confirm_time", al.confirm_time);
  al.jump_fraction = y.positive("alarms.jump_fraction", al.jump_fraction);
  al.jump_window = y.positive("alarms.jump_window", al.jump_window);
  al.drift_rate = y.positive("alarms.drift_rate", al.drift_rate);
  al.drift_window = y.positive("alarms.drift_window", al.drift_window);
  y.rejectUnknownKeys();
  if (thermal_reference_missing) y.fail("thermal.reference_temperature", "missing [degC]");
  validate(c, path);
  return c;
}

}  // namespace pmsm_param_id
