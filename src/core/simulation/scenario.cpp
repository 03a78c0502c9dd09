#include "pmsm_param_id/simulation/scenario.hpp"

#include <cmath>
#include <memory>
#include <utility>

#include "pmsm_param_id/io/config_error.hpp"
#include "pmsm_param_id/io/yaml_reader.hpp"

namespace pmsm_param_id {

Scenario loadScenario(const std::string& path) {
  const YamlReader y = YamlReader::fromFile(path);
  Scenario s;
  s.name = y.text("name", path);
  if (!y.has("motor.pole_pairs")) y.fail("motor.pole_pairs", "missing");
  const long pole_pairs = y.integer("motor.pole_pairs", -1, 1, 1000);
  s.motor.pole_pairs = static_cast<int>(pole_pairs);
  s.motor.R_s = y.positive("motor.R_s");
  s.motor.L_d = y.positive("motor.L_d");
  s.motor.L_q = y.positive("motor.L_q");
  s.motor.psi_f = y.positive("motor.psi_f");
  s.motor.inertia = y.positive("motor.inertia");
  s.motor.friction = y.number("motor.friction");
  if (s.motor.friction < 0) y.fail("motor.friction", "must be >= 0");

  s.drive.sample_period = y.positive("drive.sample_period");
  if (s.drive.sample_period < 1e-7 || s.drive.sample_period > 1e-2)
    y.fail("drive.sample_period", "must be between 1e-7 s (10 MHz) and 1e-2 s (100 Hz)");
  const long substeps = y.integer("drive.integration_substeps", 10, 1, 10000);
  s.drive.integration_substeps = static_cast<int>(substeps);
  s.drive.dc_bus_voltage = y.positive("drive.dc_bus_voltage");
  s.drive.max_current = y.positive("drive.max_current");
  s.drive.current_loop_bandwidth_hz = y.positive("drive.current_loop_bandwidth_hz", 1000.0);
  s.drive.speed_loop_bandwidth_hz = y.positive("drive.speed_loop_bandwidth_hz", 20.0);
  if (s.drive.current_loop_bandwidth_hz * s.drive.sample_period > 0.25)
    y.fail("drive.current_loop_bandwidth_hz", "too high for the sampling period (keep bandwidth * T_s <= 0.25)");

  s.sensors.current_noise_sigma = y.nonNegative("sensors.current_noise_sigma", 0.0);
  const long bits = y.integer("sensors.adc_bits", 0, 0, 32);
  s.sensors.adc_bits = static_cast<int>(bits);
  s.sensors.adc_range = y.positive("sensors.adc_range", 50.0);

  InverterSettings& inv = s.inverter;
  inv.dead_time = y.number("inverter.dead_time", 0.0);
  if (inv.dead_time < 0 || inv.dead_time > 0.2 * s.drive.sample_period)
    y.fail("inverter.dead_time", "must be in [0, 0.2 x drive.sample_period] [s]");
  inv.switching_frequency = y.nonNegative("inverter.switching_frequency", 0.0, " (0 = 1 / sample_period)");
  inv.device_drop = y.nonNegative("inverter.device_drop", 0.0, " [V]");
  inv.device_resistance = y.nonNegative("inverter.device_resistance", 0.0, " [ohm]");
  inv.zero_crossing_current = y.positive("inverter.zero_crossing_current", inv.zero_crossing_current);
  const std::string hold = y.oneOf("inverter.voltage_hold", "dq", {"dq", "stationary"});
  inv.stationary_hold = hold == "stationary";
  inv.computation_delay = static_cast<int>(y.integer("inverter.computation_delay", 0, 0, 1));
  inv.dc_ripple = y.number("inverter.dc_ripple", 0.0);
  if (inv.dc_ripple < 0 || inv.dc_ripple >= 0.5) y.fail("inverter.dc_ripple", "must be in [0, 0.5)");
  inv.dc_ripple_frequency = y.positive("inverter.dc_ripple_frequency", inv.dc_ripple_frequency);
  const std::string model = y.oneOf("inverter.model", "average", {"average", "switching"});
  inv.switching = model == "switching";
  if (inv.switching) {
    if (y.has("inverter.switching_frequency") && std::abs(inv.switching_frequency * s.drive.sample_period - 1.0) > 1e-9)
      y.fail("inverter.switching_frequency", "the switching model runs one PWM period per sample: leave it out or set 1 / sample_period");
    if (y.has("inverter.zero_crossing_current"))
      y.fail("inverter.zero_crossing_current", "belongs to the average model (the switching model follows the actual current)");
    if (y.has("inverter.voltage_hold") && !inv.stationary_hold)
      y.fail("inverter.voltage_hold", "a PWM inverter holds the vector in the stator frame: stationary (or leave it out)");
    inv.stationary_hold = true;
  }
  if (y.has("inverter.angle_prediction")) {
    inv.angle_prediction = y.number("inverter.angle_prediction");
    if (!(std::abs(inv.angle_prediction) <= 4.0)) y.fail("inverter.angle_prediction", "must be in [-4, 4] periods");
  }
  const std::string logged = y.oneOf("inverter.logged_voltage", "reference", {"reference", "applied"});
  inv.log_applied_voltage = logged == "applied";
  const std::string frame = y.oneOf("sensors.frame", "dq", {"dq", "phase"});
  s.sensors.phase_currents = frame == "phase";
  for (const char* key : {"sensors.phase_offset", "sensors.phase_gain"}) {
    if (!y.has(key)) continue;
    const std::vector<double> v = y.numbers(key);
    if (v.size() != 3) y.fail(key, "expected three values [a, b, c]");
    auto& target = std::string(key) == "sensors.phase_offset" ? s.sensors.phase_offset : s.sensors.phase_gain;
    for (int i = 0; i < 3; ++i) target[static_cast<std::size_t>(i)] = v[static_cast<std::size_t>(i)];
  }
  s.sensors.encoder_lines = static_cast<int>(y.integer("sensors.encoder_lines", 0, 0, 1 << 24));
  s.sensors.speed_filter_hz = y.positive("sensors.speed_filter_hz", s.sensors.speed_filter_hz);
  s.sensors.speed_window_periods = static_cast<int>(y.integer("sensors.speed_window_periods", 0, 0, 100000));
  if (s.sensors.speed_window_periods > 0 && s.sensors.encoder_lines == 0)
    y.fail("sensors.speed_window_periods", "needs an encoder (sensors.encoder_lines)");
  if (s.sensors.speed_window_periods > 0 && y.has("sensors.speed_filter_hz"))
    y.fail("sensors.speed_filter_hz", "give either a speed filter or a count-difference window, not both");
  if (y.has("thermal")) {
    ThermalModelSettings& th = s.thermal;
    th.enabled = true;
    th.reference_temperature = y.number("thermal.reference_temperature", th.reference_temperature);
    th.ambient_temperature = y.number("thermal.ambient_temperature", th.ambient_temperature);
    th.winding_capacity = y.positive("thermal.winding_capacity", th.winding_capacity);
    th.winding_to_ambient = y.positive("thermal.winding_to_ambient", th.winding_to_ambient);
    th.winding_to_magnet = y.positive("thermal.winding_to_magnet", th.winding_to_magnet);
    th.magnet_capacity = y.positive("thermal.magnet_capacity", th.magnet_capacity);
    th.magnet_to_ambient = y.positive("thermal.magnet_to_ambient", th.magnet_to_ambient);
    th.magnet_loss_coefficient = y.nonNegative("thermal.magnet_loss_coefficient", th.magnet_loss_coefficient);
    th.copper_coefficient = y.positive("thermal.copper_coefficient", th.copper_coefficient);
    th.magnet_coefficient = y.number("thermal.magnet_coefficient", th.magnet_coefficient);
    if (!(th.magnet_coefficient < 0)) y.fail("thermal.magnet_coefficient", "must be < 0 [1/K]");
  }
  if (y.has("saturation")) {
    SaturationSettings& sat = s.saturation;
    sat.enabled = true;
    sat.q_saturation_current = y.nonNegative("saturation.q_saturation_current", 0.0, " [A] (0 = linear q axis)");
    sat.cross_saturation = y.nonNegative("saturation.cross_saturation", 0.0, " [H/A]");
    const std::string map = y.text("saturation.flux_map_csv", "");
    if (!map.empty()) {
      if (y.has("saturation.q_saturation_current") || y.has("saturation.cross_saturation"))
        y.fail("saturation.flux_map_csv", "give either a flux map or the analytic model's constants, not both");
      // Relative to the scenario file, as users keep a map beside the scenario that uses it.
      const std::string resolved = map.front() == '/' ? map : path.substr(0, path.find_last_of('/') + 1) + map;
      try {
        sat.flux_map = std::make_shared<const FluxTable>(loadFluxTable(resolved));
      } catch (const UserError& e) {
        y.fail("saturation.flux_map_csv", e.what());
      }
    }
  }
  const std::string mode = y.oneOf("drive.mode", "speed", {"speed", "torque"});
  s.drive.torque_control = mode == "torque";
  s.duration = y.positive("run.duration");
  if (s.duration / s.drive.sample_period > 1e9) y.fail("run.duration", "more than 1e9 samples");
  const long seed = y.integer("run.seed", 1, 0, 1L << 53);
  s.seed = static_cast<uint64_t>(seed);

  s.speed_reference_rpm = y.profile("profiles.speed_rpm");
  s.load_torque = y.profile("profiles.load_torque");
  s.d_current_injection = y.profile("profiles.d_current_injection", Profile::constant(0.0));
  s.q_current_reference = y.profile("profiles.q_current_reference", Profile::constant(0.0));
  if (s.drive.torque_control && !y.has("profiles.q_current_reference"))
    y.fail("profiles.q_current_reference", "missing (drive.mode: torque sets i_q from it)");
  s.R_s_scale = y.profile("profiles.R_s_scale", Profile::constant(1.0));
  s.psi_f_scale = y.profile("profiles.psi_f_scale", Profile::constant(1.0));
  s.L_d_scale = y.profile("profiles.L_d_scale", Profile::constant(1.0));
  s.L_q_scale = y.profile("profiles.L_q_scale", Profile::constant(1.0));
  if (s.saturation.flux_map)  // the map is the machine's flux as measured: nothing scales it
    for (const char* key : {"profiles.psi_f_scale", "profiles.L_d_scale", "profiles.L_q_scale", "thermal"})
      if (y.has(key))
        y.fail(key, "not with saturation.flux_map_csv (the map's fluxes are used as they are, at one temperature)");
  y.rejectUnknownKeys();
  return s;
}

Scenario withFluxMap(Scenario s, std::shared_ptr<const FluxTable> map) {
  s.saturation = SaturationSettings{};
  s.saturation.enabled = true;
  s.saturation.flux_map = std::move(map);
  return s;
}

}  // namespace pmsm_param_id
