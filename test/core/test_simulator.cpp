// The drive simulator: steady state against Eq. (1)-(2), control, injection, sensors, drift, seeds.
#include <gtest/gtest.h>

#include <cmath>
#include <numeric>

#include "test_helpers.hpp"

using namespace pmsm_param_id;
using test_helpers::run;
using test_helpers::scenario;

namespace {
struct SteadyState {
  double u_d, u_q;
};
// Mean of the applied voltages over the last `span` seconds (a whole number of injection periods).
SteadyState meanVoltages(const std::vector<SimulatedSample>& d, double span) {
  const double t_end = d.back().sample.t;
  double ud = 0, uq = 0;
  int n = 0;
  for (const auto& s : d)
    if (s.sample.t > t_end - span) {
      ud += s.sample.u_d;
      uq += s.sample.u_q;
      ++n;
    }
  return {ud / n, uq / n};
}
// Closed form of Eq. (1)-(2) at i_d = 0: i_q from the torque balance at the reference speed.
SteadyState closedForm(const Scenario& s, double rpm, double load) {
  const MotorParameters& m = s.motor;
  const double omega_m = rpm * 2 * M_PI / 60, omega_e = m.pole_pairs * omega_m;
  const double i_q = (load + m.friction * omega_m) / (1.5 * m.pole_pairs * m.psi_f);
  const auto u = steadyStateVoltages(m, 0.0, i_q, omega_e);
  return {u[0], u[1]};
}
}  // namespace

class PaperConditions : public ::testing::TestWithParam<std::tuple<const char*, double, double>> {};

TEST_P(PaperConditions, SteadyStateMatchesClosedFormWithinHalfPercent) {
  const auto [file, rpm, load] = GetParam();
  const Scenario s = scenario(file);
  const auto data = run(s);
  const SteadyState sim = meanVoltages(data, 0.1);  // 10 periods of the 100 Hz injection
  const SteadyState ref = closedForm(s, rpm, load);
  EXPECT_NEAR(sim.u_d, ref.u_d, 0.005 * std::abs(ref.u_d)) << file;
  EXPECT_NEAR(sim.u_q, ref.u_q, 0.005 * std::abs(ref.u_q)) << file;
  // Mean speed (the injection's reluctance torque ripples the speed at 100 Hz by ~0.5 %).
  double omega = 0;
  int n = 0;
  for (const auto& x : data)
    if (x.sample.t > data.back().sample.t - 0.1) omega += x.sample.omega_e, ++n;
  const double omega_ref = s.motor.pole_pairs * rpm * 2 * M_PI / 60;
  EXPECT_NEAR(omega / n, omega_ref, 1e-3 * omega_ref) << file;
}
INSTANTIATE_TEST_SUITE_P(Scenarios, PaperConditions,
                         ::testing::Values(std::make_tuple("wc1.yaml", 1000.0, 10.0),
                                           std::make_tuple("wc2.yaml", 1200.0, 20.0),
                                           std::make_tuple("wc1_no_injection.yaml", 1000.0, 10.0),
                                           std::make_tuple("wc1_drive.yaml", 1000.0, 10.0),
                                           std::make_tuple("wc2_drive.yaml", 1200.0, 20.0)));

TEST(DriveSimulator, HoldsIdZeroAndReachesSpeedWithoutInjection) {
  const Scenario s = scenario("wc1_no_injection.yaml");
  const auto data = run(s);
  double max_id = 0;
  for (const auto& x : data)
    if (x.sample.t > 0.2) max_id = std::max(max_id, std::abs(x.i_d_true));
  EXPECT_LT(max_id, 0.02);
  const double omega_ref = s.motor.pole_pairs * 1000 * 2 * M_PI / 60;
  EXPECT_NEAR(data.back().sample.omega_e, omega_ref, 0.001 * omega_ref);
  EXPECT_FALSE(data.back().voltage_limited);
}

TEST(DriveSimulator, InjectionReferenceAndResponse) {
  Scenario s = scenario("wc1_drive.yaml");
  s.sensors = {};  // look at the plant itself
  const auto data = run(s);
  double max_ref = 0, max_id = 0;
  for (const auto& x : data) {
    EXPECT_NEAR(x.i_d_reference, 2.0 * std::sin(2 * M_PI * 100 * x.sample.t), 1e-9);
    if (x.sample.t > 0.3) {
      max_ref = std::max(max_ref, std::abs(x.i_d_reference));
      max_id = std::max(max_id, std::abs(x.i_d_true));
    }
  }
  EXPECT_NEAR(max_ref, 2.0, 1e-3);
  EXPECT_NEAR(max_id, 2.0, 0.1);  // 1 kHz current loop follows 100 Hz within 5 %
}

