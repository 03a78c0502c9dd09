// IPMSM model of the seed paper, Eq. (1)-(3), in the rotor (d-q) frame. SI units throughout.
#pragma once
#include <array>
#include <cmath>
#include <string>

namespace pmsm_param_id {

/// The four electrical parameters identified by this package, in a fixed order.
enum ParameterIndex : int { kRs = 0, kLd = 1, kLq = 2, kPsiF = 3 };
constexpr int kParameterCount = 4;
/// Parameter names as used in YAML, CSV, JSON and messages.
inline const std::array<std::string, kParameterCount>& parameterNames() {
  static const std::array<std::string, kParameterCount> names{"R_s", "L_d", "L_q", "psi_f"};
  return names;
}
/// {R_s [ohm], L_d [H], L_q [H], psi_f [Wb]}
using ParameterVector = std::array<double, kParameterCount>;

struct MotorParameters {
  int pole_pairs = 4;
  double R_s = 2.875;      ///< stator resistance [ohm]
  double L_d = 0.0045;     ///< d-axis inductance [H]
  double L_q = 0.0135;     ///< q-axis inductance [H]
  double psi_f = 0.17858;  ///< permanent-magnet flux linkage [Wb]
  double inertia = 0.003;  ///< rotor + load inertia [kg m^2]
  double friction = 0.001; ///< viscous friction [N m s/rad] (mechanical speed)

  ParameterVector electrical() const { return {R_s, L_d, L_q, psi_f}; }
};

/// Continuous plant state.
struct PlantState {
  double i_d = 0.0;      ///< [A]
  double i_q = 0.0;      ///< [A]
  double omega_m = 0.0;  ///< mechanical speed [rad/s]
  double theta_e = 0.0;  ///< electrical angle [rad] (kept for completeness)
};

/// Time derivative of PlantState (same layout).
struct PlantDerivative {
  double di_d = 0.0, di_q = 0.0, domega_m = 0.0, dtheta_e = 0.0;
};

/// Electromagnetic torque [N m]: 1.5 p (psi_f i_q + (L_d - L_q) i_d i_q).
inline double electromagneticTorque(const MotorParameters& m, double i_d, double i_q) {
  return 1.5 * m.pole_pairs * (m.psi_f * i_q + (m.L_d - m.L_q) * i_d * i_q);
}

/// Eq. (1)-(3) plus the mechanics J domega_m/dt = T_e - T_load - B omega_m.
/// u_d, u_q [V]; load_torque [N m].
inline PlantDerivative plantDerivative(const MotorParameters& m, const PlantState& x, double u_d,
                                       double u_q, double load_torque) {
  const double omega_e = m.pole_pairs * x.omega_m;
  PlantDerivative dx;
  dx.di_d = (u_d - m.R_s * x.i_d + omega_e * m.L_q * x.i_q) / m.L_d;
  dx.di_q = (u_q - m.R_s * x.i_q - omega_e * m.L_d * x.i_d - omega_e * m.psi_f) / m.L_q;
  dx.domega_m =
      (electromagneticTorque(m, x.i_d, x.i_q) - load_torque - m.friction * x.omega_m) / m.inertia;
  dx.dtheta_e = omega_e;
  return dx;
}

/// One classical 4th-order Runge-Kutta step of length h [s] with inputs held constant.
inline PlantState rk4Step(const MotorParameters& m, const PlantState& x, double u_d, double u_q,
                          double load_torque, double h) {
  auto add = [](const PlantState& s, const PlantDerivative& d, double k) {
    return PlantState{s.i_d + k * d.di_d, s.i_q + k * d.di_q, s.omega_m + k * d.domega_m,
                      s.theta_e + k * d.dtheta_e};
  };
  const PlantDerivative k1 = plantDerivative(m, x, u_d, u_q, load_torque);
  const PlantDerivative k2 = plantDerivative(m, add(x, k1, h / 2), u_d, u_q, load_torque);
  const PlantDerivative k3 = plantDerivative(m, add(x, k2, h / 2), u_d, u_q, load_torque);
  const PlantDerivative k4 = plantDerivative(m, add(x, k3, h), u_d, u_q, load_torque);
  PlantState out = x;
  out.i_d += h / 6 * (k1.di_d + 2 * k2.di_d + 2 * k3.di_d + k4.di_d);
  out.i_q += h / 6 * (k1.di_q + 2 * k2.di_q + 2 * k3.di_q + k4.di_q);
  out.omega_m += h / 6 * (k1.domega_m + 2 * k2.domega_m + 2 * k3.domega_m + k4.domega_m);
  out.theta_e += h / 6 * (k1.dtheta_e + 2 * k2.dtheta_e + 2 * k3.dtheta_e + k4.dtheta_e);
  return out;
}

/// Steady state of Eq. (1)-(2) (d/dt = 0) for given currents and electrical speed: {u_d, u_q} [V].
inline std::array<double, 2> steadyStateVoltages(const MotorParameters& m, double i_d, double i_q,
                                                 double omega_e) {
  return {m.R_s * i_d - omega_e * m.L_q * i_q,
          m.R_s * i_q + omega_e * m.L_d * i_d + omega_e * m.psi_f};
}

}  // namespace pmsm_param_id
