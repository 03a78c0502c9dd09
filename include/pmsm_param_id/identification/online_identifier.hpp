// Sample-by-sample identification of {R_s, L_d, L_q, psi_f}: the one code path for live data,
// bag replay and CSV logs. Concrete methods: SwarmIdentifier (pso, sapso, fbdapso),
// EkfIdentifier, RlsIdentifier. The base class owns what every method shares: timing, the block
// statistics, the data-driven search box and the assessment of every estimate.
#pragma once
#include <cstdint>
#include <deque>
#include <optional>
#include <utility>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "pmsm_param_id/identification/angle_quantum.hpp"
#include "pmsm_param_id/identification/assessment.hpp"
#include "pmsm_param_id/identification/block_statistics.hpp"
#include "pmsm_param_id/identification/identifier_config.hpp"
#include "pmsm_param_id/identification/sample_period.hpp"
#include "pmsm_param_id/identification/slow_estimate.hpp"
#include "pmsm_param_id/model/sample.hpp"

namespace pmsm_param_id {

/// What happened to one sample.
enum class SampleStatus {
  Used,              ///< processed (or held until the nominal sampling period is known)
  SkippedNonFinite,  ///< a NaN or inf field: not used, blocks restart after it
  SkippedDuplicate,  ///< same stamp as the previous sample: not used
  SkippedTooClose,   ///< less than a quarter of the nominal period after the previous sample
  TimeReset,         ///< stamp went backwards: the identifier restarted from scratch with it
  Gap,               ///< processed after a gap longer than max_gap_periods: blocks restarted
  PeriodChanged      ///< the stream's sampling rate changed: statistics restarted at the new rate
};
const char* toString(SampleStatus s);

struct IdentifierCounters {
  std::uint64_t used = 0, skipped_nonfinite = 0, skipped_duplicate = 0, skipped_too_close = 0, time_resets = 0,
                gaps = 0, period_changes = 0;
  /// Step changes of the motor seen by the fitness window (a fault, a demagnetisation), each of
  /// which started the long and the slow window again.
  std::uint64_t motor_changes = 0;
  std::uint64_t skipped() const { return skipped_nonfinite + skipped_duplicate + skipped_too_close; }
};

/// Where the motor was while the window's data were taken (what a saturating machine's estimates
/// stand for: doc/algorithm.md section 11).
struct OperatingPoint {
  double i_d = std::numeric_limits<double>::quiet_NaN();      ///< window mean of i_d [A]
  double i_q = std::numeric_limits<double>::quiet_NaN();      ///< window mean of i_q [A]
  double omega_e = std::numeric_limits<double>::quiet_NaN();  ///< window mean of omega_e [rad/s]
  double i_d_spread = std::numeric_limits<double>::quiet_NaN();  ///< window standard deviation of i_d [A]
  double i_q_spread = std::numeric_limits<double>::quiet_NaN();  ///< window standard deviation of i_q [A]
};

/// The slow estimates of an Estimate.
struct SlowEstimate {
  ParameterVector parameters{};  ///< the slow window's optimum (R_s, psi_f meaningful) [SI]
  std::array<ParameterStatus, kParameterCount> status{};
  std::array<std::string, kParameterCount> reason{};
  std::array<bool, kParameterCount> identifiable{};
  ParameterVector relative_uncertainty{};  ///< stated uncertainty / value [-]
  double window_time_constant = 0.0;       ///< [s]
  double t = std::numeric_limits<double>::quiet_NaN();  ///< stamp of the data the fit ended at [s]
};

struct Estimate {
  std::string method;
  double t = 0.0;                   ///< stamp of the last sample used [s]
  ParameterVector parameters{};     ///< {R_s [ohm], L_d [H], L_q [H], psi_f [Wb]} (NaN before the start)
  std::array<ParameterStatus, kParameterCount> status{};
  std::array<std::string, kParameterCount> reason{};
  std::array<bool, kParameterCount> identifiable{};  ///< status == identified
  ParameterVector relative_uncertainty{};  ///< stated uncertainty / value [-] (inf when unknown)
  /// R_s or psi_f taken from the slow window (identified there and not by the fitness window):
  /// parameters, status and uncertainty are then slow's, the reason names both.
  std::array<bool, kParameterCount> from_slow_window{};
  FitCheck fit;                     ///< the data's own fit and its check
  double inverter_voltage = 0.0;    ///< estimated inverter error voltage [V] (NaN when not modelled)
  ParameterStatus inverter_status = ParameterStatus::NoData;
  std::string inverter_reason;
  double inverter_relative_uncertainty = 0.0;  ///< [-]
  /// The drive model in use when the identifier chose it from the data (nothing declared, doc/
  /// algorithm.md section 8); empty while it is the configured one.
  std::string drive_model;
  /// R_s and psi_f on the thermal time scale (slow_estimate.hpp): the slow window's exact fit,
  /// the same for every method, with its own statuses (L_d, L_q: no_data, the fast path's).
  SlowEstimate slow;
  /// From the slow R_s while it is identified, else from R_s while identified (thermal: block),
  /// else NaN [degC]; the uncertainty includes a learnt reference's.
  Temperature winding_temperature;
  /// From psi_f or the slow psi_f, whichever is identified with the smaller uncertainty [degC].
  Temperature magnet_temperature;
  /// The torque and speed constants drive users ask for, from psi_f (the fast or the slow one,
  /// whichever is identified with the smaller uncertainty; NaN where neither is, or where
  /// motor.pole_pairs is not given). Amplitude-invariant dq (as every estimate here):
  ///   K_t = 1.5 p psi_f [N m/A] per ampere of phase-current amplitude (i_q),
  ///   K_e = sqrt(3) p psi_f [V s/rad]: line-to-line back-EMF amplitude per mechanical rad/s,
  ///   K_v = 60 / (2 pi K_e) [rpm/V]: the speed constant.
  double torque_constant = std::numeric_limits<double>::quiet_NaN();  ///< K_t [N m/A]
  double speed_constant = std::numeric_limits<double>::quiet_NaN();   ///< K_v [rpm/V]
  double motor_constant_relative_uncertainty = std::numeric_limits<double>::quiet_NaN();  ///< psi_f's [-]
  OperatingPoint operating_point;   ///< means over the fitness window (its forgetting time constant)
  double fitness = 0.0;             ///< the method's fitness at the estimate [A^2] (block, or paper: section 10)
  double sample_period = 0.0;       ///< nominal sampling period in use [s] (0 while unknown)
  std::uint64_t iteration = 0;      ///< swarm iterations (0 for ekf, rls)
  double temperature = 0.0;         ///< mean particle temperature (NaN where there is none)
  IdentifierCounters counters;
};

/// Where the methods search: fixed by the config, or centred on the data's optimum.
struct SearchBox {
  bool valid = false;
  ParameterVector lower{}, upper{}, centre{};
};

class OnlineIdentifier {
 public:
  explicit OnlineIdentifier(const IdentifierConfig& config);
  virtual ~OnlineIdentifier() = default;

