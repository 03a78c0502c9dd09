#include <Eigen/LU>
#include <algorithm>
#include <cmath>

#include "pmsm_param_id/identification/identifiers.hpp"
#include "pmsm_param_id/model/frames.hpp"

namespace pmsm_param_id {

EkfIdentifier::EkfIdentifier(const IdentifierConfig& config) : OnlineIdentifier(config) {}

void EkfIdentifier::restart() {
  x_.setZero();
  for (int p = 0; p < kParameterCount; ++p) x_(2 + p) = box_.centre[p];
  P_.setZero();
  P_(0, 0) = P_(1, 1) = 1.0;
  for (int p = 0; p < kParameterCount; ++p) {
    const double s = config_.ekf.initial_relative_std * box_.centre[p];
    P_(2 + p, 2 + p) = s * s;
  }
  clamped_.fill(false);
  have_previous_ = false;
}

namespace {
EkfState ekfPredictCross(const EkfState& x, const Sample& k, double T, EkfJacobian* jacobian,
                         const EkfCrossSaturation& c) {
  const double id = x(0), iq = x(1), R = x(2), Ld = x(3), Lq = x(4), psi = x(5);
  const double w = k.omega_e, Lqq = c.L_qq, Ldq = c.L_dq, ib = c.i_bar;
  const double psi_q = Lq * ib + Lqq * (iq - ib) + Ldq * id;
  const double psi_d = psi + Ldq * (iq - ib) + Ld * id;
  const double fd = k.u_d - R * id + w * psi_q;
  const double fq = k.u_q - R * iq - w * psi_d;
  const double det = Ld * Lqq - Ldq * Ldq;
  // di/dt = A f with A = [[L_d, L_dq], [L_dq, L_qq]]^-1
  const double a00 = Lqq / det, a01 = -Ldq / det, a11 = Ld / det;
  const double gd = a00 * fd + a01 * fq, gq = a01 * fd + a11 * fq;
  EkfState xp = x;
  xp(0) = id + T * gd;
  xp(1) = iq + T * gq;
  if (jacobian) {
    // d f / d {i_d, i_q, R, L_d, L_q, psi}; L_d also in A: d(A f)/dL_d = A (df/dL_d - [g_d, 0]).
    const double dfd[6] = {-R + w * Ldq, w * Lqq, -id, 0.0, w * ib, 0.0};
    const double dfq[6] = {-w * Ld, -R - w * Ldq, -iq, -w * id, 0.0, -w};
    EkfJacobian& F = *jacobian;
    F.setIdentity();
    for (int j = 0; j < 6; ++j) {
      const double ud = dfd[j] - (j == 3 ? gd : 0.0), uq = dfq[j];
      F(0, j) += T * (a00 * ud + a01 * uq);
      F(1, j) += T * (a01 * ud + a11 * uq);
    }
  }
  return xp;
}
}  // namespace

EkfState ekfPredict(const EkfState& x, const Sample& k, double T, EkfJacobian* jacobian, const EkfCrossSaturation& cross) {
  if (cross.on) return ekfPredictCross(x, k, T, jacobian, cross);
  const double id = x(0), iq = x(1), R = x(2), Ld = x(3), Lq = x(4), psi = x(5);
  const double w = k.omega_e;
  // The paper's forward-Euler model (Eq. 11), inputs of the previous sample.
  const double fd = k.u_d - R * id + w * Lq * iq;
  const double fq = k.u_q - R * iq - w * Ld * id - w * psi;
  EkfState xp = x;
  xp(0) = id + T / Ld * fd;
  xp(1) = iq + T / Lq * fq;
  if (jacobian) {
    EkfJacobian& F = *jacobian;
    F.setIdentity();
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
  }
  return xp;
}

void EkfIdentifier::update(const Sample& s, bool, bool continuity_broken) {
  // Measurement noise: configured, or the data's own (floored at 0.1 % of the current, so that
  // noise-free data do not make the filter overconfident).
  const double current_scale = std::abs(s.i_d) + std::abs(s.i_q);
  const double sigma_m = config_.ekf.measurement_sigma > 0 ? config_.ekf.measurement_sigma
                                                           : std::max({noiseStd(), 1e-3 * current_scale, 1e-9});
  const double sigma_p = config_.ekf.process_current_sigma > 0 ? config_.ekf.process_current_sigma : 0.3 * sigma_m;
  if (continuity_broken || !have_previous_) {  // (re)start the current states from the measurement
    x_(0) = s.i_d;
    x_(1) = s.i_q;
    P_.topLeftCorner<2, 2>().setIdentity();
    P_.topLeftCorner<2, 2>() *= sigma_m * sigma_m;
    P_.topRightCorner<2, 4>().setZero();
    P_.bottomLeftCorner<4, 2>().setZero();
    previous_ = s;
    have_previous_ = true;
    return;
  }
  // The previous sample's voltage as the motor received it: less the inverter voltage the data's
  // exact fit estimates (0 unless inverter.model: estimate).
  Sample k = previous_;
  if (stats_.inverterVoltage() != 0.0) {
    double sd = 0.0, sq = 0.0;
    inverterShape(k, sd, sq);
    k.u_d -= stats_.inverterVoltage() * sd;
    k.u_q -= stats_.inverterVoltage() * sq;
  }
  const double T = s.t - k.t;
  if (stats_.voltageAngle() != 0.0) {  // the drive's voltage angle from the data's exact fit: the acting vector
    const Vec2 turned = rotate({k.u_d, k.u_q}, stats_.voltageAngle() * k.omega_e * stats_.nominalPeriod());
    k.u_d = turned.x;
    k.u_q = turned.y;
  }
  Mat6 F;
  EkfCrossSaturation cross;  // a saturating machine: the known cross terms of the data's exact fit
  if (stats_.crossSaturationSet())
    cross = {true, stats_.crossLqq(), stats_.crossLdq(), stats_.crossLinearisationCurrent()};
  const Vec6 xp = ekfPredict(x_, k, T, &F, cross);
  Mat6 Q = Mat6::Zero();
  const double qc = sigma_p;
  Q(0, 0) = Q(1, 1) = qc * qc;
  for (int p = 0; p < kParameterCount; ++p) {
    const double q = config_.ekf.parameter_drift * std::abs(x_(2 + p));
    Q(2 + p, 2 + p) = q * q * T;
  }
  Mat6 Pp = F * P_ * F.transpose() + Q;
  // Measurement: the two currents.
  const double r = sigma_m * sigma_m;
  Eigen::Matrix2d S = Pp.topLeftCorner<2, 2>();
  S(0, 0) += r;
  S(1, 1) += r;
  const Eigen::Matrix<double, 6, 2> K = Pp.leftCols<2>() * S.inverse();
  const Eigen::Vector2d innovation(s.i_d - xp(0), s.i_q - xp(1));
  x_ = xp + K * innovation;
  P_ = Pp - K * Pp.topRows<2>();
  P_ = 0.5 * (P_ + P_.transpose());
  for (int p = 0; p < kParameterCount; ++p) {  // keep the model physical: inside the search box
    const double v = x_(2 + p);
    clamped_[p] = !(v > box_.lower[p] && v < box_.upper[p]);
    x_(2 + p) = std::isfinite(v) ? std::min(std::max(v, box_.lower[p]), box_.upper[p]) : box_.centre[p];
    // Bounded covariance: an hour of standstill must not leave a random walk of many times the
    // value, which the first excitation would turn into a jump to the bounds.
    const double cap = config_.ekf.initial_relative_std * x_(2 + p);
    const double var = P_(2 + p, 2 + p);
    if (!(var <= cap * cap)) {
      const double k = std::isfinite(var) && var > 0 ? cap / std::sqrt(var) : 0.0;
      P_.row(2 + p) *= k;
      P_.col(2 + p) *= k;
      if (k == 0.0) P_(2 + p, 2 + p) = cap * cap;
    }
  }
  if (!x_.allFinite() || !P_.allFinite()) restart();
  previous_ = s;
}

ParameterVector EkfIdentifier::current() const { return {x_(2), x_(3), x_(4), x_(5)}; }

}  // namespace pmsm_param_id
