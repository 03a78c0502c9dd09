#include "pmsm_param_id/identification/block_statistics.hpp"

#include <cmath>
#include <stdexcept>

namespace pmsm_param_id {

BlockStatistics::BlockStatistics(const WindowSettings& settings) : settings_(settings) {}

void BlockStatistics::reset() {
  block_samples_ = 0;
  nominal_period_ = 0.0;
  ring_.clear();
  head_ = count_ = 0;
  S_d_.setZero();
  S_q_.setZero();
  dS_d_.setZero();
  dS_q_.setZero();
  stored_weight_ = stored_difference_weight_ = 0.0;
  weight_ = difference_weight_ = 0.0;
  scale_ = 1.0;
  blocks_ = 0;
  have_previous_block_ = false;
  long_d_.setZero();
  long_q_.setZero();
  long_weight_ = 0.0;
  have_long_block_ = false;
  blocks_in_stretch_ = 0;
}

void BlockStatistics::configure(double nominal_period) {
  if (!(nominal_period > 0) || !std::isfinite(nominal_period))
    throw std::invalid_argument("BlockStatistics: nominal period must be > 0");
  reset();
  nominal_period_ = nominal_period;
  block_samples_ = std::max(1, static_cast<int>(std::lround(settings_.block_length / nominal_period)));
  lambda_ = std::exp(-nominal_period / settings_.forgetting_time_constant);
  long_lambda_ = std::exp(-block_samples_ * nominal_period / settings_.long_time_constant);
  ring_.resize(static_cast<std::size_t>(block_samples_) + 1);
}

void BlockStatistics::breakContinuity() {
  count_ = 0;
  have_previous_block_ = false;
  have_long_block_ = false;
  blocks_in_stretch_ = 0;
}

namespace {
// Upper triangle of S += alpha z z^T (small fixed sizes: plain loops beat the general routine).
template <int N>
inline void rankOneUpper(Eigen::Matrix<double, N, N>& S, const Eigen::Matrix<double, N, 1>& z, double alpha) {
  for (int j = 0; j < N; ++j) {
    const double azj = alpha * z(j);
    for (int i = 0; i <= j; ++i) S(i, j) += azj * z(i);
  }
}
}  // namespace

bool BlockStatistics::add(const Sample& s) {
  if (block_samples_ == 0) throw std::logic_error("BlockStatistics::add before configure()");
  Cumulative c{};
  c.t = s.t;
  c.i_d = s.i_d;
  c.i_q = s.i_q;
  c.omega_e = s.omega_e;
  c.u_d = s.u_d;
  c.u_q = s.u_q;
  const double magnitude2 = s.i_d * s.i_d + s.i_q * s.i_q;
  const double inverse_magnitude = magnitude2 > 0 ? 1.0 / std::sqrt(magnitude2) : 0.0;
  c.dir_d = s.i_d * inverse_magnitude;
  c.dir_q = s.i_q * inverse_magnitude;
  const std::size_t cap = ring_.size();
  if (count_ > 0) {
    const Cumulative& p = ring_[(head_ + count_ - 1) % cap];
    const bool delayed = settings_.voltage_delay_samples > 0;
    c.applied_d = delayed ? p.u_d : s.u_d;
    c.applied_q = delayed ? p.u_q : s.u_q;
    c.applied_prev_d = p.applied_d;
    c.applied_prev_q = p.applied_q;
    const double dt = s.t - p.t;
    const double h = 0.5 * dt;
    c.I_d = p.I_d + h * (p.i_d + s.i_d);
    c.I_q = p.I_q + h * (p.i_q + s.i_q);
    c.OmIq = p.OmIq + h * (p.omega_e * p.i_q + s.omega_e * s.i_q);
    c.OmId = p.OmId + h * (p.omega_e * p.i_d + s.omega_e * s.i_d);
    c.Om = p.Om + h * (p.omega_e + s.omega_e);
    c.U_d = p.U_d + dt * p.applied_d;  // zero-order hold over [t_j, t_j+1)
    c.U_q = p.U_q + dt * p.applied_q;
    c.Ustep_d = p.Ustep_d + dt * (p.applied_d - p.applied_prev_d);
    c.Ustep_q = p.Ustep_q + dt * (p.applied_q - p.applied_prev_q);
    c.Dir_d = p.Dir_d + h * (p.dir_d + c.dir_d);
    c.Dir_q = p.Dir_q + h * (p.dir_q + c.dir_q);
  } else {
    // First sample of a stretch: with a declared delay the voltage acting now is unknown; the
    // commanded one stands in for the first period only (one period in a block of M).
    c.applied_d = c.applied_prev_d = s.u_d;
    c.applied_q = c.applied_prev_q = s.u_q;
  }
  if (count_ == cap) {  // drop the oldest
    head_ = (head_ + 1) % cap;
    --count_;
  }
  ring_[(head_ + count_) % cap] = c;
  ++count_;
  if (count_ < cap) return false;

  const Cumulative& a = ring_[head_];  // M periods back
  BlockD zd;
  BlockQ zq;
  zd << c.i_d - a.i_d, c.I_d - a.I_d, c.OmIq - a.OmIq, c.U_d - a.U_d, c.Ustep_d - a.Ustep_d, c.Dir_d - a.Dir_d;
  zq << c.i_q - a.i_q, c.I_q - a.I_q, c.OmId - a.OmId, c.U_q - a.U_q, c.Om - a.Om, c.Ustep_q - a.Ustep_q,
      c.Dir_q - a.Dir_q;
  // Forgetting: every stored sum is implicitly multiplied by lambda; new terms enter with scale_.
  scale_ /= lambda_;
  rankOneUpper(S_d_, zd, scale_);
  rankOneUpper(S_q_, zq, scale_);
  stored_weight_ += scale_;
  if (have_previous_block_) {
    const BlockD dd = zd - last_d_;
    const BlockQ dq = zq - last_q_;
    rankOneUpper(dS_d_, dd, scale_);
    rankOneUpper(dS_q_, dq, scale_);
    stored_difference_weight_ += scale_;
  }
  weight_ = stored_weight_ / scale_;
  difference_weight_ = stored_difference_weight_ / scale_;
  last_d_ = zd;
  last_q_ = zq;
  have_previous_block_ = true;
  ++blocks_;
  if (scale_ > 1e150) rescale();
  // Every M-th block of a stretch: consecutive non-overlapping blocks, and the long window keeps
  // their differences. Differencing removes what varies slowly (a drifting R_s or psi_f would
  // otherwise bias a constant-parameter fit over seconds) and keeps the steps.
  if (++blocks_in_stretch_ % static_cast<std::uint64_t>(block_samples_) == 0) {
    if (have_long_block_) {
      const BlockD dd = zd - long_last_d_;
      const BlockQ dq = zq - long_last_q_;
      long_d_ = long_lambda_ * long_d_ + dd * dd.transpose();
      long_q_ = long_lambda_ * long_q_ + dq * dq.transpose();
      long_weight_ = long_lambda_ * long_weight_ + 1.0;
    }
    long_last_d_ = zd;
    long_last_q_ = zq;
    have_long_block_ = true;
  }
  // Keep the running integrals small: rebase on the oldest entry once per block length (exact).
  if (blocks_ % static_cast<std::uint64_t>(cap) == 0) {
    const Cumulative base = ring_[head_];
    for (Cumulative& e : ring_) {
      e.I_d -= base.I_d; e.I_q -= base.I_q; e.OmIq -= base.OmIq; e.OmId -= base.OmId;
      e.U_d -= base.U_d; e.U_q -= base.U_q; e.Om -= base.Om; e.Ustep_d -= base.Ustep_d;
      e.Ustep_q -= base.Ustep_q; e.Dir_d -= base.Dir_d; e.Dir_q -= base.Dir_q;
    }
  }
  return true;
}

void BlockStatistics::rescale() {
  const double k = 1.0 / scale_;
  S_d_ *= k;
  S_q_ *= k;
  dS_d_ *= k;
  dS_q_ *= k;
  stored_weight_ *= k;
  stored_difference_weight_ *= k;
  scale_ = 1.0;
}

WindowSums BlockStatistics::window() const {
  WindowSums w;
  w.mean_d = meanProductD();
  w.mean_q = meanProductQ();
  w.mean_difference_d = meanDifferenceProductD();
  w.mean_difference_q = meanDifferenceProductQ();
  w.weight = weight_;
  w.has_differences = difference_weight_ > 0;
  w.block_duration = blockDuration();
  return w;
}

WindowSums BlockStatistics::longWindow() const {
  WindowSums w;
  if (long_weight_ <= 0) return w;
  w.mean_d = long_d_ / long_weight_;
  w.mean_q = long_q_ / long_weight_;
  w.weight = long_weight_;
  w.block_duration = blockDuration();
  return w;
}

ProductD BlockStatistics::meanProductD() const {
  if (stored_weight_ <= 0) return ProductD::Zero();
  return ProductD(S_d_.selfadjointView<Eigen::Upper>()) / stored_weight_;
}
ProductQ BlockStatistics::meanProductQ() const {
  if (stored_weight_ <= 0) return ProductQ::Zero();
  return ProductQ(S_q_.selfadjointView<Eigen::Upper>()) / stored_weight_;
}
ProductD BlockStatistics::meanDifferenceProductD() const {
  if (stored_difference_weight_ <= 0) return ProductD::Zero();
  return ProductD(dS_d_.selfadjointView<Eigen::Upper>()) / stored_difference_weight_;
}
ProductQ BlockStatistics::meanDifferenceProductQ() const {
  if (stored_difference_weight_ <= 0) return ProductQ::Zero();
  return ProductQ(dS_q_.selfadjointView<Eigen::Upper>()) / stored_difference_weight_;
}

}  // namespace pmsm_param_id
