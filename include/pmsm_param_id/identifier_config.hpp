// Settings of every identification method, read from config/identifiers/*.yaml.
#pragma once
#include <cstdint>
#include <string>

#include "pmsm_param_id/horizon_statistics.hpp"
#include "pmsm_param_id/motor_model.hpp"
#include "pmsm_param_id/particle_swarm.hpp"

namespace pmsm_param_id {

struct EkfSettings {
  double measurement_sigma = 0.03;     ///< current measurement noise [A]
  double process_current_sigma = 0.01; ///< current process noise per step [A]
  double parameter_drift = 0.2;        ///< random-walk rate of each parameter [relative / sqrt(s)]
  double initial_relative_std = 1.0;   ///< initial parameter std, relative to the initial value [-]
};

struct RlsSettings {
  double time_constant = 0.05;   ///< forgetting time constant [s]
  double initial_covariance = 1e6;  ///< P(0) = initial_covariance * I
};

struct IdentifierConfig {
  std::string method = "fbdapso";   ///< fbdapso | sapso | pso | ekf | rls
  std::uint64_t seed = 1;
  ParameterVector lower{0.5, 0.5e-3, 0.5e-3, 0.02};   ///< search bounds [SI]
  ParameterVector upper{10.0, 30e-3, 30e-3, 0.6};
  ParameterVector initial{5.0, 10e-3, 25e-3, 0.35};   ///< shared starting values [SI]
  HorizonSettings horizon;
  SwarmSettings swarm;
  double sapso_T1 = 1000, sapso_C1 = 0.8;
  double fbdapso_T1 = 800, fbdapso_T2 = 500, fbdapso_C1 = 0.8, fbdapso_C2 = 0.9, fbdapso_zero_delta = 0.001;
  int iterations_per_sample = 1;
  EkfSettings ekf;
  RlsSettings rls;
  double current_noise = 0.03;       ///< current measurement noise std assumed by the observability test [A]
  double max_relative_std = 0.002;   ///< identifiable when the estimated relative std is below [-]
  double max_gap_periods = 3.0;      ///< a step longer than this many nominal periods is a gap [-]
};

/// Known method names, in the order reports use.
const std::string& methodList();  // "fbdapso, sapso, pso, ekf, rls"
bool isKnownMethod(const std::string& m);

/// Reads a YAML file over the defaults above. ConfigError names the file and key.
IdentifierConfig loadIdentifierConfig(const std::string& path);
/// Checks a config built in code (bounds, population, method...). ConfigError names the key.
void validate(const IdentifierConfig& c, const std::string& source = "config");

}  // namespace pmsm_param_id