  /// Feeds one sample. Never throws on bad data: the status says what was done with it.
  SampleStatus process(const Sample& s);
  /// Current estimate with statuses (computes the data's fit: a few microseconds).
  Estimate estimate() const;
  /// Forget all data and start again.
  void reset();

  const IdentifierConfig& config() const { return config_; }
  /// The thermal references a declared cold start learnt (or that were restored); zeros where
  /// none yet. reference_temperature is the config's.
  LearntReferences learntReferences() const;
  /// References kept from an earlier run of the same motor (a restart: io/thermal_state.hpp).
  /// They are taken instead of learning the present, perhaps hot, values as cold; one the config
  /// declares stays declared. Kept through reset(). ConfigError where r was learnt at another
  /// reference temperature than the config's.
  void restoreReferences(const LearntReferences& r);
  const IdentifierCounters& counters() const { return counters_; }
  /// Current parameter vector only (cheaper than estimate()); NaN before the method starts.
  ParameterVector parameters() const { return started() ? current() : nanVector(); }
  const BlockStatistics& statistics() const { return stats_; }
  /// The drive's voltage angle remembered from the settled fitness window that determined it best
  /// (doc/algorithm.md section 8), where it is known and both the drive model's adoption and that
  /// window lie within the long window's time constant; else null.
  const RememberedAngle* rememberedAngle() const;
  const SearchBox& searchBox() const { return box_; }
  double samplePeriod() const { return period_.nominal(); }
  virtual std::string method() const = 0;

