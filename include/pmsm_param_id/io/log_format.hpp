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
  std::string speed_unit = "rad/s";   ///< rad/s (electrical) | mech_rad/s | rpm (mechanical) | hz (electrical)
  std::string current_unit = "A";     ///< A | mA
  std::string voltage_unit = "V";     ///< V | mV
  std::string angle_unit = "rad";     ///< rad | deg (electrical)
  std::string dq_scaling = "amplitude_invariant";  ///< amplitude_invariant | power_invariant
  int pole_pairs = 0;                 ///< needed by mechanical speed units

  /// Factors that turn file values into SI / electrical / amplitude-invariant values.
  double timeFactor() const;
  double speedFactor() const;
  double currentFactor() const;  ///< includes the dq scaling
  double voltageFactor() const;  ///< includes the dq scaling
  double busVoltageFactor() const;  ///< the voltage unit only (the bus voltage is not a dq quantity)
  double angleFactor() const;
  /// ConfigError naming `source` and the key when a unit is unknown or pole pairs are missing.
  void validate(const std::string& source) const;
};

/// Reads a log-format YAML (keys: columns.{t,u_d,...}, units.{time,speed,current,voltage,angle},
/// pole_pairs, dq_scaling); unknown keys are errors.
LogFormat loadLogFormat(const std::string& path);

}  // namespace pmsm_param_id
