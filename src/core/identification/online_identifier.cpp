#include "pmsm_param_id/identification/online_identifier.hpp"

#include "pmsm_param_id/identification/motor_map.hpp"
#include "pmsm_param_id/io/config_error.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>

namespace pmsm_param_id {

namespace {
// Starting point of the exact fit before the data say anything, and the stand-in for a parameter
// the data do not determine yet: the geometric middle of the supported range of motors
// (20 uH - 200 mH, 0.02 - 20 ohm, 2 mWb - 2 Wb). It only seeds directions the data leave open.
constexpr ParameterVector kGenericCentre{0.63, 2e-3, 2e-3, 0.063};
// A parameter may centre the box once the window determines it to within this (1 sigma).
constexpr double kCentringRelativeStd = 0.3;
// The data's exact fit determines parameter p, to max_relative_std, at a value some PMSM could have.
bool fitDetermines(const FitCheck& fit, int p, double max_relative_std) {
  return fit.determined[p] && fit.relative_std[p] <= max_relative_std && plausible(p, fit.optimum[p]);
}
}  // namespace

const char* toString(SampleStatus s) {
  switch (s) {
    case SampleStatus::Used: return "used";
    case SampleStatus::SkippedNonFinite: return "skipped: non-finite value";
    case SampleStatus::SkippedDuplicate: return "skipped: duplicate time stamp";
    case SampleStatus::SkippedTooClose: return "skipped: less than a quarter of the sampling period after the previous sample";
    case SampleStatus::TimeReset: return "time went backwards: identifier reset";
    case SampleStatus::Gap: return "gap in the stream";
    case SampleStatus::PeriodChanged: return "the sampling period changed: statistics restarted";
  }
  return "?";
}

ParameterVector OnlineIdentifier::nanVector() {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  return {nan, nan, nan, nan};
}

namespace {
WindowSettings windowFor(const IdentifierConfig& c) {
  WindowSettings w = c.window;
  w.inverter_wide_shape = c.inverter.estimate_voltage;  // the extra column only when it is used
  return w;
}
}  // namespace

OnlineIdentifier::OnlineIdentifier(const IdentifierConfig& config)
    : config_(config), stats_(windowFor(config)), period_(config.time.sample_period), declared_window_(config.window),
      declared_inverter_(config.inverter) {
  validate(config_);
}

namespace {
// How long a drive effect's misfit must last before the drive model changes, in forgetting time
// constants of the fitness window: a motor's step change has left the window to e^-6 = 0.25 %.
constexpr double kDriveEffectWindows = 6.0;
// Where neither delay fits at the switch and the two run beside each other, at most this many
// forgetting time constants until one leaves at most kDriveEffectAdvantage of the other's residual.
constexpr double kOtherDelayWindows = 20.0;
// The drive's effects (inverter voltage, voltage angle, delay) must leave at most this
// fraction of the mean square residual that the paper's model, and a cross-saturation inductance,
// leave.
constexpr double kDriveEffectAdvantage = 0.5;
// ... in at least this share of the checks over those time constants.
constexpr double kDriveEffectShare = 0.75;
// After this many quiet checks in a row, the drive's effects are fitted only every so many checks.
constexpr int kQuietDriveChecks = 20, kQuietDriveCheckEvery = 8;
// A drive effect is significant beyond this many standard deviations (the diagnosis's threshold).
constexpr double kDriveEffectSignificance = 5.0;
// Half-width of the centred mean of a quantised logged angle [samples] (watchAngleQuantum).
constexpr int kAngleSmoothingSamples = 8;
}  // namespace

void OnlineIdentifier::watchDriveModel() {
  // Nothing about the drive declared: the paper's model first; where the window's fit improves
  // twofold with the drive's effects added (an inverter error voltage, a voltage
  // angle, a delay), one of them significant or the paper's model failing its fit check, in three
  // quarters of the checks over six fitness windows, with the motor running, and where a
  // cross-saturation inductance explains the misfit less well, the real drive's model: the inverter
  // voltage and its shape, the voltage angle, the stationary hold, the current sensors' offsets and
  // gains where the log has the angle, and the delay the data fit. Once in it, a whole-sample delay
  // the diagnosis names is turned round once. Each change starts the statistics again
  // (doc/algorithm.md section 8).
  if (!config_.automatic_drive_model || config_.magnetics.cross_saturation || !stats_.hasBlocks()) return;
  if (drive_model_switched_ && delay_flipped_) return;
  // Before the switch: the window's plain fit, and one fit with the drive's effects (inverter
  // voltage, voltage angle, delay; without the shape's second width, nearly collinear with V: a
  // third less of the watch's instructions by callgrind) added; evidence where one of them is significant or the
  // plain fit fails, and they leave at most half its residual. After it: the fit's diagnosis, for a
  // whole-sample delay.
  // (The full diagnosis at every check cost FBDAPSO a third more per sample on wc1_drive.)
  const FitCheck fit = checkFit(stats_, config_.assessment, box_.valid ? box_.centre : kGenericCentre,
                                drive_model_switched_, config_.inverter.estimate_voltage, stats_.inverterVoltage(), false);
  if (!fit.available) return;
  if (other_delay_) {
    watchOtherDelay(fit);
    return;
  }
  const MisfitCause kind = fit.likely_cause_kind;
  // A drive effect stays; a change of the motor inside the window (a fault, a demagnetisation)
  // misfits too, and a drive effect may fit part of it, but only until the window has forgotten the
  // change. So the checks of the last kDriveEffectWindows forgetting time constants must show a
  // drive effect in at least kDriveEffectShare of them, this one included.
  // Only while the motor runs with current: at a standstill the noise level of the window falls to
  // zero and whatever it still remembers of the run before misfits without end.
  const bool running = runningWithCurrent(fit);
  const LinearBlockModel drive_effects =
      LinearBlockModel::withDelay(LinearBlockModel::withVoltageAngle(LinearBlockModel::inverter()));
  const int delay_entry = drive_effects.size() - 1, angle_entry = drive_effects.size() - 2;
  BlockFit effects_fit;
  bool evidence = false;
  if (drive_model_switched_) {
    evidence = running && !fit.consistent && kind == MisfitCause::Delay;
  } else if (running && !(fit.consistent && quiet_drive_checks_ >= kQuietDriveChecks &&
                           quiet_drive_checks_ % kQuietDriveCheckEvery != 0)) {
    const WindowSums window = stats_.window();
    Eigen::VectorXd start = Eigen::VectorXd::Zero(drive_effects.size());
    for (int p = 0; p < kParameterCount; ++p) start(p) = fit.optimum[p];
    effects_fit = BlockLeastSquares::fit(window, drive_effects, start, {}, config_.assessment.variance_inflation);
    const auto significant = [&](int j, double relevance) {
      const double b = effects_fit.beta(j), sd = effects_fit.standard_deviation(j);
      return std::isfinite(b) && std::abs(b) > relevance && std::abs(b) > kDriveEffectSignificance * sd;
    };
    // V relevant beyond 1 % of the resistive drop it would hide in R_s (as the diagnosis's test).
    const double Tb = window.block_duration;
    const double current_rms = std::sqrt(window.mean_d(kIntegralId, kIntegralId) + window.mean_q(kIntegralIq, kIntegralIq)) / Tb;
    const bool inverter = effects_fit.ok && effects_fit.beta(4) > 0 &&
                          significant(4, 0.01 * std::abs(effects_fit.beta(kRs)) * current_rms);
    const bool timing = effects_fit.ok && (significant(delay_entry, 0.2) || significant(angle_entry, 0.2));
    // (V's wide share makes V itself undetermined in some windows: where the plain fit fails, its
    // residual halved by the drive's effects is evidence too.)
    evidence = effects_fit.ok && (inverter || timing || !fit.consistent) &&
               effects_fit.fitness() < kDriveEffectAdvantage * fit.optimum_fitness;
    if (evidence) {
      // A saturating machine misfits the paper's model too, and an inverter voltage with a turned,
      // delayed voltage can mimic part of its cross-saturation: the drive's effects must explain
      // the window clearly better (half the mean square residual) than a cross-saturation
      // inductance does.
      Eigen::VectorXd cross_start(6);
      cross_start << fit.optimum[kRs], fit.optimum[kLd], fit.optimum[kLq], fit.optimum[kPsiF], fit.optimum[kLq], 0.0;
      const BlockFit cross_fit = BlockLeastSquares::fit(
          window, LinearBlockModel::crossSaturation(window.crossLinearisationCurrent()), cross_start, {},
          config_.assessment.variance_inflation);
      evidence = !cross_fit.ok || effects_fit.fitness() < kDriveEffectAdvantage * cross_fit.fitness();
    }
  }
  // A drive whose data have fitted the paper's model for kQuietDriveChecks checks in a row is looked
  // at closely only every kQuietDriveCheckEvery-th check while it keeps fitting (on wc1_drive's
  // 0.5 s recording, all before this back-off, the watch's fits were about a seventh of the
  // identifier's instructions by callgrind).
  quiet_drive_checks_ = fit.consistent && !evidence ? quiet_drive_checks_ + 1 : 0;
  const double span = kDriveEffectWindows * stats_.forgettingTimeConstant();
  if (drive_checks_.empty() && !evidence) return;  // nothing to weigh yet
  drive_checks_.emplace_back(last_t_, evidence);
  if (drive_checks_.size() == 1) first_drive_check_t_ = last_t_;
  while (!drive_checks_.empty() && drive_checks_.front().first < last_t_ - span) drive_checks_.pop_front();
  std::size_t named = 0;
  for (const auto& c : drive_checks_) named += c.second ? 1 : 0;
  if (named == 0) {
    drive_checks_.clear();
    return;
  }
  if (!evidence || last_t_ - first_drive_check_t_ < span ||
      static_cast<double>(named) < kDriveEffectShare * static_cast<double>(drive_checks_.size()))
    return;
  drive_checks_.clear();
  WindowSettings w = config_.window;
  const auto delayFrom = [&](int present) {
    return std::clamp(present + static_cast<int>(std::lround(fit.misfit_delay)), 0, 1);
  };
  char buf[240];
  std::optional<BlockStatistics> chosen;  // the chosen width's statistics of the recent samples
  std::optional<BlockStatistics> other_delay;  // the other delay's, where they are to run beside them
  if (!drive_model_switched_) {
    // The delay from the fit with the drive's effects (a log of the applied voltage fits 0, a log of
    // the reference most often 1): 0 only where it lies below half a sample by three standard
    // deviations (a fast low-inductance drive left it between: 0.18 +- 0.13 on robot_joint_realistic,
    // whose delay is 1). That fit's delay is a first-order column beside a model without the
    // stationary hold's ramp or the inverter's shape, and it can miss a whole sample with a small
    // standard deviation (robot_joint_realistic with an exact angle, noise-free: -0.25 +- 0.17):
    // so the other delay is tried in the full model below, and taken where it fits clearly better
    // or where its fitness window passes the fit check and the chosen one's does not.
    int delay = 1;
    const double d = effects_fit.beta(delay_entry), d_std = effects_fit.standard_deviation(delay_entry);
    if (std::isfinite(d) && std::isfinite(d_std) && d + 3.0 * d_std < 0.5) delay = w.voltage_delay_samples;
    w.voltage_delay_samples = delay;
    w.stationary_hold = true;
    w.estimate_voltage_angle = true;
    w.sensor_offsets = w.sensor_gains = angle_logged_;
    w.inverter_wide_shape = true;
    const double V = effects_fit.ok ? effects_fit.beta(4) : 0.0;
    ModelTrial best;
    w.inverter_zero_crossing_current =
        chooseZeroCrossingCurrent(w, fit, std::isfinite(V) && V > 0 ? V : 0.0, &chosen, &best);
    if (chosen) {
      w.inverter_edge_shape = chosen->settings().inverter_edge_shape;
      // The other delay with the chosen shape, replayed once more: taken where its slow window's
      // residual beats the chosen one's by more than chance (as a narrower width must), or where
      // its fitness window passes the fit check and the chosen one's fails it (a wrong delay
      // misfits the 50 ms window clearly: robot_joint_realistic seed 2, d residual 8.6 with delay
      // 0 against 3.3 with 1, while the slow windows, which both misfit, stay within chance), or
      // where the chosen one's fitness window fails the check and the other fits both windows
      // better (robot_joint_realistic seeds 6, 8, 9, 10 with the smoothed angle: slow 9.5 against
      // 11.3, fitness window 8.8 against 11.9, d + q, for seed 6). Where the chosen delay passes,
      // a better fit of the other is not enough: on wc1_realistic seed 5 delay 0 fitted both windows
      // better at the switch (1.54 / 1.89 against 2.38 / 2.06) and misfitted later.
      WindowSettings other = w;
      other.voltage_delay_samples = 1 - w.voltage_delay_samples;
      ParameterVector start = fit.optimum;
      if (w.inverter_edge_shape) {
        start[kLd] = chosen->edgeLd();
        start[kLq] = chosen->edgeLq();
      }
      BlockStatistics trial(other);
      const ModelTrial t = replayModel(other, start, chosen->edgeV(), trial);
      const bool take = t.ratio < best.relevance * best.ratio || (t.consistent && !best.consistent) ||
                        (!best.consistent && t.ratio < best.ratio && t.window_ratio < best.window_ratio);
      const bool settled = take ? t.consistent : best.consistent;
      if (take) {
        w = other;
        std::swap(*chosen, trial);  // the trial's statistics now hold the delay not taken
      }
      // Where neither fits the recent samples at the noise level, each was replayed with the edges'
      // shape taken from the measured currents' chords (the shape's observer starts only from a fit
      // of the new model), and which delay fits shows only once each has followed its own fits for
      // a while (robot_joint_pwm seed 1: at the switch delay 0 read slow 163 / window 91 against
      // 1's 393 / 173; 0.35 s later, each following its own fits, the fitness window 41.6 against
      // 11, and 1 is the drive's). So the delay not taken runs beside the one taken
      // (watchOtherDelay).
      if (!settled) other_delay = std::move(trial);
    }
    config_.inverter.estimate_voltage = true;
    drive_model_switched_ = true;
    std::snprintf(buf, sizeof buf,
                  "real drive, from the data at t = %.4g s: inverter voltage (%szero-crossing width %.3g A), voltage angle, "
                  "stationary hold, delay %d%s",
                  last_t_, w.inverter_edge_shape ? "switching edges, " : "", w.inverter_zero_crossing_current,
                  w.voltage_delay_samples,
                  angle_logged_ ? ", current-sensor offsets and gains" : "");
  } else {
    w.voltage_delay_samples = delayFrom(w.voltage_delay_samples);
    delay_flipped_ = true;
    if (w.voltage_delay_samples == config_.window.voltage_delay_samples) return;
    std::snprintf(buf, sizeof buf, "%s; delay %d from t = %.4g s", drive_model_note_.c_str(), w.voltage_delay_samples,
                  last_t_);
  }
  drive_model_note_ = buf;
  adoptWindow(w, chosen);
  if (other_delay) {
    other_delay_ = std::move(other_delay);
    other_delay_since_ = last_t_;
    other_delay_note_ = drive_model_note_;
    std::snprintf(buf, sizeof buf, "; delay %d runs beside it (%.3g to %.3g s), taken where it fits clearly better",
                  1 - w.voltage_delay_samples, kDriveEffectWindows * stats_.forgettingTimeConstant(),
                  kOtherDelayWindows * stats_.forgettingTimeConstant());
    drive_model_note_ += buf;
  }
}

void OnlineIdentifier::watchOtherDelay(const FitCheck& fit) {
  // The other delay's statistics follow their own fits, as the chosen ones do (adoptExactFitTerms
  // in refreshSearchBox), at the watch's pace. Where the chosen delay's fitness window passes the
  // fit check, they stop. From kDriveEffectWindows forgetting time constants on, the other delay
  // is taken where its fitness window passes the check or leaves at most kDriveEffectAdvantage of
  // the chosen one's residual (d + q); they stop where the chosen one leaves at most that of the
  // other's, or after kOtherDelayWindows. After that decision the delay is not turned round again.
  // (Decided at six time constants whatever the residuals, the drive's delay 0 on robot_joint_pwm's
  // variants left 0.45-0.69 of delay 1's residual there and was taken in 2 of 9 runs; run on until
  // clear, in 9 of 9, 0.35-0.4 s after the switch.)
  BlockStatistics& other = *other_delay_;
  const FitCheck f = checkFit(other, config_.assessment, fit.optimum, false, true, other.inverterVoltage(), false);
  if (f.available) adoptExactFitTerms(f, other);
  if (fit.consistent) {
    other_delay_.reset();
    drive_model_note_ = other_delay_note_;
    return;
  }
  const double tau = stats_.forgettingTimeConstant(), ran = last_t_ - other_delay_since_;
  if (ran < kDriveEffectWindows * tau) return;
  const double chosen_ratio = fit.fit_ratio_d + fit.fit_ratio_q, other_ratio = f.fit_ratio_d + f.fit_ratio_q;
  const bool other_better = f.available && (f.consistent || other_ratio < kDriveEffectAdvantage * chosen_ratio);
  const bool chosen_better = !f.available || chosen_ratio < kDriveEffectAdvantage * other_ratio;
  if (!other_better && !chosen_better && ran < kOtherDelayWindows * tau) return;  // not yet clear either way
  delay_flipped_ = true;
  const int other_delay = 1 - config_.window.voltage_delay_samples;
  char buf[400];
  if (!other_better) {
    std::snprintf(buf, sizeof buf,
                  "%s; delay %d, run beside it from t = %.4g to %.4g s, not taken (it left the fitness window %.3g "
                  "times the noise against %.3g)",
                  other_delay_note_.c_str(), other_delay, other_delay_since_, last_t_, other_ratio, chosen_ratio);
    drive_model_note_ = buf;
    other_delay_.reset();
    return;
  }
  WindowSettings w = config_.window;
  w.voltage_delay_samples = other_delay;
  std::snprintf(buf, sizeof buf,
                "%s; delay %d from t = %.4g s (run beside delay %d from t = %.4g s, it left the fitness window "
                "%.3g times the noise against %.3g)",
                other_delay_note_.c_str(), w.voltage_delay_samples, last_t_, config_.window.voltage_delay_samples,
                other_delay_since_, other_ratio, chosen_ratio);
  drive_model_note_ = buf;
  std::optional<BlockStatistics> taken = std::move(other_delay_);
  adoptWindow(w, taken);
}

void OnlineIdentifier::adoptWindow(const WindowSettings& w, std::optional<BlockStatistics>& chosen) {
  config_.window = w;
  if (chosen) {
    stats_ = std::move(*chosen);
  } else {
    stats_ = BlockStatistics(windowFor(config_));
    stats_.configure(period_.nominal());
    // The recent samples again, through the new model's blocks (about 0.1 us each: 2 ms for 20 000).
    for (const RecentSample& r : recent_) {
      if (r.continuity_broken) stats_.breakContinuity();
      stats_.add(r.sample);
    }
  }
  other_delay_.reset();
  box_ = SearchBox{};
  fit_cache_ = FitCheck{};
  fit_blocks_ = ~0ull;
  broken_ = true;
  have_watched_ = false;
  drive_constants_ = DriveConstants{};  // of the previous model's terms
  remembered_angle_ = RememberedAngle{};
  fit_held_remembered_angle_ = false;
  model_since_t_ = last_t_;
  forgetSlowFit(std::numeric_limits<double>::quiet_NaN());
  recent_optima_.clear();
  last_remembered_t_ = -std::numeric_limits<double>::infinity();
}

bool OnlineIdentifier::runningWithCurrent(const FitCheck& fit) const {
  const OperatingPoint& op = operating_point_;
  return std::hypot(op.i_d, op.i_q) > 10.0 * std::max(fit.noise_std_d, fit.noise_std_q) &&
         std::abs(op.omega_e) * period_.nominal() > 1e-4;
}

void OnlineIdentifier::measureDeclaredWidth() {
  // A declared drive whose inverter's zero-crossing width is left to the data: measured as the
  // automatic model measures it (chooseZeroCrossingCurrent), once the motor has run with current
  // for kDriveEffectWindows forgetting time constants, so that the recent samples hold the window's
  // worth of zero crossings. Why: a declared width is a constant of one inverter; real_drive.yaml's
  // 0.3 A on robot_joint_realistic's 0.5 A (its exact angle) read R_s 2.14 % off along the run,
  // identified, and noise-free R_s -0.8 %, L_q +2.2 % at 0.2 s (doc/results.md).
  if (!stats_.hasBlocks()) return;
  const FitCheck fit = checkFit(stats_, config_.assessment, box_.valid ? box_.centre : kGenericCentre, false, true,
                                stats_.inverterVoltage(), false);
  if (!fit.available) return;
  if (!runningWithCurrent(fit)) {
    width_running_since_ = std::numeric_limits<double>::quiet_NaN();
    return;
  }
  if (std::isnan(width_running_since_)) width_running_since_ = last_t_;
  if (last_t_ - width_running_since_ < kDriveEffectWindows * stats_.forgettingTimeConstant()) return;
  WindowSettings w = windowFor(config_);
  const double V = fit.inverter_modelled && fit.inverter_voltage > 0 ? fit.inverter_voltage : 0.0;
  std::optional<BlockStatistics> chosen;
  w.inverter_zero_crossing_current = chooseZeroCrossingCurrent(w, fit, V, &chosen);
  if (chosen) w.inverter_edge_shape = chosen->settings().inverter_edge_shape;
  char buf[200];
  std::snprintf(buf, sizeof buf, "inverter zero-crossing width %.3g A%s, from the data at t = %.4g s",
                w.inverter_zero_crossing_current, w.inverter_edge_shape ? " (switching edges)" : "", last_t_);
  drive_model_note_ = buf;
  adoptWindow(w, chosen);
  recent_.clear();
}

OnlineIdentifier::ModelTrial OnlineIdentifier::replayModel(const WindowSettings& w, const ParameterVector& start,
                                                           double edge_V, BlockStatistics& trial) const {
  trial.configure(period_.nominal());
  if (w.inverter_edge_shape) trial.setEdgeModel(start[kLd], start[kLq], edge_V);
  for (const RecentSample& r : recent_) {
    if (r.continuity_broken) trial.breakContinuity();
    trial.add(r.sample);
  }
  const FitCheck f = checkFit(trial, config_.assessment, start, false, true, 0.0, false);
  // (Without R_s's rate: the candidates share the winding's heating over the recent samples.)
  DriveConstants scratch;
  const SlowFit slow = slowFit(trial, config_.assessment, f, scratch, last_t_, false);
  ModelTrial t;
  t.consistent = f.available && f.consistent;
  if (f.available) t.window_ratio = f.fit_ratio_d + f.fit_ratio_q;
  // A width far beyond the ripple makes the shape a line through zero, a resistance: its two
  // widths' shares then fit anything, V hundreds of volts either way. Only a physical error
  // counts: V determined to 10 % and positive. (A negative wide share is not unphysical: it
  // sharpens the narrow shape where the error's own width is narrower still.)
  const bool physical = slow.available && slow.inverter_voltage > 0 && slow.inverter_relative_std < 0.1;
  if (physical) t.ratio = slow.fit_ratio_d + slow.fit_ratio_q;
  // The slow window's blocks that count: its effective length, or the recent samples if fewer.
  const double blocks = std::min(static_cast<double>(recent_.size()) / std::max(1, trial.blockSamples()),
                                 2.0 * w.slow_time_constant / std::max(trial.blockDuration(), 1e-12));
  t.relevance = 1.0 - kZeroCrossingSignificance * std::sqrt(2.0 / std::max(blocks, 1.0));
  t.optimum = f.optimum;
  t.V = slow.inverter_voltage;
  return t;
}

double OnlineIdentifier::chooseZeroCrossingCurrent(const WindowSettings& w, const FitCheck& fit, double inverter_voltage,
                                                   std::optional<BlockStatistics>* chosen, ModelTrial* summary) const {
  // The inverter error passes zero over the current ripple at the switching edges (about
  // V_dc T_s / L: 0.1 A on a 36 mH, 540 V, 8 kHz drive, amperes on a 40 uH, 48 V, 20 kHz one), a
  // constant of the drive that no log states. Too wide a shape reads part of the error as a
  // resistance that changes with the current's magnitude (R_s +1 % at 6 A on the 36 mH drive with
  // 0.3 A against 0.1 A). So the width is measured: the recent samples go through the statistics
  // of each candidate, from the currents' RMS down by halves (the fitted shape mixes each width
  // with twice it; the two widest only where a quarter of the RMS is taken), and the one whose
  // slow window the fit leaves the smallest residual is taken, a narrower one only where its
  // residual is lower by more than chance allows (the residual flattens out below the true width,
  // and the shares then trade against each other; a 5 % margin was within chance: one seed of ten
  // took a quarter of the width, and its L_d's zero-crossing term then grew to 20 %).
  // (The error of a width that is too narrow is a few per cent of V; of one too wide, a resistance.)
  double sum2 = 0.0;
  for (const RecentSample& r : recent_) sum2 += r.sample.i_d * r.sample.i_d + r.sample.i_q * r.sample.i_q;
  const double rms = recent_.empty() ? 0.0 : std::sqrt(sum2 / static_cast<double>(recent_.size()));
  if (!(rms > 0) || !std::isfinite(rms)) return kAutomaticZeroCrossingCurrent;
  // The switching edges' shape (inverter_edges.hpp) is tried after the smooth one, with the same
  // rule among its widths, from half the smooth shape's width down by halves (at most
  // kEdgeWidthCandidates): the edges explain the ripple's part of the error's spread at zero, so
  // their width is narrower. It needs the logged angle and a V to size the dead time's ripple.
  struct Best {
    ModelTrial summary;  // its replay's (ratio infinite: none yet)
    double width = 0.0;
    std::optional<BlockStatistics> trial;
  } smooth_best, edge_best;
  const bool edges = angle_logged_ && inverter_voltage > 0 && fit.available && fit.optimum[kLd] > 0 && fit.optimum[kLq] > 0;
  // The smooth ladder starts at kFirstZeroCrossingCandidate; where its widest rung is taken, the
  // ladder is climbed again from the currents' RMS (the rule compares each width with the wider
  // ones, so the whole ladder is replayed).
  int first = kFirstZeroCrossingCandidate;
  for (int trial_index = first; trial_index < kZeroCrossingCandidates + (edges ? kEdgeWidthCandidates : 0); ++trial_index) {
    WindowSettings candidate = w;
    candidate.inverter_edge_shape = trial_index >= kZeroCrossingCandidates;
    // From half the smooth shape's width down, and a narrower one only while the last one fitted
    // better than the smooth shape (each trial replays the recent samples).
    const int edge_index = trial_index - kZeroCrossingCandidates;
    if (candidate.inverter_edge_shape &&
        (!(smooth_best.width > 0) || (edge_index > 0 && !(edge_best.summary.ratio < smooth_best.summary.ratio))))
      break;
    candidate.inverter_zero_crossing_current = candidate.inverter_edge_shape
                                                   ? smooth_best.width * std::ldexp(1.0, -(edge_index + 1))
                                                   : rms * std::ldexp(1.0, -trial_index);
    // The edges' ripple from the best smooth candidate's inductances and V where it has them (its
    // model of the drive is closer than the plain fit's, which misfits the drive's effects).
    const ModelTrial& sb = smooth_best.summary;
    const bool from_smooth = sb.V > 0 && sb.optimum[kLd] > 0 && sb.optimum[kLq] > 0;
    const ParameterVector& start = candidate.inverter_edge_shape && from_smooth ? sb.optimum : fit.optimum;
    BlockStatistics trial(candidate);
    const ModelTrial t = replayModel(candidate, start, from_smooth ? sb.V : inverter_voltage, trial);
    Best& b = candidate.inverter_edge_shape ? edge_best : smooth_best;
    if (t.ratio < t.relevance * b.summary.ratio) {  // a narrower width only where it fits clearly better
      b.summary = t;
      b.width = candidate.inverter_zero_crossing_current;
      if (chosen) b.trial = std::move(trial);  // kept: the new model's statistics without another pass
    }
    if (trial_index == kZeroCrossingCandidates - 1 && first > 0 &&
        smooth_best.summary.ratio < std::numeric_limits<double>::infinity() && smooth_best.width == rms * std::ldexp(1.0, -first)) {
      first = 0;
      trial_index = -1;  // the next pass: the currents' RMS
      smooth_best = Best{};
    }
  }
  // The edges' shape is taken where its slow window's residual is the smaller: the data say which
  // inverter they come from. (Decided against taking it unless clearly worse, as the switching
  // inverter's physics: where the error follows the sampled current's sign, as in the average
  // model, the edges' ripple is wrong physics, and on robot_joint_realistic that rule cost 2 of 10
  // consistent fits and 3 of 8 identified L_q.)
  const bool take_edges = edge_best.summary.ratio < smooth_best.summary.ratio;
  Best& b = take_edges ? edge_best : smooth_best;
  const bool physical = b.summary.ratio < std::numeric_limits<double>::infinity();
  if (summary) *summary = b.summary;
  if (chosen) {
    *chosen = std::move(b.trial);
    if (!physical) chosen->reset();  // the middle: replayed
  }
  // Where no candidate gives a physical error (one operating point: V not determined), the middle
  // of the range.
  return physical ? b.width : rms * std::ldexp(1.0, -kZeroCrossingCandidates / 2);
}

LearntReferences OnlineIdentifier::learntReferences() const {
  LearntReferences r = learnt_;
  r.reference_temperature = config_.thermal.reference_temperature;
  return r;
}

void OnlineIdentifier::restoreReferences(const LearntReferences& r) {
  const ThermalSettings& th = config_.thermal;
  if (!th.enabled) throw ConfigError("a thermal state needs a thermal: block in the identifier config");
  if (!(std::abs(r.reference_temperature - th.reference_temperature) <= 1e-9))
    throw ConfigError("the thermal state was learnt at another reference_temperature than the config's");
  restored_ = r;
  if (th.R_s_at_reference > 0) restored_.R_s = restored_.R_s_relative_uncertainty = 0.0;
  if (th.psi_f_at_reference > 0) restored_.psi_f = restored_.psi_f_relative_uncertainty = 0.0;
  // A parameter not in r is still learnt where the run is early enough; one in r is never learnt
  // again.
  if (restored_.R_s > 0) {
    learnt_.R_s = restored_.R_s;
    learnt_.R_s_relative_uncertainty = restored_.R_s_relative_uncertainty;
    learnt_.R_s_learnt_at = restored_.R_s_learnt_at;
  }
  if (restored_.psi_f > 0) {
    learnt_.psi_f = restored_.psi_f;
    learnt_.psi_f_relative_uncertainty = restored_.psi_f_relative_uncertainty;
    learnt_.psi_f_learnt_at = restored_.psi_f_learnt_at;
  }
}

double OnlineIdentifier::temperature() const { return std::numeric_limits<double>::quiet_NaN(); }

void OnlineIdentifier::reset() {
  // Back to the configured drive model: what the data chose (the real drive's model, a declared
  // drive's inverter width, the angle's smoothing) is chosen again.
  const WindowSettings& d = declared_window_;
  const WindowSettings& w = config_.window;
  if (drive_model_switched_ || w.inverter_zero_crossing_current != d.inverter_zero_crossing_current ||
      w.inverter_edge_shape != d.inverter_edge_shape || w.angle_smoothing_samples != d.angle_smoothing_samples ||
      w.angle_quantum != d.angle_quantum) {
    config_.window = declared_window_;
    config_.inverter = declared_inverter_;
    stats_ = BlockStatistics(windowFor(config_));
  }
  width_running_since_ = std::numeric_limits<double>::quiet_NaN();
  consistent_since_s_ = std::numeric_limits<double>::quiet_NaN();
  remembered_angle_ = RememberedAngle{};
  fit_held_remembered_angle_ = false;
  model_since_t_ = std::numeric_limits<double>::quiet_NaN();
  drive_model_switched_ = false;
  drive_model_note_.clear();
  angle_quantum_.reset();
  angle_note_.clear();
  recent_.clear();
  other_delay_.reset();
  delay_flipped_ = false;
  drive_checks_.clear();
  quiet_drive_checks_ = 0;
  last_drive_watch_t_ = -std::numeric_limits<double>::infinity();
  stats_.reset();
  period_.reset();
  held_.clear();
  box_ = SearchBox{};
  have_last_ = false;
  broken_ = true;
  noise_std_ = 0.0;
  fit_blocks_ = ~0ull;
  learnt_ = restored_;
  drive_constants_ = DriveConstants{};
  forgetSlowFit(std::numeric_limits<double>::quiet_NaN());
  recent_optima_.clear();
  last_remembered_t_ = -std::numeric_limits<double>::infinity();
  pending_R_reference_ = pending_psi_reference_ = PendingReference{};
  operating_point_ = OperatingPoint{};
  largest_operating_current_ = 0.0;
  variance_i_d_ = variance_i_q_ = 0.0;
  first_sample_t_ = std::numeric_limits<double>::quiet_NaN();
  operating_alpha_tau_ = -1.0;
  samples_since_refresh_ = 0;
  have_watched_ = false;
}

void OnlineIdentifier::watchAngleQuantum() {
  const double q = angle_quantum_.quantum();
  if (q > 0) {  // whether the count locks to the sampling: tracked whatever the smoothing (CountLock)
    config_.window.angle_quantum = q;
    stats_.setAngleQuantum(q);
    if (other_delay_) other_delay_->setAngleQuantum(q);
  }
  if (!(q > 0) || declared_window_.angle_smoothing_samples >= 0 || !stats_.configured()) return;
  // 2 m + 1 = 17 samples cut the quantisation error at a block's ends about fourfold; at most a
  // fifth of the block keeps the mean local to its end (doc/algorithm.md section 8).
  const int m = std::min(kAngleSmoothingSamples, stats_.blockSamples() / 5);
  if (m < 1) return;
  config_.window.angle_smoothing_samples = m;
  stats_.setAngleSmoothing(m);
  if (other_delay_) other_delay_->setAngleSmoothing(m);
  char buf[160];
  std::snprintf(buf, sizeof buf, "angle quantised to %.3g mrad (an encoder): the flux's rotation from its mean over %d samples",
                1e3 * q, 2 * m + 1);
  angle_note_ = buf;
}

SampleStatus OnlineIdentifier::process(const Sample& s) {
  if (!(std::isfinite(s.t) && std::isfinite(s.u_d) && std::isfinite(s.u_q) && std::isfinite(s.i_d) &&
        std::isfinite(s.i_q) && std::isfinite(s.omega_e))) {
    ++counters_.skipped_nonfinite;
    broken_ = true;
    stats_.breakContinuity();
    return SampleStatus::SkippedNonFinite;
  }
  SampleStatus status = SampleStatus::Used;
  if (have_last_) {
    const double dt = s.t - last_t_;
    if (dt == 0.0) {
      ++counters_.skipped_duplicate;
      return SampleStatus::SkippedDuplicate;
    }
    if (dt < 0.0) {
      const IdentifierCounters kept = counters_;
      reset();
      counters_ = kept;
      ++counters_.time_resets;
      status = SampleStatus::TimeReset;
    } else if (period_.addStep(dt)) {
      if (!held_.empty()) {  // the first nominal period: process the samples held so far
        stats_.configure(period_.nominal());
        std::vector<Sample> held;
        held.swap(held_);
        for (std::size_t k = 0; k < held.size(); ++k) admit(held[k], k > 0, SampleStatus::Used);
      } else {  // the rate changed: blocks of the new length from here on
        ++counters_.period_changes;
        recent_.clear();  // blocks of the old length
        other_delay_.reset();
        stats_.configure(period_.nominal());
        broken_ = true;
        status = SampleStatus::PeriodChanged;
      }
    }
  }
  if (!period_.known()) {  // hold the sample until the steps give the nominal period
    held_.push_back(s);
    have_last_ = true;
    last_t_ = s.t;
    return status;
  }
  if (!stats_.configured()) stats_.configure(period_.nominal());
  return admit(s, have_last_ && status == SampleStatus::Used, status);
}

SampleStatus OnlineIdentifier::admit(const Sample& s, bool check_step, SampleStatus status) {
  if (check_step) {  // the step from the last used sample, against the nominal period
    const double dt = s.t - last_t_;
    if (dt < 0.25 * period_.nominal()) {
      ++counters_.skipped_too_close;
      return SampleStatus::SkippedTooClose;  // last_t_ stays: the next step is measured from the last used sample
    }
    if (dt > config_.time.max_gap_periods * period_.nominal()) {
      ++counters_.gaps;
      broken_ = true;
      stats_.breakContinuity();
      status = SampleStatus::Gap;
    }
  }
  have_last_ = true;
  last_t_ = s.t;
  return processTimed(s, status);
}

SampleStatus OnlineIdentifier::processTimed(const Sample& s, SampleStatus status) {
  if (std::isnan(first_sample_t_)) first_sample_t_ = s.t;
  angle_logged_ = std::isfinite(s.theta_e);
  if (angle_quantum_.add(s.theta_e)) watchAngleQuantum();
  const bool new_block = stats_.add(s);
  if (other_delay_) {
    if (broken_) other_delay_->breakContinuity();
    other_delay_->add(s);
  }
  if ((config_.automatic_drive_model && !(drive_model_switched_ && delay_flipped_)) || widthPending()) {
    recent_.push_back({s, broken_});
    if (recent_.size() > kDriveModelReplaySamples) recent_.pop_front();
  } else if (!recent_.empty()) {
    recent_.clear();
  }
  // The operating point: means forgotten with the fitness window's time constant.
  const double tau = stats_.forgettingTimeConstant();
  if (tau != operating_alpha_tau_ && tau > 0) {
    operating_alpha_ = 1.0 - std::exp(-period_.nominal() / tau);
    operating_alpha_tau_ = tau;
  }
  OperatingPoint& op = operating_point_;
  if (std::isnan(op.i_d)) {
    op = {s.i_d, s.i_q, s.omega_e};
  } else {  // exponentially weighted mean and variance (West's update; the spreads in estimate())
    const double a = operating_alpha_, dd = s.i_d - op.i_d, dq = s.i_q - op.i_q;
    op.i_d += a * dd;
    op.i_q += a * dq;
    op.omega_e += a * (s.omega_e - op.omega_e);
    variance_i_d_ = (1.0 - a) * (variance_i_d_ + a * dd * dd);
    variance_i_q_ = (1.0 - a) * (variance_i_q_ + a * dq * dq);
  }
  if (!box_.valid && new_block) tryStart();
  if (box_.valid) update(s, new_block, broken_);
  broken_ = false;
  ++counters_.used;
  // Every ten swarm cycles' worth of samples: the box, the noise level, the inverter voltage and a
  // watch for sudden changes of the motor (an exact fit, ~5 us, amortised over 500 samples).
  if (box_.valid && ++samples_since_refresh_ >= static_cast<std::uint64_t>(10 * config_.swarm.reset_iterations)) {
    samples_since_refresh_ = 0;
    refreshSearchBox();
  } else if (box_.valid && trailsWindowOptimum() &&
             !(last_t_ - last_remembered_t_ < 0.1 * stats_.forgettingTimeConstant() && last_t_ >= last_remembered_t_)) {
    rememberSearchedOptimum();
  }
  // The drive model, where nothing about the drive was declared: watched at the same pace (before
  // the box exists too: a real drive's data may never give the paper's model a scale).
  // Every 500 samples, and at most every half forgetting time constant (at 1 MHz, every 25 000).
  // (A declared drive's width left to the data is measured at the same pace.)
  const bool watch_due = new_block && !(last_t_ - last_drive_watch_t_ < 0.5 * stats_.forgettingTimeConstant()) &&
                         stats_.blocks() % static_cast<std::uint64_t>(10 * config_.swarm.reset_iterations) == 0;
  if (watch_due && (config_.automatic_drive_model || widthPending())) {
    last_drive_watch_t_ = last_t_;
    if (config_.automatic_drive_model) watchDriveModel();
    else measureDeclaredWidth();
  }
  // A declared cold start: the thermal references are learnt from the data (see estimate()), whether or not
  // anybody asks for an estimate then (checked once per block length until both are learnt).
  const ThermalSettings& th = config_.thermal;
  const bool learning = th.enabled && s.t - first_sample_t_ <= th.learning_time &&
                        ((th.R_s_at_reference == 0.0 && learnt_.R_s == 0.0) ||
                         (th.psi_f_at_reference == 0.0 && learnt_.psi_f == 0.0));
  if (learning && new_block && box_.valid && stats_.blocks() % static_cast<std::uint64_t>(stats_.blockSamples()) == 0)
    estimate();
  return status;
}

void OnlineIdentifier::setBox(const ParameterVector& centre) {
  const double k = config_.search.span_factor;
  box_.centre = centre;
  for (int p = 0; p < kParameterCount; ++p) {
    box_.lower[p] = centre[p] / k;
    box_.upper[p] = centre[p] * k;
  }
  box_.valid = true;
}

bool OnlineIdentifier::tryStart() {
  const SearchSettings& search = config_.search;
  if (search.fixed_bounds) {
    box_.lower = search.lower;
    box_.upper = search.upper;
    for (int p = 0; p < kParameterCount; ++p)
      box_.centre[p] = search.has_initial ? search.initial[p] : std::sqrt(search.lower[p] * search.upper[p]);
    box_.valid = true;
  } else if (search.has_initial) {
    setBox(search.initial);
  } else {
    const FitCheck fit = checkFit(stats_, config_.assessment, kGenericCentre, false, config_.inverter.estimate_voltage, 0.0,
                                  config_.magnetics.cross_saturation);
    if (!fit.available) return false;
    const auto usable = [&](int p) {
      return fitDetermines(fit, p, kCentringRelativeStd);
    };
    if (!usable(kLd) && !usable(kLq)) return false;  // the motor's scale is not known yet
    ParameterVector centre = kGenericCentre;
    for (int p = 0; p < kParameterCount; ++p)
      if (usable(p)) centre[p] = fit.optimum[p];
    if (!usable(kLd)) centre[kLd] = centre[kLq];
    if (!usable(kLq)) centre[kLq] = centre[kLd];
    noise_std_ = std::max(fit.noise_std_d, fit.noise_std_q);
    adoptExactFitTerms(fit);
    setBox(centre);
  }
  restart();
  return true;
}

void OnlineIdentifier::adoptExactFitTerms(const FitCheck& fit, BlockStatistics& stats) const {
  const WindowSettings& window = stats.settings();
  // A saturating machine's L_qq and L_dq (the swarm's fitness takes them as known).
  if (fit.cross_saturation_modelled && std::isfinite(fit.L_qq) && fit.L_qq > 0 && std::isfinite(fit.L_dq))
    stats.setCrossSaturation(fit.L_dq, fit.L_qq);
  // The stationary hold's bending of the currents needs the inductances: the data's, once determined.
  if (window.stationary_hold && fit.available && fitDetermines(fit, kLd, 0.1) && fitDetermines(fit, kLq, 0.1))
    stats.setHoldInductances(fit.optimum[kLd], fit.optimum[kLq]);
  // The drive's voltage angle, likewise taken as known by the swarm's fitness (a direction the
  // window leaves open keeps the fit's value on its ridge: the parameters along it are then not
  // identified, whichever value the fitness takes).
  if (fit.voltage_angle_modelled)
    stats.setVoltageAngle(std::isfinite(fit.voltage_angle) && std::abs(fit.voltage_angle) < 4.0 ? fit.voltage_angle : 0.0);
  // The swarm's fitness (and RLS, EKF) take the data's estimate of the inverter voltage as known:
  // the paper's swarm searches four dimensions; V is profiled out by the exact fit.
  if (!fit.inverter_modelled) return;
  const double V = fit.inverter_voltage;
  const bool usable = std::isfinite(V) && V > 0 && fit.inverter_relative_std < 0.3 &&
                      std::isfinite(fit.inverter_wide_share) && std::isfinite(fit.inverter_bus_share);
  stats.setInverterVoltage(usable ? V : 0.0, usable ? fit.inverter_wide_share : 0.0,
                           usable ? fit.inverter_bus_share : 0.0);
  // The inverter shape's current observer runs the data's model: once all four are determined to
  // 1 % by a fit that is consistent. A fit that is not drops it, and the shape takes the measured
  // currents again: an observer run with a wrong model feeds the fit wrong shapes, and the fit
  // would never become consistent again to correct it (with a 10 % limit that locked 11 of 30
  // robot-joint swarm runs into a poor fit).
  // (Determined with the drive's timing at its estimate: along the ridge where L_q and the voltage
  // angle trade, every point predicts the same currents, which is all the observer needs.)
  bool all = usable && fit.consistent;
  for (int p = 0; p < kParameterCount; ++p)
    all = all && fit.determined[p] && fit.relative_std_known_timing[p] <= 0.01 && plausible(p, fit.optimum[p]);
  // The switching edges' ripple needs the inductances and V: the data's, once determined to 10 %.
  if (window.inverter_edge_shape && usable && fitDetermines(fit, kLd, 0.1) && fitDetermines(fit, kLq, 0.1))
    stats.setEdgeModel(fit.optimum[kLd], fit.optimum[kLq], V);
  // With the switching edges replayed from the logged bus voltage the observer follows each period
  // forward through the edges (BlockStatistics::observePeriodForward), and the fit is poor until it
  // runs (robot_joint_pwm with its delay declared: 56 / 92 times the noise without it, 1.57 / 1.33
  // with it): there it runs with every fit whose four values are plausible, consistent or not.
  // (Measured against other rules on the switching-level drive's monitoring runs, FBDAPSO and RLS,
  // 10 seeds, doc/algorithm.md section 8: keeping the last consistent fit's model through
  // inconsistent ones found the inter-turn fault in 4 and 1 of 10 seeds instead of 10 and 10;
  // keeping it until a fit determines all four to 1 %, which R_s behind the inverter seldom is, put
  // fewer psi_f estimates outside their stated uncertainty on the duty cycle but left psi_f 0.2 %
  // high for seconds after a 4 % demagnetisation.)
  const bool forward = stats.observerFollowsForward();
  if (all) {
    stats.setShapeObserverModel(fit.optimum);
  } else if (forward) {
    bool take = usable && fit.available;
    for (int p = 0; p < kParameterCount; ++p) take = take && plausible(p, fit.optimum[p]);
    if (take) stats.setShapeObserverModel(fit.optimum);
  } else if (!fit.consistent) {
    stats.setShapeObserverModel({});
  }
}

bool OnlineIdentifier::refreshSearchBox() {
  optimum_inside_.fill(false);
  if (!box_.valid || config_.search.fixed_bounds || !stats_.hasBlocks()) return false;
  const FitCheck fit = checkFit(stats_, config_.assessment, box_.centre, false, config_.inverter.estimate_voltage,
                                stats_.inverterVoltage(), config_.magnetics.cross_saturation, rememberedAngle());
  if (!fit.available) return false;
  noise_std_ = std::max(fit.noise_std_d, fit.noise_std_q);
  // Where the fit starts or stops holding the remembered angle, the swarm's fitness takes another
  // angle (adoptExactFitTerms): the optima remembered under the other one were of another fitness
  // and are no reference for a method that trails them.
  if (fit.voltage_angle_remembered != fit_held_remembered_angle_) recent_optima_.clear();
  fit_held_remembered_angle_ = fit.voltage_angle_remembered;
  adoptExactFitTerms(fit);
  updateSlow(fit);
  // A sudden change of the motor (a step of R_s, L_d, L_q or psi_f: a fault, a demagnetisation)
  // would read, in the long check window of differenced blocks, as a unit error for its whole
  // memory. When the model fits the window again and an optimum has moved by more than 2 % and 5
  // standard deviations of the change (both fits' own, in quadrature) from the last one that
  // fitted, the long window starts again. (The change's, not the new fit's alone: behind an
  // inverter a load step determines R_s to 0.4 % where the window before it, at one current
  // magnitude, left it at 6-7 %, and on a healthy drive R_s moved between them by 5-29 %: each
  // such restart cleared the slow window's history, and with it the winding temperature, doc/
  // algorithm.md section 9.) (With a wrong unit the fit never settles, so the evidence of the unit
  // is kept.)
  if (fit.consistent && have_watched_) {
    for (int p = 0; p < kParameterCount; ++p) {
      if (!(fit.determined[p] && std::isfinite(fit.relative_std[p]))) continue;
      const double change = std::abs(fit.optimum[p] / watched_optimum_[p] - 1.0);
      if (change > 0.02 && change > 5.0 * std::hypot(fit.relative_std[p], watched_relative_std_[p])) {
        stats_.resetLongWindow();  // and the slow window
        ++counters_.motor_changes;
        forgetSlowFit(last_t_);  // its last fit is of blocks across the step
        recent_optima_.clear();
        // And the remembered angle: the angle a window fits absorbs a share of what the model
        // misses, which a changed motor changes (doc/algorithm.md section 8).
        remembered_angle_ = RememberedAngle{};
        break;
      }
    }
  }
  if (fit.consistent) {
    watched_optimum_ = fit.optimum;
    for (int p = 0; p < kParameterCount; ++p)
      watched_relative_std_[p] = fit.determined[p] ? fit.relative_std[p] : std::numeric_limits<double>::infinity();
    have_watched_ = true;
    if (!std::isfinite(consistent_since_s_)) consistent_since_s_ = last_t_;
  } else {
    consistent_since_s_ = std::numeric_limits<double>::quiet_NaN();
  }
  // The drive's voltage angle, remembered from the fit that determines it best once the fit has held
  // consistent for the settling time (the hold behind the observer's: a fit that has just become
  // consistent may still move with the observer's model); only while it can be used.
  if (angleMemoryOpen() && fit.consistent && fit.voltage_angle_modelled && consistentForS() >= settlingTimeS() &&
      std::isfinite(fit.own_voltage_angle) && fit.own_voltage_angle_std < remembered_angle_.standard_deviation) {
    remembered_angle_.angle = fit.own_voltage_angle;
    remembered_angle_.standard_deviation = fit.own_voltage_angle_std;
    remembered_angle_.t = last_t_;
  }
  const double inner = std::sqrt(config_.search.span_factor);
  ParameterVector centre = box_.centre;
  bool moved = false;
  for (int p = 0; p < kParameterCount; ++p) {
    const double x = fit.optimum[p];
    if (!fitDetermines(fit, p, kCentringRelativeStd)) continue;
    if (x < centre[p] / inner || x > centre[p] * inner) {
      centre[p] = x;
      moved = true;
    }
  }
  for (int p = 0; p < kParameterCount; ++p) {
    const double x = fit.optimum[p];
    optimum_inside_[static_cast<std::size_t>(p)] =
        fit.consistent && fitDetermines(fit, p, kCentringRelativeStd) && x >= centre[p] / inner && x <= centre[p] * inner;
  }
  if (!moved) return false;
  setBox(centre);
  searchBoxMoved();
  return true;
}

std::optional<ParameterVector> OnlineIdentifier::searchedOptimum() const {
  // The exact optimum of the fitness the swarm searches: the paper's model on its sums, a
  // Gauss-Newton fit of four parameters warm-started from the last one; a parameter the window
  // leaves undetermined is NaN.
  const WindowSums window = stats_.searchedWindow();
  if (!window.hasBlocks()) return std::nullopt;
  const ParameterVector& previous = recent_optima_.empty() ? box_.centre : recent_optima_.back().optimum;
  Eigen::VectorXd start(kParameterCount);
  for (int p = 0; p < kParameterCount; ++p) start(p) = std::isfinite(previous[p]) ? previous[p] : box_.centre[p];
  const BlockFit f = BlockLeastSquares::fit(window, LinearBlockModel::paper(), start, {}, config_.assessment.variance_inflation);
  if (!f.ok) return std::nullopt;
  ParameterVector optimum;
  for (int p = 0; p < kParameterCount; ++p)
    optimum[p] = f.determined[static_cast<std::size_t>(p)] ? f.beta(p) : std::numeric_limits<double>::quiet_NaN();
  return optimum;
}

void OnlineIdentifier::rememberSearchedOptimum() {
  // Every tenth of the window's time constant, from the data alone (whether or not estimates are
  // asked for).
  last_remembered_t_ = last_t_;
  const std::optional<ParameterVector> optimum = searchedOptimum();
  if (!optimum) return;
  const double horizon = stats_.forgettingTimeConstant();
  while (!recent_optima_.empty() && (recent_optima_.front().t < last_t_ - horizon || recent_optima_.front().t > last_t_))
    recent_optima_.pop_front();
  recent_optima_.push_back({last_t_, *optimum});
}

std::optional<TrailedOptima> OnlineIdentifier::trailedOptima(const FitCheck& fit) const {
  if (!fit.consistent || !trailsWindowOptimum() || !box_.valid) return std::nullopt;
  const std::optional<ParameterVector> now = searchedOptimum();
  if (!now) return std::nullopt;
  TrailedOptima out;
  out.now = *now;
  const double tau = stats_.forgettingTimeConstant();
  for (const RememberedOptimum& r : recent_optima_)
    if (r.t < last_t_ && last_t_ - r.t <= tau)
      out.earlier.push_back({last_t_ - r.t, 1.0 - std::exp(-(last_t_ - r.t) / tau), last_t_ - r.t <= 0.5 * tau, r.optimum});
  return out;
}

void OnlineIdentifier::forgetSlowFit(double restarted_t) {
  slow_fit_ = SlowFit{};
  slow_fit_t_ = std::numeric_limits<double>::quiet_NaN();
  slow_lag_.fill(std::numeric_limits<double>::infinity());
  slow_history_.clear();
  slow_restarted_t_ = restarted_t;
}

void OnlineIdentifier::updateSlow(const FitCheck& fast) {
  // Started again after a step of the motor, the window's first blocks do not yet hold the new
  // motor's operating point (fitted, R_s -7e23 ohm at a residual of 0 / 1634 times the noise): it
  // is fitted once it holds one time constant of the fitness window's data.
  if (slowRestarting()) return;
  const double tau = stats_.slowTimeConstant();
  if (std::isfinite(slow_fit_t_) && last_t_ >= slow_fit_t_ && last_t_ - slow_fit_t_ < tau / 20) return;
  slow_fit_ = slowFit(stats_, config_.assessment, fast, drive_constants_, last_t_);
  slow_fit_t_ = last_t_;
  slow_lag_.fill(std::numeric_limits<double>::infinity());
  if (!(slow_fit_.available && slow_fit_.consistent)) return;
  // The window's exponential average trails a value that changes at a steady rate by tau x the
  // rate (an exponentially weighted fit of a ramp reads the ramp's value tau ago). The rate is the
  // slope of a straight line through the window's own estimates over the last two tau; until the
  // history spans 1.75 tau the lag is unknown (and nothing slow is identified). (The largest move
  // within two tau would count the estimates' own noise again, three times over, on top of the
  // statistical part; a step is caught in estimate(), against the fitness window.)
  while (!slow_history_.empty() && slow_history_.front().first < last_t_ - 2.0 * tau) slow_history_.pop_front();
  if (!slow_history_.empty() && slow_history_.front().first <= last_t_ - 1.75 * tau) {
    std::vector<std::pair<double, ParameterVector>> points(slow_history_.begin(), slow_history_.end());
    points.emplace_back(last_t_, slow_fit_.optimum);
    double t_mean = 0.0;
    for (const auto& h : points) t_mean += h.first;
    t_mean /= static_cast<double>(points.size());
    double stt = 0.0;
    for (const auto& h : points) stt += (h.first - t_mean) * (h.first - t_mean);
    for (int p = 0; p < kParameterCount; ++p) {
      double x_mean = 0.0, stx = 0.0;
      for (const auto& h : points) x_mean += h.second[p];
      x_mean /= static_cast<double>(points.size());
      for (const auto& h : points) stx += (h.first - t_mean) * (h.second[p] - x_mean);
      const double slope = stt > 0 ? stx / stt : 0.0;  // [unit/s]
      slow_lag_[p] = tau * std::abs(slope) / std::abs(slow_fit_.optimum[p]);
    }
  }
  slow_history_.emplace_back(last_t_, slow_fit_.optimum);
}

Estimate OnlineIdentifier::estimate() const {
  Estimate e;
  e.method = method();
  e.t = last_t_;
  e.parameters = parameters();
  e.iteration = iterations();
  e.temperature = temperature();
  e.counters = counters_;
  e.sample_period = period_.nominal();
  // The data's optimum is refitted at every call (warm-started: a few microseconds), so that a
  // method's distance to it is current; the model tests (nested fits, the long window: tens of
  // microseconds) are redone once per block length of new data, not at every call: a node
  // publishing every millisecond would otherwise spend a fifth of a core on them.
  const ParameterVector start = box_.valid ? box_.centre : kGenericCentre;
  const std::uint64_t stale_after = static_cast<std::uint64_t>(std::max(1, stats_.blockSamples()));
  const bool retest = fit_blocks_ == ~0ull || stats_.blocks() < fit_blocks_ ||
                      stats_.blocks() - fit_blocks_ >= stale_after || !fit_cache_.available;
  const bool inverter = config_.inverter.estimate_voltage;
  // Warm-started only from a plausible previous fit: a degenerate one (a window of a few blocks that
  // the sensor terms explain almost entirely read 2e7 V) would otherwise seed every later fit, and
  // directions the data leave open keep their start values.
  bool warm = fit_cache_.available;
  for (int p = 0; p < kParameterCount && warm; ++p) warm = plausible(p, fit_cache_.optimum[p]);
  const double cached_v = fit_cache_.inverter_voltage;
  const double v_start = warm && fit_cache_.inverter_modelled && std::isfinite(cached_v) && std::abs(cached_v) < 1e3 ? cached_v : 0.0;
  const bool cross = config_.magnetics.cross_saturation;
  FitCheck fit = checkFit(stats_, config_.assessment, warm ? fit_cache_.optimum : start, retest, inverter, v_start, cross,
                          rememberedAngle());
  if (!fit.available && fit_cache_.available)
    fit = checkFit(stats_, config_.assessment, start, retest, inverter, 0.0, cross, rememberedAngle());
  if (retest) {
    fit_blocks_ = stats_.blocks();
    fit_cache_ = fit;
  } else {  // keep the cached model tests, take the fresh optimum
    fit.consistent = fit.consistent && fit_cache_.consistent;
    fit.likely_cause = fit_cache_.likely_cause;
    fit.likely_cause_kind = fit_cache_.likely_cause_kind;
    fit.misfit_delay = fit_cache_.misfit_delay;
    fit.speed_unit_verified = fit_cache_.speed_unit_verified;
    fit.speed_scale_short = fit_cache_.speed_scale_short;
    fit.speed_scale_long = fit_cache_.speed_scale_long;
    const bool tested_consistent = fit_cache_.consistent;
    fit_cache_ = fit;
    fit_cache_.consistent = tested_consistent;
  }
  // A sampling period no drive uses: the time column's unit is the likely cause (1 kHz - 1 MHz is
  // the supported range; a control loop slower than 500 Hz cannot run a current loop).
  const double T = period_.nominal();
  if (T > 2e-3 || (T > 0 && T < 1e-7)) {
    char buf[200];
    std::snprintf(buf, sizeof buf, "the sampling period is %.3g s, outside any drive's control period (1e-6 to 1e-3 s): "
                  "%s", T, T > 2e-3 ? (T < 2.0 ? "is time in ms?" : "is time in us?") : "is time in a unit other than s?");
    fit.consistent = false;
    fit.likely_cause = buf;
    fit.likely_cause_kind = MisfitCause::Unit;
  }
  // The other whole-sample delay runs beside the one taken at the switch only while that one's fit
  // is poor (watchOtherDelay): its misfit is first the undecided delay. A whole or fractional delay
  // that explains it is that delay, not a decimated log or a declaration to change (robot_joint_pwm
  // up to 0.6 s, the drive's delay 1 beside the chosen 0: a fractional delay of half a sample fits
  // best); any other cause is named after it.
  if (other_delay_ && !fit.consistent) {
    char buf[240];
    std::snprintf(buf, sizeof buf,
                  "the drive's delay is not decided yet: delay %d, taken at the switch, misfits and delay %d runs beside "
                  "it from t = %.4g s until one of the two fits clearly better",
                  config_.window.voltage_delay_samples, 1 - config_.window.voltage_delay_samples, other_delay_since_);
    const bool a_delay =
        fit.likely_cause_kind == MisfitCause::Delay || fit.likely_cause_kind == MisfitCause::FractionalDelay;
    fit.likely_cause = a_delay || fit.likely_cause.empty() ? std::string(buf) : std::string(buf) + "; " + fit.likely_cause;
    if (a_delay || fit.likely_cause_kind == MisfitCause::None) fit.likely_cause_kind = MisfitCause::Delay;
  }
  const std::optional<TrailedOptima> trailed = trailedOptima(fit);
  e.fit = fit;
  e.drive_model = drive_model_note_.empty() || angle_note_.empty() ? drive_model_note_ + angle_note_
                                                                    : drive_model_note_ + "; " + angle_note_;
  const Assessment a = assess(e.parameters, e.fit, atBound(), config_.assessment, trailed ? &*trailed : nullptr);
  const InverterAssessment inv = assessInverter(e.fit, config_.assessment, config_.inverter.max_relative_uncertainty);
  e.inverter_voltage = e.fit.inverter_modelled ? e.fit.inverter_voltage : std::numeric_limits<double>::quiet_NaN();
  e.inverter_status = inv.status;
  e.inverter_reason = inv.reason;
  e.inverter_relative_uncertainty = inv.relative_uncertainty;
  e.status = a.status;
  e.reason = a.reason;
  e.relative_uncertainty = a.relative_uncertainty;
  holdWhileObserverSettles(e);
  // On a saturating machine the estimates stand for one operating point (section 11). A window
  // whose q current moved across more than a cell of the map (a load change) fits the extended
  // model's lines in i_q through several points, which is no point's L_d, L_q or psi_f.
  OperatingPoint op = operating_point_;
  if (std::isfinite(op.i_q)) {
    op.i_d_spread = std::sqrt(variance_i_d_);
    op.i_q_spread = std::sqrt(variance_i_q_);
    largest_operating_current_ = std::max(largest_operating_current_, std::hypot(op.i_d, op.i_q));
  }
  if (fit.cross_saturation_modelled) {
    // L_d, the slope across the injection, is the most sensitive to a load change still in the
    // window: under a speed loop (saturated_speed_control.yaml, 30 seeds) identified values reached
    // 2.9 % off with half a cell, 2.1 % with a quarter, 1.4 % with an eighth (doc/algorithm.md
    // section 11); so it waits for half the spread the others wait for.
    const bool steady = windowWithinOneCell(op, largest_operating_current_, config_.map, fit.noise_std_q);
    const bool settled = windowWithinOneCell(op, largest_operating_current_, config_.map, fit.noise_std_q, 0.125);
    for (int p : {kLd, kLq, kPsiF}) {
      if (e.status[p] != ParameterStatus::Identified || (p == kLd ? settled : steady)) continue;
      e.status[p] = ParameterStatus::NotExcited;
      char buf[200];
      std::snprintf(buf, sizeof buf,
                    "the window spans a load change (i_q %.3g A, spread %.2g A): on a saturating machine this "
                    "stands for no single operating point", op.i_q, op.i_q_spread);
      e.reason[p] = buf;
    }
  }
  const char* const width_pending =
      "the inverter error's zero-crossing width is measured from the data first (inverter.zero_crossing_current: "
      "auto), once the motor has run with current for 6 forgetting time constants";
  if (widthPending())
    for (int p = 0; p < kParameterCount; ++p) {
      if (e.status[p] != ParameterStatus::Identified) continue;
      e.status[p] = ParameterStatus::NotExcited;
      e.reason[p] = width_pending;
    }
  for (int p = 0; p < kParameterCount; ++p) e.identifiable[p] = e.status[p] == ParameterStatus::Identified;
  {
    // The lag as of this estimate: while the fitness window does not fit one set of parameters,
    // something is changing faster than the slow window follows (a step of the motor, a
    // transient), and its lag is unknown; where the fitness window determines a parameter and
    // lies further from the slow value than its own uncertainty, the excess is lag too (a step
    // is followed by the fitness window within a few of its time constants, by the slow window
    // only over its own).
    ParameterVector lag = slow_lag_;
    if (slow_fit_.rate_modelled) lag[kRs] = 0.0;  // the fit states R_s at its newest snapshot, with its rate
    if (e.fit.available && !e.fit.consistent) lag.fill(std::numeric_limits<double>::infinity());
    if (e.fit.available && e.fit.consistent && slow_fit_.available)
      for (int p = 0; p < kParameterCount; ++p) {
        if (!e.fit.determined[p] || !std::isfinite(e.fit.relative_std[p]) || !std::isfinite(lag[p])) continue;
        const double apart = std::abs(slow_fit_.optimum[p] - e.fit.optimum[p]) / std::abs(slow_fit_.optimum[p]);
        lag[p] = std::max(lag[p], apart - config_.assessment.confidence_sigmas * e.fit.relative_std[p]);
      }
    const SlowAssessment slow = assessSlow(slow_fit_, config_.assessment, lag);
    e.slow.parameters = slow_fit_.optimum;
    e.slow.status = slow.status;
    e.slow.reason = slow.reason;
    e.slow.relative_uncertainty = slow.relative_uncertainty;
    // A cause the fitness window's diagnosis names (a unit, the drive's timing, a decimated log)
    // holds for the slow window's data too, whose own check may not see it.
    if (!e.fit.consistent && e.fit.likely_cause_kind != MisfitCause::None)
      for (int p : {kRs, kPsiF}) {
        e.slow.status[p] = ParameterStatus::PoorFit;
        e.slow.reason[p] = "the fitness window's diagnosis of its misfit holds here too: " + e.fit.likely_cause;
      }
    if (widthPending())
      for (int p : {kRs, kPsiF})
        if (e.slow.status[p] == ParameterStatus::Identified) {
          e.slow.status[p] = ParameterStatus::NotExcited;
          e.slow.reason[p] = width_pending;
        }
    if (slowRestarting()) {
      char why[200];
      std::snprintf(why, sizeof why,
                    "the slow window started again at t = %.4g s after a step of the motor; it is fitted once it holds "
                    "the fitness window's time constant (%.3g s) of the new motor's data",
                    slow_restarted_t_, stats_.forgettingTimeConstant());
      for (int p : {kRs, kPsiF}) {
        e.slow.status[p] = ParameterStatus::NoData;
        e.slow.reason[p] = why;
      }
    }
    for (int p = 0; p < kParameterCount; ++p) e.slow.identifiable[p] = e.slow.status[p] == ParameterStatus::Identified;
    e.slow.window_time_constant = stats_.slowTimeConstant();
    e.slow.t = slow_fit_t_;
    // R_s and psi_f are thermal quantities: where the fitness window does not identify one and the
    // slow window does, the estimate is the slow window's (the data's exact optimum over its
    // seconds, the same for every method), and the reason says so. Behind an inverter R_s needs
    // current magnitudes apart, which a fitness window of 50 ms rarely holds and a slow one of
    // seconds does (doc/algorithm.md section 9).
    for (int p : {kRs, kPsiF}) {
      if (e.identifiable[p] || !e.slow.identifiable[p]) continue;
      char buf[160];
      std::snprintf(buf, sizeof buf, "+-%.3g %%, from the slow window (%.3g s); the fitness window's: ",
                    100 * e.slow.relative_uncertainty[p], e.slow.window_time_constant);
      e.reason[p] = buf + std::string(toString(e.status[p])) + (e.reason[p].empty() ? "" : ", " + e.reason[p]);
      e.parameters[p] = e.slow.parameters[p];
      e.relative_uncertainty[p] = e.slow.relative_uncertainty[p];
      e.status[p] = ParameterStatus::Identified;
      e.identifiable[p] = true;
      e.from_slow_window[p] = true;
    }
  }
  const ThermalSettings& th = config_.thermal;
  if (th.enabled) {
    // References: configured, or learnt at a declared cold start at reference_temperature: the
    // data's exact optimum (the same for every method) the first time the data determine the
    // parameter to the identification threshold with a consistent fit, within learning_time of the
    // first sample. A method that identifies late would otherwise take a hot motor's value.
    const bool early = e.t - first_sample_t_ <= th.learning_time;
    // The value a reference is learnt from: the slow estimate where its fit holds and it states
    // the parameter to half the temperature budget (max_uncertainty), else the fitness window's
    // optimum where it determines the parameter to the identification threshold.
    // Within learning_time the motor is declared at reference_temperature: nothing thermal changes
    // yet, so the slow window's lag is taken as none (its own estimates span no 1.75 tau so early).
    // So is R_s's rate: where the slow fit carries it (behind an inverter), the early value is the
    // slow window's fit without it (the rate's freedom would otherwise take the start-up's current
    // magnitudes, which separate R_s from the inverter's error voltage: the first 5 s of the
    // switching-level duty cycle then learnt no reference, and gave no winding temperature).
    SlowAssessment cold;
    SlowFit cold_fit;
    if (early) {
      if (slow_fit_.rate_modelled) {
        DriveConstants constants = drive_constants_;  // a scratch copy: this fit teaches the drive nothing
        cold_fit = slowFit(stats_, config_.assessment, e.fit, constants, last_t_, false);
      } else {
        cold_fit = slow_fit_;
      }
      cold = assessSlow(cold_fit, config_.assessment, ParameterVector{});
    }
    const auto learnable = [&](int p, double coefficient, double& value, double& uncertainty) {
      if (!early) return false;
      const ParameterStatus slow_status = cold.status[p];
      if ((slow_status == ParameterStatus::Identified || slow_status == ParameterStatus::NotExcited) &&
          e.slow.status[p] != ParameterStatus::PoorFit &&
          cold.relative_uncertainty[p] <= 0.5 * th.max_uncertainty * std::abs(coefficient)) {
        value = cold_fit.optimum[p];
        uncertainty = cold.relative_uncertainty[p];
        return true;
      }
      if (!(e.fit.available && e.fit.consistent && e.fit.determined[p] && plausible(p, e.fit.optimum[p]))) return false;
      value = e.fit.optimum[p];
      uncertainty = std::max(config_.assessment.confidence_sigmas * e.fit.relative_std[p], config_.assessment.min_relative_uncertainty);
      return uncertainty <= config_.assessment.max_relative_uncertainty;
    };
    // A value is taken once a second one, at least confirm_time later, agrees with it within the
    // identification threshold (a start-up transient can make a short window's optimum look
    // determined and yet be off: measured 15 % on R_s in a live run).
    const double confirm_time = 0.1;  // [s]
    const auto learn = [&](int p, double coefficient, double configured, double& learned, double& learned_uncertainty,
                           double& learned_t, PendingReference& pending) {
      double value = 0.0, uncertainty = 0.0;
      if (configured != 0.0 || learned != 0.0 || !learnable(p, coefficient, value, uncertainty)) return;
      if (pending.t < 0 || std::abs(value / pending.value - 1.0) > std::max(uncertainty, config_.assessment.max_relative_uncertainty)) {
        pending = {e.t, value};  // (re)start: the first candidate, or one that moved
      } else if (e.t - pending.t >= confirm_time) {
        learned = value;
        learned_uncertainty = uncertainty;
        learned_t = e.t;
      }
    };
    learn(kRs, th.copper_coefficient, th.R_s_at_reference, learnt_.R_s, learnt_.R_s_relative_uncertainty,
          learnt_.R_s_learnt_at, pending_R_reference_);
    learn(kPsiF, th.magnet_coefficient, th.psi_f_at_reference, learnt_.psi_f, learnt_.psi_f_relative_uncertainty,
          learnt_.psi_f_learnt_at, pending_psi_reference_);
    const double R_ref = th.R_s_at_reference > 0 ? th.R_s_at_reference : learnt_.R_s;
    const double psi_ref = th.psi_f_at_reference > 0 ? th.psi_f_at_reference : learnt_.psi_f;
    const double R_ref_u = th.R_s_at_reference > 0 ? 0.0 : learnt_.R_s_relative_uncertainty;
    const double psi_ref_u = th.psi_f_at_reference > 0 ? 0.0 : learnt_.psi_f_relative_uncertainty;
    // Each temperature from the estimate with the smaller stated uncertainty: the fast one where
    // it is identified, the slow one where its fit holds (identified, or determined short of the
    // 1 % a motor parameter needs: a winding temperature to a few kelvin is worth reporting);
    // reported where its uncertainty is at most max_uncertainty.
    const auto temperatureOf = [&](int p, double reference, double reference_u, double coefficient) {
      const ParameterStatus slow_status = e.slow.status[p];
      const bool slow_ok = (slow_status == ParameterStatus::Identified || slow_status == ParameterStatus::NotExcited) &&
                           std::isfinite(e.slow.relative_uncertainty[p]);
      const bool fast_ok = e.identifiable[p];
      Temperature out;
      if (!slow_ok && !fast_ok) return out;
      const bool slow_better = slow_ok && (!fast_ok || e.slow.relative_uncertainty[p] <= e.relative_uncertainty[p]);
      out = temperatureFrom(slow_better ? e.slow.parameters[p] : e.parameters[p],
                            slow_better ? e.slow.relative_uncertainty[p] : e.relative_uncertainty[p], reference,
                            th.reference_temperature, coefficient, reference_u);
      if (!(out.uncertainty <= th.max_uncertainty)) out = Temperature{};
      return out;
    };
    e.winding_temperature = temperatureOf(kRs, R_ref, R_ref_u, th.copper_coefficient);
    e.magnet_temperature = temperatureOf(kPsiF, psi_ref, psi_ref_u, th.magnet_coefficient);
  }
  {  // K_t and K_v from the psi_f identified with the smaller uncertainty
    const bool fast_ok = e.identifiable[kPsiF], slow_ok = e.slow.identifiable[kPsiF];
    if (config_.pole_pairs > 0 && (fast_ok || slow_ok)) {
      const bool slow_better = slow_ok && (!fast_ok || e.slow.relative_uncertainty[kPsiF] < e.relative_uncertainty[kPsiF]);
      const double psi = slow_better ? e.slow.parameters[kPsiF] : e.parameters[kPsiF];
      const double p = static_cast<double>(config_.pole_pairs);
      e.torque_constant = 1.5 * p * psi;
      e.speed_constant = 60.0 / (2.0 * M_PI * std::sqrt(3.0) * p * psi);
      e.motor_constant_relative_uncertainty = slow_better ? e.slow.relative_uncertainty[kPsiF] : e.relative_uncertainty[kPsiF];
    }
  }
  bool positive = true;
  for (double v : e.parameters) positive = positive && std::isfinite(v) && v > 0;
  e.fitness = positive ? fitnessAt(e.parameters) : std::numeric_limits<double>::quiet_NaN();
  e.operating_point = op;
  return e;
}

const RememberedAngle* OnlineIdentifier::rememberedAngle() const {
  // It stands in for the long window while that still holds the blocks of the drive model's start
  // (built with the observer's earlier models, which do not fit): within the long window's time
  // constant of the model's adoption, and of the window that gave it. Later the long window speaks
  // for itself, and over minutes the terms whose misses the angle absorbs a share of (the winding's
  // resistance, the magnets' flux, the inverter's error voltage) move with the temperatures.
  // (Measured along the four-minute switching-level duty cycle, FBDAPSO's L_q identified more than
  // 2 % off: held without limit in 47 of 172 733 estimates, worst 3.68 %; for 10 s after the window
  // that gave it, in 1-5 of about 52 000, worst 3.10 %.)
  if (!remembered_angle_.known() || !angleMemoryOpen() ||
      !(last_t_ - remembered_angle_.t <= stats_.settings().long_time_constant))
    return nullptr;
  return &remembered_angle_;
}

bool OnlineIdentifier::angleMemoryOpen() const {
  const double since = std::isfinite(model_since_t_) ? model_since_t_ : first_sample_t_;
  return last_t_ - since <= stats_.settings().long_time_constant;
}

double OnlineIdentifier::settlingTimeS() const {
  return config_.assessment.observer_settling_time_constants * stats_.forgettingTimeConstant();
}

double OnlineIdentifier::consistentForS() const {
  return std::isfinite(consistent_since_s_) ? std::max(0.0, last_t_ - consistent_since_s_) : 0.0;
}

void OnlineIdentifier::holdWhileObserverSettles(Estimate& e) const {
  // The shape's observer runs each fit's model forward through the switching edges, and the fit is
  // poor until it runs (adoptExactFitTerms); so the window holds blocks the observer built with
  // earlier models, which did not fit. Once the fit is consistent those blocks fade with the
  // window's forgetting, and the fit and the observer's model still move towards each other
  // meanwhile (a robot joint at 1.0 us of dead time: L_d 2.1 % high at the first consistent fit,
  // falling 0.2-0.4 % per 25 ms refresh). Until the fit has been consistent for the set number of
  // window time constants nothing is identified (doc/algorithm.md section 8).
  // (With bounds given the refreshes, which adopt each fit's model and watch its consistency, do not
  // run: no loop, and nothing to hold for.)
  const double need_s = settlingTimeS();
  if (!(need_s > 0) || config_.search.fixed_bounds ||
      !(stats_.observerFollowsForward() && stats_.shapeObserverActive()))
    return;
  const double held_s = consistentForS();
  if (held_s >= need_s) return;
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "the fit has been consistent for %.3g ms of the %.3g ms (%.3g window time constants) it must hold: "
                "the window still holds blocks the current observer built with earlier models that did not fit, "
                "and the fit and the observer's model may still be settling; more data settles it",
                1e3 * held_s, 1e3 * need_s, config_.assessment.observer_settling_time_constants);
  for (int p = 0; p < kParameterCount; ++p)
    if (e.status[static_cast<std::size_t>(p)] == ParameterStatus::Identified) {
      e.status[static_cast<std::size_t>(p)] = ParameterStatus::NotConverged;
      e.reason[static_cast<std::size_t>(p)] = buf;
    }
}

double OnlineIdentifier::fitnessAt(const ParameterVector& p) const {
  if (!stats_.hasBlocks()) return std::numeric_limits<double>::quiet_NaN();
  return stats_.crossSaturationSet() ? stats_.fitnessWithCrossSaturation(p) : stats_.fitness(p);
}

}  // namespace pmsm_param_id