 protected:
  /// Method-specific update with a sample that follows the previous one. new_block: the block
  /// statistics completed a block with this sample. continuity_broken: the previous sample is not
  /// a valid predecessor (first sample, gap, or a skipped sample in between). Called only once
  /// the search box exists.
  virtual void update(const Sample& s, bool new_block, bool continuity_broken) = 0;
  virtual ParameterVector current() const = 0;
  /// Start (again) from the search box's centre; called when the box first exists.
  virtual void restart() = 0;
  /// The box moved (data-driven box only): keep the state, follow the new bounds.
  virtual void searchBoxMoved() {}
  virtual std::array<bool, kParameterCount> atBound() const { return {}; }
  virtual std::uint64_t iterations() const { return 0; }
  virtual double temperature() const;
  /// The fitness the method minimises, at p [A^2] (the block fitness unless the method has its own).
  virtual double fitnessAt(const ParameterVector& p) const;
  /// The method searches the window's block fitness as it changes (a swarm), so that its value
  /// trails the window's optimum: it is assessed against the optima of the last moments too.
  virtual bool trailsWindowOptimum() const { return false; }
  bool started() const { return box_.valid; }
  /// Re-fits the window and re-centres a data-driven box whose centre the data's optimum has left
  /// (outside [centre / sqrt(k), centre * sqrt(k)]). Returns true when it moved.
  bool refreshSearchBox();
  /// Where the last refreshSearchBox() found a consistent fit that determines parameter p with its
  /// optimum inside the box's inner part [centre / sqrt(k), centre * sqrt(k)] (false before one).
  bool optimumInside(int p) const { return optimum_inside_[static_cast<std::size_t>(p)]; }
  /// The current noise estimate of the data [A] (0 before it exists).
  double noiseStd() const { return noise_std_; }
  static ParameterVector nanVector();

  IdentifierConfig config_;
  BlockStatistics stats_;
  SearchBox box_;

 private:
  /// Checks the step from the last used sample (too close: skipped; too long: a gap), then uses it.
  SampleStatus admit(const Sample& s, bool check_step, SampleStatus status);
  SampleStatus processTimed(const Sample& s, SampleStatus status);
  bool tryStart();
  /// Takes the exact fit's drive terms (inverter voltage, voltage angle, the hold's and the edges'
  /// inductances, the observer's model) into `stats`' model, whose settings say which it has.
  void adoptExactFitTerms(const FitCheck& fit, BlockStatistics& stats) const;
  void adoptExactFitTerms(const FitCheck& fit) { adoptExactFitTerms(fit, stats_); }
  /// After the switch, where the chosen delay's fit is poor: the other delay's statistics, run
  /// beside the chosen ones until one of the two fits clearly better, and taken where they do.
  void watchOtherDelay(const FitCheck& fit);
  /// Behind the shape's forward observer: nothing identified until the fit has been consistent for
  /// assessment.observer_settling_time_constants window time constants.
  void holdWhileObserverSettles(Estimate& e) const;
  /// How long the fit must hold consistent before it counts as settled (the hold, the remembered
  /// angle): assessment.observer_settling_time_constants window time constants [s].
  double settlingTimeS() const;
  /// How long the exact fit has been consistent without a break (0 where it is not) [s].
  double consistentForS() const;
  /// Within the long window's time constant of the drive model's adoption (of the first sample
  /// with a declared model): where a remembered angle is formed and held (rememberedAngle()).
  bool angleMemoryOpen() const;
  /// Nothing about the drive declared: switches to the real drive's model where the data show one.
  void watchDriveModel();
  /// Once the logged angle's quantum is decided: the flux columns' smoothing (automatic, with one).
  void watchAngleQuantum();
  /// A declared drive model whose inverter width is left to the data: measures it (once).
  void measureDeclaredWidth();
  /// The motor runs with current (|i| above ten times the fit's noise, omega_e T_s above 1e-4).
  bool runningWithCurrent(const FitCheck& fit) const;
  bool widthPending() const {
    return !config_.automatic_drive_model && config_.inverter.estimate_voltage && config_.window.inverter_zero_crossing_current < 0;
  }
  /// Takes w as the drive model (the chosen statistics, or the recent samples replayed into new ones).
  void adoptWindow(const WindowSettings& w, std::optional<BlockStatistics>& chosen);
  /// The inverter error's zero-crossing width that fits the recent samples best (w: the new
  /// drive model; fit: the present window's check, for its start values; inverter_voltage: the
  /// drive-effects fit's V [V], 0 = none) [A]; the switching edges' shape is tried as well where
  /// the angle is logged and V given. `chosen`, where given, receives the recent samples'
  /// statistics of the chosen shape (empty where none fitted).
  /// One drive model's trial on the recent samples (the statistics of `w` replayed into `trial`,
  /// its fit started at `start`, the switching edges sized by start's L_d, L_q and edge_V where `w`
  /// has them): its slow window's residual
  /// ratio (d + q; infinite where V is not positive and determined to 10 %), the chance factor of
  /// a narrower width or another delay, whether its fitness window passes the fit check, its
  /// fitness window's optimum and its slow window's V.
  struct ModelTrial {
    double ratio = std::numeric_limits<double>::infinity();
    double relevance = 1.0;
    bool consistent = false;
    double window_ratio = std::numeric_limits<double>::infinity();  // the fitness window's, d + q
    ParameterVector optimum{};
    double V = 0.0;
  };
  /// `summary`, where given, receives the chosen shape's trial (ratio infinite where none fitted).
  double chooseZeroCrossingCurrent(const WindowSettings& w, const FitCheck& fit, double inverter_voltage,
                                   std::optional<BlockStatistics>* chosen = nullptr,
                                   ModelTrial* summary = nullptr) const;
  ModelTrial replayModel(const WindowSettings& w, const ParameterVector& start, double edge_V,
                         BlockStatistics& trial) const;
  void setBox(const ParameterVector& centre);

