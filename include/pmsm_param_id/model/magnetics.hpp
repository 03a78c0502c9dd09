// Saturating interior-PM magnetics for the simulator (doc/simulator.md, "Saturation"): flux
// linkages from a co-energy W'(i_d, i_q), so that the incremental inductance matrix is symmetric
// (reciprocity) and the torque is 1.5 p (psi_d i_q - psi_q i_d):
//   W' = psi_f i_d + L_d0 i_d^2 / 2 + L_q0 I_s [i_q asinh(i_q / I_s) - sqrt(I_s^2 + i_q^2)] - c i_d i_q^2 / 2
//   psi_d = dW'/di_d = psi_f + L_d0 i_d - c i_q^2 / 2        (cross-saturation: d flux falls with load)
//   psi_q = dW'/di_q = L_q0 I_s asinh(i_q / I_s) - c i_d i_q  (q self-saturation, and the cross term)
//   L_dd = L_d0,  L_qq = L_q0 / sqrt(1 + (i_q / I_s)^2) - c i_d,  L_dq = L_qd = -c i_q.
// I_s = q_saturation_current (0: no q saturation); c = cross_saturation [H/A].
#pragma once
#include <cmath>

#include "pmsm_param_id/model/motor_model.hpp"

namespace pmsm_param_id {

struct SaturationSettings {
  bool enabled = false;
  double q_saturation_current = 0.0;  ///< I_s [A]: incremental L_q is L_q0 / sqrt(2) at i_q = I_s; 0 = linear q axis
  double cross_saturation = 0.0;      ///< c [H/A]: psi_d falls by c i_q^2 / 2; L_dq = -c i_q
};

/// Flux linkages and inductances of the machine at one current.
struct MagneticState {
  double psi_d = 0.0, psi_q = 0.0;       ///< [Wb]
  double L_dd = 0.0, L_qq = 0.0, L_dq = 0.0;  ///< incremental inductances d psi / d i [H]
  double L_q_secant = 0.0;               ///< psi_q / i_q (its limit L_qq at i_q = 0) [H]
  double psi_d_at_zero_i_d = 0.0;        ///< psi_d(0, i_q) [Wb]
};

/// m's L_d, L_q and psi_f are the small-current values L_d0, L_q0 and psi_f.
inline MagneticState magneticState(const MotorParameters& m, const SaturationSettings& s, double i_d, double i_q) {
  MagneticState x;
  const double Is = s.enabled ? s.q_saturation_current : 0.0, c = s.enabled ? s.cross_saturation : 0.0;
  const double self_q = Is > 0 ? m.L_q * Is * std::asinh(i_q / Is) : m.L_q * i_q;
  const double self_L_qq = Is > 0 ? m.L_q / std::sqrt(1.0 + (i_q / Is) * (i_q / Is)) : m.L_q;
  x.psi_d_at_zero_i_d = m.psi_f - 0.5 * c * i_q * i_q;
  x.psi_d = x.psi_d_at_zero_i_d + m.L_d * i_d;
  x.psi_q = self_q - c * i_d * i_q;
  x.L_dd = m.L_d;
  x.L_qq = self_L_qq - c * i_d;
  x.L_dq = -c * i_q;
  x.L_q_secant = std::abs(i_q) > 1e-9 ? self_q / i_q : m.L_q;
  return x;
}

/// The plant with saturating magnetics: d psi/dt = u - R i - omega J psi, with d psi/dt = L_inc di/dt
/// (the 2x2 incremental inductance matrix), and the torque from the flux linkages.
inline PlantDerivative saturatedPlantDerivative(const MotorParameters& m, const SaturationSettings& s,
                                                const PlantState& x, double u_d, double u_q, double load_torque) {
  const double omega_e = m.pole_pairs * x.omega_m;
  const MagneticState g = magneticState(m, s, x.i_d, x.i_q);
  const double dpsi_d = u_d - m.R_s * x.i_d + omega_e * g.psi_q;
  const double dpsi_q = u_q - m.R_s * x.i_q - omega_e * g.psi_d;
  const double det = g.L_dd * g.L_qq - g.L_dq * g.L_dq;
  PlantDerivative dx;
  dx.di_d = (g.L_qq * dpsi_d - g.L_dq * dpsi_q) / det;
  dx.di_q = (g.L_dd * dpsi_q - g.L_dq * dpsi_d) / det;
  const double torque = 1.5 * m.pole_pairs * (g.psi_d * x.i_q - g.psi_q * x.i_d);
  dx.domega_m = (torque - load_torque - m.friction * x.omega_m) / m.inertia;
  dx.dtheta_e = omega_e;
  return dx;
}

}  // namespace pmsm_param_id
