// The IPMSM model: steady state, power balance, RK4 convergence order.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "pmsm_param_id/model/frames.hpp"
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

// The mid-period phasor from the sample's (frames.hpp advance()): within a few ulps of cos and sin
// of the summed angle, on both sides of the series' range and for large (unwrapped) angles, where
// the summed angle's own rounding is the larger error.
TEST(Frames, AdvancedPhasorMatchesCosAndSinOfTheSummedAngle) {
  double worst_ulps = 0.0;
  for (const double angle : {0.0, 0.3, -1.2, 2.9, -3.1, 40.0, -250.7}) {
    for (const double delta : {0.0, 1e-9, -3e-4, 0.01, -0.07, 0.16, 0.2499, -0.25}) {
      const Phasor e = advance(phasorOf(angle), angle, delta);
      const long double exact = static_cast<long double>(angle) + static_cast<long double>(delta);
      const double c = static_cast<double>(std::cos(exact)), s = static_cast<double>(std::sin(exact));
      // In ulps of 1 (the phasor's scale): cos and sin of a sum near a zero of either are small.
      worst_ulps = std::max({worst_ulps, std::abs(e.c - c) / 2.2e-16, std::abs(e.s - s) / 2.2e-16});
    }
  }
  EXPECT_LT(worst_ulps, 4.0);
  // Beyond the series' range (and for NaN) it takes cos and sin of the sum itself.
  const Phasor far = advance(phasorOf(1.0), 1.0, 0.6);
  EXPECT_DOUBLE_EQ(far.c, std::cos(1.6));
  EXPECT_DOUBLE_EQ(far.s, std::sin(1.6));
  EXPECT_TRUE(std::isnan(advance(phasorOf(1.0), 1.0, std::nan("")).c));
}

// The wrapped angle (frames.hpp wrappedAngle()) is std::remainder(angle, 2 pi) to the bit, inside
// [-pi, pi] (where it skips the call), on its edges, beyond them and for NaN.
TEST(Frames, WrappedAngleIsTheRemainderToTheBit) {
  const double pi = M_PI;
  for (const double angle : {0.0, -0.0, 1e-300, 0.3, -1.2, 2.9, -3.1, pi, -pi, std::nextafter(pi, 4.0),
                             std::nextafter(-pi, -4.0), 3 * pi, -3 * pi, 6.5, -6.5, 40.0, -250.7, 1e9}) {
    const double wrapped = wrappedAngle(angle), reference = std::remainder(angle, 2.0 * pi);
    EXPECT_EQ(std::memcmp(&wrapped, &reference, sizeof wrapped), 0) << angle << ": " << wrapped << " vs " << reference;
    EXPECT_LE(std::abs(wrapped), pi) << angle;
  }
  EXPECT_TRUE(std::isnan(wrappedAngle(std::nan(""))));
}

// The logged angle's phasors sample by sample (PhasorTracker): advanced by each increment, yet within
// 1e-14 of cos and sin over a million samples of an angle turning 0.2 rad per sample
// (without the exact cos/sin every 64 samples the rounding would accumulate), and exact after a
// wrap, a jump and a NaN.
TEST(Frames, TrackedPhasorsDoNotDriftFromCosAndSin) {
  PhasorTracker tracker;
  double worst = 0.0, angle = 0.3;
  for (int k = 0; k < 1000000; ++k) {
    angle += 0.2 + 1e-7 * (k % 7);  // unwrapped: no wrap recomputes the phasor
    const Phasor e = tracker.next(angle);
    worst = std::max({worst, std::abs(e.c - std::cos(angle)), std::abs(e.s - std::sin(angle))});
  }
  EXPECT_LT(worst, 1e-14);  // measured 2.4e-15; 1.4e-11 without the exact cos/sin every 64
  for (const double jump : {2.5, std::nan(""), 1.0}) {
    const Phasor e = tracker.next(jump);
    if (std::isnan(jump)) continue;
    EXPECT_EQ(e.c, std::cos(jump));
    EXPECT_EQ(e.s, std::sin(jump));
  }
}
