// Identification from averaged telemetry: a log sampled far slower than the current loop (a VESC's
// 50-1000 Hz stream, a 2 Hz data set). Averaged over an interval much longer than L/R, the dq
// equations lose their derivative terms and become algebraic (doc/algorithm.md section 12):
//
//   u_d = R_s i_d - omega_e L_q i_q + V s_d(i) + k omega_e u_q
//   u_q = R_s i_q + omega_e L_d i_d + omega_e psi_f + V s_q(i) - k omega_e u_d
//
// with V s(i) the inverter's average error voltage along the current (the fundamental of each
// phase's smoothed sign, its zero-crossing width chosen from the data) and k the drive's
// unrecorded voltage timing (the applied vector turned by k omega_e against the logged one: an
// angle prediction or delay of the PWM, k = c T_pwm [s]). The fit is linear in
// (R_s, L_d, L_q, psi_f, V, k); which of them the data determine follows from their information,
// as in the fast path: psi_f and L_q from how u varies with omega_e and i_q, R_s apart from V only
// across current magnitudes, L_d only where i_d varies, L_q apart from k only across load or
// speed changes.
#pragma once
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "pmsm_param_id/identification/online_identifier.hpp"
#include "pmsm_param_id/model/sample.hpp"

namespace pmsm_param_id {

/// A log whose sampling period exceeds this is telemetry (no drive runs its current loop slower
/// than 500 Hz): the steady-state fit applies, the methods that follow the current loop do not [s].
constexpr double kTelemetryPeriod = 2e-3;

/// A sample is left out as a transient where its currents or speed step from a neighbour by more
/// than this many robust standard deviations of the log's own sample-to-sample changes [-].
constexpr double kTransientSigmas = 6.0;

struct SteadyStateFit {
  Estimate estimate;                  ///< method "steady_state"; statuses and reasons as the fast path's
  std::size_t samples = 0;            ///< finite samples in the log
  std::size_t steady = 0;             ///< samples used (no step to either neighbour)
  std::size_t transients = 0;         ///< samples left out as transients
  double sample_period = 0.0;         ///< median spacing of the samples [s]
  double zero_crossing_current = 0.0; ///< the inverter shape's width the data chose [A]
  double voltage_timing = std::numeric_limits<double>::quiet_NaN();      ///< k [s]
  double voltage_timing_std = std::numeric_limits<double>::infinity();   ///< its standard deviation [s]
  double noise_std_d = 0.0, noise_std_q = 0.0;  ///< voltage-equation noise from the data [V]
  std::string note;                   ///< one line where the data give too little for a fit
  /// The thermal trajectory (with a thermal: block): R_s and psi_f over time, psi_f pinned at the
  /// load and speed changes (doc/algorithm.md section 13). Its temperatures are the estimate's.
  std::size_t thermal_changes = 0;    ///< load or speed changes that pin psi_f
  double thermal_knot_spacing = 0.0;  ///< R_s's knots, chosen by BIC [s] (0: no trajectory)
  LearntReferences thermal_references;  ///< R_s and psi_f at the first steady sample (0: not determined)
  std::string thermal_note;           ///< why no temperature is reported, where none is
  /// The constant fit failed and the thermal trajectory fits: the estimate is the trajectory's at
  /// the last sample (R_s and psi_f there; doc/algorithm.md section 13).
  bool from_trajectory = false;
};

/// The steady-state fit of a whole log (samples in time order; non-finite ones are counted and
/// left out, a gap or a time going back starts a new stretch for the transient test).
/// config: its assessment settings (the tolerance, the fit-ratio limit) and the inverter's.
/// references: R_s and psi_f at the thermal reference temperature from an earlier part of the
/// stream (TelemetryIdentifier, once the cold start's samples are let go), in place of those of
/// the first sample.
SteadyStateFit fitSteadyState(const std::vector<Sample>& samples, const IdentifierConfig& config,
                              const LearntReferences* references = nullptr);

/// The median of the positive, finite spacings of the samples' stamps; 0 where there are none [s].
double medianSpacing(const std::vector<Sample>& samples);

/// The steady-state fit of a stream (the identifier node's telemetry path): the samples since the
/// start, or since the stamps last went back, are kept (the newest max_samples of them), and the fit
/// is redone when estimate() is asked for after new samples. Over the same samples it is exactly
/// fitSteadyState, so a stream and the log it came from give the same estimate.
class TelemetryIdentifier {
 public:
  /// At most this many samples are kept by default (11 min of a 50 Hz stream): a motor heating
  /// over longer leaves no one set of parameters for the whole window, and the fit's cost grows
  /// with it (about 40 us per sample: 1.3 s for these; measured on 240 000 samples, 10.6 s).
  static constexpr std::size_t kDefaultMaxSamples = std::size_t{1} << 15;

  /// config: as fitSteadyState's; max_samples >= 2 * the fit's columns (throws ConfigError).
  explicit TelemetryIdentifier(IdentifierConfig config, std::size_t max_samples = kDefaultMaxSamples);

  /// Keeps the sample. TimeReset where its stamp is before the previous one's (the samples kept
  /// so far are let go: a looping bag, a restarted drive), SkippedNonFinite for a NaN or inf field
  /// (kept and counted by the fit, as the log's reading does), Used otherwise.
  SampleStatus process(const Sample& s);
  /// The fit of the samples kept (redone only where samples came since the last one).
  const SteadyStateFit& fit();
  const Estimate& estimate() { return fit().estimate; }
  /// The last fit done, without fitting again (for a status display between fits).
  const SteadyStateFit& lastFit() const { return fit_; }
  std::size_t size() const { return samples_.size(); }
  /// Samples let go as the oldest beyond max_samples since the start.
  std::uint64_t forgotten() const { return forgotten_; }
  std::uint64_t timeResets() const { return time_resets_; }
  /// Lets every sample go (a reset).
  void reset();

 private:
  IdentifierConfig config_;
  std::size_t max_samples_;
  std::vector<Sample> samples_;
  SteadyStateFit fit_;
  LearntReferences references_;  // of the cold start, kept once its samples are let go
  bool start_kept_ = true;       // the first sample since the start (or a time reset) is still kept
  bool stale_ = true;
  std::uint64_t forgotten_ = 0, time_resets_ = 0;
};

/// The dq image's magnitude of the fundamental of tanh(i_phase / width) for a current vector of
/// magnitude `current` (4/pi for a sharp sign, current / width near zero) [-].
double inverterFundamental(double current, double width);

}  // namespace pmsm_param_id
