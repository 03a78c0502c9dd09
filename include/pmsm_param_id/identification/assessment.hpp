// What an estimate is worth: per-parameter status with its reason, the stated uncertainty, and
// the check that the model fits the data at the noise level the data themselves show.
//
// "identified" means right within the stated uncertainty: the data determine the parameter
// (excitation), the model fits the data as well as their noise allows (fit check), the method's
// value lies within that uncertainty of the data's exact optimum, not on a search bound, and is
// physically plausible. doc/algorithm.md section 4 gives the equations and the measured thresholds.
#pragma once
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "pmsm_param_id/identification/angle_quantum.hpp"
#include "pmsm_param_id/identification/block_least_squares.hpp"
#include "pmsm_param_id/identification/identifier_config.hpp"

namespace pmsm_param_id {

enum class ParameterStatus : std::uint8_t {
  NoData = 0,        ///< no complete block yet, or the method has not started
  Identified = 1,    ///< right within the stated uncertainty
  NotExcited = 2,    ///< the data in the window do not determine it to the required uncertainty
  PoorFit = 3,       ///< the model does not fit the data at their noise level (see likely_cause)
  AtBound = 4,       ///< the method's value sits on its search bound or clamp
  Implausible = 5,   ///< non-finite, <= 0 or outside every PMSM's range
  NotConverged = 6,  ///< the method's value is further from the data's optimum than the uncertainty allows
};
const char* toString(ParameterStatus s);  ///< "no_data", "identified", "not_excited", ...

/// The physical envelope of a PMSM's parameters, far wider than any shipped scenario (watch
/// motors to megawatt machines): {R_s [ohm], L_d [H], L_q [H], psi_f [Wb]}.
constexpr ParameterVector kPlausibleLower{1e-4, 1e-7, 1e-7, 1e-5};
constexpr ParameterVector kPlausibleUpper{1e3, 10.0, 10.0, 50.0};
bool plausible(int parameter, double value);

/// The clause of a `not_excited` reason that names the inverter's error voltage (V [V], its relative
/// uncertainty at the confidence level) as the part of a parameter's relative uncertainty
/// `statistical` that `known_inverter` (the same with V known) lacks, in quadrature, where that part
/// is half of it or more; "" otherwise. `source` is said after V's uncertainty (where V comes from),
/// `nature` after that (what V is), `separation` at the end (what would separate them). One wording
/// for the fitness window's reasons and the slow window's.
std::string inverterShareClause(double statistical, double known_inverter, double V, double V_relative,
                                const std::string& source, const std::string& nature, const std::string& separation);

/// What the fit diagnosis names as the likely cause of a misfit.
enum class MisfitCause : std::uint8_t {
  None = 0,
  Unit,          ///< the speed's or the time's unit
  Delay,         ///< the voltage acts a whole sample later or earlier than declared
  FractionalDelay,  ///< a fraction of a sample: the logged voltage does not hold over the period
  VoltageAngle,  ///< the voltage acts turned against the declared timing (angle prediction)
  Inverter,      ///< an inverter error voltage along the current
  Saturation,    ///< a cross-saturation inductance
  Other,         ///< none of the above
};

/// The data's own verdict, the same for every method on the same window.
struct FitCheck {
  bool available = false;          ///< blocks exist and the exact fit succeeded
  ParameterVector optimum{};       ///< exact minimiser of the block fitness (undetermined: start values)
  ParameterVector relative_std{};  ///< of the optimum, from the information and the estimated noise [-]
  std::array<bool, kParameterCount> determined{};
  double noise_std_d = 0.0;        ///< current noise estimated from the data (block differences) [A]
  double noise_std_q = 0.0;        ///< [A]
  double block_noise_variance_d = 0.0;  ///< block-residual variance the noise explains [A^2]
  double block_noise_variance_q = 0.0;  ///< [A^2]
  double fit_ratio_d = 0.0;        ///< mean r_d^2 at the optimum / what the noise explains [-]
  double fit_ratio_q = 0.0;        ///< [-]
  double optimum_fitness = 0.0;    ///< [A^2]
  bool consistent = false;         ///< the model fits at the noise level
  bool speed_unit_verified = false; ///< q-axis current steps tie the speed terms to the Di terms (3 %)
  double speed_scale_short = NAN;  ///< speed-term / current-step-term inductance ratio, fitness window [-]
  double speed_scale_long = NAN;   ///< the same over the long check window [-] (1 when the units are right)
  std::string likely_cause;        ///< one line when the fit is poor and a cause fits the data
  MisfitCause likely_cause_kind = MisfitCause::None;
  double misfit_delay = 0.0;       ///< the delay that fits [samples] when likely_cause_kind is Delay
  double sampling_floor = 0.0;     ///< (omega_e T_s)^2: relative error of sampled integrals at speed [-]
  /// c z^2, z = T_s V / (w L): the inverter error's zero crossings within a period, where the
  /// currents are not the chords between the samples; added to L_d's stated uncertainty while the
  /// shape observer, which follows them, does not run (doc/algorithm.md section 8) [-]
  double crossing_floor = 0.0;
  bool inverter_modelled = false;  ///< the fit estimated an inverter voltage error V with the four
  double inverter_voltage = 0.0;   ///< V [V] (pole-voltage error amplitude, V_dc t_dead f_sw + drop)
  /// The zero-crossing shape: the part of V whose error builds up over twice the configured current
  /// (the rest over the configured current) [V]; see LinearBlockModel::inverterWithShape().
  double inverter_wide_share = 0.0;
  /// The part of V that follows the logged DC-bus voltage (the dead time's), at the first logged bus
  /// voltage [V]; 0 without a logged bus (LinearBlockModel::inverterWithShapeAndBus()).
  double inverter_bus_share = 0.0;
  double inverter_relative_std = std::numeric_limits<double>::infinity();  ///< of V [-]
  bool cross_saturation_modelled = false;  ///< the fit estimated L_qq and L_dq (magnetics.cross_saturation)
  double L_qq = NAN, L_dq = NAN;           ///< incremental q and cross-saturation inductances [H]
  double L_qq_std = NAN, L_dq_std = NAN;   ///< their standard deviations [H] (inf: undetermined)
  /// The fit estimated the voltage angle a (the acting vector turned by a omega_e T_s against the
  /// declared timing; WindowSettings::estimate_voltage_angle).
  bool voltage_angle_modelled = false;
  double voltage_angle = NAN;       ///< a [periods of omega_e T_s]
  double voltage_angle_std = NAN;   ///< its standard deviation [-] (inf: undetermined)
  /// The angle came from the long check window (it determined it better than the fitness window):
  /// the fitness window's fit holds it there, and the parameters' std include its std's effect.
  bool voltage_angle_from_long_window = false;
  /// The angle came from an earlier fitness window that determined it better (RememberedAngle): the
  /// fit holds it the same way.
  bool voltage_angle_remembered = false;
  double voltage_angle_remembered_t = NAN;  ///< the stamp of the window that gave it [s]
  /// The fitness window's own estimate of a, whatever the fit then held [-] (inf std: undetermined).
  double own_voltage_angle = NAN;
  double own_voltage_angle_std = std::numeric_limits<double>::infinity();
  /// The inverter voltage and its shape came from the long check window in the same way (several
  /// current magnitudes there separate V from R_s); inverter_relative_std is then the long window's.
  bool inverter_from_long_window = false;
  /// Per parameter: the relative std with a held at its estimate (what the data would give if the
  /// drive's timing were known); where this is within the limit and relative_std is not, the
  /// parameter cannot be told from the drive's timing in this window.
  ParameterVector relative_std_known_timing{};
  /// Per parameter: the model's own systematic error (an inverter model's spread: what moving V by
  /// it moves the parameter by), added to the stated uncertainty [-]; zero where not assessed.
  ParameterVector model_floor{};
  /// Per parameter: where the window fits its own voltage angle and that disagrees with the drive's
  /// remembered one by more than one combined standard deviation, what holding the remembered angle
  /// instead moves the parameter by, added to the stated uncertainty [-].
  ParameterVector angle_disagreement{};
  /// Per parameter: the relative std with the inverter voltage and its shape held at their
  /// estimate (its own uncertainty left out): where this is within the limit and relative_std is
  /// not, the parameter (R_s) cannot be told from the inverter's error voltage in this data.
  ParameterVector relative_std_known_inverter{};
  /// Per parameter: where the encoder's count is locked to the sampling, what the drive's frame
  /// wobbling against the rotor by half a count with the d current moves it by (countLockMoves),
  /// added to the stated uncertainty [-]; zero where not locked.
  ParameterVector count_lock{};
};

/// Where the encoder's count was locked to the sampling over a window (CountLock): the frame may
/// wobble against the rotor by up to half a count (the quantum q [rad]), and a d-axis injection's
/// torque ripple moves the rotor in phase with i_d, so the d voltage carries up to
/// psi_f omega_e (q / 2) (i_d - mean) / swing, swing = sqrt(2) times the d current's spread. What
/// that moves each parameter of the fit f by (its entries `hold` held, the window's sums w),
/// scaled by the window's locked share [-]; zeros where nothing was locked.
ParameterVector countLockMoves(const WindowSums& w, const LinearBlockModel& model, const BlockFit& f,
                               const std::vector<bool>& hold, const CountLock::Window& lock, double quantum,
                               double variance_inflation);
/// The clause a reason takes where countLockMoves (relative_move [-]) is a quarter or more of a
/// parameter's stated uncertainty.
std::string countLockClause(double relative_move);

/// The drive's voltage angle as an earlier fitness window determined it (a constant of the drive:
/// its angle prediction and computation delay). A window spanning a load step or a speed reversal
/// tells the angle from L_q; one at a steady operating point cannot, and takes the remembered one
/// where that is better determined than its own and the two agree (doc/algorithm.md section 8).
struct RememberedAngle {
  double angle = NAN;                                                   ///< a [periods of omega_e T_s]
  double standard_deviation = std::numeric_limits<double>::infinity();  ///< [-]
  double t = NAN;                                                       ///< stamp of the window that gave it [s]
  bool known() const { return std::isfinite(angle) && std::isfinite(standard_deviation) && standard_deviation > 0; }
};
/// A remembered angle is taken only where it agrees with the window's own within this many
/// combined standard deviations; between one and this, its standard deviation is scaled by the
/// disagreement (in combined standard deviations). Where taken, it is combined with the window's own
/// by their standard deviations (checkFit).
constexpr double kRememberedAngleAgreement = 3.0;

/// Exact fit of the window starting from `start` (positive inductances), and its check.
/// estimate_inverter: fit V and its zero-crossing shape with the four (start value inverter_start).
/// estimate_cross_saturation: fit L_qq and L_dq with the four (section 11); excludes estimate_inverter.
FitCheck checkFit(const BlockStatistics& stats, const AssessmentSettings& settings, const ParameterVector& start,
                  bool diagnose, bool estimate_inverter = false, double inverter_start = 0.0,
                  bool estimate_cross_saturation = false, const RememberedAngle* remembered = nullptr);

/// Status of the estimated inverter voltage: identified within max_relative_uncertainty, or why not.
struct InverterAssessment {
  ParameterStatus status = ParameterStatus::NoData;
  std::string reason;
  double relative_uncertainty = std::numeric_limits<double>::infinity();
};
InverterAssessment assessInverter(const FitCheck& fit, const AssessmentSettings& a, double max_relative_uncertainty);

struct Assessment {
  std::array<ParameterStatus, kParameterCount> status{};
  std::array<std::string, kParameterCount> reason{};
  ParameterVector relative_uncertainty{};  ///< stated uncertainty / value [-] (inf where unknown)
};

/// The optimum of the fitness a swarm searches, a little earlier (age seconds ago).
struct RecentOptimum {
  double age = 0.0;           ///< [s]
  double renewed = 0.0;       ///< the share of the window's weight that came in since [-]
  bool reference = true;      ///< recent enough to assess a trailing method against (else: drift test only)
  ParameterVector optimum{};  ///< [SI] (NaN where the window did not determine the parameter)
};

/// The optima of the fitness a swarm searches: now, and over the last moments.
struct TrailedOptima {
  ParameterVector now{};               ///< [SI] (NaN where the window does not determine it)
  std::vector<RecentOptimum> earlier;  ///< oldest first
};

/// Status of a method's parameters against the data's fit. at_bound: the method's own bounds.
/// trailed: for a method that trails the window's optimum (a swarm searching the changing
/// fitness), the optima of that fitness: where none of the earlier ones lies further from the one
/// now than the noise moves it, the value is stated against the nearest of those marked
/// `reference` where that is nearer than the data's optimum (doc/algorithm.md section 4).
Assessment assess(const ParameterVector& parameters, const FitCheck& fit, const std::array<bool, kParameterCount>& at_bound,
                  const AssessmentSettings& settings, const TrailedOptima* trailed = nullptr);

}  // namespace pmsm_param_id
