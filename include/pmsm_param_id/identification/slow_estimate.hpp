// R_s and psi_f on a thermal time scale (doc/algorithm.md section 9).
//
// The fitness window (50 ms) serves L_d and L_q; as thermometers R_s and psi_f need more data than
// it holds, and behind a real inverter R_s needs more than one current magnitude: at any one
// magnitude the inverter's error voltage V along the current acts as a resistance V / |i|. Two
// facts separate them. V is a constant of the drive (dead time x bus voltage x switching
// frequency, device drops), R_s moves with the winding's temperature over minutes; and a window of
// seconds holds a load change now and then. So:
//   - the slow window keeps the non-overlapping blocks as they are over slow_time_constant
//     (1 s by default), with every drive term the fitness window has;
//   - its exact fit, all terms free, determines V (and the voltage angle) wherever its blocks span
//     current magnitudes (and load or speed changes); the best determination so far, from a fit
//     that is consistent with the noise, is remembered as the drive's constants;
//   - between load changes the slow fit holds the remembered constants, and each parameter's
//     standard deviation adds what one standard deviation of a held constant moves it by.
// The slow estimates are the data's exact optimum (the same for every method), with their own
// fit check, statuses and stated uncertainty; the identifier adds the lag of the exponential
// window behind a changing temperature (OnlineIdentifier).
#pragma once
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include "pmsm_param_id/identification/assessment.hpp"
#include "pmsm_param_id/identification/block_statistics.hpp"

namespace pmsm_param_id {

/// The drive's constants as the slow window determined them best so far.
struct DriveConstants {
  bool inverter_known = false;
  double V = 0.0, V_wide = 0.0, V_bus = 0.0;  ///< inverter voltage and its shape's shares [V]
  double V_std = std::numeric_limits<double>::infinity();  ///< [V]
  double inverter_t = NAN;                    ///< stamp of the window that gave them [s]
  /// The range of V over the windows that determined it to kWellDeterminedInverter: the inverter
  /// model (a shape through zero, one V along the current) is not exact, and V moves with the
  /// operating point (+-0.1-0.25 V of 12 V on the switching-level industrial drive) [V].
  double V_min = std::numeric_limits<double>::infinity(), V_max = -std::numeric_limits<double>::infinity();
  bool angle_known = false;
  double angle = 0.0;                                          ///< [periods of omega_e T_s]
  double angle_std = std::numeric_limits<double>::infinity();  ///< [-]
  double angle_t = NAN;                                        ///< [s]
};

/// The exact fit of the slow window.
struct SlowFit {
  bool available = false;
  bool consistent = false;         ///< its residual is what the noise explains (assessment.max_fit_ratio)
  double fit_ratio_d = NAN, fit_ratio_q = NAN;
  double window_time_constant = 0.0;  ///< slow_time_constant [s]
  ParameterVector optimum{};
  std::array<bool, kParameterCount> determined{};
  ParameterVector relative_std{};  ///< information and the held constants' share [-]
  ParameterVector relative_std_known_inverter{};  ///< the same without V's share [-]
  /// What V moving by its systematic spread (half the range of its determinations, at least
  /// kInverterModelFloor of V) moves each parameter by, at this window's currents [-]; a bound,
  /// added to the stated uncertainty as it is.
  ParameterVector inverter_model_relative{};
  double inverter_model_spread = 0.0;  ///< that spread [V]
  /// Where the encoder's count is locked to the sampling (CountLock): what a wobble of the drive's
  /// frame against the rotor by half a count, in phase with the d current's swing, moves each
  /// parameter by [-]; a bound, added to the stated uncertainty as it is (0 where not locked).
  ParameterVector count_lock_relative{};
  bool inverter_modelled = false;
  bool inverter_held = false;      ///< V and its shape taken from DriveConstants
  double inverter_voltage = NAN;   ///< the V in the fit [V]
  double inverter_wide_share = NAN;  ///< the part of it with twice the zero-crossing width [V]
  double inverter_relative_std = std::numeric_limits<double>::infinity();
  bool angle_held = false;
  /// R_s's own rate is fitted (behind an inverter): R_s is the value at the newest snapshot and
  /// needs no lag from the window's history.
  bool rate_modelled = false;
};

/// V counts towards its systematic range where a window determined it to this relative std [-].
constexpr double kWellDeterminedInverter = 0.005;
/// The smallest systematic spread of V the slow window assumes: the range of a few determinations
/// underestimates it (measured: 1-2 % of V between operating points of the switching-level
/// industrial drive) [-].
constexpr double kInverterModelFloor = 0.01;
/// The same for the switching edges' model (inverter_edges.hpp), which follows the ripple's share
/// itself: with exact currents its V varied by +-0.14-0.26 % between the operating points of the
/// switching-level industrial drive and +-0.50 % on wc1_applied_log (the smooth shape's by
/// +-0.54-0.98 % and +-0.73 %); the largest of those [-].
constexpr double kInverterEdgeModelFloor = 0.005;

/// Fits the slow window. `fast` is the fitness window's check of the same statistics (its drive
/// terms, noise level and optimum as the start); `constants` is updated where this window
/// determines them better, from a fit consistent with the noise. t: the stamp of the data [s].
/// resistance_rate: behind an inverter, R_s's rate and heating are fitted with it (SlowFit::rate_modelled).
SlowFit slowFit(const BlockStatistics& stats, const AssessmentSettings& a, const FitCheck& fast,
                DriveConstants& constants, double t, bool resistance_rate = true);

/// Status of the slow R_s and psi_f (the inductances are the fitness window's business).
/// lag_relative: per parameter, how far the window's exponential average may trail a changing
/// value [-] (added to the stated uncertainty).
struct SlowAssessment {
  std::array<ParameterStatus, kParameterCount> status{};
  std::array<std::string, kParameterCount> reason{};
  ParameterVector relative_uncertainty{};
};
SlowAssessment assessSlow(const SlowFit& fit, const AssessmentSettings& a, const ParameterVector& lag_relative);

}  // namespace pmsm_param_id
