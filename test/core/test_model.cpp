// The IPMSM model: steady state, power balance, RK4 convergence order.
#include <gtest/gtest.h>

#include <cmath>

#include "pmsm_param_id/model/motor_model.hpp"

using namespace pmsm_param_id;

TEST(MotorModel, SteadyStateVoltagesZeroTheCurrentDerivatives) {
  MotorParameters m;
  const double omega_e = 4 * 1000 * 2 * M_PI / 60, i_d = -1.5, i_q = 9.3;
  const auto u = steadyStateVoltages(m, i_d, i_q, omega_e);
  PlantState x{i_d, i_q, omega_e / m.pole_pairs, 0};
  const PlantDerivative dx = plantDerivative(m, x, u[0], u[1], 0.0);
  EXPECT_NEAR(dx.di_d, 0.0, 1e-9);
  EXPECT_NEAR(dx.di_q, 0.0, 1e-9);
  // Closed form of Eq. (1) at i_d = 0: u_d = -w L_q i_q, u_q = R i_q + w psi_f.
  const auto u0 = steadyStateVoltages(m, 0.0, i_q, omega_e);
  EXPECT_DOUBLE_EQ(u0[0], -omega_e * m.L_q * i_q);
  EXPECT_DOUBLE_EQ(u0[1], m.R_s * i_q + omega_e * m.psi_f);
}

TEST(MotorModel, PowerBalanceHoldsForAnyStateAndInput) {
  MotorParameters m;
  for (int k = 0; k < 20; ++k) {
    PlantState x{-3.0 + 0.4 * k, 12.0 - 0.9 * k, 50.0 + 7.0 * k, 0.0};
    const double u_d = -40.0 + 3.0 * k, u_q = 90.0 - 2.0 * k;
    const PlantDerivative dx = plantDerivative(m, x, u_d, u_q, 0.0);
    const double p_in = 1.5 * (u_d * x.i_d + u_q * x.i_q);
    const double p_copper = 1.5 * m.R_s * (x.i_d * x.i_d + x.i_q * x.i_q);
    const double p_magnetic = 1.5 * (m.L_d * x.i_d * dx.di_d + m.L_q * x.i_q * dx.di_q);
    const double p_mech = electromagneticTorque(m, x.i_d, x.i_q) * x.omega_m;
    EXPECT_NEAR(p_in, p_copper + p_magnetic + p_mech, 1e-9 * std::abs(p_in) + 1e-9);
  }
}

TEST(MotorModel, TorqueIncludesReluctanceTerm) {
  MotorParameters m;
  EXPECT_DOUBLE_EQ(electromagneticTorque(m, 0.0, 10.0), 1.5 * 4 * m.psi_f * 10.0);
  EXPECT_LT(electromagneticTorque(m, 2.0, 10.0), electromagneticTorque(m, 0.0, 10.0));  // L_d < L_q
}

TEST(MotorModel, Rk4IsFourthOrder) {
  MotorParameters m;
  const PlantState x0{0.5, 5.0, 100.0, 0.0};
  const double horizon = 2e-3;
  auto integrate = [&](int n) {
    PlantState x = x0;
    for (int i = 0; i < n; ++i) x = rk4Step(m, x, -30.0, 110.0, 5.0, horizon / n);
    return x;
  };
  const PlantState ref = integrate(4096);
  const double e1 = std::abs(integrate(8).i_q - ref.i_q);
  const double e2 = std::abs(integrate(16).i_q - ref.i_q);
  const double ratio = e1 / e2;
  EXPECT_GT(ratio, 12.0);  // 2^4 = 16 for a fourth-order method
  EXPECT_LT(ratio, 20.0);
}