TEST(DriveSimulator, SquareInjectionSwitchesBetweenLevels) {
  const Profile p = Profile::square(0.0, 1.5, 50.0);
  EXPECT_DOUBLE_EQ(p(0.001), 1.5);
  EXPECT_DOUBLE_EQ(p(0.011), -1.5);
  EXPECT_DOUBLE_EQ(p(0.021), 1.5);
}

TEST(DriveSimulator, SensorNoiseHasTheConfiguredStatistics) {
  Scenario s = scenario("wc1_drive.yaml");
  s.sensors.adc_bits = 0;
  s.sensors.current_noise_sigma = 0.03;
  const auto data = run(s);
  double sum = 0, sum2 = 0;
  for (const auto& x : data) {
    const double e = x.sample.i_q - x.i_q_true;
    sum += e;
    sum2 += e * e;
  }
  const double n = static_cast<double>(data.size());
  const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
  EXPECT_NEAR(mean, 0.0, 4 * 0.03 / std::sqrt(n));
  EXPECT_NEAR(sd, 0.03, 0.03 * 0.03);  // 5000 samples: relative std of sd ~ 1 %
}

TEST(DriveSimulator, QuantisationRoundsToTheLsb) {
  Scenario s = scenario("wc1_drive.yaml");
  s.sensors.current_noise_sigma = 0.0;
  s.sensors.adc_bits = 12;
  s.sensors.adc_range = 50.0;
  const double lsb = 100.0 / 4096;
  const auto data = run(s);
  for (const auto& x : data) {
    const double steps = x.sample.i_d / lsb;
    EXPECT_NEAR(steps, std::round(steps), 1e-9);
    EXPECT_LE(std::abs(x.sample.i_d - x.i_d_true), 0.5 * lsb + 1e-12);
  }
}

TEST(DriveSimulator, DriftProfilesMoveTheTrueParameters) {
  const Scenario s = scenario("rs_drift.yaml");
  DriveSimulator sim(s);
  EXPECT_DOUBLE_EQ(sim.trueMotorAt(0.05).R_s, s.motor.R_s);
  EXPECT_NEAR(sim.trueMotorAt(0.6).R_s, 1.1 * s.motor.R_s, 1e-12);
  EXPECT_NEAR(sim.trueMotorAt(1.4).R_s, 1.2 * s.motor.R_s, 1e-12);
  EXPECT_DOUBLE_EQ(sim.trueMotorAt(1.4).psi_f, s.motor.psi_f);
  const auto data = run(s);
  const auto& last = data.back();
  EXPECT_NEAR(last.truth[kRs], 1.2 * s.motor.R_s, 1e-12);
  // The plant really uses the drifted R_s: u_q rises by about 0.2 R_s i_q at steady state.
  EXPECT_GT(last.sample.u_q, data[1000].sample.u_q + 0.1 * s.motor.R_s * 9.0);
}

TEST(DriveSimulator, SameSeedSameSamplesOtherSeedOtherNoise) {
  Scenario s = scenario("wc1_drive.yaml");
  s.duration = 0.05;
  const auto a = run(s), b = run(s);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k].sample.i_d, b[k].sample.i_d);
    EXPECT_EQ(a[k].sample.u_q, b[k].sample.u_q);
  }
  s.seed = 2;
  const auto c = run(s);
  int differing = 0;
  for (std::size_t k = 0; k < a.size(); ++k) differing += a[k].sample.i_d != c[k].sample.i_d;
  EXPECT_GT(differing, static_cast<int>(a.size()) / 2);
}

TEST(DriveSimulator, SampleCountAndTimesFollowTs) {
  Scenario s = scenario("wc1_drive.yaml");
  s.duration = 0.01;
  const auto d = run(s);
  ASSERT_EQ(d.size(), 100u);
  EXPECT_DOUBLE_EQ(d[0].sample.t, 0.0);
  EXPECT_NEAR(d[99].sample.t, 99e-4, 1e-15);
}
