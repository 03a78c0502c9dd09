// Settings of every identification method, read from config/identifiers/*.yaml. Every default
// holds for any PMSM: nothing here depends on one motor (doc/algorithm.md).
#pragma once
#include <algorithm>
#include <cstdint>
#include <string>

#include "pmsm_param_id/identification/block_statistics.hpp"
#include "pmsm_param_id/identification/particle_swarm.hpp"
#include "pmsm_param_id/identification/thermal.hpp"
#include "pmsm_param_id/identification/monitor_settings.hpp"
#include "pmsm_param_id/identification/output_error.hpp"
#include "pmsm_param_id/model/motor_model.hpp"

namespace pmsm_param_id {

struct EkfSettings {
  double measurement_sigma = 0.0;      ///< current measurement noise [A]; 0 = the noise level estimated from the data
  double process_current_sigma = 0.0;  ///< current process noise per step [A]; 0 = 0.3 x measurement sigma
  double parameter_drift = 0.2;        ///< random-walk rate of each parameter [relative / sqrt(s)]
  double initial_relative_std = 1.0;   ///< initial parameter std, relative to the starting value [-]
};

struct RlsSettings {
  double time_constant = 0.0;       ///< forgetting time constant [s]; 0 = the fitness window's
  double initial_covariance = 1e6;  ///< P(0) = initial_covariance * I; also P's ceiling (standstill)
};

/// Where the swarm searches. With no bounds configured the box is data-driven: centred on the
/// exact minimiser of the block fitness, spanning span_factor either way, re-centred as data arrive.
struct SearchSettings {
  bool fixed_bounds = false;       ///< bounds given in the config: never moved
  ParameterVector lower{}, upper{};  ///< [SI] when fixed_bounds
  bool has_initial = false;        ///< initial values given in the config
  ParameterVector initial{};       ///< [SI] starting values of every method when has_initial
  double span_factor = 10.0;       ///< data-driven box: [centre / k, centre * k] [-]
};

/// When is a parameter "identified" (doc/algorithm.md section 4).
struct AssessmentSettings {
  double max_relative_uncertainty = 0.01;  ///< identified when the stated uncertainty is within this [-]
  double confidence_sigmas = 3.0;          ///< the stated uncertainty is this many standard deviations [-]
  double variance_inflation = 9.0;         ///< information-based variance x this (measured calibration) [-]
  double max_fit_ratio = 4.0;              ///< poor fit: mean square residual > this x what noise explains [-]
  double fit_floor_relative = 1e-4;        ///< residual RMS below this x RMS current is always a fit [-]
  double min_relative_uncertainty = 0.002; ///< the stated uncertainty is never below this (sampling effects) [-]
  /// Behind a switching inverter's forward current observer: nothing is identified until the fit has
  /// been consistent for this many window time constants (0: at once) [-]
  double observer_settling_time_constants = 2.0;
};

/// What the identifier knows about the drive's inverter (doc/algorithm.md section 8).
struct InverterModelSettings {
  bool estimate_voltage = false;  ///< estimate the inverter voltage error V with R_s, L_d, L_q, psi_f
  double max_relative_uncertainty = 0.05;  ///< V is identified within this [-]
};

/// What the identifier assumes about the machine's magnetics (doc/algorithm.md section 11).
struct MagneticsModelSettings {
  /// Fit the incremental L_qq and the cross-saturation L_dq with the four (a saturating interior-PM
  /// machine): L_d is then the incremental d inductance, L_q the secant psi_q / i_q, psi_f the flux
  /// psi_d at i_d = 0, and R_s is told from omega_e L_dq through the q axis's response to i_d.
  bool cross_saturation = false;
};

/// The online map of the motor (doc/algorithm.md section 12).
struct MotorMapSettings {
  /// Two operating points share a cell when i_d and i_q each differ by at most this fraction of
  /// the larger current magnitude (of the two points, and at least 5 % of the largest current seen).
  /// An estimate is filed only when its window's data lie in one cell: the window's i_q spread
  /// (standard deviation) at most a quarter of that tolerance; i_d may move more (the injection), L_d is
  /// the slope across it.
  double cell_fraction = 0.1;
  /// At most this many cells: a new operating point beyond them replaces the cell seen longest ago
  /// (a drive wandering over a fine spread of points must not grow the map without end).
  int max_cells = 1000;
  /// The cell tolerance [A] about a current of this magnitude [A]: cell_fraction times the larger
  /// of it and 5 % of the largest current seen (the map, its one-cell rule and the monitor's cells).
  double tolerance(double current, double largest_current) const {
    return cell_fraction * std::max(current, 0.05 * largest_current);
  }
};

struct TimeSettings {
  double sample_period = 0.0;   ///< nominal sampling period [s]; 0 = median of the stream's steps
  double max_gap_periods = 3.0; ///< a step longer than this many nominal periods is a gap [-]
};

/// The inverter error's zero-crossing width the automatic drive model falls back to where the
/// samples before the switch have no current to scale it by [A] (that of
/// config/identifiers/real_drive.yaml; the fitted shape mixes it with twice it). Otherwise the
/// width is chosen from the data (OnlineIdentifier::chooseZeroCrossingCurrent).
constexpr double kAutomaticZeroCrossingCurrent = 0.3;

struct IdentifierConfig {
  std::string method = "fbdapso";   ///< fbdapso | sapso | pso | ekf | rls | wls
  /// drive_model: auto and nothing about the drive declared (delay, hold, voltage angle or
  /// prediction, inverter, current sensors, cross-saturation): the identifier switches to the real
  /// drive's model where the data show one (doc/algorithm.md section 8).
  bool automatic_drive_model = true;
  std::uint64_t seed = 1;
  /// Pole pairs of the motor (motor.pole_pairs), for the torque and speed constants only; 0 =
  /// unknown (everything else works in electrical quantities).
  int pole_pairs = 0;
  SearchSettings search;
  WindowSettings window;
  SwarmSettings swarm;
  double sapso_T1 = 1000, sapso_C1 = 0.8;
  double fbdapso_T1 = 800, fbdapso_T2 = 500, fbdapso_C1 = 0.8, fbdapso_C2 = 0.9, fbdapso_zero_delta = 0.001;
  int iterations_per_sample = 1;
  /// What the swarm methods minimise (doc/algorithm.md section 10); ekf, rls and wls keep their own.
  FitnessKind fitness = FitnessKind::Block;
  int fitness_window_samples = 300;   ///< N of the paper fitness: the adjustable model runs over the last N samples
  EkfSettings ekf;
  RlsSettings rls;
  AssessmentSettings assessment;
  TimeSettings time;
  InverterModelSettings inverter;
  MagneticsModelSettings magnetics;
  MotorMapSettings map;
  ThermalSettings thermal;
  AlarmSettings alarms;
};

/// Known method names, in the order reports use.
const std::string& methodList();  // "fbdapso, sapso, pso, ekf, rls, wls"
bool isKnownMethod(const std::string& m);
/// fbdapso, sapso or pso: a particle swarm on the configured fitness.
bool isSwarmMethod(const std::string& m);

/// Reads a YAML file over the defaults above; every key is optional, an unknown key is an error.
/// ConfigError names the file and key.
IdentifierConfig loadIdentifierConfig(const std::string& path);
/// Checks a config built in code (bounds, population, method...). ConfigError names the key.
void validate(const IdentifierConfig& c, const std::string& source = "config");

}  // namespace pmsm_param_id
