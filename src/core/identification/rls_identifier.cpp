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
  const Vec5 phi_d = (Vec5() << d(kIntegralId), d(kDeltaId), -d(kIntegralOmegaIq), 0.0, d(kIntegralInverterD)).finished();
  const Vec5 phi_q = (Vec5() << q(kIntegralIq), q(kIntegralOmegaId), q(kDeltaIq), q(kIntegralOmega), q(kIntegralInverterQ)).finished();
  P_ /= lambda;
  for (const auto& [phi, y] : {std::make_pair(phi_d, d(kIntegralUd)), std::make_pair(phi_q, q(kIntegralUq))}) {
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
