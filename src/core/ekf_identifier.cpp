#include <Eigen/LU>
#include <cmath>

#include "pmsm_param_id/identifiers.hpp"

namespace pmsm_param_id {

EkfIdentifier::EkfIdentifier(const IdentifierConfig& config) : OnlineIdentifier(config) { restart(); }

void EkfIdentifier::restart() {
  x_.setZero();
  for (int p = 0; p < kParameterCount; ++p) x_(2 + p) = config_.initial[p];
  P_.setZero();
  P_(0, 0) = P_(1, 1) = 1.0;
  for (int p = 0; p < kParameterCount; ++p) {
    const double s = config_.ekf.initial_relative_std * config_.initial[p];
    P_(2 + p, 2 + p) = s * s;
  }
  have_previous_ = false;
}

void EkfIdentifier::update(const Sample& s, bool, bool continuity_broken) {
  if (continuity_broken || !have_previous_) {  // (re)start the current states from the measurement
    x_(0) = s.i_d;
    x_(1) = s.i_q;
    P_.topLeftCorner<2, 2>().setIdentity();
    P_.topLeftCorner<2, 2>() *= config_.ekf.measurement_sigma * config_.ekf.measurement_sigma;
    P_.topRightCorner<2, 4>().setZero();
    P_.bottomLeftCorner<4, 2>().setZero();
    previous_ = s;
    have_previous_ = true;
    return;
  }
  const Sample& k = previous_;
  const double T = s.t - k.t;
  const double id = x_(0), iq = x_(1), R = x_(2), Ld = x_(3), Lq = x_(4), psi = x_(5);
  const double w = k.omega_e;
  // Prediction with the paper's forward-Euler model (Eq. 11), inputs of the previous sample.
  const double fd = k.u_d - R * id + w * Lq * iq;
  const double fq = k.u_q - R * iq - w * Ld * id - w * psi;
  Vec6 xp = x_;
  xp(0) = id + T / Ld * fd;
  xp(1) = iq + T / Lq * fq;
  Mat6 F = Mat6::Identity();
  F(0, 0) = 1.0 - T * R / Ld;
  F(0, 1) = T * w * Lq / Ld;
  F(0, 2) = -T * id / Ld;
  F(0, 3) = -T * fd / (Ld * Ld);
  F(0, 4) = T * w * iq / Ld;
  F(1, 0) = -T * w * Ld / Lq;
  F(1, 1) = 1.0 - T * R / Lq;
  F(1, 2) = -T * iq / Lq;
  F(1, 3) = -T * w * id / Lq;
  F(1, 4) = -T * fq / (Lq * Lq);
  F(1, 5) = -T * w / Lq;
  Mat6 Q = Mat6::Zero();
  const double qc = config_.ekf.process_current_sigma;
  Q(0, 0) = Q(1, 1) = qc * qc;
  for (int p = 0; p < kParameterCount; ++p) {
    const double q = config_.ekf.parameter_drift * std::abs(x_(2 + p));
    Q(2 + p, 2 + p) = q * q * T;
  }
  Mat6 Pp = F * P_ * F.transpose() + Q;
  // Measurement: the two currents.
  const double r = config_.ekf.measurement_sigma * config_.ekf.measurement_sigma;
  Eigen::Matrix2d S = Pp.topLeftCorner<2, 2>();
  S(0, 0) += r;
  S(1, 1) += r;
  const Eigen::Matrix<double, 6, 2> K = Pp.leftCols<2>() * S.inverse();
  const Eigen::Vector2d innovation(s.i_d - xp(0), s.i_q - xp(1));
  x_ = xp + K * innovation;
  P_ = Pp - K * Pp.topRows<2>();
  P_ = 0.5 * (P_ + P_.transpose());
  for (int p = 0; p < kParameterCount; ++p)  // keep the model physical
    x_(2 + p) = std::min(std::max(x_(2 + p), config_.lower[p]), config_.upper[p]);
  previous_ = s;
}

ParameterVector EkfIdentifier::current() const { return {x_(2), x_(3), x_(4), x_(5)}; }

}  // namespace pmsm_param_id
