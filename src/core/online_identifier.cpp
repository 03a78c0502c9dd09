#include "pmsm_param_id/online_identifier.hpp"

#include <Eigen/Cholesky>
#include <cmath>
#include <limits>

namespace pmsm_param_id {

const char* toString(SampleStatus s) {
  switch (s) {
    case SampleStatus::Used: return "used";
    case SampleStatus::SkippedNonFinite: return "skipped: non-finite value";
    case SampleStatus::SkippedDuplicate: return "skipped: duplicate time stamp";
    case SampleStatus::TimeReset: return "time went backwards: identifier reset";
    case SampleStatus::Gap: return "gap in the stream";
  }
  return "?";
}

OnlineIdentifier::OnlineIdentifier(const IdentifierConfig& config) : config_(config), stats_(config.horizon) {
  validate(config_);
}

double OnlineIdentifier::temperature() const { return std::numeric_limits<double>::quiet_NaN(); }

void OnlineIdentifier::reset() {
  stats_.reset();
  have_last_ = false;
  broken_ = true;
  nominal_dt_ = 0.0;
  restart();
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
    } else {
      if (nominal_dt_ == 0.0) nominal_dt_ = dt;
      if (dt > config_.max_gap_periods * nominal_dt_) {
        ++counters_.gaps;
        broken_ = true;
        stats_.breakContinuity();
        status = SampleStatus::Gap;
      }
    }
  }
  const bool new_block = stats_.add(s);
  update(s, new_block, broken_);
  broken_ = false;
  have_last_ = true;
  last_t_ = s.t;
  ++counters_.used;
  return status;
}

Estimate OnlineIdentifier::estimate() const {
  Estimate e;
  e.method = method();
  e.t = last_t_;
  e.parameters = current();
  e.iteration = iterations();
  e.temperature = temperature();
  e.counters = counters_;
  e.identifiable.fill(false);
  e.relative_std.fill(std::numeric_limits<double>::infinity());
  bool physical = true;
  for (double v : e.parameters) physical = physical && std::isfinite(v) && v > 0;
  if (!stats_.hasBlocks() || !physical) {  // no data yet, or an estimate the model cannot evaluate
    e.fitness = std::numeric_limits<double>::quiet_NaN();
    return e;
  }
  e.fitness = stats_.fitness(e.parameters);
  // Cramer-Rao style check on the data alone: covariance ~ sigma_r^2 F^-1 with sigma_r^2 the
  // block-residual variance that the sensor noise causes (2 sigma^2: two noisy end points). It
  // does not depend on how good this method's estimate is, so all methods flag the same data alike.
  const double sigma_r2 = 2.0 * config_.current_noise * config_.current_noise;
  const Eigen::Matrix4d F = stats_.information(e.parameters);
  // Scale to relative units so that the decomposition is well conditioned.
  Eigen::Matrix4d Fs;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) Fs(i, j) = F(i, j) * e.parameters[i] * e.parameters[j];
  Eigen::LDLT<Eigen::Matrix4d> ldlt(Fs);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return e;
  const Eigen::Matrix4d inv = ldlt.solve(Eigen::Matrix4d::Identity());
  for (int i = 0; i < 4; ++i) {
    const double var = sigma_r2 * inv(i, i);
    e.relative_std[i] = var > 0 && std::isfinite(var) ? std::sqrt(var) : std::numeric_limits<double>::infinity();
    e.identifiable[i] = e.relative_std[i] <= config_.max_relative_std;
  }
  return e;
}

}  // namespace pmsm_param_id
