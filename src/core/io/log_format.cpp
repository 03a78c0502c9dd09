#include "pmsm_param_id/io/log_format.hpp"

#include <cmath>

#include "pmsm_param_id/io/yaml_reader.hpp"

namespace pmsm_param_id {

namespace {
// Power-invariant dq quantities are sqrt(3/2) times the amplitude-invariant ones.
double dqFactor(const std::string& scaling) { return scaling == "power_invariant" ? std::sqrt(2.0 / 3.0) : 1.0; }
}  // namespace

double LogFormat::timeFactor() const { return time_unit == "ms" ? 1e-3 : time_unit == "us" ? 1e-6 : 1.0; }
double LogFormat::speedFactor() const {
  if (speed_unit == "mech_rad/s") return pole_pairs;
  if (speed_unit == "rpm") return pole_pairs * 2.0 * M_PI / 60.0;
  if (speed_unit == "hz") return 2.0 * M_PI;
  return 1.0;
}
double LogFormat::currentFactor() const { return (current_unit == "mA" ? 1e-3 : 1.0) * dqFactor(dq_scaling); }
double LogFormat::voltageFactor() const { return busVoltageFactor() * dqFactor(dq_scaling); }
double LogFormat::busVoltageFactor() const { return voltage_unit == "mV" ? 1e-3 : 1.0; }
double LogFormat::angleFactor() const { return angle_unit == "deg" ? M_PI / 180.0 : 1.0; }

void LogFormat::validate(const std::string& source) const {
  const auto fail = [&](const std::string& key, const std::string& msg) {
    throw ConfigError(source + ": key '" + key + "': " + msg);
  };
  if (time_unit != "s" && time_unit != "ms" && time_unit != "us") fail("units.time", "expected s, ms or us, got '" + time_unit + "'");
  if (speed_unit != "rad/s" && speed_unit != "mech_rad/s" && speed_unit != "rpm" && speed_unit != "hz")
    fail("units.speed", "expected rad/s (electrical), mech_rad/s, rpm (mechanical) or hz (electrical), got '" + speed_unit + "'");
  if (current_unit != "A" && current_unit != "mA") fail("units.current", "expected A or mA, got '" + current_unit + "'");
  if (voltage_unit != "V" && voltage_unit != "mV") fail("units.voltage", "expected V or mV, got '" + voltage_unit + "'");
  if (angle_unit != "rad" && angle_unit != "deg") fail("units.angle", "expected rad or deg, got '" + angle_unit + "'");
  if (dq_scaling != "amplitude_invariant" && dq_scaling != "power_invariant")
    fail("dq_scaling", "expected amplitude_invariant or power_invariant, got '" + dq_scaling + "'");
  if ((speed_unit == "mech_rad/s" || speed_unit == "rpm") && pole_pairs < 1)
    fail("pole_pairs", "needed (>= 1) to turn a mechanical speed (" + speed_unit + ") into the electrical one");
  if (pole_pairs < 0 || pole_pairs > 1000) fail("pole_pairs", "must be in [1, 1000]");
}

LogFormat loadLogFormat(const std::string& path) {
  const YamlReader y = YamlReader::fromFile(path);
  LogFormat f;
  for (auto& [quantity, column] : f.columns) column = y.text("columns." + quantity, column);
  f.time_unit = y.text("units.time", f.time_unit);
  f.speed_unit = y.text("units.speed", f.speed_unit);
  f.current_unit = y.text("units.current", f.current_unit);
  f.voltage_unit = y.text("units.voltage", f.voltage_unit);
  f.angle_unit = y.text("units.angle", f.angle_unit);
  f.dq_scaling = y.text("dq_scaling", f.dq_scaling);
  f.pole_pairs = static_cast<int>(y.integer("pole_pairs", 0, 1, 1000));
  y.rejectUnknownKeys();
  f.validate(path);
  return f;
}

}  // namespace pmsm_param_id
