#include "pmsm_param_id/io/log_format.hpp"

#include <cmath>
#include <fstream>

#include "pmsm_param_id/io/config_error.hpp"
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
  if (speed_unit == "erpm") return 2.0 * M_PI / 60.0;
  return 1.0;
}
double LogFormat::currentFactor() const { return (current_unit == "mA" ? 1e-3 : 1.0) * dqFactor(dq_scaling); }
double LogFormat::voltageFactor() const { return busVoltageFactor() * dqFactor(dq_scaling); }
double LogFormat::busVoltageFactor() const { return voltage_unit == "mV" ? 1e-3 : 1.0; }
double LogFormat::angleFactor() const { return angle_unit == "deg" ? M_PI / 180.0 : 1.0; }

void LogFormat::validate(const std::string& source, bool require_pole_pairs) const {
  const auto fail = [&](const std::string& key, const std::string& msg) {
    throw ConfigError(source + ": key '" + key + "': " + msg);
  };
  if (time_unit != "s" && time_unit != "ms" && time_unit != "us") fail("units.time", "expected s, ms or us, got '" + time_unit + "'");
  if (speed_unit != "rad/s" && speed_unit != "mech_rad/s" && speed_unit != "rpm" && speed_unit != "erpm" && speed_unit != "hz")
    fail("units.speed", "expected rad/s (electrical), mech_rad/s, rpm (mechanical), erpm (electrical rpm) or hz (electrical), got '" +
                            speed_unit + "'");
  if (separator != ',' && separator != ';') fail("separator", std::string("expected ',' or ';', got '") + separator + "'");
  if (!(time_wraps_at >= 0) || !std::isfinite(time_wraps_at)) fail("units.time_wraps_at", "must be >= 0 (0: no wrap)");
  if (!(sample_period >= 0) || !std::isfinite(sample_period)) fail("sample_period", "must be >= 0 [s]");
  if (columns.at("t").empty() && !(sample_period > 0))
    fail("columns.t", "empty (no time column) needs sample_period: the rows' spacing [s]");
  if (current_unit != "A" && current_unit != "mA") fail("units.current", "expected A or mA, got '" + current_unit + "'");
  if (voltage_unit != "V" && voltage_unit != "mV") fail("units.voltage", "expected V or mV, got '" + voltage_unit + "'");
  if (angle_unit != "rad" && angle_unit != "deg") fail("units.angle", "expected rad or deg, got '" + angle_unit + "'");
  if (dq_scaling != "amplitude_invariant" && dq_scaling != "power_invariant")
    fail("dq_scaling", "expected amplitude_invariant or power_invariant, got '" + dq_scaling + "'");
  if (require_pole_pairs && (speed_unit == "mech_rad/s" || speed_unit == "rpm") && pole_pairs < 1)
    fail("pole_pairs", "needed (>= 1) to turn a mechanical speed (" + speed_unit + ") into the electrical one");
  if (pole_pairs < 0 || pole_pairs > 1000) fail("pole_pairs", "must be in [1, 1000]");
}

std::string shippedFormatsDir() {
  const std::string installed = std::string(PMSM_INSTALL_SHARE_DIR) + "/config/formats";
  if (std::ifstream(installed + "/vesc.yaml")) return installed;
  return std::string(PMSM_SOURCE_DIR) + "/config/formats";
}

LogFormat loadLogFormat(const std::string& path_or_name) {
  const bool name = path_or_name.find('/') == std::string::npos &&
                    (path_or_name.size() < 5 || path_or_name.compare(path_or_name.size() - 5, 5, ".yaml") != 0);
  const std::string path = name ? shippedFormatsDir() + "/" + path_or_name + ".yaml" : path_or_name;
  if (name && !std::ifstream(path))
    throw ConfigError("--format " + path_or_name + ": no such shipped format (" + shippedFormatsDir() +
                      " holds them; or give a YAML file's path)");
  const YamlReader y = YamlReader::fromFile(path);
  LogFormat f;
  for (auto& [quantity, column] : f.columns) column = y.text("columns." + quantity, column);
  f.time_unit = y.text("units.time", f.time_unit);
  f.time_wraps_at = y.number("units.time_wraps_at", 0.0);
  f.speed_unit = y.text("units.speed", f.speed_unit);
  f.current_unit = y.text("units.current", f.current_unit);
  f.voltage_unit = y.text("units.voltage", f.voltage_unit);
  f.angle_unit = y.text("units.angle", f.angle_unit);
  f.dq_scaling = y.text("dq_scaling", f.dq_scaling);
  const std::string separator = y.text("separator", ",");
  if (separator.size() != 1) throw ConfigError(path + ": key 'separator': expected one character, ',' or ';'");
  f.separator = separator[0];
  f.sample_period = y.number("sample_period", 0.0);
  f.pole_pairs = static_cast<int>(y.integer("pole_pairs", 0, 1, 1000));
  y.rejectUnknownKeys();
  f.validate(path, false);
  return f;
}

}  // namespace pmsm_param_id
