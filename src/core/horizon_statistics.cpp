#include "pmsm_param_id/horizon_statistics.hpp"

#include <cmath>
#include <limits>

namespace pmsm_param_id {

HorizonStatistics::HorizonStatistics(const HorizonSettings& settings) : settings_(settings) {}

void HorizonStatistics::reset() {
  horizon_samples_ = 0;
  ring_.clear();
  head_ = count_ = 0;
  S_d_.setZero();
  S_q_.setZero();
  weight_ = 0.0;
  blocks_ = 0;
}

void HorizonStatistics::breakContinuity() { count_ = 0; }

bool HorizonStatistics::add(const Sample& s) {
  Cumulative c{s.t, s.i_d, s.i_q, s.omega_e, s.u_d, s.u_q, 0, 0, 0, 0, 0, 0, 0};
  if (count_ > 0) {
    const Cumulative p = ring_[(head_ + count_ - 1) % ring_.size()];  // a copy: the ring may be replaced below
    const double dt = s.t - p.t;
    if (horizon_samples_ == 0) {  // the first period seen fixes M and the ring size
      horizon_samples_ = std::max(1, static_cast<int>(std::lround(settings_.horizon / dt)));
      std::vector<Cumulative> ring(static_cast<std::size_t>(horizon_samples_) + 1);
      ring[0] = p;
      ring_.swap(ring);
      head_ = 0;
    }
    const double h = 0.5 * dt;
    c.I_d = p.I_d + h * (p.i_d + s.i_d);
    c.I_q = p.I_q + h * (p.i_q + s.i_q);
    c.W_d = p.W_d + h * (p.omega_e * p.i_q + s.omega_e * s.i_q);
    c.W_q = p.W_q + h * (p.omega_e * p.i_d + s.omega_e * s.i_d);
    c.Om = p.Om + h * (p.omega_e + s.omega_e);
    c.U_d = p.U_d + dt * p.u_d;  // zero-order hold: u(t_j) applies on [t_j, t_j+1)
    c.U_q = p.U_q + dt * p.u_q;
  }
  if (ring_.empty()) ring_.resize(2);
  const std::size_t cap = ring_.size();
  if (count_ == cap) {  // drop the oldest
    head_ = (head_ + 1) % cap;
    --count_;
  }
  ring_[(head_ + count_) % cap] = c;
  ++count_;
  if (horizon_samples_ == 0 || count_ < cap) return false;

  const Cumulative& a = ring_[head_];  // M periods back
  last_d_ << c.i_d - a.i_d, c.I_d - a.I_d, c.W_d - a.W_d, c.U_d - a.U_d;
  last_q_ << c.i_q - a.i_q, c.I_q - a.I_q, c.W_q - a.W_q, c.U_q - a.U_q, c.Om - a.Om;
  const double dt = c.t - ring_[(head_ + count_ - 2) % cap].t;
  if (dt != lambda_dt_) {  // the sampling period rarely changes: one exp() per change, not per sample
    lambda_dt_ = dt;
    lambda_ = std::exp(-dt / settings_.time_constant);
  }
  const double lambda = lambda_;
  S_d_ *= lambda;
  S_q_ *= lambda;
  S_d_.selfadjointView<Eigen::Upper>().rankUpdate(last_d_);
  S_q_.selfadjointView<Eigen::Upper>().rankUpdate(last_q_);
  weight_ = lambda * weight_ + 1.0;
  ++blocks_;
  // Keep the running integrals small: rebase on the oldest entry once per horizon (exact).
  if (blocks_ % static_cast<std::uint64_t>(cap) == 0) {
    const Cumulative base = ring_[head_];
    for (Cumulative& e : ring_) {
      e.I_d -= base.I_d; e.I_q -= base.I_q; e.W_d -= base.W_d; e.W_q -= base.W_q;
      e.U_d -= base.U_d; e.U_q -= base.U_q; e.Om -= base.Om;
    }
  }
  return true;
}

Eigen::Matrix4d HorizonStatistics::information(const ParameterVector& p) const {
  // Near the optimum, r_d = e_d / L_d with e_d linear in the parameters:
  //   grad e_d = {I_d, Di_d, -W_d, 0},   grad e_q = {I_q, W_q, Di_q, Om}.
  const Eigen::Matrix4d Sd = S_d_.selfadjointView<Eigen::Upper>();
  const Eigen::Matrix<double, 5, 5> Sq = S_q_.selfadjointView<Eigen::Upper>();
  Eigen::Matrix4d Pd = Eigen::Matrix4d::Zero();  // grad = Pd * z_d
  Pd(kRs, 1) = 1.0;
  Pd(kLd, 0) = 1.0;
  Pd(kLq, 2) = -1.0;
  Eigen::Matrix<double, 4, 5> Pq = Eigen::Matrix<double, 4, 5>::Zero();
  Pq(kRs, 1) = 1.0;
  Pq(kLd, 2) = 1.0;
  Pq(kLq, 0) = 1.0;
  Pq(kPsiF, 4) = 1.0;
  return Pd * Sd * Pd.transpose() / (p[kLd] * p[kLd]) + Pq * Sq * Pq.transpose() / (p[kLq] * p[kLq]);
}

}  // namespace pmsm_param_id