  IdentifierCounters counters_;
  SamplePeriodEstimator period_;
  std::vector<Sample> held_;  // samples before the nominal period is known
  double last_t_ = 0.0;
  bool have_last_ = false;
  bool broken_ = true;
  double noise_std_ = 0.0;
  std::uint64_t samples_since_refresh_ = 0;
  ParameterVector watched_optimum_{};
  ParameterVector watched_relative_std_{};  ///< its fit's relative standard deviations (inf: undetermined)
  bool have_watched_ = false;
  std::array<bool, kParameterCount> optimum_inside_{};
  mutable std::uint64_t fit_blocks_ = ~0ull;  // block count of the cached fit
  mutable FitCheck fit_cache_;
  // The thermal references learnt at a declared cold start (zeros until learnt), and those
  // restored from an earlier run (kept through reset()).
  mutable LearntReferences learnt_;
  LearntReferences restored_;
  struct PendingReference {
    double t = -1.0, value = 0.0;  // a candidate reference and when it was seen
  };
  mutable PendingReference pending_R_reference_, pending_psi_reference_;
  /// Refits the slow window (at most every slow_time_constant / 20 of data) with the fitness
  /// window's fresh check.
  void updateSlow(const FitCheck& fast);
  DriveConstants drive_constants_;  // as the slow window determined them best
  SlowFit slow_fit_;
  double slow_fit_t_ = std::numeric_limits<double>::quiet_NaN();
  /// Where a step of the motor last started the slow window again [s] (NaN: never, or forgotten).
  double slow_restarted_t_ = std::numeric_limits<double>::quiet_NaN();
  /// The slow fit, its lag and its history forgotten (a new drive model, a restart of the stream, a
  /// step of the motor at restarted_t; NaN for none).
  void forgetSlowFit(double restarted_t);
  /// The slow window started again less than the fitness window's time constant ago.
  bool slowRestarting() const {
    return std::isfinite(slow_restarted_t_) && last_t_ >= slow_restarted_t_ &&
           last_t_ - slow_restarted_t_ < stats_.forgettingTimeConstant();
  }
  std::deque<std::pair<double, ParameterVector>> slow_history_;  // (t, optimum) of consistent slow fits
  // The optima of the fitness a swarm searches over the last forgetting time constant (t,
  // optimum), every tenth of it: the references a method trailing the window is assessed against,
  // and the test that the optimum held still meanwhile.
  struct RememberedOptimum {
    double t;
    ParameterVector optimum;
  };
  std::deque<RememberedOptimum> recent_optima_;
  double last_remembered_t_ = -std::numeric_limits<double>::infinity();  // [s]
  /// Files the searched fitness's optimum now among the recent ones, dropping those older than the
  /// forgetting time constant.
  void rememberSearchedOptimum();
  /// The searched fitness's optimum now (none before the swarm's sums exist).
  std::optional<ParameterVector> searchedOptimum() const;
  /// It now and those remembered over the last time constant, those of its last half marked as
  /// references (none for a method that does not trail the window, or where this fit is not consistent).
  std::optional<TrailedOptima> trailedOptima(const FitCheck& fit) const;
  ParameterVector slow_lag_{};  // |x(t) - x(t - tau)| / x: the window's lag behind a changing value [-]
  OperatingPoint operating_point_;         // exponentially forgotten means, as the fitness window
  double variance_i_d_ = 0.0, variance_i_q_ = 0.0;  // and the currents' variances (the spreads, when read)
  mutable double largest_operating_current_ = 0.0;  // [A], as the map's cells scale with it
  double first_sample_t_ = std::numeric_limits<double>::quiet_NaN();  // of the run (thermal learning)
  double operating_alpha_ = 0.0, operating_alpha_tau_ = -1.0;  // thermal references learnt at the start
  // The drive model chosen from the data (watchDriveModel): the configured one to go back to.
  WindowSettings declared_window_;
  InverterModelSettings declared_inverter_;
  bool drive_model_switched_ = false, delay_flipped_ = false, angle_logged_ = false;
  std::deque<std::pair<double, bool>> drive_checks_;  // (t, a drive effect named) of the recent checks
  double first_drive_check_t_ = 0.0;  // the first check of the present evidence [s]
  double last_drive_watch_t_ = -std::numeric_limits<double>::infinity();  // [s]
  int quiet_drive_checks_ = 0;  // checks in a row where the paper's model fitted and no drive effect showed
  std::string drive_model_note_;
  // The logged angle's quantum (an encoder's count), decided from the first steps; with one, the
  // flux columns' rotation is smoothed (WindowSettings::angle_smoothing_samples, when automatic).
  AngleQuantum angle_quantum_;
  std::string angle_note_;
  double width_running_since_ = std::numeric_limits<double>::quiet_NaN();  // measureDeclaredWidth [s]
  // While the drive model may still change: the last samples used (and whether the stream broke
  // before each), replayed into the new model's statistics at a change, so that a short log's load
  // steps and speed changes before the change still reach the long window.
  struct RecentSample {
    Sample sample;
    bool continuity_broken = false;
  };
  std::deque<RecentSample> recent_;
  double consistent_since_s_ = std::numeric_limits<double>::quiet_NaN();  ///< the exact fit consistent since [s]
  /// The drive's voltage angle as the best-determined settled fitness window gave it (section 8):
  /// from fits consistent for the settling time, forgotten where the drive model or the motor changes.
  RememberedAngle remembered_angle_;
  bool fit_held_remembered_angle_ = false;  ///< the last refresh's fit held the remembered angle
  double model_since_t_ = std::numeric_limits<double>::quiet_NaN();  ///< the drive model adopted at [s] (NaN: the declared one)
  // The other whole-sample delay's statistics, run beside the chosen model's from the switch while
  // the chosen one's fit is poor (watchOtherDelay), and since when [s].
  std::optional<BlockStatistics> other_delay_;
  double other_delay_since_ = 0.0;
  std::string other_delay_note_;  // the drive model's note without the other delay's
};

/// Samples kept for a drive-model change (2 s at 10 kHz; about 1.4 MB per identifier).
constexpr std::size_t kDriveModelReplaySamples = 20000;
/// Zero-crossing widths tried at a switch to the real drive's model: the currents' RMS down by
/// halves.
constexpr int kZeroCrossingCandidates = 8;
/// The first of them tried: a quarter of the currents' RMS. The two wider ones are tried only where
/// it is taken. (A shape that wide is nearly a line through zero over the drive's currents, a
/// resistance: in 110 switches to the real drive's model, seeds 1-10 of eleven scenarios with an
/// inverter, neither gave a physical error, and their replays were 0.3 of
/// FBDAPSO's cost on industrial_pwm in units of its cost on wc1_drive.)
constexpr int kFirstZeroCrossingCandidate = 2;
/// Widths tried for the switching edges' shape: half the smooth shape's chosen width and one
/// halving below it, the second only where the first fitted better than the smooth shape. (Each
/// candidate replays the recent samples, about 1 us per sample: eight of them doubled FBDAPSO's
/// cost on the 1.2 s industrial_pwm log, against a goal of 5x its cost on wc1_drive. On the
/// real_drive_* logs the data took a half or a quarter of the smooth width, once an eighth, where
/// L_d's chord term, 0.001 z^2, then kept it unidentified.)
constexpr int kEdgeWidthCandidates = 2;
/// A narrower candidate is taken where its slow window's residual is lower than the best wider
/// one's by more than this many times the chance spread of a residual ratio over n blocks,
/// sqrt(2 / n) (one width is as good as another until the data say otherwise).
constexpr double kZeroCrossingSignificance = 3.0;

/// Builds the identifier named by config.method. ConfigError on an unknown method or bad values.
std::unique_ptr<OnlineIdentifier> makeIdentifier(const IdentifierConfig& config);

}  // namespace pmsm_param_id
