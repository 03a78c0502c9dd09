#include <cmath>

#include "pmsm_param_id/identification/identifiers.hpp"

namespace pmsm_param_id {

RlsIdentifier::RlsIdentifier(const IdentifierConfig& config) : OnlineIdentifier(config) {}

void RlsIdentifier::restart() {
  for (int p = 0; p < kParameterCount; ++p) theta_(p) = box_.centre[p];
  theta_(4) = 0.0;
  P_ = Mat5::Identity() * config_.rls.initial_covariance;
  if (!config_.inverter.estimate_voltage) P_(4, 4) = 0.0;  // V stays 0
  have_last_ = false;
}

void RlsIdentifier::update(const Sample& s, bool new_block, bool) {
  const double dt = have_last_ ? s.t - last_t_ : 0.0;
  last_t_ = s.t;
  have_last_ = true;
  if (!new_block) return;
  const double tau = config_.rls.time_constant > 0 ? config_.rls.time_constant : stats_.forgettingTimeConstant();
  const double lambda = std::exp(-dt / tau);
  const BlockD& d = stats_.lastBlockD();  // {Di_d, I_d, W_d, U_d}
  const BlockQ& q = stats_.lastBlockQ();  // {Di_q, I_q, W_q, U_q, Om}
  Vec5 phi_d = (Vec5() << d(kIntegralId), d(kDeltaId), -d(kIntegralOmegaIq), 0.0, d(kIntegralInverterD)).finished();
  Vec5 phi_q = (Vec5() << q(kIntegralIq), q(kIntegralOmegaId), q(kDeltaIq), q(kIntegralOmega), q(kIntegralInverterQ)).finished();
  // The inverter voltage's zero-crossing shape from the data's exact fit (V itself is RLS's fifth
  // parameter): the part that builds up over twice the zero-crossing current, and the part that
  // follows the logged bus voltage, move to the measured side.
  const double V_wide = stats_.inverterWideShare(), V_bus = stats_.inverterBusShare();
  double y_d = d(kIntegralUd) - V_wide * (d(kIntegralInverterWideD) - d(kIntegralInverterD)) - V_bus * d(kIntegralInverterBusD);
  double y_q = q(kIntegralUq) - V_wide * (q(kIntegralInverterWideQ) - q(kIntegralInverterQ)) - V_bus * q(kIntegralInverterBusQ);
  // The drive's voltage angle from the data's exact fit (time.voltage_angle: estimate): the acting voltage.
  const double angle = stats_.voltageAngle();
  y_d -= angle * d(kIntegralAngleUqInD);
  y_q += angle * q(kIntegralAngleUdInQ);
  if (stats_.crossSaturationSet()) {
    // A saturating machine (section 11): the swarms' model, with L_qq and L_dq from the data's exact
    // fit taken as known and moved to the measured side; L_q and psi_f the secant and the flux at i_bar.
    const double L_qq = stats_.crossLqq(), L_dq = stats_.crossLdq(), i_bar = stats_.crossLinearisationCurrent();
    y_d -= L_dq * (d(kDeltaIqInD) - d(kIntegralOmegaIdInD)) - L_qq * (d(kIntegralOmegaIq) - i_bar * d(kIntegralOmegaInD));
    phi_d(2) = -i_bar * d(kIntegralOmegaInD);
    y_q -= L_qq * q(kDeltaIq) + L_dq * (q(kDeltaIdInQ) + q(kIntegralOmegaIqInQ) - i_bar * q(kIntegralOmega));
    phi_q(2) = 0.0;
  }
  P_ /= lambda;
  for (const auto& [phi, y] : {std::make_pair(phi_d, y_d), std::make_pair(phi_q, y_q)}) {
    const Vec5 Pphi = P_ * phi;
    const double denom = 1.0 + phi.dot(Pphi);
    const Vec5 gain = Pphi / denom;
    theta_ += gain * (y - phi.dot(theta_));
    P_ -= gain * Pphi.transpose();
  }
  P_ = 0.5 * (P_ + P_.transpose());
  // Bounded covariance: without excitation (standstill) P grows by 1/lambda every block and
  // would overflow to inf and NaN; it never needs to exceed its starting size.
  const double largest = P_.diagonal().maxCoeff();
  if (!(largest <= config_.rls.initial_covariance)) {
    if (std::isfinite(largest)) P_ *= config_.rls.initial_covariance / largest;
    else {
      P_ = Mat5::Identity() * config_.rls.initial_covariance;
      if (!config_.inverter.estimate_voltage) P_(4, 4) = 0.0;
    }
  }
  if (!theta_.allFinite()) restart();
}

ParameterVector RlsIdentifier::current() const { return {theta_(0), theta_(1), theta_(2), theta_(3)}; }

}  // namespace pmsm_param_id
