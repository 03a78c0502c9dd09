// Saturating interior-PM magnetics for the simulator (doc/simulator.md, "Saturation"): flux
// linkages from a co-energy W'(i_d, i_q), so that the incremental inductance matrix is symmetric
// (reciprocity) and the torque is 1.5 p (psi_d i_q - psi_q i_d):
//   W' = psi_f i_d + L_d0 i_d^2 / 2 + L_q0 I_s [i_q asinh(i_q / I_s) - sqrt(I_s^2 + i_q^2)] - c i_d i_q^2 / 2
//   psi_d = dW'/di_d = psi_f + L_d0 i_d - c i_q^2 / 2        (cross-saturation: d flux falls with load)
//   psi_q = dW'/di_q = L_q0 I_s asinh(i_q / I_s) - c i_d i_q  (q self-saturation, and the cross term)
//   L_dd = L_d0,  L_qq = L_q0 / sqrt(1 + (i_q / I_s)^2) - c i_d,  L_dq = L_qd = -c i_q.
// I_s = q_saturation_current (0: no q saturation); c = cross_saturation [H/A].
// Or a flux map from a CSV grid (model/flux_map.hpp) in place of the analytic model.
// The plant's state is then the flux linkage; the currents follow from it (currentsFromFlux).
#pragma once
#include <cmath>
#include <memory>

#include "pmsm_param_id/model/flux_map.hpp"
#include "pmsm_param_id/model/motor_model.hpp"

namespace pmsm_param_id {

struct SaturationSettings {
  bool enabled = false;
  double q_saturation_current = 0.0;  ///< I_s [A]: incremental L_q is L_q0 / sqrt(2) at i_q = I_s; 0 = linear q axis
  double cross_saturation = 0.0;      ///< c [H/A]: psi_d falls by c i_q^2 / 2; L_dq = -c i_q
  std::shared_ptr<const FluxTable> flux_map;  ///< set: the fluxes come from this grid, not the model above
};

/// Flux linkages and inductances of the machine at one current.
struct MagneticState {
  double psi_d = 0.0, psi_q = 0.0;       ///< [Wb]
  double L_dd = 0.0, L_qq = 0.0;          ///< incremental self-inductances d psi_d/d i_d, d psi_q/d i_q [H]
  double L_dq = 0.0, L_qd = 0.0;          ///< incremental cross terms d psi_d/d i_q, d psi_q/d i_d [H] (equal for the model)
  double L_q_secant = 0.0;               ///< psi_q(0, i_q) / i_q (its limit L_qq at i_q = 0) [H]
  double psi_d_at_zero_i_d = 0.0;        ///< psi_d(0, i_q) [Wb]
};

/// m's L_d, L_q and psi_f are the small-current values L_d0, L_q0 and psi_f.
inline MagneticState magneticState(const MotorParameters& m, const SaturationSettings& s, double i_d, double i_q) {
  MagneticState x;
  if (s.enabled && s.flux_map) {
    const FluxLinkage f = s.flux_map->at(i_d, i_q), at_zero = s.flux_map->at(0.0, i_q);
    x.psi_d = f.psi_d;
    x.psi_q = f.psi_q;
    x.L_dd = f.dpsi_d_di_d;
    x.L_qq = f.dpsi_q_di_q;
    x.L_dq = f.dpsi_d_di_q;
    x.L_qd = f.dpsi_q_di_d;
    x.psi_d_at_zero_i_d = at_zero.psi_d;
    x.L_q_secant = std::abs(i_q) > 1e-9 ? at_zero.psi_q / i_q : at_zero.dpsi_q_di_q;
    return x;
  }
  const double Is = s.enabled ? s.q_saturation_current : 0.0, c = s.enabled ? s.cross_saturation : 0.0;
  const double self_q = Is > 0 ? m.L_q * Is * std::asinh(i_q / Is) : m.L_q * i_q;
  const double self_L_qq = Is > 0 ? m.L_q / std::sqrt(1.0 + (i_q / Is) * (i_q / Is)) : m.L_q;
  x.psi_d_at_zero_i_d = m.psi_f - 0.5 * c * i_q * i_q;
  x.psi_d = x.psi_d_at_zero_i_d + m.L_d * i_d;
  x.psi_q = self_q - c * i_d * i_q;
  x.L_dd = m.L_d;
  x.L_qq = self_L_qq - c * i_d;
  x.L_dq = x.L_qd = -c * i_q;
  x.L_q_secant = std::abs(i_q) > 1e-9 ? self_q / i_q : m.L_q;
  return x;
}

/// The currents that carry the flux linkage (psi_d, psi_q): Newton's method on the magnetics from
/// the guess (the last currents), with the incremental inductance matrix as the Jacobian.
inline MagneticState currentsFromFlux(const MotorParameters& m, const SaturationSettings& s, double psi_d, double psi_q,
                                      double& i_d, double& i_q) {
  MagneticState g = magneticState(m, s, i_d, i_q);
  for (int k = 0; k < 30; ++k) {
    const double rd = psi_d - g.psi_d, rq = psi_q - g.psi_q;
    const double det = g.L_dd * g.L_qq - g.L_dq * g.L_qd;
    const double step_d = (g.L_qq * rd - g.L_dq * rq) / det, step_q = (g.L_dd * rq - g.L_qd * rd) / det;
    i_d += step_d;
    i_q += step_q;
    g = magneticState(m, s, i_d, i_q);
    if (std::abs(step_d) + std::abs(step_q) <= 1e-12 * (1.0 + std::abs(i_d) + std::abs(i_q))) break;
  }
  return g;
}

/// The plant with saturating magnetics, flux linkages as the state:
///   d psi_d/dt = u_d - R i_d + omega_e psi_q,   d psi_q/dt = u_q - R i_q - omega_e psi_d,
/// the torque 1.5 p (psi_d i_q - psi_q i_d); (i_d, i_q) the currents that carry (psi_d, psi_q).
struct FluxDerivative {
  double dpsi_d = 0.0, dpsi_q = 0.0, domega_m = 0.0, dtheta_e = 0.0;
};
inline FluxDerivative saturatedPlantDerivative(const MotorParameters& m, double psi_d, double psi_q, double i_d,
                                               double i_q, double omega_m, double u_d, double u_q, double load_torque) {
  const double omega_e = m.pole_pairs * omega_m;
  FluxDerivative dx;
  dx.dpsi_d = u_d - m.R_s * i_d + omega_e * psi_q;
  dx.dpsi_q = u_q - m.R_s * i_q - omega_e * psi_d;
  const double torque = 1.5 * m.pole_pairs * (psi_d * i_q - psi_q * i_d);
  dx.domega_m = (torque - load_torque - m.friction * omega_m) / m.inertia;
  dx.dtheta_e = omega_e;
  return dx;
}

}  // namespace pmsm_param_id
