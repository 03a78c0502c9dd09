// How a drive log from another tool names and scales its columns. The core works in SI with the
// electrical speed and amplitude-invariant dq quantities; a LogFormat converts on reading.
#pragma once
#include <map>
#include <string>

namespace pmsm_param_id {

struct LogFormat {
  /// Column name in the file for each quantity: t, u_d, u_q, i_d, i_q, omega_e; theta_e and v_dc
  /// (the DC-bus voltage) are optional.
  std::map<std::string, std::string> columns{{"t", "t"},         {"u_d", "u_d"},         {"u_q", "u_q"},
                                             {"i_d", "i_d"},     {"i_q", "i_q"},         {"omega_e", "omega_e"},
                                             {"theta_e", "theta_e"}, {"v_dc", "v_dc"}};
  std::string time_unit = "s";        ///< s | ms | us
  std::string speed_unit = "rad/s";   ///< rad/s (electrical) | mech_rad/s | rpm (mechanical) | erpm (electrical rpm) | hz (electrical)
  std::string current_unit = "A";     ///< A | mA
  std::string voltage_unit = "V";     ///< V | mV
  std::string angle_unit = "rad";     ///< rad | deg (electrical)
  std::string dq_scaling = "amplitude_invariant";  ///< amplitude_invariant | power_invariant
  int pole_pairs = 0;                 ///< needed by mechanical speed units
  char separator = ',';               ///< between cells: ',' or ';' (VESC Tool's logs)
  /// The time column restarts from zero at this value, in its own unit (VESC Tool's ms_today:
  /// 86 400 000 ms, midnight); 0: it never wraps. A step back by more than half of it is a wrap.
  double time_wraps_at = 0.0;
  /// A log without a time column (columns.t empty): its rows are this far apart [s].
  double sample_period = 0.0;

  /// Factors that turn file values into SI / electrical / amplitude-invariant values.
  double timeFactor() const;
  double speedFactor() const;
  double currentFactor() const;  ///< includes the dq scaling
  double voltageFactor() const;  ///< includes the dq scaling
  double busVoltageFactor() const;  ///< the voltage unit only (the bus voltage is not a dq quantity)
  double angleFactor() const;
  /// ConfigError naming `source` and the key when a unit is unknown or pole pairs are missing
  /// (those only with require_pole_pairs: a format file may leave them to the command line).
  void validate(const std::string& source, bool require_pole_pairs = true) const;
};

/// Reads a log-format YAML (keys: columns.{t,u_d,...}, units.{time,speed,current,voltage,angle},
/// time_wraps_at, separator, pole_pairs, dq_scaling); unknown keys are errors. A name without a
/// folder or .yaml (vesc, motor_temperature) is a format the package ships (config/formats/).
LogFormat loadLogFormat(const std::string& path_or_name);

/// The folder of the shipped formats (config/formats of the package's source or share).
std::string shippedFormatsDir();

}  // namespace pmsm_param_id
