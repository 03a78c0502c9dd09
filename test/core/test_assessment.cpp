// "Identified" means right within the stated uncertainty, on any motor, with no configuration;
// a model that does not fit is said so, with its likely cause; no stamp glitch breaks timing.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>

#include "pmsm_param_id/identification/angle_quantum.hpp"
#include "pmsm_param_id/identification/block_statistics.hpp"
#include "pmsm_param_id/identification/identifiers.hpp"
#include "pmsm_param_id/identification/metrics.hpp"
#include "pmsm_param_id/identification/monitor.hpp"
#include "pmsm_param_id/identification/motor_map.hpp"
#include "pmsm_param_id/identification/online_identifier.hpp"
#include "pmsm_param_id/identification/sample_period.hpp"
#include "pmsm_param_id/identification/slow_estimate.hpp"
#include "pmsm_param_id/io/config_error.hpp"
#include "pmsm_param_id/io/log_format.hpp"
#include "pmsm_param_id/io/sample_csv.hpp"
#include "pmsm_param_id/io/thermal_state.hpp"
#include "test_helpers.hpp"

using namespace pmsm_param_id;

namespace {
/// The scenario's run with this seed, cut to `duration` (0: the scenario's own) [s].
std::vector<SimulatedSample> drive(const char* file, std::uint64_t seed = 1, double duration = 0.3) {
  Scenario s = test_helpers::scenario(file);
  s.seed = seed;
  if (duration > 0) s.duration = duration;
  return test_helpers::run(s);
}
Estimate identify(const std::vector<Sample>& samples, const std::string& method, IdentifierConfig c = {},
                  std::uint64_t seed = 1) {
  c.method = method;
  c.seed = seed;
  auto id = makeIdentifier(c);
  for (const auto& s : samples) id->process(s);
  return id->estimate();
}
std::vector<Sample> samplesOf(const std::vector<SimulatedSample>& data) {
  std::vector<Sample> out;
  for (const auto& d : data) out.push_back(d.sample);
  return out;
}
}  // namespace

// Three motors two to three decades apart, no identifier configuration: every parameter reported
// identified is within 1 % of the truth, over 10 seeds, for every method, and within its stated
// uncertainty (a ~3 sigma bound: over 2943 identified values of the 30-seed benches 0.24 % exceeded
// it, by at most 9 %; hence the 1.25 here). L_q and the flux are identified in every seed by the
// swarm and RLS, L_d in most.
class AnyMotor : public ::testing::TestWithParam<const char*> {};
TEST_P(AnyMotor, IdentifiedMeansWithinTheStatedUncertaintyWithNoConfig) {
  int ld_identified = 0;  // of 20: fbdapso and rls over 10 seeds
  for (std::uint64_t seed = 1; seed <= 10; ++seed) {
    const auto data = drive(GetParam(), seed);
    const ParameterVector truth = data.back().truth;
    for (const char* method : {"fbdapso", "sapso", "pso", "ekf", "rls"}) {
      const Estimate e = identify(samplesOf(data), method, {}, seed);
      for (int p = 0; p < kParameterCount; ++p) {
        const double err = std::abs(errorPercent(e.parameters[p], truth[p]));
        if (e.identifiable[p]) {
          EXPECT_LE(err, 1.25 * 100.0 * e.relative_uncertainty[p])
              << GetParam() << " seed " << seed << " " << method << " " << parameterNames()[p];
          EXPECT_LT(err, 1.0) << GetParam() << " seed " << seed << " " << method << " " << parameterNames()[p];
        }
      }
      if (std::string(method) == "fbdapso" || std::string(method) == "rls") {
        for (int p : {kLq, kPsiF}) EXPECT_TRUE(e.identifiable[p]) << GetParam() << " " << method << " " << e.reason[p];
        ld_identified += e.identifiable[kLd];
      }
    }
  }
  // The injection determines L_d to well within 1 % in most seeds (0.3 s of data).
  EXPECT_GE(ld_identified, 14) << GetParam();
}
INSTANTIATE_TEST_SUITE_P(Motors, AnyMotor, ::testing::Values("robot_joint.yaml", "wc1_drive.yaml", "industrial.yaml"));

// The ends of the supported range, 20 uH / 0.02 ohm / 2 mWb at 40 kHz and 200 mH / 20 ohm / 2 Wb at
// 1 kHz, with no configuration: nothing identified is more than 1 % off; the small motor is fully
// identified, the slow one at least in L_q and psi_f (its 3 s at 1 kHz hold little information).
TEST(AnyMotor, TheEndsOfTheSupportedRange) {
  for (std::uint64_t seed = 1; seed <= 3; ++seed) {
    for (const char* file : {"small_fast.yaml", "large_slow.yaml"}) {
      Scenario s = test_helpers::scenario(file);
      s.seed = seed;
      const auto data = test_helpers::run(s);
      for (const char* method : {"fbdapso", "rls"}) {
        const Estimate e = identify(samplesOf(data), method, {}, seed);
        for (int p = 0; p < kParameterCount; ++p) {
          const double err = std::abs(errorPercent(e.parameters[p], data.back().truth[p]));
          if (e.identifiable[p]) {
            EXPECT_LT(err, 1.0) << file << " " << method << " " << parameterNames()[p];
          }
          if (std::string(file) == "small_fast.yaml" || p == kLq || p == kPsiF) {
            EXPECT_TRUE(e.identifiable[p]) << file << " " << method << " " << e.reason[p];
          }
        }
      }
    }
  }
}

// An estimate asked for at every sample of a drive's start: before a second block has measured
// the noise, the one block's fit leaves no residual and its values rest on the solver's start. Not
// one value is identified then (WLS, RLS and the EKF stated L_q, R_s or psi_f identified 27-13 700 %
// off at +-0.2-0.7 % at the first block of these scenarios); after it, each identified value lies
// within its stated uncertainty up to 15 ms.
TEST(Assessment, NothingIsIdentifiedBeforeTheNoiseIsMeasured) {
  for (const char* file : {"industrial_pwm.yaml", "wc1_realistic.yaml", "robot_joint_realistic.yaml"}) {
    const auto data = drive(file, 1, 0.015);
    const ParameterVector truth = data.back().truth;
    for (const char* method : {"wls", "rls", "ekf", "fbdapso"}) {
      IdentifierConfig c;
      c.method = method;
      auto id = makeIdentifier(c);
      int identified = 0, first_block = 0;
      for (const auto& d : data) {
        id->process(d.sample);
        const Estimate e = id->estimate();
        const std::string label = std::string(file) + " " + method + " t = " + std::to_string(d.sample.t);
        if (e.fit.available && first_block == 0) first_block = 1;
        for (int p = 0; p < kParameterCount; ++p) {
          if (e.status[p] != ParameterStatus::Identified) continue;
          ++identified;
          EXPECT_LE(std::abs(e.parameters[p] / truth[p] - 1.0), e.relative_uncertainty[p])
              << label << " " << parameterNames()[p] << ": " << e.reason[p];
        }
        if (!e.fit.available) {
          for (int p = 0; p < kParameterCount; ++p) EXPECT_NE(e.status[p], ParameterStatus::Identified) << label;
        }
      }
      EXPECT_EQ(first_block, 1) << file << " " << method << ": no fit within 15 ms";
    }
  }
}

TEST(Assessment, TheInverterIsNamedWhereItHoldsHalfOfAnUncertaintyOrMore) {
  // +-2 % with V free, +-1 % with V known: sqrt(4 - 1) = 1.73 % is the inverter's, named with V,
  // where V comes from, what V is and what would separate them, in that order.
  const std::string named = inverterShareClause(0.02, 0.01, 12.3, 0.035, ", from the long window", ": dead time",
                                                "; a load step separates them");
  EXPECT_EQ(named, "; +-1.73 % of it (in quadrature) from the inverter's error voltage (12.3 V +-3.5 %, from the long "
                   "window: dead time), which acts as a resistance at any one current magnitude; a load step separates them");
  // +-0.62 % of +-2 %: less than half, not named; nor where the uncertainty is not finite.
  EXPECT_EQ(inverterShareClause(0.02, 0.019, 12.3, 0.035, "", "", ""), "");
  EXPECT_EQ(inverterShareClause(std::numeric_limits<double>::infinity(), 0.01, 12.3, 0.035, "", "", ""), "");
}

TEST(Assessment, NoiseLevelIsEstimatedFromTheData) {
  const Estimate e = identify(samplesOf(drive("wc1_drive.yaml")), "rls");
  // 0.03 A of noise plus 12-bit quantisation (LSB 24 mA: 7 mA rms) = 0.031 A.
  EXPECT_NEAR(e.fit.noise_std_d, 0.031, 0.003);
  EXPECT_NEAR(e.fit.noise_std_q, 0.031, 0.003);
  EXPECT_TRUE(e.fit.consistent);
  EXPECT_LT(e.fit.fit_ratio_d, 2.0);
  EXPECT_LT(e.fit.fit_ratio_q, 2.0);
}

// The noise level counts the current noise that enters a block through the current integrals
// (doc/algorithm.md section 4), which blocks one sample apart do not show: on the robot joint
// (R T / L = 0.11 per sample, 100 samples a block) that is a factor 1.65 in d, and before it a right
// model read 1.31-2.09 times the noise (median 1.61 over 30 seeds; wc1_drive 1.45). Now the median
// over five seeds is near 1 on both.
TEST(Assessment, ARightModelReadsTheNoiseLevel) {
  for (const char* file : {"robot_joint.yaml", "wc1_drive.yaml"}) {
    std::vector<double> ratio_d, ratio_q;
    for (std::uint64_t seed = 1; seed <= 5; ++seed) {
      const Estimate e = identify(samplesOf(drive(file, seed, 0.5)), "wls", {}, seed);
      ratio_d.push_back(e.fit.fit_ratio_d);
      ratio_q.push_back(e.fit.fit_ratio_q);
    }
    EXPECT_NEAR(median(ratio_d), 1.0, 0.25) << file;
    EXPECT_NEAR(median(ratio_q), 1.0, 0.25) << file;
  }
}

TEST(Assessment, SpeedLoggedInRpmIsAPoorFitWithItsCause) {
  auto samples = samplesOf(drive("wc1_drive.yaml"));
  for (auto& s : samples) s.omega_e *= 60.0 / (2.0 * M_PI) / 4.0;  // mechanical rpm of the 4-pole-pair motor
  for (const char* method : {"fbdapso", "rls", "ekf"}) {
    const Estimate e = identify(samples, method);
    for (int p = 0; p < kParameterCount; ++p) {
      EXPECT_FALSE(e.identifiable[p]) << method << " " << parameterNames()[p];
      EXPECT_EQ(e.status[p], ParameterStatus::PoorFit) << method << " " << e.reason[p];
    }
    EXPECT_NE(e.fit.likely_cause.find("rpm"), std::string::npos) << e.fit.likely_cause;
    EXPECT_NE(e.fit.likely_cause.find("4 pole pairs"), std::string::npos) << e.fit.likely_cause;
  }
}

// On a motor with little saliency the steady state cannot show the speed unit; the start-up's
// q-axis current steps can, and the long check window remembers them after the fitness window
// has forgotten them.
TEST(Assessment, MechanicalSpeedOnANonSalientMotorIsCaughtByTheLongWindow) {
  auto samples = samplesOf(drive("robot_joint.yaml"));
  for (auto& s : samples) s.omega_e /= 14.0;
  for (const char* method : {"fbdapso", "rls"}) {
    const Estimate e = identify(samples, method);
    for (int p = 0; p < kParameterCount; ++p) EXPECT_FALSE(e.identifiable[p]) << method << " " << e.reason[p];
    EXPECT_NE(e.fit.likely_cause.find("mechanical speed"), std::string::npos) << e.fit.likely_cause;
  }
}

// A log that starts in steady state without injection has no q-axis current steps: L_q and psi_f
// are identified through the speed terms alone, and their reason says so.
TEST(Assessment, SteadyStateWithoutStepsSaysTheSpeedUnitIsUnverified) {
  const auto samples = samplesOf(drive("industrial_no_injection.yaml", 1, 0.8));
  std::vector<Sample> steady(samples.begin() + 4000, samples.end());
  // With the logged angle the speed is checked against the angle's rate directly.
  const Estimate with_angle = identify(steady, "rls");
  EXPECT_TRUE(with_angle.fit.speed_unit_verified);
  for (Sample& s : steady) s.theta_e = std::numeric_limits<double>::quiet_NaN();
  const Estimate e = identify(steady, "rls");
  EXPECT_FALSE(e.fit.speed_unit_verified);
  EXPECT_TRUE(e.identifiable[kLq]) << e.reason[kLq];
  EXPECT_NE(e.reason[kLq].find("speed terms only"), std::string::npos) << e.reason[kLq];
}

// A speed in rpm on a 10-pole-pair motor is only 4.7 % from the electrical rad/s: the speed terms
// cannot tell it from the current steps, the logged angle can.
TEST(Assessment, RpmOnATenPolePairMotorIsCaughtThroughTheLoggedAngle) {
  Scenario s = test_helpers::scenario("wc1_drive.yaml");
  s.motor.pole_pairs = 10;
  s.duration = 0.5;
  auto samples = samplesOf(test_helpers::run(s));
  for (auto& x : samples) x.omega_e *= 60.0 / (2.0 * M_PI) / 10.0;  // mechanical rpm
  const Estimate e = identify(samples, "rls");
  for (int p = 0; p < kParameterCount; ++p) EXPECT_EQ(e.status[p], ParameterStatus::PoorFit) << e.reason[p];
  EXPECT_NE(e.fit.likely_cause.find("10 pole pairs"), std::string::npos) << e.fit.likely_cause;
  // Without the angle the speed terms cannot see it (doc/results.md).
  for (auto& x : samples) x.theta_e = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(identify(samples, "rls").fit.likely_cause.find("rpm"), std::string::npos);
}

TEST(Assessment, MechanicalSpeedIsAPoorFitWithItsCause) {
  auto samples = samplesOf(drive("wc1_drive.yaml"));
  for (auto& s : samples) s.omega_e /= 4.0;
  const Estimate e = identify(samples, "fbdapso");
  for (int p = 0; p < kParameterCount; ++p) EXPECT_EQ(e.status[p], ParameterStatus::PoorFit) << e.reason[p];
  EXPECT_NE(e.fit.likely_cause.find("mechanical speed"), std::string::npos) << e.fit.likely_cause;
  EXPECT_NE(e.fit.likely_cause.find("pole pairs about 4"), std::string::npos) << e.fit.likely_cause;
}

// Most drives apply the voltage computed at t_k from t_k+1 on. Emulated on simulated data: row k
// of the log holds the voltage that acted on [t_k+1, t_k+2).
TEST(Assessment, VoltageOneSampleLateIsAPoorFitUntilTheDelayIsDeclared) {
  const auto data = drive("wc1_drive.yaml");
  auto samples = samplesOf(data);
  for (std::size_t k = 0; k + 1 < samples.size(); ++k) {
    samples[k].u_d = samples[k + 1].u_d;
    samples[k].u_q = samples[k + 1].u_q;
  }
  samples.pop_back();
  const Estimate e = identify(samples, "rls");
  for (int p = 0; p < kParameterCount; ++p) EXPECT_FALSE(e.identifiable[p]) << e.reason[p];
  EXPECT_NE(e.fit.likely_cause.find("later than the model's delay"), std::string::npos) << e.fit.likely_cause;
  IdentifierConfig declared;
  declared.window.voltage_delay_samples = 1;
  for (const char* method : {"rls", "fbdapso"}) {
    const Estimate d = identify(samples, method, declared);
    EXPECT_TRUE(d.fit.consistent) << method;
    for (int p = 0; p < kParameterCount; ++p)
      EXPECT_LT(std::abs(errorPercent(d.parameters[p], data.back().truth[p])), 1.0) << method << " " << parameterNames()[p];
  }
}

// A log decimated by 2 holds each logged voltage over two periods although the drive changed it
// after one: R_s came out 4 % high. It must not be reported identified.
TEST(Assessment, ALogDecimatedFromAFasterLoopIsAPoorFit) {
  for (const char* file : {"wc1_drive.yaml", "robot_joint.yaml"}) {
    const auto data = drive(file, 1, 0.5);
    std::vector<Sample> samples;
    for (std::size_t k = 1; k < data.size(); k += 2) samples.push_back(data[k].sample);
    for (const char* method : {"fbdapso", "rls"}) {
      const Estimate e = identify(samples, method);
      for (int p = 0; p < kParameterCount; ++p)
        EXPECT_EQ(e.status[p], ParameterStatus::PoorFit) << file << " " << method << " " << e.reason[p];
    }
  }
}

// A fit that fails, and an alternative that is significant but explains a sliver of the misfit, is
// not named as its cause: the inter-turn fault (R_s -8 %, L_d and L_q -15 % at 1.5 s) 20 ms into the
// window, where the best alternative, a voltage acting a dozen samples early, still leaves most of
// the residual ("the voltages act 12 samples earlier than the model's delay", named, would send the
// user to the wrong place).
TEST(Assessment, AnAlternativeThatExplainsASliverOfAMisfitIsNotItsCause) {
  auto data = test_helpers::run(test_helpers::scenario("inter_turn_fault.yaml"));
  while (!data.empty() && data.back().sample.t >= 1.52) data.pop_back();
  const Estimate e = identify(samplesOf(data), "wls", IdentifierConfig{});
  ASSERT_FALSE(e.fit.consistent);
  EXPECT_EQ(e.fit.likely_cause.find("earlier than the model's delay"), std::string::npos) << e.fit.likely_cause;
  EXPECT_NE(e.fit.likely_cause.find("not one of the effects tested"), std::string::npos) << e.fit.likely_cause;
  EXPECT_NE(e.reason[kLq].find("not one of the effects tested"), std::string::npos) << e.reason[kLq];
}

// A fit that fails while the drive's delay is still being decided is named as that first, never as
// a log decimated from a faster control loop (which it is not): the robot joint behind its
// switching inverter, nothing declared, up to 0.6 s, where the drive model took delay 0 (its
// drive's is 1) and the other delay still runs beside it; the best alternative there is a
// fractional delay of about half a sample (measured with the 0.05 V threshold). The MOSFET bridge
// and the threshold alike.
TEST(Assessment, AMisfitWhileTheDelayIsUndecidedIsNamedAsThat) {
  for (const char* name : {"robot_joint_pwm.yaml", "robot_joint_pwm_threshold.yaml"}) {
    SCOPED_TRACE(name);
    auto data = test_helpers::run(test_helpers::scenario(name));
    while (!data.empty() && data.back().sample.t >= 0.6) data.pop_back();
    const Estimate e = identify(samplesOf(data), "wls", IdentifierConfig{});
    EXPECT_NE(e.drive_model.find("delay 1 runs beside it"), std::string::npos) << e.drive_model;
    ASSERT_FALSE(e.fit.consistent);
    EXPECT_EQ(e.fit.likely_cause.find("decimated"), std::string::npos) << e.fit.likely_cause;
    EXPECT_EQ(e.fit.likely_cause.find("the drive's delay is not decided yet: delay 0"), 0u) << e.fit.likely_cause;
    EXPECT_NE(e.reason[kLq].find("delay 1 runs beside it"), std::string::npos) << e.reason[kLq];
  }
}

TEST(Assessment, TimeInMillisecondsIsNamed) {
  auto samples = samplesOf(drive("wc1_drive.yaml"));
  for (auto& s : samples) s.t *= 1e3;
  const Estimate e = identify(samples, "rls");
  for (int p = 0; p < kParameterCount; ++p) EXPECT_FALSE(e.identifiable[p]) << e.reason[p];
  EXPECT_NE(e.fit.likely_cause.find("is time in ms?"), std::string::npos) << e.fit.likely_cause;
}

TEST(Assessment, FixedBoundsAwayFromTheMotorGiveAtBoundNeverIdentified) {
  IdentifierConfig c;
  c.search.fixed_bounds = true;
  c.search.lower = {0.5, 0.5e-3, 20e-3, 0.02};  // L_q's box excludes the true 13.5 mH
  c.search.upper = {10.0, 30e-3, 30e-3, 0.6};
  const Estimate e = identify(samplesOf(drive("wc1_drive.yaml")), "fbdapso", c);
  EXPECT_EQ(e.status[kLq], ParameterStatus::AtBound) << e.reason[kLq];
  EXPECT_FALSE(e.identifiable[kLq]);
}

TEST(Assessment, ImplausibleValuesAreNeverIdentified) {
  FitCheck fit;
  fit.available = true;
  fit.consistent = true;
  fit.determined.fill(true);
  fit.optimum = {1.0, -1e-3, 1e-3, 0.1};
  fit.relative_std = {1e-4, 1e-4, 1e-4, 1e-4};
  const Assessment a =
      assess({1.0, -1e-3, 1e-3, std::numeric_limits<double>::quiet_NaN()}, fit, {}, AssessmentSettings{});
  EXPECT_EQ(a.status[kRs], ParameterStatus::Identified);
  EXPECT_EQ(a.status[kLd], ParameterStatus::Implausible);
  EXPECT_EQ(a.status[kPsiF], ParameterStatus::Implausible);
}

TEST(Assessment, AMethodTrailingTheWindowIsStatedAgainstTheOptimumItTrails) {
  // L_d determined to 3 x 0.25 % = 0.75 %; the method's value is 0.35 % from the current optimum
  // (1.10 % in all: not identified) and 0.10 % from the optimum of 25 ms ago (40 % of the window's
  // weight new since), which the noise alone could have moved to the searched fitness's optimum
  // now, here the data's (0.25 % against 2 x 0.25 % x sqrt(0.4 x 1.4) = 0.37 %): the value is
  // right within 0.75 % + 0.10 %.
  FitCheck fit;
  fit.available = true;
  fit.consistent = true;
  fit.determined.fill(true);
  fit.optimum = {1.0, 1.0e-3, 2.0e-3, 0.1};
  fit.relative_std = {1e-3, 2.5e-3, 1e-3, 1e-3};
  const ParameterVector x = {1.0, 0.9965e-3, 2.0e-3, 0.1};
  const Assessment alone = assess(x, fit, {}, AssessmentSettings{});
  EXPECT_EQ(alone.status[kLd], ParameterStatus::NotExcited) << alone.reason[kLd];
  EXPECT_NEAR(alone.relative_uncertainty[kLd], 0.0075 + 0.0035 / 0.9965, 1e-6);
  RecentOptimum earlier{0.025, 0.4, true, fit.optimum};
  earlier.optimum[kLd] = 0.9975e-3;
  const TrailedOptima with_earlier{fit.optimum, {earlier}};
  const Assessment trailing = assess(x, fit, {}, AssessmentSettings{}, &with_earlier);
  EXPECT_EQ(trailing.status[kLd], ParameterStatus::Identified) << trailing.reason[kLd];
  EXPECT_NEAR(trailing.relative_uncertainty[kLd], 0.0075 + 0.001 / 0.9965, 1e-6);
  // One the window did not determine (NaN) is no reference.
  RecentOptimum undetermined = earlier;
  undetermined.optimum[kLd] = std::numeric_limits<double>::quiet_NaN();
  const TrailedOptima with_undetermined{fit.optimum, {undetermined}};
  EXPECT_EQ(assess(x, fit, {}, AssessmentSettings{}, &with_undetermined).relative_uncertainty[kLd],
            alone.relative_uncertainty[kLd]);
  // An optimum of the last time constant further from the current one than the noise moves it
  // (1 % against 0.51 %) shows a change: no earlier optimum is a reference then.
  RecentOptimum older{0.05, 0.63, false, fit.optimum};
  older.optimum[kLd] = 0.990e-3;
  const TrailedOptima with_older{fit.optimum, {older, earlier}};
  const Assessment drifting = assess(x, fit, {}, AssessmentSettings{}, &with_older);
  EXPECT_EQ(drifting.relative_uncertainty[kLd], alone.relative_uncertainty[kLd]);
  EXPECT_NE(drifting.status[kLd], ParameterStatus::Identified) << drifting.reason[kLd];
  EXPECT_NE(drifting.reason[kLd].find("distance to the data's optimum 0.351 % (need"), std::string::npos) << drifting.reason[kLd];
  // Where the distance to the earlier optimum still leaves too much, the reason says which optimum.
  earlier.optimum[kLd] = 0.9995e-3;
  const TrailedOptima with_nearer{fit.optimum, {earlier}};
  const Assessment named = assess(x, fit, {}, AssessmentSettings{}, &with_nearer);
  EXPECT_EQ(named.status[kLd], ParameterStatus::NotExcited);
  EXPECT_NEAR(named.relative_uncertainty[kLd], 0.0075 + 0.003 / 0.9965, 1e-6);
  EXPECT_NE(named.reason[kLd].find("(its optimum 25 ms ago)"), std::string::npos) << named.reason[kLd];
  // The searched fitness's optimum now 10 % from the data's (the data's fit holds a voltage angle
  // the swarm's fitness has not adopted yet), the value at the searched optima: stated against
  // them plus that gap, so not identified; 0.05 % apart, the gap is added to the earlier one's distance.
  ParameterVector searched = fit.optimum;
  searched[kLd] = 1.1e-3;
  RecentOptimum stale{0.025, 0.4, true, searched};
  const ParameterVector at_searched = {1.0, 1.1e-3, 2.0e-3, 0.1};
  const TrailedOptima apart{searched, {stale}};
  const Assessment other_fitness = assess(at_searched, fit, {}, AssessmentSettings{}, &apart);
  EXPECT_NE(other_fitness.status[kLd], ParameterStatus::Identified) << other_fitness.reason[kLd];
  EXPECT_NEAR(other_fitness.relative_uncertainty[kLd], 0.0075 + 0.1e-3 / 1.1e-3, 1e-6);
  searched[kLd] = 0.9995e-3;
  earlier.optimum[kLd] = 0.9975e-3;
  const TrailedOptima near_data{searched, {earlier}};
  const Assessment close = assess(x, fit, {}, AssessmentSettings{}, &near_data);
  EXPECT_EQ(close.status[kLd], ParameterStatus::Identified) << close.reason[kLd];
  EXPECT_NEAR(close.relative_uncertainty[kLd], 0.0075 + (0.001e-3 + 0.0005e-3) / 0.9965e-3, 1e-6);
}

// ---------------------------------------------------------------------------------------------
// Timing

TEST(Timing, SecondRowOneNanosecondAfterTheFirstChangesNothing) {
  const auto data = drive("wc1_drive.yaml");
  auto samples = samplesOf(data);
  Sample glitch = samples[0];
  glitch.t += 1e-9;
  samples.insert(samples.begin() + 1, glitch);
  IdentifierConfig c;
  c.method = "fbdapso";
  auto id = makeIdentifier(c);
  for (const auto& s : samples) id->process(s);
  const Estimate e = id->estimate();
  EXPECT_NEAR(e.sample_period, 1e-4, 1e-12);
  EXPECT_EQ(e.counters.skipped_too_close, 1u);
  EXPECT_EQ(e.counters.gaps, 0u);
  for (int p = 0; p < kParameterCount; ++p) {
    EXPECT_TRUE(e.identifiable[p]) << e.reason[p];
    EXPECT_LT(std::abs(errorPercent(e.parameters[p], data.back().truth[p])), 1.0);
  }
}

// The pipeline with a NaN, a time reset and a forward jump ends within 1 % of the truth.
TEST(Timing, NanResetAndForwardJumpStillEndWithinOnePercent) {
  const auto data = drive("wc1_drive.yaml", 3, 0.6);
  std::vector<Sample> samples;
  for (std::size_t k = 0; k < data.size(); ++k) {
    Sample s = data[k].sample;
    if (k == 1000) s.i_d = std::numeric_limits<double>::quiet_NaN();
    if (k >= 2000) s.t -= 0.15;  // the clock jumps back (reset) ...
    if (k >= 2001) s.t += 10.0;  // ... and then forward
    samples.push_back(s);
  }
  for (const char* method : {"fbdapso", "rls"}) {
    IdentifierConfig c;
    c.method = method;
    auto id = makeIdentifier(c);
    for (const auto& s : samples) id->process(s);
    const Estimate e = id->estimate();
    EXPECT_EQ(e.counters.skipped_nonfinite, 1u);
    EXPECT_EQ(e.counters.time_resets, 1u);
    EXPECT_EQ(e.counters.gaps, 1u);
    EXPECT_NEAR(e.sample_period, 1e-4, 1e-12);
    for (int p = 0; p < kParameterCount; ++p)
      EXPECT_LT(std::abs(errorPercent(e.parameters[p], data.back().truth[p])), 1.0)
          << method << " " << parameterNames()[p];
  }
}

TEST(Timing, ADecimatedStreamIsReBlockedAtItsNewRate) {
  const auto data = drive("wc1_drive.yaml", 1, 0.6);
  std::vector<Sample> samples;
  for (std::size_t k = 0; k < data.size(); ++k)
    if (k < 1000 || k % 2 == 0) samples.push_back(data[k].sample);
  IdentifierConfig c;
  c.method = "rls";
  auto id = makeIdentifier(c);
  for (const auto& s : samples) id->process(s);
  const Estimate e = id->estimate();
  EXPECT_EQ(e.counters.period_changes, 1u);
  EXPECT_NEAR(e.sample_period, 2e-4, 1e-12);
}

// The rate watch re-blocks when the median of its 32 steps (the step of rank 16) lies more than
// 30 % from the nominal period: at the boundary, 16 long steps move it and 15 do not; 17 short
// steps move it and 16 do not. (The watch counts the steps beyond the limits and selects the
// median only where it can lie beyond them.)
TEST(Timing, TheRateWatchFollowsTheMedianOfItsWindow) {
  // 1e-4 s nominal; then a watch window whose first `count` steps are `step` long.
  const auto watch = [](std::size_t count, double step) {
    SamplePeriodEstimator estimator;
    for (std::size_t k = 0; k < SamplePeriodEstimator::kStartupSteps; ++k) estimator.addStep(1e-4);
    bool changed = false;
    for (std::size_t k = 0; k < SamplePeriodEstimator::kWatchSteps; ++k)
      changed = estimator.addStep(k < count ? step : 1e-4) || changed;
    return std::make_pair(changed, estimator.nominal());
  };
  EXPECT_EQ(watch(16, 2e-4), std::make_pair(true, 2e-4));
  EXPECT_EQ(watch(15, 2e-4), std::make_pair(false, 1e-4));
  EXPECT_EQ(watch(17, 0.5e-4), std::make_pair(true, 0.5e-4));
  EXPECT_EQ(watch(16, 0.5e-4), std::make_pair(false, 1e-4));
  EXPECT_EQ(watch(32, 0.5e-4), std::make_pair(true, 0.5e-4));
}

// ---------------------------------------------------------------------------------------------
// Baselines never give NaN or a negative inductance.

TEST(Baselines, AStandstillMinuteLeavesRlsAndEkfWorking) {
  const auto data = drive("wc1_drive.yaml", 1, 0.3);
  for (const char* method : {"rls", "ekf"}) {
    IdentifierConfig c;
    c.method = method;
    auto id = makeIdentifier(c);
    for (const auto& d : data) id->process(d.sample);
    // 60 s of standstill with no current: without a bounded covariance, RLS's P grows by e^1200.
    double t = data.back().sample.t;
    for (int k = 0; k < 600000; ++k) {
      t += 1e-4;
      id->process(Sample{t, 0.0, 0.0, 0.0, 0.0, 0.0});
    }
    for (double v : id->parameters()) EXPECT_TRUE(std::isfinite(v) && v > 0) << method;
    // The drive starts again: the same parameters are found again.
    const auto again = drive("wc1_drive.yaml", 2, 0.3);
    for (const auto& d : again) {
      Sample s = d.sample;
      s.t += t + 1e-4;
      id->process(s);
    }
    const Estimate e = id->estimate();
    for (int p = 0; p < kParameterCount; ++p) {
      EXPECT_TRUE(std::isfinite(e.parameters[p])) << method;
      if (std::string(method) == "rls") {
        EXPECT_LT(std::abs(errorPercent(e.parameters[p], again.back().truth[p])), 1.0) << parameterNames()[p];
      }
    }
  }
}

TEST(Baselines, EkfJacobianMatchesFiniteDifferences) {
  EkfState x;
  x << 1.3, 7.9, 2.9, 4.4e-3, 13.1e-3, 0.175;
  const Sample k{0.0, -40.0, 120.0, 1.2, 8.0, 420.0};
  const double T = 1e-4;
  // The linear model, and a saturating machine's (known L_qq, L_dq about i_bar; section 11).
  for (const EkfCrossSaturation& cross : {EkfCrossSaturation{}, EkfCrossSaturation{true, 8.0e-3, -1.5e-3, 7.5}}) {
    EkfJacobian F;
    ekfPredict(x, k, T, &F, cross);
    for (int j = 0; j < 6; ++j) {
      const double h = 1e-6 * std::max(1.0, std::abs(x(j))) * (j >= 3 ? 1e-3 : 1.0);
      EkfState xp = x, xm = x;
      xp(j) += h;
      xm(j) -= h;
      const EkfState numeric = (ekfPredict(xp, k, T, nullptr, cross) - ekfPredict(xm, k, T, nullptr, cross)) / (2 * h);
      for (int i = 0; i < 6; ++i)
        EXPECT_NEAR(F(i, j), numeric(i), 1e-6 * std::max(1.0, std::abs(numeric(i)))) << i << "," << j << " " << cross.on;
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Strict inputs

namespace {
std::string loadError(const std::string& text, bool scenario) {
  const std::string path = test_helpers::writeTemp("strict.yaml", text);
  try {
    if (scenario) loadScenario(path);
    else loadIdentifierConfig(path);
  } catch (const ConfigError& e) {
    const std::string m = e.what();
    return m.substr(path.size() + 2);
  }
  return "no error";
}
std::string scenarioWith(const std::string& old_text, const std::string& new_text) {
  std::ifstream in(test_helpers::sourcePath("config/scenarios/wc1_drive.yaml"));
  std::string s((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto at = s.find(old_text);
  EXPECT_NE(at, std::string::npos) << old_text;
  return s.replace(at, old_text.size(), new_text);
}
}  // namespace

TEST(StrictInputs, UnknownKeysNameTheNearestKnownOne) {
  EXPECT_EQ(loadError(scenarioWith("current_noise_sigma:", "current_noise:"), true),
            "key 'sensors.current_noise': unknown key (did you mean 'sensors.current_noise_sigma'?)");
  EXPECT_EQ(loadError("window:\n  block_lenght: 0.005\n", false),
            "key 'window.block_lenght': unknown key (did you mean 'window.block_length'?)");
  EXPECT_EQ(loadError("swarm:\n  particles: 20\nfbdapso:\n  T3: 1\n", false),
            "key 'fbdapso.T3': unknown key (did you mean 'fbdapso.T1'?)");
}

TEST(StrictInputs, IntegersAreRangeChecked) {
  EXPECT_EQ(loadError(scenarioWith("pole_pairs: 4 ", "pole_pairs: 1e10 "), true),
            "key 'motor.pole_pairs': must be an integer in [1, 1000], got 1e10");
  EXPECT_EQ(loadError("swarm:\n  particles: 2.5\n", false), "key 'swarm.particles': expected an integer, got 2.5");
  EXPECT_EQ(loadError("time:\n  voltage_delay_samples: 3\n", false),
            "key 'time.voltage_delay_samples': must be an integer in [0, 1], got 3");
}

TEST(StrictInputs, PartialBoundsAreRefused) {
  EXPECT_EQ(loadError("bounds:\n  R_s: [1, 2]\n", false),
            "key 'bounds': give all four of R_s, L_d, L_q, psi_f or none (none: a data-driven search box)");
}

TEST(StrictInputs, EveryShippedIdentifierConfigLoads) {
  for (const char* f : {"default.yaml", "paper.yaml"})
    EXPECT_NO_THROW(loadIdentifierConfig(test_helpers::sourcePath(std::string("config/identifiers/") + f))) << f;
}

// ---------------------------------------------------------------------------------------------
// Logs from other drives

TEST(LogFormat, RpmMilliampsAndPowerInvariantLogsReadAsSi) {
  const std::string path = test_helpers::writeTemp(
      "other_drive.csv", "time_ms,vd,vq,id_mA,iq_mA,rpm,angle\n0,1.5,3,300,600,60,90\n0.1,1.5,3,300,600,60,90\n");
  LogFormat f;
  f.columns = {{"t", "time_ms"}, {"u_d", "vd"}, {"u_q", "vq"}, {"i_d", "id_mA"},
               {"i_q", "iq_mA"}, {"omega_e", "rpm"}, {"theta_e", "angle"}};
  f.time_unit = "ms";
  f.current_unit = "mA";
  f.speed_unit = "rpm";
  f.angle_unit = "deg";
  f.pole_pairs = 4;
  f.dq_scaling = "power_invariant";
  const SampleLog log = readSampleCsv(path, f);
  ASSERT_EQ(log.samples.size(), 2u);
  const Sample& s = log.samples[1];
  const double k = std::sqrt(2.0 / 3.0);
  EXPECT_DOUBLE_EQ(s.t, 1e-4);
  EXPECT_NEAR(s.u_d, 1.5 * k, 1e-12);
  EXPECT_NEAR(s.i_q, 0.6 * k, 1e-12);
  EXPECT_NEAR(s.omega_e, 60.0 * 2.0 * M_PI / 60.0 * 4, 1e-12);
  EXPECT_NEAR(s.theta_e, M_PI / 2, 1e-12);
  f.pole_pairs = 0;
  try {
    readSampleCsv(path, f);
    ADD_FAILURE();
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()),
              "log format: key 'pole_pairs': needed (>= 1) to turn a mechanical speed (rpm) into the electrical one");
  }
}

TEST(LogFormat, ThetaIsCarriedThroughCsv) {
  const auto data = drive("wc1_drive.yaml", 1, 0.01);
  const std::string path = ::testing::TempDir() + "theta.csv";
  writeSampleCsv(path, data);
  const SampleLog log = readSampleCsv(path);
  ASSERT_EQ(log.samples.size(), data.size());
  for (std::size_t k = 0; k < data.size(); ++k) EXPECT_EQ(log.samples[k].theta_e, data[k].sample.theta_e);
  EXPECT_TRUE(std::isfinite(log.samples.back().theta_e));
}

// A node asks for an estimate after every sample, from the first one on, before any method starts.
TEST(OnlineIdentifier, EstimateIsSafeBeforeTheMethodStarts) {
  const auto data = drive("wc1_drive.yaml", 1, 0.02);
  for (const char* method : {"fbdapso", "sapso", "pso", "ekf", "rls"}) {
    IdentifierConfig c;
    c.method = method;
    auto id = makeIdentifier(c);
    Estimate e = id->estimate();
    EXPECT_EQ(e.method, method);
    EXPECT_EQ(e.status[kLq], ParameterStatus::NoData);
    for (const auto& d : data) e = (id->process(d.sample), id->estimate());
    EXPECT_TRUE(std::isfinite(e.parameters[kLq])) << method;
  }
}

// ---------------------------------------------------------------------------------------------
// Real drives (the simulator's inverter and sensors; config/identifiers/real_drive.yaml declares
// the delay, the stationary hold and the inverter model).

namespace {
// real_drive.yaml with the timing of the realistic scenarios declared (their angle prediction is the
// delay's own, k_p = 1): these tests look at the inverter and sensor models; the estimated voltage
// angle has its own tests (VoltageAngle.*).
IdentifierConfig realDriveConfig() {
  IdentifierConfig c = loadIdentifierConfig(test_helpers::sourcePath("config/identifiers/real_drive.yaml"));
  c.window.estimate_voltage_angle = false;
  return c;
}
// Every parameter reported identified lies within `factor` times its stated uncertainty.
void expectIdentifiedWithinStated(const Estimate& e, const ParameterVector& truth, const std::string& label,
                                  double factor = 1.0) {
  for (int p = 0; p < kParameterCount; ++p) {
    if (!e.identifiable[p]) continue;
    EXPECT_LE(std::abs(errorPercent(e.parameters[p], truth[p])), factor * 100 * e.relative_uncertainty[p])
        << label << " " << parameterNames()[p] << " " << e.reason[p];
  }
}
/// A real-drive fit that must work: consistent, L_q and psi_f identified, every identified value
/// within its stated uncertainty.
void expectConsistentAndRight(const Estimate& e, const ParameterVector& truth, const std::string& method) {
  EXPECT_TRUE(e.fit.consistent) << method << " d " << e.fit.fit_ratio_d << " q " << e.fit.fit_ratio_q;
  EXPECT_TRUE(e.identifiable[kLq] && e.identifiable[kPsiF]) << method << " " << e.reason[kLq] << " / " << e.reason[kPsiF];
  expectIdentifiedWithinStated(e, truth, method);
}
Scenario idealSensors(Scenario s) {
  s.sensors.phase_offset = {0, 0, 0};
  s.sensors.phase_gain = {1, 1, 1};
  s.sensors.encoder_lines = 0;
  s.inverter.dc_ripple = 0.0;
  return s;
}
}  // namespace

// Dead time inflates R_s by (4/pi) V_err / |i| in a model without it: the nested inverter test must
// see it, so R_s is never reported identified; with the inverter voltage estimated, R_s and V are
// right (V within 5 % of its true equivalent value).
TEST(RealDriveIdentification, InverterErrorIsSeenWithoutTheModelAndEstimatedWithIt) {
  Scenario s = idealSensors(test_helpers::scenario("wc1_realistic.yaml"));
  s.duration = 1.0;
  const auto data = test_helpers::run(s);
  const ParameterVector truth = data.back().truth;
  IdentifierConfig without = realDriveConfig();
  without.inverter.estimate_voltage = false;
  for (const char* method : {"fbdapso", "rls"}) {
    const Estimate e = identify(samplesOf(data), method, without);
    EXPECT_FALSE(e.identifiable[kRs]) << method << " " << e.reason[kRs];
    EXPECT_NE(e.fit.likely_cause.find("inverter voltage error"), std::string::npos) << e.fit.likely_cause;
    const Estimate m = identify(samplesOf(data), method, realDriveConfig());
    // R_s may stay unidentified: the unknown shape of the zero crossing leaves about +-1 % (reason).
    expectIdentifiedWithinStated(m, truth, method, 1.25);
    EXPECT_TRUE(m.fit.consistent) << method;
    EXPECT_EQ(m.inverter_status, ParameterStatus::Identified) << m.inverter_reason;
    EXPECT_NEAR(m.inverter_voltage, data.back().inverter_error_voltage, 0.05 * data.back().inverter_error_voltage);
  }
}

// An incremental encoder: the controller turns its delayed voltage into the stator frame at the
// quantised angle plus its filtered speed times the period. The identifier rotates each delayed
// voltage by that prediction's miss, computed from the logged angle and speed; before, the fit was
// poor (d residual 4.3-5.3 times the noise over seeds 1-3 of this drive).
TEST(RealDriveIdentification, AnEncoderDriveFitsThroughTheLoggedAngle) {
  Scenario s = idealSensors(test_helpers::scenario("wc1_realistic.yaml"));
  s.sensors.encoder_lines = 2500;
  s.sensors.speed_filter_hz = 1000.0;
  s.duration = 1.0;
  const auto data = test_helpers::run(s);
  const ParameterVector truth = data.back().truth;
  for (const char* method : {"fbdapso", "rls"}) {
    const Estimate e = identify(samplesOf(data), method, realDriveConfig());
    expectConsistentAndRight(e, truth, method);
  }
}

// DC-bus ripple (3 % at 100 Hz on the robot joint's 48 V bus): the dead-time part of the inverter
// error follows the bus voltage, so with V taken as constant the q residual carries the ripple
// times the error's shape. Without the logged bus the fit is poor; with it (Sample::v_dc) the dead-
// time part is fitted as its own share of V, the fit is consistent and every identified value right.
TEST(RealDriveIdentification, TheDeadTimeFollowsTheLoggedBusVoltage) {
  Scenario s = idealSensors(test_helpers::scenario("robot_joint_realistic.yaml"));
  s.inverter.dc_ripple = 0.03;
  s.duration = 0.55;  // before the reversal: light load and a load step
  const auto data = test_helpers::run(s);
  const ParameterVector truth = data.back().truth;
  std::vector<Sample> without_bus = samplesOf(data);
  for (Sample& x : without_bus) x.v_dc = std::numeric_limits<double>::quiet_NaN();
  const Estimate poor = identify(without_bus, "wls", realDriveConfig());
  EXPECT_FALSE(poor.fit.consistent) << "d " << poor.fit.fit_ratio_d << " q " << poor.fit.fit_ratio_q;
  const double dead_time_part = s.drive.dc_bus_voltage * s.inverter.dead_time * s.inverter.switching_frequency;
  for (const char* method : {"fbdapso", "wls"}) {
    const Estimate e = identify(samplesOf(data), method, realDriveConfig());
    expectConsistentAndRight(e, truth, method);
    EXPECT_NEAR(e.inverter_voltage, data.back().inverter_error_voltage, 0.05 * data.back().inverter_error_voltage);
    EXPECT_NEAR(e.fit.inverter_bus_share, dead_time_part, 0.1 * dead_time_part) << method;  // 0.188 of 0.192 V (seed 1)
  }
}

// The inverter shape's current observer (doc/algorithm.md section 8) runs the data's model on the
// logged voltages and is pulled towards the measured currents by 0.1 per sample. Given the true
// parameters and the inverter's true shape it must follow the true currents with a fraction of the
// sensors' noise and no offset (earlier forms of its step, one chord per period, sat 5-10 mA off
// without the stationary hold's bend and 2-7 mA off with the inverter error by the trapezoid).
TEST(RealDriveIdentification, TheShapeObserverFollowsTheTrueCurrents) {
  Scenario s = idealSensors(test_helpers::scenario("robot_joint_realistic.yaml"));
  s.duration = 0.55;  // light load, a load step up and one down
  const auto data = test_helpers::run(s);
  WindowSettings w = realDriveConfig().window;
  w.inverter_zero_crossing_current = s.inverter.zero_crossing_current;  // the inverter's own shape
  BlockStatistics stats(w);
  stats.configure(s.drive.sample_period);
  const MotorParameters& m = s.motor;
  stats.setInverterVoltage(data.back().inverter_error_voltage);
  stats.setHoldInductances(m.L_d, m.L_q);
  stats.setShapeObserverModel({m.R_s, m.L_d, m.L_q, m.psi_f});
  ASSERT_TRUE(stats.shapeObserverActive());
  double mean_d = 0, mean_q = 0, observed2 = 0, measured2 = 0;
  int n = 0;
  for (const SimulatedSample& x : data) {
    stats.add(x.sample);
    if (x.sample.t < 0.05) continue;
    const auto [i_d, i_q] = stats.observerCurrents();
    const double ed = i_d - x.i_d_true, eq = i_q - x.i_q_true;
    mean_d += ed;
    mean_q += eq;
    observed2 += ed * ed + eq * eq;
    measured2 += std::pow(x.sample.i_d - x.i_d_true, 2) + std::pow(x.sample.i_q - x.i_q_true, 2);
    ++n;
  }
  EXPECT_LT(std::abs(mean_d / n), 0.002);
  EXPECT_LT(std::abs(mean_q / n), 0.002);
  EXPECT_LT(std::sqrt(observed2 / n), 0.25 * std::sqrt(measured2 / n));
}

// On the realistic robot joint the sensors' noise in the inverter error's shape (a slope of about
// 1 ohm at each zero crossing, twelve times R_s) left the d residual twice the noise (doc/results.md
// "Real drives"), and the shapes on the chords between samples (z = T V / (w L) near 1 here) needed
// L_d's stated uncertainty to grow by the zero crossings within a period. With the observer's path
// the d residual is near the noise, no such term is needed, and the data's fit identifies L_d within
// its stated uncertainty.
TEST(RealDriveIdentification, TheShapeFromTheObserverLeavesOnlyTheNoise) {
  const auto data = test_helpers::run(test_helpers::scenario("robot_joint_realistic.yaml"));
  const ParameterVector truth = data.back().truth;
  IdentifierConfig declared = realDriveConfig();
  declared.window.inverter_zero_crossing_current = 0.3;  // declared (this drive's own is 0.5 A)
  IdentifierConfig measured = declared;
  measured.window.inverter_shape_observer_gain = 0.0;
  const Estimate before = identify(samplesOf(data), "wls", measured);
  EXPECT_GT(before.fit.fit_ratio_d, 1.6);
  EXPECT_GT(before.fit.crossing_floor, 0.001);
  for (const char* method : {"wls", "fbdapso"}) {
    const Estimate e = identify(samplesOf(data), method, declared);
    expectConsistentAndRight(e, truth, method);
    EXPECT_LT(e.fit.fit_ratio_d, 1.3) << method;
    EXPECT_EQ(e.fit.crossing_floor, 0.0) << method;
    EXPECT_LE(std::abs(errorPercent(e.parameters[kLd], truth[kLd])), 100 * e.relative_uncertainty[kLd]) << method;
    if (std::string(method) == "wls") {
      EXPECT_TRUE(e.identifiable[kLd]) << e.reason[kLd];
    }
  }
}

// Currents without noise (the 12-bit converter's steps only) and the inverter's own zero-crossing
// width: what is left is how the shapes and the currents are integrated within a period. On the
// chords between the samples L_d read +0.25 % (z = T V / (w L) = 0.83 on the robot joint); along the
// observer's path within 0.1 %.
TEST(RealDriveIdentification, TheObserverPathRemovesTheChordBias) {
  Scenario s = idealSensors(test_helpers::scenario("robot_joint_realistic.yaml"));
  s.sensors.current_noise_sigma = 0.0;
  s.duration = 0.55;
  const auto data = test_helpers::run(s);
  const ParameterVector truth = data.back().truth;
  IdentifierConfig c = realDriveConfig();
  c.window.inverter_zero_crossing_current = s.inverter.zero_crossing_current;
  IdentifierConfig chords = c;
  chords.window.inverter_shape_observer_gain = 0.0;
  const Estimate on_chords = identify(samplesOf(data), "wls", chords);
  EXPECT_GT(errorPercent(on_chords.parameters[kLd], truth[kLd]), 0.15);
  const Estimate on_path = identify(samplesOf(data), "wls", c);
  for (int p = 0; p < kParameterCount; ++p)
    EXPECT_LT(std::abs(errorPercent(on_path.parameters[p], truth[p])), 0.1) << parameterNames()[p];
}

// An inverter whose error changes sign within +-0.05 A, far sharper than the mix of the 0.3 and
// 0.6 A shapes the config fits can represent: L_d reads 4-6 % and L_q 1.1-1.6 % high, so the fit
// must stay poor and nothing may be reported identified outside its stated uncertainty. (A noise
// allowance for the currents' noise in the shapes, tried for the robot joint's d residual, made this
// fit "consistent" with L_q 1.1 % off at a stated +-0.37 %; it was not kept, doc/results.md.)
TEST(RealDriveIdentification, AZeroCrossingSharperThanTheShapeMixIsPoorFit) {
  Scenario s = idealSensors(test_helpers::scenario("robot_joint_realistic.yaml"));
  s.inverter.zero_crossing_current = 0.05;
  s.duration = 1.0;
  const auto data = test_helpers::run(s);
  const ParameterVector truth = data.back().truth;
  for (const char* method : {"fbdapso", "wls"}) {
    const Estimate e = identify(samplesOf(data), method, realDriveConfig());
    EXPECT_FALSE(e.fit.consistent) << method << " d " << e.fit.fit_ratio_d << " q " << e.fit.fit_ratio_q;
    expectIdentifiedWithinStated(e, truth, method);
  }
}

// Phase-current sensor offsets (30 and -24 mA on the robot-joint motor: a current ripple at omega_e
// that no voltage explains): not modelled, the fit is poor; fitted out (current_sensors.offsets:
// estimate), the fit is consistent and every identified value within 1 % (the swarm's fitness and
// the exact fit see the projected statistics; RLS and the EKF do not model the offsets).
TEST(RealDriveIdentification, SensorOffsetsArePoorFitUnlessFittedOut) {
  Scenario s = idealSensors(test_helpers::scenario("robot_joint_realistic.yaml"));
  s.inverter.dead_time = 0.0;
  s.inverter.device_drop = 0.0;
  s.sensors.phase_offset = {0.03, -0.024, 0.0};
  s.duration = 0.55;  // before the reversal: light load and a load step
  const auto data = test_helpers::run(s);
  const ParameterVector truth = data.back().truth;
  IdentifierConfig without = realDriveConfig();
  without.window.sensor_offsets = without.window.sensor_gains = false;
  const Estimate poor = identify(samplesOf(data), "rls", without);
  EXPECT_FALSE(poor.fit.consistent) << "d " << poor.fit.fit_ratio_d << " q " << poor.fit.fit_ratio_q;
  for (int p = 0; p < kParameterCount; ++p) EXPECT_FALSE(poor.identifiable[p]) << poor.reason[p];
  for (const char* method : {"fbdapso", "wls"}) {
    const Estimate e = identify(samplesOf(data), method, realDriveConfig());
    EXPECT_TRUE(e.fit.consistent) << method << " d " << e.fit.fit_ratio_d << " q " << e.fit.fit_ratio_q;
    EXPECT_TRUE(e.identifiable[kLq] && e.identifiable[kPsiF]) << method << " " << e.reason[kLq] << " / " << e.reason[kPsiF];
    for (int p = 0; p < kParameterCount; ++p) {
      if (!e.identifiable[p]) continue;
      EXPECT_LE(std::abs(errorPercent(e.parameters[p], truth[p])), 1.0) << method << " " << parameterNames()[p];
    }
  }
}

// Phase-sensor gain mismatch (1 %: an error at 2 theta times the currents): poor fit unless fitted
// out (current_sensors.gains: estimate), then consistent and every identified value right.
TEST(RealDriveIdentification, SensorGainMismatchIsPoorFitUnlessFittedOut) {
  Scenario s = idealSensors(test_helpers::scenario("robot_joint_realistic.yaml"));
  s.inverter.dead_time = 0.0;
  s.inverter.device_drop = 0.0;
  s.sensors.phase_gain = {1.01, 0.99, 1.0};
  s.duration = 0.55;
  const auto data = test_helpers::run(s);
  const ParameterVector truth = data.back().truth;
  IdentifierConfig without = realDriveConfig();
  without.window.sensor_gains = false;
  const Estimate poor = identify(samplesOf(data), "wls", without);
  EXPECT_FALSE(poor.fit.consistent) << "d " << poor.fit.fit_ratio_d << " q " << poor.fit.fit_ratio_q;
  for (const char* method : {"fbdapso", "wls"}) {
    const Estimate e = identify(samplesOf(data), method, realDriveConfig());
    expectConsistentAndRight(e, truth, method);
  }
}

// A voltage held in the stator frame turns by omega_e T_s per period: undeclared on a fast
// low-inductance motor it is a poor fit; declared, every identified value is right.
TEST(RealDriveIdentification, StationaryHoldUndeclaredIsAPoorFitDeclaredIsRight) {
  Scenario s = test_helpers::scenario("robot_joint.yaml");
  s.speed_reference_rpm = Profile::ramp(0.0, 1000.0, 0.0, 0.05);  // omega_e T_s = 0.073
  s.inverter.stationary_hold = true;
  s.duration = 0.4;
  const auto data = test_helpers::run(s);
  const Estimate undeclared = identify(samplesOf(data), "rls");
  EXPECT_FALSE(undeclared.fit.consistent);
  for (int p = 0; p < kParameterCount; ++p) EXPECT_FALSE(undeclared.identifiable[p]) << undeclared.reason[p];
  IdentifierConfig c;
  c.window.stationary_hold = true;
  for (const char* method : {"fbdapso", "rls"}) {
    const Estimate e = identify(samplesOf(data), method, c);
    EXPECT_TRUE(e.identifiable[kLq]) << method << " " << e.reason[kLq];
    expectIdentifiedWithinStated(e, data.back().truth, method, 1.25);
  }
}

// A voltage held in the stator frame ramps in the rotor frame within each period, so the currents
// bend between samples: R_s times the i_d the trapezoid missed read as L_q 0.7-1.2 % high (at a
// stated +-0.5 %) on the robot joint at light load, 300 rpm, 20 kHz. Corrected, every identified
// value is within its stated uncertainty.
TEST(RealDriveIdentification, TheStationaryHoldsBendingOfTheCurrentsIsCorrected) {
  Scenario s = test_helpers::scenario("robot_joint.yaml");
  s.load_torque = Profile::constant(0.3);  // i_q about 2.4 A: the q signal small against the bending
  s.inverter.stationary_hold = true;
  s.duration = 0.3;
  IdentifierConfig c;
  c.window.stationary_hold = true;
  for (std::uint64_t seed : {1u, 2u}) {
    s.seed = seed;
    const auto data = test_helpers::run(s);
    for (const char* method : {"wls", "fbdapso"}) {
      const Estimate e = identify(samplesOf(data), method, c);
      EXPECT_TRUE(e.identifiable[kLq]) << method << " " << e.reason[kLq];
      expectIdentifiedWithinStated(e, data.back().truth, std::string(method) + " seed " + std::to_string(seed));
    }
  }
}

// The same bending moves the phase currents' zero crossings, where the inverter error's shape
// changes: on the robot joint (35 uH) at a tenth of the realistic noise the d residual was 60 times
// what the noise explains; with the bent currents in the shape integral it is 6-8.
TEST(RealDriveIdentification, TheInverterShapeFollowsTheBentCurrents) {
  Scenario s = idealSensors(test_helpers::scenario("robot_joint_realistic.yaml"));
  s.sensors.current_noise_sigma = 0.005;
  s.sensors.adc_bits = 0;
  s.inverter.computation_delay = 0;
  s.duration = 0.55;
  const auto data = test_helpers::run(s);
  IdentifierConfig c = realDriveConfig();
  c.window.voltage_delay_samples = 0;
  c.window.sensor_offsets = c.window.sensor_gains = false;
  const Estimate e = identify(samplesOf(data), "wls", c);
  EXPECT_LT(e.fit.fit_ratio_d, 15.0);
  EXPECT_NEAR(e.inverter_voltage, data.back().inverter_error_voltage, 0.02 * data.back().inverter_error_voltage);
}

// On the full realistic drives (sensor offsets, gain mismatch, encoder, smooth zero crossings)
// nothing is reported identified more than 2 % from the truth, by any method, with or without the
// real-drive declarations.
TEST(RealDriveIdentification, NoConfidentlyWrongNumberOnTheRealisticScenarios) {
  for (const char* file : {"wc1_realistic.yaml", "robot_joint_realistic.yaml"}) {
    Scenario s = test_helpers::scenario(file);
    s.duration = 0.8;
    const auto data = test_helpers::run(s);
    for (bool declared : {false, true})
      for (const char* method : {"fbdapso", "sapso", "pso", "ekf", "rls"}) {
        const Estimate e = identify(samplesOf(data), method, declared ? realDriveConfig() : IdentifierConfig{});
        for (int p = 0; p < kParameterCount; ++p) {
          if (!e.identifiable[p]) continue;
          EXPECT_LT(std::abs(errorPercent(e.parameters[p], data.back().truth[p])), 2.0)
              << file << " " << method << (declared ? " declared " : " ") << parameterNames()[p];
        }
      }
  }
}

// Along the run, not only at its end (bench's check, every 10 ms): the two cases it found. On
// noise-free data without injection, wls (the data's exact optimum) stated L_d to +-0.2 % after the
// speed ramp while 8-160 % off, because the noise from the block differences is near zero and a
// model error below the fit floor was not counted; on a realistic drive a misfit the fit check
// accepts (3.6 x the noise) left SAPSO's psi_f 2.06 % off at a stated +-0.93 %. The parameters'
// uncertainties now assume at least the residual the fit leaves and the fit floor.
TEST(Assessment, NothingIdentifiedIsWrongAlongTheRun) {
  const auto alongTheRun = [](const std::vector<SimulatedSample>& data, const IdentifierConfig& c, const char* what) {
    auto id = makeIdentifier(c);
    const std::size_t stride = std::max<std::size_t>(1, static_cast<std::size_t>(std::lround(0.01 / (data[1].sample.t - data[0].sample.t))));
    int identified = 0;
    for (std::size_t k = 0; k < data.size(); ++k) {
      id->process(data[k].sample);
      if (k % stride != stride - 1) continue;
      const Estimate e = id->estimate();
      for (int p = 0; p < kParameterCount; ++p) {
        if (!e.identifiable[p]) continue;
        ++identified;
        EXPECT_LT(std::abs(errorPercent(e.parameters[p], data[k].truth[p])), 2.0)
            << what << " " << c.method << " " << parameterNames()[p] << " at t = " << data[k].sample.t;
      }
    }
    return identified;
  };
  IdentifierConfig wls;
  wls.method = "wls";
  EXPECT_GT(alongTheRun(test_helpers::run(test_helpers::scenario("wc1_no_injection.yaml")), wls, "wc1_no_injection"), 0);
  Scenario realistic = test_helpers::scenario("wc1_realistic.yaml");
  realistic.seed = 2;
  IdentifierConfig sapso = realDriveConfig();
  sapso.method = "sapso";
  sapso.seed = 2;
  EXPECT_GT(alongTheRun(test_helpers::run(realistic), sapso, "wc1_realistic"), 0);
}

// wls is the exact minimiser of the block fitness: no method ends below it on the same window,
// and the swarms end close to it.
TEST(Wls, NoMethodEndsBelowTheExactOptimum) {
  const auto data = drive("wc1_drive.yaml", 4);
  const Estimate reference = identify(samplesOf(data), "wls");
  for (int p = 0; p < kParameterCount; ++p) EXPECT_TRUE(reference.identifiable[p]) << reference.reason[p];
  for (const char* method : {"fbdapso", "sapso", "pso", "rls", "ekf"}) {
    const Estimate e = identify(samplesOf(data), method);
    EXPECT_GE(e.fitness, reference.fitness * (1 - 1e-9)) << method;
    if (std::string(method) != "ekf") {
      for (int p = 0; p < kParameterCount; ++p)
        EXPECT_LT(std::abs(errorPercent(e.parameters[p], reference.parameters[p])), 0.5) << method << " " << parameterNames()[p];
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Temperatures from identified parameters (a thermal: block is all the config needs).

TEST(Thermal, WindingAndMagnetTemperaturesFollowRsAndPsiF) {
  const std::string path = test_helpers::writeTemp(
      "thermal.yaml", "thermal:\n  reference_temperature: 20.0\n  R_s_at_reference: 2.875\n  psi_f_at_reference: 0.17858\n");
  const IdentifierConfig c = loadIdentifierConfig(path);
  ASSERT_TRUE(c.thermal.enabled);
  Scenario s = test_helpers::scenario("wc1_drive.yaml");
  s.duration = 0.6;
  s.R_s_scale = Profile::ramp(1.0, 1.2, 0.1, 0.3);      // winding +50.9 K
  s.psi_f_scale = Profile::ramp(1.0, 0.97, 0.1, 0.3);   // magnet +25 K (NdFeB, -0.12 %/K)
  const auto data = test_helpers::run(s);
  for (const char* method : {"fbdapso", "rls"}) {
    const Estimate e = identify(samplesOf(data), method, c);
    ASSERT_TRUE(e.identifiable[kRs]) << e.reason[kRs];
    ASSERT_TRUE(e.identifiable[kPsiF]) << e.reason[kPsiF];
    EXPECT_NEAR(e.winding_temperature.value, 20.0 + 0.2 / 3.93e-3, 3.0) << method;
    EXPECT_NEAR(e.magnet_temperature.value, 20.0 + 0.03 / 1.2e-3, 5.0) << method;
    EXPECT_GT(e.winding_temperature.uncertainty, 0.0);
  }
  // No temperature from a parameter that is not identified: speed in rpm makes every fit poor.
  auto bad = samplesOf(data);
  for (auto& x : bad) x.omega_e *= 60.0 / (2.0 * M_PI) / 4.0;
  const Estimate e = identify(bad, "rls", c);
  EXPECT_TRUE(std::isnan(e.winding_temperature.value));
  EXPECT_TRUE(std::isnan(e.magnet_temperature.value));
}

TEST(Thermal, ReferencesAreLearntAtADeclaredColdStart) {
  const std::string path = test_helpers::writeTemp("cold.yaml", "thermal:\n  reference_temperature: 25.0\n");
  const IdentifierConfig c = loadIdentifierConfig(path);
  EXPECT_EQ(loadError("thermal:\n  reference_temprature: 25\n", false),
            "key 'thermal.reference_temprature': unknown key (did you mean 'thermal.reference_temperature'?)");
  Scenario s = test_helpers::scenario("wc1_drive.yaml");
  s.duration = 0.8;
  s.R_s_scale = Profile::ramp(1.0, 1.1, 0.3, 0.45);  // heats by 25.4 K after the cold start
  const auto data = test_helpers::run(s);
  IdentifierConfig cc = c;
  cc.method = "rls";
  auto id = makeIdentifier(cc);
  for (const auto& d : data) {
    id->process(d.sample);
    if (d.sample.t > 0.25 && d.sample.t < 0.2502) {  // still cold: the learnt references hold
      const Estimate cold = id->estimate();
      EXPECT_NEAR(cold.winding_temperature.value, 25.0, 1.0);
    }
  }
  // Learnt without any estimate asked for before the end (as ./run identify does).
  EXPECT_NEAR(id->estimate().winding_temperature.value, 25.0 + 0.1 / 3.93e-3, 3.0) << id->estimate().reason[kRs];
  auto quiet = makeIdentifier(cc);
  for (const auto& d : data) quiet->process(d.sample);
  EXPECT_NEAR(quiet->estimate().winding_temperature.value, 25.0 + 0.1 / 3.93e-3, 3.0);
  // Nothing is learnt after learning_time: a motor identified late may be hot already, and its
  // temperatures stay unknown instead of being read from a hot reference.
  IdentifierConfig late = cc;
  late.thermal.learning_time = 0.004;  // before the first block is complete
  auto unlearnt = makeIdentifier(late);
  for (const auto& d : data) unlearnt->process(d.sample);
  const Estimate e = unlearnt->estimate();
  EXPECT_TRUE(e.identifiable[kRs]) << e.reason[kRs];
  EXPECT_TRUE(std::isnan(e.winding_temperature.value));
  EXPECT_TRUE(std::isnan(e.magnet_temperature.value));
}

// A node restarted on a hot motor: the references its cold start learnt come back from the thermal
// state file and are not learnt again (the hot values would read as the reference temperature).
TEST(Thermal, ReferencesKeptAcrossARestartGiveAHotMotorsTemperature) {
  const std::string config_path = test_helpers::writeTemp("cold_restart.yaml", "thermal:\n  reference_temperature: 25.0\n");
  IdentifierConfig c = loadIdentifierConfig(config_path);
  c.method = "rls";
  Scenario s = test_helpers::scenario("wc1_drive.yaml");
  s.duration = 1.4;
  s.R_s_scale = Profile::ramp(1.0, 1.1, 0.3, 0.45);  // +25.4 K after the cold start
  const auto data = test_helpers::run(s);
  const auto first = makeIdentifier(c);
  std::vector<Sample> hot;  // what a node started at 0.8 s sees
  for (const auto& d : data) {
    if (d.sample.t < 0.6) first->process(d.sample);
    else if (d.sample.t >= 0.8) hot.push_back(d.sample);
  }
  const LearntReferences learnt = first->learntReferences();
  ASSERT_GT(learnt.R_s, 0.0);
  ASSERT_GT(learnt.psi_f, 0.0);
  EXPECT_NEAR(learnt.R_s, s.motor.R_s, 0.01 * s.motor.R_s);
  EXPECT_GT(learnt.R_s_relative_uncertainty, 0.0);
  EXPECT_TRUE(std::isfinite(learnt.R_s_learnt_at));
  const std::string state = test_helpers::writeTemp("thermal_state.yaml", "");
  writeThermalState(state, learnt, "rls");
  const LearntReferences read = loadThermalStateFor(state, 25.0);
  EXPECT_EQ(read, learnt);
  EXPECT_EQ(read.R_s_learnt_at, learnt.R_s_learnt_at);
  EXPECT_EQ(read.reference_temperature, 25.0);

  const double truth = 25.0 + 0.1 / 3.93e-3;
  const auto restarted = makeIdentifier(c);
  restarted->restoreReferences(read);
  for (const Sample& x : hot) restarted->process(x);
  const Estimate e = restarted->estimate();
  ASSERT_TRUE(std::isfinite(e.winding_temperature.value)) << e.reason[kRs];
  EXPECT_LE(std::abs(e.winding_temperature.value - truth), e.winding_temperature.uncertainty) << e.winding_temperature.value;
  EXPECT_EQ(restarted->learntReferences(), learnt);  // not learnt again
  restarted->reset();                                 // a looping bag: the references stay
  EXPECT_EQ(restarted->learntReferences(), learnt);
  // Without the file the same restart learns the hot motor as cold: 25 K off.
  const auto forgetful = makeIdentifier(c);
  for (const Sample& x : hot) forgetful->process(x);
  EXPECT_GT(std::abs(forgetful->estimate().winding_temperature.value - truth), 20.0);
}

TEST(Thermal, AStateFileFromAnotherReferenceTemperatureOrWithAnUnknownKeyIsRefused) {
  const std::string state = test_helpers::writeTemp("state_other.yaml", "reference_temperature: 20\nR_s_at_reference: 2.9\n");
  try {
    loadThermalStateFor(state, 25.0);
    FAIL() << "accepted";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()), state + ": learnt at reference_temperature 20 degC, the config says 25 degC "
                                             "(delete the file to learn anew at a cold start)");
  }
  EXPECT_FALSE(loadThermalStateFor(state + ".absent", 25.0).any());  // a first cold start
  const std::string typo = test_helpers::writeTemp("state_typo.yaml", "reference_temperature: 20\nR_s_at_referense: 2.9\n");
  EXPECT_THROW(readThermalState(typo), ConfigError);
  IdentifierConfig no_thermal;
  auto id = makeIdentifier(no_thermal);
  EXPECT_THROW(id->restoreReferences(readThermalState(state)), ConfigError);
}

TEST(MotorConstants, TorqueAndSpeedConstantsFollowPsiFWithThePolePairs) {
  const auto data = test_helpers::run(test_helpers::scenario("wc1_drive.yaml"));
  IdentifierConfig c;
  const Estimate unknown = identify(samplesOf(data), "rls", c);
  ASSERT_TRUE(unknown.identifiable[kPsiF]) << unknown.reason[kPsiF];
  EXPECT_TRUE(std::isnan(unknown.torque_constant));  // no pole pairs given
  c.pole_pairs = 4;
  const Estimate e = identify(samplesOf(data), "rls", c);
  EXPECT_NEAR(e.torque_constant, 1.5 * 4 * 0.17858, 0.01 * 1.5 * 4 * 0.17858);
  EXPECT_NEAR(e.speed_constant, 60.0 / (2 * M_PI * std::sqrt(3.0) * 4 * 0.17858), 0.01 * e.speed_constant);
  EXPECT_GT(e.motor_constant_relative_uncertainty, 0.0);
  EXPECT_EQ(loadError("motor:\n  pole_pairs: -1\n", false), "key 'motor.pole_pairs': must be an integer in [0, 1000], got -1");
}

// ---------------------------------------------------------------------------------------------
// Condition monitoring (alarms) on the estimates.

namespace {
// Feeds a run to an identifier with the thermal references of the paper's motor at 20 degC and a
// monitor that sees an estimate every millisecond; returns the events.
std::vector<AlarmEvent> monitorRun(const std::vector<SimulatedSample>& data, const std::string& method, std::uint64_t seed,
                                   bool with_temperatures = true) {
  IdentifierConfig c;
  c.method = method;
  c.seed = seed;
  c.thermal.enabled = with_temperatures;
  c.thermal.reference_temperature = 20.0;
  c.thermal.R_s_at_reference = 2.875;
  c.thermal.psi_f_at_reference = 0.17858;
  auto id = makeIdentifier(c);
  ConditionMonitor monitor;
  std::vector<AlarmEvent> events;
  for (std::size_t k = 0; k < data.size(); ++k) {
    id->process(data[k].sample);
    if (k % 10 == 9)
      for (const AlarmEvent& ev : monitor.update(id->estimate())) events.push_back(ev);
  }
  return events;
}
}  // namespace

TEST(Monitor, FivePercentDemagnetisationIsAlarmedWithinHalfASecondAndAHealthyRunRaisesNothing) {
  for (std::uint64_t seed = 1; seed <= 10; ++seed) {
    Scenario s = test_helpers::scenario("wc1_drive.yaml");
    s.seed = seed;
    s.duration = 0.9;
    const auto healthy = test_helpers::run(s);
    for (const AlarmEvent& ev : monitorRun(healthy, "rls", seed))
      ADD_FAILURE() << "healthy seed " << seed << ": " << toString(ev.kind) << " " << ev.text;
    s.psi_f_scale = Profile::step(1.0, 0.95, 0.4);  // 5 % of the magnetisation lost at 0.4 s
    const auto demag = test_helpers::run(s);
    double alarm_at = -1.0;
    for (const AlarmEvent& ev : monitorRun(demag, "rls", seed)) {
      if (ev.kind == AlarmKind::Demagnetisation && ev.raised && alarm_at < 0) alarm_at = ev.t;
      EXPECT_TRUE(ev.kind == AlarmKind::Demagnetisation || !ev.raised) << toString(ev.kind) << " " << ev.text;
    }
    EXPECT_GE(alarm_at, 0.4) << "seed " << seed;
    EXPECT_LE(alarm_at, 0.9) << "seed " << seed;
    EXPECT_LE(alarm_at - 0.4, 0.5) << "seed " << seed;
  }
}

// Without a thermal: block there are no temperatures: the fall of psi_f alone, faster than any
// heating, raises the alarm; it stays raised while psi_f stays low.
TEST(Monitor, DemagnetisationIsAlarmedFromTheFallOfPsiFWithoutTemperatures) {
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    Scenario s = test_helpers::scenario("wc1_drive.yaml");
    s.seed = seed;
    s.duration = 1.2;
    s.psi_f_scale = Profile::step(1.0, 0.95, 0.4);
    double raised_at = -1.0;
    bool cleared = false;
    for (const AlarmEvent& ev : monitorRun(test_helpers::run(s), "fbdapso", seed, false)) {
      if (ev.kind != AlarmKind::Demagnetisation) {
        ADD_FAILURE() << "seed " << seed << ": " << toString(ev.kind) << " " << ev.text;
        continue;
      }
      if (ev.raised && raised_at < 0) {
        raised_at = ev.t;
        EXPECT_NE(ev.text.find("psi_f fell by"), std::string::npos) << ev.text;
      }
      cleared = cleared || !ev.raised;
    }
    EXPECT_GE(raised_at, 0.4) << "seed " << seed;
    EXPECT_LE(raised_at, 0.9) << "seed " << seed;
    EXPECT_FALSE(cleared) << "seed " << seed << ": the magnetisation did not come back";
  }
}

// An inter-turn short, approximated as the issue does by steps of R_s and L (fewer effective turns:
// R down by the shorted fraction, L by about twice it): a jump alarm naming the parameter, and no
// demagnetisation alarm (psi_f did not move).
TEST(Monitor, InterTurnFaultStepsRaiseAJumpAndNothingElse) {
  Scenario s = test_helpers::scenario("wc1_drive.yaml");
  s.duration = 1.2;
  s.R_s_scale = Profile::step(1.0, 0.92, 0.4);
  s.L_d_scale = Profile::step(1.0, 0.85, 0.4);
  s.L_q_scale = Profile::step(1.0, 0.85, 0.4);
  const auto data = test_helpers::run(s);
  EXPECT_NEAR(data.back().truth[kLd], 0.85 * s.motor.L_d, 1e-12);
  double jump_at = -1.0;
  for (const AlarmEvent& ev : monitorRun(data, "fbdapso", 1)) {
    EXPECT_NE(ev.kind, AlarmKind::Demagnetisation) << ev.text;
    EXPECT_NE(ev.kind, AlarmKind::WindingOverTemperature) << ev.text;
    if (ev.kind == AlarmKind::ParameterJump && ev.raised && jump_at < 0) {
      jump_at = ev.t;
      // a fall of R_s (-8 %) or of an inductance (-15 %), named
      EXPECT_TRUE(ev.text.rfind("R_s changed by -", 0) == 0 || ev.text.rfind("L_d changed by -", 0) == 0 ||
                  ev.text.rfind("L_q changed by -", 0) == 0)
          << ev.text;
    }
  }
  // Measured 0.556 s after the step: the exponentially forgotten window holds the 15 % inconsistency
  // of the old blocks for about ten time constants before the fit is consistent again.
  EXPECT_GE(jump_at, 0.4);
  EXPECT_LE(jump_at, 1.0);
  // The plant followed the new inductances: the identifier finds them after the step.
  const Estimate e = identify(samplesOf(data), "wls", IdentifierConfig{});
  EXPECT_TRUE(e.identifiable[kLd] && e.identifiable[kLq]) << e.reason[kLd] << " / " << e.reason[kLq];
  EXPECT_NEAR(e.parameters[kLd] / (0.85 * s.motor.L_d), 1.0, 0.01);
  EXPECT_NEAR(e.parameters[kLq] / (0.85 * s.motor.L_q), 1.0, 0.01);
}

// A saturating machine declared so (magnetics.cross_saturation): L_q falls by tens of per cent
// from light load to rated by design, and the load steps raise nothing; a real 10 % step of the
// inductances while the load stays in one cell still raises a jump. Without the cell rule the load
// steps themselves were reported as jumps (+19 % L_q).
TEST(Monitor, OnASaturatingMachineLoadStepsAreNotJumpsButAFaultIs) {
  Scenario s = test_helpers::scenario("saturated_map.yaml");
  s.duration = 3.0;  // 2, 4, 6 A
  IdentifierConfig c = loadIdentifierConfig(test_helpers::sourcePath("config/identifiers/saturating_machine.yaml"));
  c.method = "wls";
  const auto events = [&](const std::vector<SimulatedSample>& data, ConditionMonitor monitor) {
    auto id = makeIdentifier(c);
    std::vector<AlarmEvent> out;
    for (std::size_t k = 0; k < data.size(); ++k) {
      id->process(data[k].sample);
      if (k % 10 == 9)
        for (const AlarmEvent& ev : monitor.update(id->estimate())) out.push_back(ev);
    }
    return out;
  };
  const auto healthy = test_helpers::run(s);
  for (const AlarmEvent& ev : events(healthy, ConditionMonitor::forConfig(c)))
    ADD_FAILURE() << toString(ev.kind) << (ev.raised ? " raised: " : " cleared: ") << ev.text;
  bool across = false;  // the same data without the cell rule: the load steps look like jumps
  for (const AlarmEvent& ev : events(healthy, ConditionMonitor(c.alarms))) across = across || ev.kind == AlarmKind::ParameterJump;
  EXPECT_TRUE(across);
  s.L_d_scale = Profile::step(1.0, 0.9, 2.5);  // in the middle of the 6 A level
  s.L_q_scale = Profile::step(1.0, 0.9, 2.5);
  double jump_at = -1.0;
  for (const AlarmEvent& ev : events(test_helpers::run(s), ConditionMonitor::forConfig(c)))
    if (ev.kind == AlarmKind::ParameterJump && ev.raised && jump_at < 0) jump_at = ev.t;
  EXPECT_GE(jump_at, 2.5);
  EXPECT_LE(jump_at, 3.0);
}

namespace {
// Every parameter identified to 0.1 % at one operating point: the monitor's input, made by hand.
Estimate healthyIdentifiedEstimate() {
  Estimate e;
  e.status.fill(ParameterStatus::Identified);
  e.identifiable.fill(true);
  e.relative_uncertainty.fill(0.001);
  e.operating_point = {0.0, 5.0, 400.0, 0.1, 0.01};
  e.parameters = {1.0, 0.004, 0.012, 0.17};
  return e;
}
}  // namespace

TEST(Monitor, APsiFFallAcrossAGapInItsIdentifiedValuesIsJudgedByItsRate) {
  // psi_f identified until 1 s, not identified for 1.1 s (a method following a step), then 4 %
  // lower: 3.6 %/s, faster than heat allows. The same 4 % spread over 4 s (1 %/s) raises nothing.
  const auto run = [](double gap_end) {
    ConditionMonitor monitor;
    Estimate e = healthyIdentifiedEstimate();
    bool raised = false;
    for (int k = 0; k <= 600; ++k) {
      e.t = 0.01 * k;
      e.identifiable[kPsiF] = e.t <= 1.0 || e.t >= gap_end;
      if (e.t >= gap_end) e.parameters[kPsiF] = 0.17 * 0.96;
      for (const AlarmEvent& ev : monitor.update(e)) raised = raised || (ev.kind == AlarmKind::Demagnetisation && ev.raised);
    }
    return raised;
  };
  EXPECT_TRUE(run(2.1));
  EXPECT_FALSE(run(5.0));
}

TEST(Monitor, AStreamThatRestartsClearsItsAlarmsAndIsNotComparedWithTheOldOne) {
  // A looping bag: stamps go back to the start. Alarms raised by the first pass clear with a reason,
  // and the second pass's values are not compared with the first's (R_s 50 % higher after the
  // restart is no jump); the map starts again too.
  ConditionMonitor monitor;
  MotorMap map;
  Estimate e = healthyIdentifiedEstimate();
  e.winding_temperature = {200.0, 1.0};  // above the 155 degC limit
  bool raised = false;
  for (int k = 0; k <= 100; ++k) {
    e.t = 0.01 * k;
    for (const AlarmEvent& ev : monitor.update(e)) raised = raised || (ev.kind == AlarmKind::WindingOverTemperature && ev.raised);
    map.add(e);
  }
  ASSERT_TRUE(raised);
  ASSERT_TRUE(monitor.active(AlarmKind::WindingOverTemperature));
  e.operating_point = {0.0, 9.0, 400.0, 0.1, 0.01};  // another operating point after the restart
  e.parameters = {1.5, 0.004, 0.012, 0.17};
  e.winding_temperature = {40.0, 1.0};
  std::vector<AlarmEvent> events;
  for (int k = 0; k <= 100; ++k) {
    e.t = 0.01 * k;
    for (const AlarmEvent& ev : monitor.update(e)) events.push_back(ev);
    map.add(e);
  }
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.front().kind, AlarmKind::WindingOverTemperature);
  EXPECT_FALSE(events.front().raised);
  EXPECT_NE(events.front().text.find("the stream restarted"), std::string::npos) << events.front().text;
  for (const AlarmEvent& ev : events) EXPECT_FALSE(ev.raised) << toString(ev.kind) << ": " << ev.text;
  EXPECT_FALSE(monitor.active(AlarmKind::ParameterJump));
  ASSERT_EQ(map.cells().size(), 1u);  // only the second pass's operating point
  EXPECT_NEAR(map.cells()[0].i_q, 9.0, 1e-12);
}

TEST(Monitor, WindingOverTemperatureAndAJumpInResistance) {
  Scenario s = test_helpers::scenario("wc1_drive.yaml");
  s.duration = 1.2;
  s.R_s_scale = Profile::step(1.0, 1.55, 0.4);  // +55 %: 20 + 140 = 160 degC, and a sudden jump
  const auto data = test_helpers::run(s);
  bool over = false, jump = false;
  for (const AlarmEvent& ev : monitorRun(data, "rls", 1)) {
    over = over || (ev.kind == AlarmKind::WindingOverTemperature && ev.raised);
    jump = jump || (ev.kind == AlarmKind::ParameterJump && ev.raised);
  }
  EXPECT_TRUE(over);
  EXPECT_TRUE(jump);
}

// The identifier's temperatures against the simulator's thermal model (time constants shortened so
// that the motor heats within a test): the winding within 3 K, the magnet within 5 K, at the end.
TEST(Thermal, TemperaturesFollowTheSimulatorsThermalModel) {
  Scenario s = test_helpers::scenario("wc1_drive.yaml");
  s.duration = 1.5;
  s.thermal.enabled = true;
  s.thermal.winding_capacity = 3.0;   // tau_w about 0.5 s; about 350 W of copper loss: about +60 K
  s.thermal.winding_to_ambient = 0.17;
  s.thermal.winding_to_magnet = 5.0;
  s.thermal.magnet_capacity = 2.0;    // tau_m about 3 s
  s.thermal.magnet_to_ambient = 1.5;
  s.thermal.magnet_loss_coefficient = 2e-3;  // 22 W at 1000 rpm
  const auto data = test_helpers::run(s);
  IdentifierConfig c;
  c.thermal.enabled = true;
  c.thermal.reference_temperature = 20.0;
  c.thermal.R_s_at_reference = s.motor.R_s;
  c.thermal.psi_f_at_reference = s.motor.psi_f;
  for (const char* method : {"fbdapso", "rls"}) {
    const Estimate e = identify(samplesOf(data), method, c);
    EXPECT_GT(data.back().winding_temperature, 40.0);  // it did heat up
    EXPECT_NEAR(e.winding_temperature.value, data.back().winding_temperature, 3.0) << method << " " << e.reason[kRs];
    EXPECT_NEAR(e.magnet_temperature.value, data.back().magnet_temperature, 5.0) << method << " " << e.reason[kPsiF];
  }
}

namespace {
// A monitoring scenario of the switching-level drive cut to `duration`, RLS with cold_start.yaml
// ready to run over it, and the stride of an estimate every 10 ms.
struct ColdStartRun {
  std::vector<SimulatedSample> data;
  std::unique_ptr<OnlineIdentifier> id;
  std::size_t stride = 1;
};
ColdStartRun coldStartRun(const char* scenario, double duration, const char* method = "rls", std::uint64_t seed = 1) {
  Scenario s = test_helpers::scenario(scenario);
  s.duration = duration;
  s.seed = seed;
  IdentifierConfig c = loadIdentifierConfig(test_helpers::sourcePath("config/identifiers/cold_start.yaml"));
  c.method = method;
  c.seed = seed;
  return {test_helpers::run(s), makeIdentifier(c), static_cast<std::size_t>(std::lround(0.01 / s.drive.sample_period))};
}
}  // namespace

// The slow window on the switching-level industrial drive with nothing declared but a cold start:
// the first 30 s of the duty cycle (a load step at 20 s heats the winding by about 15 K). Across
// the step the slow window separates R_s from the inverter's error voltage, with the winding's
// rate and heating fitted beside them: its R_s is identified, within what it states (fitted
// without the heating, 43 of seed 1's slow R_s lay outside, 0.51 % off at a stated 0.47 %).
TEST(SlowWindow, WindingTemperatureBehindASwitchingInverterLiesWithinItsStatedUncertainty) {
  const ColdStartRun run = coldStartRun("real_drive_duty_cycle.yaml", 30.0);
  const auto& data = run.data;
  const auto& id = run.id;
  const std::size_t stride = run.stride;
  int estimates = 0, reported = 0, outside = 0, slow_rs_identified = 0, slow_rs_outside = 0;
  double worst = 0.0;
  for (std::size_t k = 0; k < data.size(); ++k) {
    id->process(data[k].sample);
    if (k % stride != stride - 1 || data[k].sample.t < 5.0) continue;
    const Estimate e = id->estimate();
    ++estimates;
    if (e.slow.identifiable[kRs]) {
      ++slow_rs_identified;
      const double error = std::abs(e.slow.parameters[kRs] / data[k].truth[kRs] - 1.0);
      slow_rs_outside += !(error <= e.slow.relative_uncertainty[kRs]);
      EXPECT_TRUE(e.identifiable[kRs]);  // the estimate's R_s is the slow window's where only it identifies it
    }
    if (!std::isfinite(e.winding_temperature.value)) continue;
    ++reported;
    const double error = std::abs(e.winding_temperature.value - data[k].winding_temperature);
    worst = std::max(worst, error);
    outside += !(error <= e.winding_temperature.uncertainty);
  }
  EXPECT_GT(data.back().winding_temperature, 30.0);  // it did heat
  EXPECT_GE(reported, estimates / 4) << reported << " of " << estimates;
  EXPECT_LE(outside, reported / 20) << outside << " of " << reported << " outside; worst " << worst << " K";
  EXPECT_LT(worst, 6.0);
  EXPECT_GT(slow_rs_identified, 0) << slow_rs_identified << " of " << estimates;  // 19 of 2 500: the window after the step
  EXPECT_EQ(slow_rs_outside, 0) << slow_rs_outside << " of " << slow_rs_identified;
}

// The slow window's rate and heat entries, each snapshot's blocks at its time and copper-loss clock
// (BlockStatistics moves their reference to the newest snapshot): an ideal drive whose R_s climbs
// 10 % per second. The fit with R_s's rate and heating states R_s at the newest snapshot; without
// them the window's exponential average trails it (by about its time constant times the rate).
TEST(SlowWindow, TheRateEntriesStateTheResistanceAtTheNewestSnapshot) {
  Scenario s = test_helpers::scenario("rs_drift.yaml");
  s.R_s_scale = Profile::ramp(1.0, 1.2, 0.0, 2.0);
  s.duration = 1.6;
  const auto data = test_helpers::run(s);
  BlockStatistics stats;
  stats.configure(s.drive.sample_period);
  for (const auto& x : data) stats.add(x.sample);
  WindowSums w = stats.slowWindow();
  ASSERT_TRUE(w.hasBlocks());
  const double t_ref = stats.slowWindowTime();
  EXPECT_NEAR(t_ref, data.back().sample.t, 2.0 * stats.blockDuration());
  EXPECT_GT(stats.slowWindowHeat(), 0.0);
  const double truth = s.motor.R_s * s.R_s_scale(t_ref), rate = 0.1 * s.motor.R_s;  // [ohm], [ohm/s]
  Eigen::VectorXd start = Eigen::VectorXd::Zero(6);
  start << s.motor.R_s, s.motor.L_d, s.motor.L_q, s.motor.psi_f, 0.0, 0.0;
  const BlockFit with_rate = BlockLeastSquares::fit(w, LinearBlockModel::withResistanceRate(LinearBlockModel::paper()), start);
  const BlockFit without = BlockLeastSquares::fit(w, LinearBlockModel::paper(), start.head(4));
  ASSERT_TRUE(with_rate.ok && without.ok);
  EXPECT_NEAR(with_rate.beta(kRs) / truth, 1.0, 0.002) << with_rate.beta(kRs) << " against " << truth;
  EXPECT_LT(without.beta(kRs) / truth, 0.95) << without.beta(kRs);  // trails by about tau x the rate
  // The rate at the window's mean copper loss: rho + kappa (i_d^2 + i_q^2).
  double i2 = 0.0;
  int n = 0;
  for (const auto& x : data)
    if (x.sample.t > data.back().sample.t - 1.0) {
      i2 += x.sample.i_d * x.sample.i_d + x.sample.i_q * x.sample.i_q;
      ++n;
    }
  EXPECT_NEAR((with_rate.beta(4) + with_rate.beta(5) * i2 / n) / rate, 1.0, 0.05)
      << "rho " << with_rate.beta(4) << " kappa " << with_rate.beta(5) << " i^2 " << i2 / n;
}

// The slow window behind an inverter, its history too short for its lag: R_s's reason names the
// inverter, which waiting does not change, and psi_f's the lag, which it does.
TEST(SlowWindow, BehindAnInverterTheResistancesReasonNamesTheInverterBeforeTheLag) {
  SlowFit fit;
  fit.available = fit.consistent = true;
  fit.fit_ratio_d = fit.fit_ratio_q = 1.0;
  fit.window_time_constant = 1.0;
  fit.optimum = {3.6, 0.036, 0.051, 0.55};
  fit.determined.fill(true);
  fit.relative_std.fill(0.0015);
  fit.relative_std_known_inverter = fit.relative_std;
  fit.inverter_modelled = true;
  fit.inverter_voltage = 12.3;
  fit.inverter_relative_std = 0.01;
  const AssessmentSettings a;
  ParameterVector unknown;
  unknown.fill(std::numeric_limits<double>::quiet_NaN());
  const SlowAssessment slow = assessSlow(fit, a, unknown);
  EXPECT_EQ(slow.status[kRs], ParameterStatus::NotExcited);
  EXPECT_NE(slow.reason[kRs].find("not identified behind an inverter"), std::string::npos) << slow.reason[kRs];
  // What holds it and what would separate them: the winding's temperature turned by a load change.
  EXPECT_NE(slow.reason[kRs].find("a load change also turns the winding's temperature"), std::string::npos) << slow.reason[kRs];
  EXPECT_NE(slow.reason[kRs].find("from a thermal model of the winding, would separate them"), std::string::npos)
      << slow.reason[kRs];
  EXPECT_NE(slow.reason[kRs].find("+-0.45 % statistical (how far it trails a changing value not yet known)"), std::string::npos)
      << slow.reason[kRs];
  EXPECT_EQ(slow.status[kPsiF], ParameterStatus::NotExcited);
  EXPECT_NE(slow.reason[kPsiF].find("how far it trails a changing value is not known"), std::string::npos) << slow.reason[kPsiF];
  // With the lag known and small, psi_f is identified; R_s still is not, with its stated value.
  ParameterVector none{};
  const SlowAssessment known = assessSlow(fit, a, none);
  EXPECT_EQ(known.status[kPsiF], ParameterStatus::Identified) << known.reason[kPsiF];
  EXPECT_EQ(known.status[kRs], ParameterStatus::NotExcited);
  EXPECT_EQ(known.reason[kRs].rfind("+-0.45 % across the current magnitudes", 0), 0u) << known.reason[kRs];
  // A fit that carries R_s's rate and heating states R_s at its newest snapshot: identified where
  // it determines V itself, not where it holds V from another window.
  fit.rate_modelled = true;
  const SlowAssessment with_rate = assessSlow(fit, a, none);
  EXPECT_EQ(with_rate.status[kRs], ParameterStatus::Identified) << with_rate.reason[kRs];
  EXPECT_NEAR(with_rate.relative_uncertainty[kRs], 0.0045, 1e-9);
  fit.inverter_held = true;
  const SlowAssessment held = assessSlow(fit, a, none);
  EXPECT_EQ(held.status[kRs], ParameterStatus::NotExcited);
  EXPECT_NE(held.reason[kRs].find("not identified behind an inverter with that voltage held"), std::string::npos)
      << held.reason[kRs];
  EXPECT_NE(held.reason[kRs].find("a load change within the slow window separates them"), std::string::npos)
      << held.reason[kRs];
}

// A 4 % psi_f fall within 0.2 s: the slow psi_f trails it and must not be identified meanwhile.
TEST(SlowWindow, APsiFFallIsNotReportedIdentifiedByTheLaggingSlowWindow) {
  const ColdStartRun run = coldStartRun("real_drive_demagnetisation.yaml", 18.5);
  const auto& data = run.data;
  const auto& id = run.id;
  const std::size_t stride = run.stride;
  int identified_after = 0, wrong = 0, outside_late = 0;
  for (std::size_t k = 0; k < data.size(); ++k) {
    id->process(data[k].sample);
    if (k % stride != stride - 1 || data[k].sample.t < 13.0) continue;
    const Estimate e = id->estimate();
    if (!e.slow.identifiable[kPsiF]) continue;
    identified_after += data[k].sample.t > 14.5;
    const double error = std::abs(e.slow.parameters[kPsiF] / data[k].truth[kPsiF] - 1.0);
    wrong += error > 0.02;
    // Within the fitness window's time constant (50 ms) of the onset nothing in the data shows the
    // fall yet (measured: 0.3-0.7 % off at a stated 0.21 % at 14.01-14.03 s); later, never.
    outside_late += error > e.slow.relative_uncertainty[kPsiF] && data[k].sample.t > 14.05;
  }
  EXPECT_EQ(wrong, 0);
  EXPECT_EQ(outside_late, 0);
  EXPECT_GT(identified_after, 0);  // and it comes back once the window holds the new value
}

// A swarm that followed a transient onto a face of its box: during a 4 % psi_f fall behind the
// switching inverter the data's optimum R_s passed below zero while the fit was poor, FBDAPSO's R_s
// went to the box's lower face with psi_f 7 % high to compensate, and stayed there for 1.3 s after the
// fit had settled (seed 2), along a ridge the cycles' velocity kicks do not climb; the
// demagnetisation was raised 1.365 s after the fall. A best on a face the data's determined optimum
// lies well inside starts the swarm again: psi_f identified within 0.7 s of the fall (0.61 s: the
// fit must then hold consistent for two window time constants behind the shape's observer before
// anything is identified), the alarm within 1 s.
TEST(Swarm, ASwarmHeldOnAFaceTheDataLeftStartsAgain) {
  const ColdStartRun run = coldStartRun("real_drive_demagnetisation.yaml", 15.5, "fbdapso", 2);
  const auto& data = run.data;
  const auto& id = run.id;
  const double fall = 14.03;
  ConditionMonitor monitor = ConditionMonitor::forConfig(loadIdentifierConfig(test_helpers::sourcePath("config/identifiers/cold_start.yaml")));
  double identified_at = -1.0, raised_at = -1.0;
  for (std::size_t k = 0; k < data.size(); ++k) {
    id->process(data[k].sample);
    if (k % run.stride != run.stride - 1) continue;
    const Estimate e = id->estimate();  // every 10 ms, as the bench and the node ask
    for (const AlarmEvent& ev : monitor.update(e))
      if (ev.kind == AlarmKind::Demagnetisation && ev.raised && raised_at < 0) raised_at = ev.t;
    const bool right = e.identifiable[kPsiF] && std::abs(e.parameters[kPsiF] / data[k].truth[kPsiF] - 1.0) < 0.01;
    if (data[k].sample.t > fall + 0.25 && right && identified_at < 0) identified_at = data[k].sample.t;
  }
  EXPECT_GT(identified_at, fall);
  EXPECT_LT(identified_at - fall, 0.7) << "psi_f identified again at " << identified_at << " s";
  EXPECT_GT(raised_at, fall);
  EXPECT_LT(raised_at - fall, 1.0) << "demagnetisation raised at " << raised_at << " s";
}

// The drive's angle prediction, which no log records (doc/algorithm.md section 8). The paper's
// motor behind the average inverter model with ideal sensors, the voltage computed at t_k acting
// on [t_k+1, t_k+2), turned at theta_k + k_p omega_e T_s; the window holds the load step at 0.55 s.
namespace {
std::vector<SimulatedSample> predictedAngleRun(double k_p, double until = 0.575) {
  Scenario s = idealSensors(test_helpers::scenario("wc1_realistic.yaml"));
  s.sensors.phase_currents = false;
  s.sensors.current_noise_sigma = 0.01;
  s.sensors.adc_bits = 0;
  s.inverter.angle_prediction = k_p;
  s.duration = until;
  return test_helpers::run(s);
}
IdentifierConfig angleEstimated() {
  return loadIdentifierConfig(test_helpers::sourcePath("config/identifiers/real_drive.yaml"));
}
}  // namespace

TEST(VoltageAngle, TheDataFindEachAnglePrediction) {
  for (double k_p : {0.0, 0.5, 1.0, 1.5}) {
    const auto data = predictedAngleRun(k_p);
    const Estimate e = identify(samplesOf(data), "wls", angleEstimated());
    ASSERT_TRUE(e.fit.voltage_angle_modelled);
    // real_drive.yaml's delay and hold carry k_p = 1 themselves: the data's angle is the rest.
    EXPECT_NEAR(e.fit.voltage_angle, k_p - 1.0, 0.1) << "k_p = " << k_p << " +- " << e.fit.voltage_angle_std;
    EXPECT_TRUE(e.fit.consistent) << "k_p = " << k_p << " " << e.fit.likely_cause;
    EXPECT_TRUE(e.identifiable[kLq]) << "k_p = " << k_p << " " << e.reason[kLq];
    expectIdentifiedWithinStated(e, data.back().truth, "k_p = " + std::to_string(k_p));
  }
}

TEST(VoltageAngle, AtOneSteadyOperatingPointLqIsNotSeparableFromTheTiming) {
  // The switching-level industrial drive (k_p = 1.5) at one operating point: with the angle free,
  // L_q is not identified, and the reason names the timing and what would separate them.
  // The log starts after the start-up (whose speed change the long window would keep: it
  // determines the angle, a constant of the drive).
  const auto run = test_helpers::run(test_helpers::scenario("industrial_pwm_steady.yaml"));
  std::vector<SimulatedSample> data;
  for (const auto& x : run)
    if (x.sample.t >= 0.3) data.push_back(x);
  for (const char* method : {"wls", "fbdapso"}) {
    const Estimate e = identify(samplesOf(data), method, angleEstimated());
    EXPECT_FALSE(e.identifiable[kLq]) << method;
    EXPECT_NE(e.reason[kLq].find("cannot be told from the angle at which the inverter applies the voltage"), std::string::npos)
        << method << ": " << e.reason[kLq];
    EXPECT_NE(e.reason[kLq].find("a load step or a speed change"), std::string::npos) << e.reason[kLq];
    expectIdentifiedWithinStated(e, data.back().truth, method);
  }
}

TEST(VoltageAngle, TheLongWindowsStepsAndSpeedChangeGiveTheAngleAndWithItLq) {
  // The switching-level industrial drive with nothing declared, whose final fitness window holds
  // one load step: there L_q and the drive's angle are nearly collinear. The long window's load
  // steps and speed change (its differences) and the fitness window's constants, fitted together,
  // give the angle; with it FBDAPSO's L_q is identified, within what it states (with the fitness
  // window's angle alone, the bench's seeds 1 and 3 stated +-1.02 % and +-1.01 %: not identified).
  for (std::uint64_t seed : {1u, 2u, 3u}) {
    Scenario s = test_helpers::scenario("industrial_pwm.yaml");
    s.seed = seed;
    const auto data = test_helpers::run(s);
    const Estimate e = identify(samplesOf(data), "fbdapso", IdentifierConfig{});
    const std::string label = "seed " + std::to_string(seed);
    ASSERT_TRUE(e.fit.voltage_angle_modelled) << label << " " << e.drive_model;
    EXPECT_TRUE(e.fit.voltage_angle_from_long_window) << label;
    EXPECT_NEAR(e.fit.voltage_angle, 0.5, 3.0 * e.fit.voltage_angle_std + 0.05) << label;  // k_p 1.5 against the delay's 1
    EXPECT_TRUE(e.identifiable[kLq]) << label << " " << e.reason[kLq];
    expectIdentifiedWithinStated(e, data.back().truth, label);
    // R_s: the fitness window's 50 ms at one current magnitude leave it and the inverter's error
    // voltage +-5 % apart (its reason names the voltage's share and what separates them); the slow
    // window's second, across the load steps, with the winding's rate and heating, identifies it
    // (seeds 1 and 3). In seed 2 the last slow fit holds V from an earlier window: not identified.
    EXPECT_NE(e.reason[kRs].find("from the inverter's error voltage"), std::string::npos) << label << " " << e.reason[kRs];
    EXPECT_NE(e.reason[kRs].find("current magnitudes further apart"), std::string::npos) << e.reason[kRs];
    if (seed == 2) {
      EXPECT_FALSE(e.identifiable[kRs]) << label << " " << e.reason[kRs];
      EXPECT_NE(e.slow.reason[kRs].find("not identified behind an inverter with that voltage held"), std::string::npos)
          << e.slow.reason[kRs];
      continue;
    }
    EXPECT_TRUE(e.identifiable[kRs]) << label << " " << e.reason[kRs];
    EXPECT_TRUE(e.from_slow_window[kRs]) << label;
    EXPECT_EQ(e.parameters[kRs], e.slow.parameters[kRs]) << label;
    EXPECT_NE(e.reason[kRs].find("from the slow window (1 s); the fitness window's: not_excited"), std::string::npos)
        << label << " " << e.reason[kRs];
  }
}

TEST(VoltageAngle, AContradictedDeclarationIsAPoorFitAndARightOneIsIdentified) {
  const auto data = predictedAngleRun(1.5);
  IdentifierConfig declared_own = angleEstimated();  // the delay's own k_p = 1, not estimated
  declared_own.window.estimate_voltage_angle = false;
  const Estimate wrong = identify(samplesOf(data), "wls", declared_own);
  EXPECT_FALSE(wrong.fit.consistent);
  EXPECT_NE(wrong.fit.likely_cause.find("against the declared timing"), std::string::npos)
      << wrong.fit.likely_cause << " d " << wrong.fit.fit_ratio_d << " q " << wrong.fit.fit_ratio_q;
  for (int p = 0; p < kParameterCount; ++p) EXPECT_FALSE(wrong.identifiable[p]) << parameterNames()[p];
  IdentifierConfig declared_right = declared_own;  // time.angle_prediction: 1.5
  declared_right.window.declared_voltage_angle = 0.5;
  const Estimate right = identify(samplesOf(data), "wls", declared_right);
  EXPECT_TRUE(right.fit.consistent) << right.fit.likely_cause;
  EXPECT_TRUE(right.identifiable[kLq]) << right.reason[kLq];
  expectIdentifiedWithinStated(right, data.back().truth, "declared 1.5");
}

TEST(VoltageAngle, TheConfigKeysReadAndCheck) {
  const std::string ok = test_helpers::writeTemp("angle_ok.yaml", "time: {voltage_delay_samples: 1, voltage_hold: stationary, "
                                                                  "angle_prediction: 1.5}\n");
  EXPECT_DOUBLE_EQ(loadIdentifierConfig(ok).window.declared_voltage_angle, 0.5);
  const std::string dq = test_helpers::writeTemp("angle_dq.yaml", "time: {voltage_delay_samples: 1, angle_prediction: 1.5}\n");
  EXPECT_DOUBLE_EQ(loadIdentifierConfig(dq).window.declared_voltage_angle, 0.0);  // the rotor-frame hold's own is 1.5
  const std::string bad = test_helpers::writeTemp("angle_bad.yaml", "time: {voltage_angle: maybe}\n");
  EXPECT_THROW(loadIdentifierConfig(bad), ConfigError);
  const std::string cross = test_helpers::writeTemp("angle_cross.yaml",
                                                    "time: {voltage_angle: estimate}\nmagnetics: {cross_saturation: true}\n");
  EXPECT_THROW(loadIdentifierConfig(cross), ConfigError);
  const std::string spacing = test_helpers::writeTemp("spacing.yaml", "window: {long_difference_spacing: 0.5}\n");
  EXPECT_DOUBLE_EQ(loadIdentifierConfig(spacing).window.long_difference_spacing, 0.5);
  const std::string negative = test_helpers::writeTemp("spacing_bad.yaml", "window: {long_difference_spacing: -1}\n");
  test_helpers::expectRefusedNaming<ConfigError>([&] { loadIdentifierConfig(negative); }, "window.long_difference_spacing",
                                                 "a negative spacing");
}

TEST(VoltageAngle, TheSwarmsFitnessWithAKnownAngleIsTheModelsMeanSquareResidual) {
  // The fitness folds a known angle into its sums (the acting voltage's entries): the same value as
  // the exact fit's residual of the model with the angle, at any point.
  const auto data = predictedAngleRun(1.5, 0.3);
  IdentifierConfig c = angleEstimated();
  c.window.sensor_offsets = c.window.sensor_gains = false;
  BlockStatistics stats(c.window);
  stats.configure(data[1].sample.t - data[0].sample.t);
  for (const auto& x : data) stats.add(x.sample);
  const ParameterVector p{3.0, 0.0047, 0.013, 0.18};
  for (double a : {0.0, 0.5, -0.3}) {
    stats.setVoltageAngle(a);
    Eigen::VectorXd beta(5);
    beta << p[0], p[1], p[2], p[3], a;
    double ms_d, ms_q, dd, dq;
    BlockLeastSquares::residuals(stats.window(), LinearBlockModel::withVoltageAngle(LinearBlockModel::paper()), beta, ms_d,
                                 ms_q, dd, dq);
    EXPECT_NEAR(stats.fitness(p), ms_d + ms_q, 1e-9 * (ms_d + ms_q)) << "a = " << a;
    double batch = 0.0;
    stats.fitness(&p, 1, &batch);
    EXPECT_EQ(batch, stats.fitness(p));
  }
}

namespace {
/// A scenario's log, cut to `duration_s`, through the statistics of real_drive.yaml's window.
struct RealDriveRun {
  IdentifierConfig config;
  std::vector<SimulatedSample> data;
  BlockStatistics stats;
};
RealDriveRun realDriveRun(const std::string& scenario_file, double duration_s) {
  Scenario s = test_helpers::scenario(scenario_file);
  s.duration = duration_s;
  const IdentifierConfig c = loadIdentifierConfig(test_helpers::sourcePath("config/identifiers/real_drive.yaml"));
  RealDriveRun r{c, test_helpers::run(s), BlockStatistics(c.window)};
  r.stats.configure(s.drive.sample_period);
  for (const auto& x : r.data) r.stats.add(x.sample);
  return r;
}
}  // namespace

TEST(RealDriveIdentification, TheSwarmsFitnessWithTheDrivesTermsFoldedInIsTheModelsResidual) {
  // A switching-level drive's log through the real drive's statistics (bus logged: narrow, wide and
  // bus shares), the known inverter error and voltage angle folded into the voltage entries: the
  // fitness is the exact fit's residual of the model with them as parameters, at any point, and the
  // swarm's batch call gives each point's value.
  RealDriveRun run = realDriveRun("industrial_pwm.yaml", 0.4);
  BlockStatistics& stats = run.stats;
  ASSERT_TRUE(stats.busVoltageLogged());
  const LinearBlockModel model = LinearBlockModel::withVoltageAngle(LinearBlockModel::inverterWithShapeAndBus());
  std::vector<ParameterVector> points;
  for (int k = 0; k < 23; ++k)
    points.push_back({3.6 * (1.0 + 0.01 * k), 0.036 * (1.0 - 0.004 * k), 0.051 * (1.0 + 0.003 * k), 0.55 * (1.0 - 0.002 * k)});
  for (const auto& [V, V_wide, V_bus, a] : std::vector<std::array<double, 4>>{{0.0, 0.0, 0.0, 0.0},
                                                                             {12.0, 0.0, 0.0, 0.0},
                                                                             {12.0, 4.0, 6.0, 0.5}}) {
    stats.setInverterVoltage(V, V_wide, V_bus);
    stats.setVoltageAngle(a);
    std::vector<double> batch(points.size());
    stats.fitness(points.data(), points.size(), batch.data());
    for (std::size_t k = 0; k < points.size(); ++k) {
      const ParameterVector& p = points[k];
      Eigen::VectorXd beta(8);
      beta << p[0], p[1], p[2], p[3], V, V_wide, V_bus, a;
      double ms_d, ms_q, dd, dq;
      BlockLeastSquares::residuals(stats.window(), model, beta, ms_d, ms_q, dd, dq);
      // (The exact fit reads the sensor terms' projection fresh; the fitness, refreshed once per block length.)
      EXPECT_NEAR(stats.fitness(p), ms_d + ms_q, 1e-6 * (ms_d + ms_q)) << "V = " << V << ", point " << k;
      EXPECT_EQ(batch[k], stats.fitness(p)) << "V = " << V << ", point " << k;
    }
  }
}

// The drive model chosen from the data when nothing about the drive is declared (doc/algorithm.md
// section 8).
TEST(DriveModel, WithNothingDeclaredARealDrivesLogGetsTheRealDrivesModel) {
  const auto data = test_helpers::run(test_helpers::scenario("industrial_pwm.yaml"));
  for (const char* method : {"wls", "fbdapso"}) {
    const Estimate e = identify(samplesOf(data), method, IdentifierConfig{});
    EXPECT_NE(e.drive_model.find("real drive, from the data"), std::string::npos) << method << ": '" << e.drive_model << "'";
    EXPECT_NE(e.drive_model.find("current-sensor offsets and gains"), std::string::npos) << e.drive_model;  // theta_e logged
    EXPECT_TRUE(e.fit.consistent) << method << " " << e.fit.likely_cause;
    EXPECT_TRUE(e.identifiable[kPsiF]) << method << " " << e.reason[kPsiF];
    expectIdentifiedWithinStated(e, data.back().truth, method);
  }
}

namespace {
// The robot joint behind its switching inverter, once its drive's model fits: consistent, psi_f
// identified within 0.1 %, nothing identified more than 2 % off.
void expectTheJointFits(const Estimate& e, const std::vector<SimulatedSample>& data) {
  EXPECT_TRUE(e.fit.consistent) << e.fit.fit_ratio_d << " / " << e.fit.fit_ratio_q << " " << e.fit.likely_cause;
  EXPECT_TRUE(e.identifiable[kPsiF]) << e.reason[kPsiF];
  EXPECT_NEAR(e.parameters[kPsiF], data.back().truth[kPsiF], 1e-3 * data.back().truth[kPsiF]);
  for (int p = 0; p < kParameterCount; ++p) {
    if (e.identifiable[p]) {
      EXPECT_LT(std::abs(errorPercent(e.parameters[p], data.back().truth[p])), 2.0) << parameterNames()[p];
    }
  }
}
}  // namespace

TEST(DriveModel, ARobotJointBehindASwitchingInverterFitsWithItsDelayDeclared) {
  // 40 / 60 uH behind a 20 kHz inverter whose current ripple spans the current within each period:
  // the shape's observer follows each period forward through the switching edges (the chord
  // between the samples made each edge's loss move its own edge current; the fit stayed at 56 / 92
  // times the noise with the 0.05 V threshold), and starts before the fit is consistent (it is not
  // until the observer runs). The MOSFET bridge and the threshold alike.
  for (const char* name : {"robot_joint_pwm.yaml", "robot_joint_pwm_threshold.yaml"}) {
    SCOPED_TRACE(name);
    const auto data = test_helpers::run(test_helpers::scenario(name));
    const IdentifierConfig c = loadIdentifierConfig(test_helpers::sourcePath("config/identifiers/real_drive.yaml"));
    const Estimate e = identify(samplesOf(data), "wls", c);
    expectTheJointFits(e, data);
  }
}

TEST(DriveModel, ARobotJointBehindASwitchingInverterFindsItsDelayWithNothingDeclared) {
  // At the switch to the real drive's model both delays misfit the recent samples (each replayed
  // with the edges' shape from the measured currents' chords), delay 0 less; run beside each
  // other, each following its own fits, delay 1 (the drive's) fits and is taken. The MOSFET bridge
  // and the threshold alike.
  for (const char* name : {"robot_joint_pwm.yaml", "robot_joint_pwm_threshold.yaml"}) {
    SCOPED_TRACE(name);
    const auto data = test_helpers::run(test_helpers::scenario(name));
    const Estimate e = identify(samplesOf(data), "wls", IdentifierConfig{});
    EXPECT_NE(e.drive_model.find("; delay 1 from t ="), std::string::npos) << e.drive_model;
    expectTheJointFits(e, data);
  }
}

TEST(DriveModel, BehindAMosfetBridgeTheJointsValuesHoldTheirStatedUncertaintyAndRsIsTheTerminals) {
  // The robot joint behind its MOSFET bridge (2 mohm on-state resistance, no threshold), nothing
  // declared, FBDAPSO, seeds 1-3: L_d, L_q and psi_f identified, each within its stated
  // uncertainty (with a 0.05 V threshold in its place, L_d read +0.5 to +1.4 % against a stated
  // +-0.6-0.9 %, doc/results.md). R_s is the resistance the inverter's terminals see: within its
  // stated uncertainty of R_s + R_on and outside it of the winding's R_s alone.
  for (std::uint64_t seed : {1u, 2u, 3u}) {
    SCOPED_TRACE(seed);
    Scenario s = test_helpers::scenario("robot_joint_pwm.yaml");
    s.seed = seed;
    const auto data = test_helpers::run(s);
    const ParameterVector& truth = data.back().truth;
    ASSERT_NEAR(truth[kRs], s.motor.R_s + s.inverter.device_resistance, 1e-12);
    const Estimate e = identify(samplesOf(data), "fbdapso", IdentifierConfig{});
    for (int p : {kLd, kLq, kPsiF}) EXPECT_TRUE(e.identifiable[p]) << parameterNames()[p] << ": " << e.reason[p];
    expectIdentifiedWithinStated(e, truth, "seed " + std::to_string(seed));
    EXPECT_LE(std::abs(e.parameters[kRs] / truth[kRs] - 1.0), e.relative_uncertainty[kRs]) << e.reason[kRs];
    EXPECT_GT(std::abs(e.parameters[kRs] / s.motor.R_s - 1.0), e.relative_uncertainty[kRs]) << e.reason[kRs];
  }
}

TEST(DriveModel, AtTheJointsLightSteadyLoadItsOwnAngleIsCombinedWithTheRememberedOne) {
  // robot_joint_pwm ends at a light steady load, where L_q is one column with the drive's angle. On
  // seed 8 (wls) the last window's own angle (0.508 +- 0.006) lies 1.5 combined standard deviations
  // from the one remembered from the windows across the reversal (0.498 +- 0.004): fitted with its
  // own angle, and that disagreement added, L_q was stated +-1.55 % and not identified; combined, the
  // angle lies between the two, better determined than the window's own, and L_q is identified
  // within its stated uncertainty.
  Scenario s = test_helpers::scenario("robot_joint_pwm.yaml");
  s.seed = 8;
  const auto data = test_helpers::run(s);
  IdentifierConfig c;
  c.method = "wls";
  std::unique_ptr<OnlineIdentifier> id = makeIdentifier(c);
  for (const auto& d : data) id->process(d.sample);
  const Estimate e = id->estimate();
  const RememberedAngle* remembered = id->rememberedAngle();
  ASSERT_NE(remembered, nullptr);
  ASSERT_TRUE(e.fit.voltage_angle_remembered) << e.reason[kLq];
  const double own = e.fit.own_voltage_angle;
  EXPECT_GT(std::abs(own - remembered->angle), std::hypot(e.fit.own_voltage_angle_std, remembered->standard_deviation));
  EXPECT_GT(e.fit.voltage_angle, std::min(own, remembered->angle));
  EXPECT_LT(e.fit.voltage_angle, std::max(own, remembered->angle));
  EXPECT_LT(e.fit.voltage_angle_std, e.fit.own_voltage_angle_std);
  EXPECT_TRUE(e.identifiable[kLq]) << e.reason[kLq];
  expectIdentifiedWithinStated(e, data.back().truth, "seed 8");
}

TEST(DriveModel, TheSameJointWithDelayZeroFindsItToo) {
  // The robot joint's drive without the computation delay (k_p = 0.5; its devices' loss a 0.05 V
  // threshold): the 7-parameter fit takes delay 1; delay 0 runs beside it, fits better, and is
  // taken once it leaves at most half the residual (at six time constants it did not yet on this
  // seed: 0.69 of it).
  Scenario s = test_helpers::scenario("robot_joint_pwm_threshold.yaml");
  s.inverter.computation_delay = 0;
  s.inverter.angle_prediction = 0.5;
  const auto data = test_helpers::run(s);
  const Estimate e = identify(samplesOf(data), "wls", IdentifierConfig{});
  EXPECT_NE(e.drive_model.find("; delay 0 from t ="), std::string::npos) << e.drive_model;
  expectTheJointFits(e, data);
}

TEST(DriveModel, BehindTheObserverNothingIsIdentifiedUntilTheFitHasHeldConsistent) {
  // The robot joint with 1.0 us of dead time and no device drops (seed 7): the observer's blocks
  // and the fit settle together, and the fit is first consistent 20 ms before the log ends, with
  // L_d 2.0 % high. Nothing is identified until the fit has been consistent
  // for two window time constants, with the reason; with the hold off (0), L_d is identified 2.0 %
  // off at a stated +-0.9 %, the case it exists for.
  Scenario s = test_helpers::scenario("robot_joint_pwm.yaml");
  s.inverter.dead_time = 1.0e-6;
  s.inverter.device_drop = 0.0;
  s.inverter.device_resistance = 0.0;
  s.seed = 7;
  const auto data = test_helpers::run(s);
  const ParameterVector& truth = data.back().truth;
  const Estimate e = identify(samplesOf(data), "wls", IdentifierConfig{});
  EXPECT_TRUE(e.fit.consistent) << e.fit.likely_cause;
  for (int p = 0; p < kParameterCount; ++p) EXPECT_FALSE(e.identifiable[p]) << parameterNames()[p] << ": " << e.reason[p];
  for (int p : {kLd, kPsiF})  // the two the data determine here (R_s and L_q: not excited, their own reasons)
    EXPECT_NE(e.reason[p].find("the fit has been consistent for"), std::string::npos) << e.reason[p];
  IdentifierConfig at_once;
  at_once.assessment.observer_settling_time_constants = 0.0;
  const Estimate off = identify(samplesOf(data), "wls", at_once);
  EXPECT_TRUE(off.identifiable[kLd]) << off.reason[kLd];
  EXPECT_GT(std::abs(off.parameters[kLd] / truth[kLd] - 1.0), 1.5 * off.relative_uncertainty[kLd]);
}

TEST(DriveModel, AJointAtOneOperatingPointTakesTheAngleItsReversalDetermined) {
  // The robot joint's log ends 0.3 s after its speed reversal, at one light operating point where
  // the drive's voltage angle and L_q are one column (the window's own angle +-0.006-0.007): L_q was
  // determined only to +-1.1 %. The windows across the reversal, once the fit has held consistent,
  // determine the angle to +-0.004; the last window holds that angle (it agrees with its own) and
  // L_q is identified (+1.0 % at a stated +-0.67 %: with the devices' loss a 0.05 V threshold, taken
  // as dead time, it is biased high, doc/results.md).
  const auto data = test_helpers::run(test_helpers::scenario("robot_joint_pwm_threshold.yaml"));
  const ParameterVector& truth = data.back().truth;
  const Estimate e = identify(samplesOf(data), "wls", IdentifierConfig{});
  ASSERT_TRUE(e.fit.voltage_angle_modelled);
  EXPECT_TRUE(e.fit.voltage_angle_remembered) << e.fit.voltage_angle << " +- " << e.fit.voltage_angle_std;
  EXPECT_GT(e.fit.voltage_angle_remembered_t, 0.7);  // after the reversal (0.6-0.7 s) and the delay's choice
  EXPECT_LT(e.fit.voltage_angle_std, 0.7 * e.fit.own_voltage_angle_std);
  EXPECT_TRUE(e.identifiable[kLq]) << e.reason[kLq];
  EXPECT_LT(std::abs(errorPercent(e.parameters[kLq], truth[kLq])), 1.5);
  expectTheJointFits(e, data);
}

TEST(DriveModel, BehindAnEncoderTheObserversBackEmfTurnsAtTheCountsRateOverSeveralPeriods) {
  // The robot joint's 2^14-count encoder gives 8 or 9 counts per period at 600 rpm: one period's
  // increment is up to 12 % off the rotor's speed, 0.15 V of the back EMF the forward observer
  // follows the period with. Taken over kObserverRatePeriods periods, L_d (without the devices'
  // drops, which bias it on their own) comes out within 0.36 % on average over seeds 1-10 (wls),
  // against 0.62 % with one period's increment.
  Scenario s = test_helpers::scenario("robot_joint_pwm_threshold.yaml");
  s.inverter.device_drop = 0.0;
  double sum = 0.0;
  int identified = 0;
  for (int seed = 1; seed <= 10; ++seed) {
    s.seed = static_cast<std::uint64_t>(seed);
    const auto data = test_helpers::run(s);
    const Estimate e = identify(samplesOf(data), "wls", IdentifierConfig{});
    if (!e.identifiable[kLd]) continue;
    ++identified;
    sum += std::abs(errorPercent(e.parameters[kLd], data.back().truth[kLd]));
  }
  ASSERT_GE(identified, 9);
  EXPECT_LT(sum / identified, 0.5);
}

TEST(DriveModel, ARememberedAngleIsTakenOnlyWhereTheWindowAgrees) {
  // At one steady operating point (industrial_pwm_steady) the window determines the angle poorly; a
  // remembered angle that agrees with its own is combined with it by their standard deviations
  // (one with a tenth of the window's standard deviation nearly replaces it, and L_q's standard
  // deviation falls; one with 0.8 of it, half a standard deviation away, moves it by 1.5625 / 2.5625
  // of the gap), and one ten of the window's own standard deviations away is not taken. (The long
  // window, which is preferred where it determines the angle better than the fitness window, is
  // forgotten here: the remembered angle is what serves a window whose long window does not.)
  RealDriveRun run = realDriveRun("industrial_pwm_steady.yaml", 0.5);
  BlockStatistics& stats = run.stats;
  const IdentifierConfig& c = run.config;
  stats.resetLongWindow();
  const ParameterVector start = run.data.back().truth;
  const FitCheck own = checkFit(stats, c.assessment, start, false, true, 10.0, false);
  ASSERT_TRUE(own.available && own.voltage_angle_modelled);
  const double a = own.own_voltage_angle, sigma = own.own_voltage_angle_std;
  ASSERT_TRUE(std::isfinite(sigma)) << "the window should determine the angle a little";
  EXPECT_FALSE(own.voltage_angle_remembered);
  RememberedAngle agreeing{a, 0.1 * sigma, 0.1};
  const FitCheck with = checkFit(stats, c.assessment, start, false, true, 10.0, false, &agreeing);
  EXPECT_TRUE(with.voltage_angle_remembered);
  EXPECT_NEAR(with.voltage_angle, a, 1e-12);
  EXPECT_NEAR(with.voltage_angle_std, sigma / std::sqrt(101.0), 1e-9 * sigma);
  EXPECT_LT(with.relative_std[kLq], 0.5 * own.relative_std[kLq]);
  RememberedAngle weaker{a + 0.5 * sigma, 0.8 * sigma, 0.1};
  const FitCheck combined = checkFit(stats, c.assessment, start, false, true, 10.0, false, &weaker);
  EXPECT_TRUE(combined.voltage_angle_remembered);
  EXPECT_NEAR(combined.voltage_angle, a + 0.5 * sigma * 1.5625 / 2.5625, 1e-6 * sigma);
  EXPECT_NEAR(combined.voltage_angle_std, sigma / std::sqrt(2.5625), 1e-6 * sigma);
  EXPECT_LT(combined.relative_std[kLq], own.relative_std[kLq]);
  EXPECT_GT(combined.relative_std[kLq], with.relative_std[kLq]);
  RememberedAngle contradicted{a + 10.0 * sigma, 0.1 * sigma, 0.1};
  const FitCheck against = checkFit(stats, c.assessment, start, false, true, 10.0, false, &contradicted);
  EXPECT_FALSE(against.voltage_angle_remembered);
  EXPECT_NEAR(against.voltage_angle, own.voltage_angle, 1e-9);
  EXPECT_DOUBLE_EQ(against.relative_std[kLq], own.relative_std[kLq]);
}

namespace {
/// The switching-level industrial drive's 20 s monitoring log (seed 4), its angle remembered from
/// the windows across the load step at 8 s: what the identifier remembers at each time in `at`.
std::vector<const RememberedAngle*> rememberedAlong(const Scenario& s, const std::vector<double>& at,
                                                    std::vector<RememberedAngle>& copies) {
  const auto data = test_helpers::run(s);
  IdentifierConfig c;
  c.method = "wls";
  auto id = makeIdentifier(c);
  std::vector<const RememberedAngle*> out;
  copies.reserve(at.size());
  std::size_t next = 0;
  for (const auto& x : data) {
    id->process(x.sample);
    if (next < at.size() && x.sample.t >= at[next]) {
      const RememberedAngle* r = id->rememberedAngle();
      copies.push_back(r ? *r : RememberedAngle{});
      out.push_back(r ? &copies.back() : nullptr);
      ++next;
    }
  }
  return out;
}
}  // namespace

TEST(DriveModel, AMotorChangeForgetsTheRememberedAngle) {
  // The demagnetisation brought forward to 9-9.2 s: the windows across the load step at 8 s
  // determined the angle best (the drive's is 0.5; held across the fault, such angles left L_q
  // identified 2.1-2.6 % off along the run in this family). Where the motor changes the long window
  // starts again, and the remembered angle is forgotten with it (one may form again after).
  Scenario s = test_helpers::scenario("real_drive_demagnetisation.yaml");
  s.seed = 4;
  s.duration = 10.4;
  s.psi_f_scale = Profile::piecewise({0.0, 9.0, 9.2}, {1.0, 1.0, 0.96});
  std::vector<RememberedAngle> copies;
  const auto r = rememberedAlong(s, {8.9, 10.39}, copies);
  ASSERT_EQ(r.size(), 2u);
  ASSERT_NE(r[0], nullptr) << "the load step at 8 s should have given the angle";
  EXPECT_GT(r[0]->t, 8.0);
  if (r[1]) {
    EXPECT_GT(r[1]->t, 9.0);
  }
}

TEST(DriveModel, ALoadStepOnAHealthyDriveIsNoStepOfTheMotor) {
  // Behind the inverter a load step determines R_s far better than the window at one current
  // magnitude before it did, and the two optima lie apart by several per cent within their own
  // uncertainties: judged by the new fit's uncertainty alone, the load step at 3 s read as a step of
  // R_s (seed 4), and L_q moving by 2.3 % at 15.4 s as one of L_q (seed 1, its fit before at 0.96 %),
  // each starting the long and the slow window again. The demagnetisation at 14 s is a step.
  const auto motorChanges = [](const Scenario& s) {
    IdentifierConfig c;
    c.method = "wls";
    auto id = makeIdentifier(c);
    for (const auto& x : test_helpers::run(s)) id->process(x.sample);
    return id->counters().motor_changes;
  };
  for (int seed : {1, 4}) {
    Scenario faulty = test_helpers::scenario("real_drive_demagnetisation.yaml");
    faulty.seed = seed;
    faulty.duration = 16.0;
    Scenario healthy = faulty;
    healthy.psi_f_scale = Profile::constant(1.0);
    EXPECT_EQ(motorChanges(healthy), 0u) << "seed " << seed;
    EXPECT_GE(motorChanges(faulty), 1u) << "seed " << seed;
  }
}

TEST(DriveModel, AfterAStepOfTheMotorTheSlowWindowWaitsForTheNewMotorsData) {
  // Where a step of the motor starts the slow window again, the last slow fit is of the blocks
  // across the step (here reported as a misfit of 4.35 / 199 times the noise, "something changed
  // within it"), and the window's first blocks do not yet hold the new motor's operating point.
  // Until the window holds one time constant of the fitness window's data the slow estimates have
  // no data and say why.
  Scenario s = test_helpers::scenario("real_drive_demagnetisation.yaml");
  s.seed = 1;
  s.duration = 15.0;
  IdentifierConfig c;
  c.method = "wls";
  auto id = makeIdentifier(c);
  std::uint64_t changes = 0;
  double restarted = NAN;
  int checked = 0;
  for (const auto& x : test_helpers::run(s)) {
    id->process(x.sample);
    if (id->counters().motor_changes > changes) {
      changes = id->counters().motor_changes;
      restarted = x.sample.t;
    }
    if (std::isfinite(restarted) && x.sample.t - restarted < 0.04 && std::fmod(x.sample.t, 0.005) < 1.3e-4) {
      const Estimate e = id->estimate();
      for (int p : {kRs, kPsiF}) {
        EXPECT_EQ(e.slow.status[p], ParameterStatus::NoData) << "t = " << x.sample.t << ": " << e.slow.reason[p];
        EXPECT_NE(e.slow.reason[p].find("started again"), std::string::npos) << e.slow.reason[p];
      }
      ++checked;
    }
  }
  EXPECT_EQ(changes, 1u);
  EXPECT_GT(checked, 3);
}

TEST(DriveModel, TheRememberedAngleStandsInForTheLongWindowsFirstTimeConstant) {
  // The same drive without the fault (the real drive's model adopted at 0.45 s): remembered from the
  // load step at 8 s and held until the long window (10 s) no longer holds the blocks of the
  // model's start; after that the long window speaks for itself (along the four-minute duty cycle a
  // remembered angle left FBDAPSO's L_q identified more than 2 % off).
  Scenario s = test_helpers::scenario("real_drive_demagnetisation.yaml");
  s.seed = 4;
  s.duration = 11.0;
  s.psi_f_scale = Profile::constant(1.0);
  std::vector<RememberedAngle> copies;
  const auto r = rememberedAlong(s, {10.3, 10.99}, copies);
  ASSERT_EQ(r.size(), 2u);
  ASSERT_NE(r[0], nullptr);
  EXPECT_GT(r[0]->t, 8.0);
  EXPECT_EQ(r[1], nullptr);
}

TEST(DriveModel, TheObserversSettlingKeyReadsAndChecks) {
  EXPECT_DOUBLE_EQ(IdentifierConfig{}.assessment.observer_settling_time_constants, 2.0);
  const std::string off = test_helpers::writeTemp("settle_off.yaml", "assessment: {observer_settling_time_constants: 0}\n");
  EXPECT_DOUBLE_EQ(loadIdentifierConfig(off).assessment.observer_settling_time_constants, 0.0);
  const std::string longer = test_helpers::writeTemp("settle_long.yaml", "assessment: {observer_settling_time_constants: 4.5}\n");
  EXPECT_DOUBLE_EQ(loadIdentifierConfig(longer).assessment.observer_settling_time_constants, 4.5);
  const std::string negative = test_helpers::writeTemp("settle_bad.yaml", "assessment: {observer_settling_time_constants: -1}\n");
  test_helpers::expectRefusedNaming<ConfigError>([&] { loadIdentifierConfig(negative); },
                                                 "assessment.observer_settling_time_constants", "a negative settling time");
}

TEST(DriveModel, AnIdealDriveAndAMotorsStepChangeKeepThePapersModel) {
  // The paper's model fits an ideal drive; a demagnetisation step misfits the window only until it
  // is forgotten, and must not switch the model.
  for (const char* file : {"wc1_drive.yaml", "demagnetisation.yaml", "inter_turn_fault.yaml"}) {
    const auto data = test_helpers::run(test_helpers::scenario(file));
    const Estimate e = identify(samplesOf(data), "wls", IdentifierConfig{});
    EXPECT_EQ(e.drive_model, "") << file;
    EXPECT_TRUE(e.fit.consistent) << file << " " << e.fit.likely_cause;
  }
}

TEST(DriveModel, ADeclaredModelIsKeptAndChecked) {
  const auto data = test_helpers::run(test_helpers::scenario("industrial_pwm.yaml"));
  const std::string path = test_helpers::writeTemp("declared.yaml", "drive_model: declared\n");
  const IdentifierConfig declared = loadIdentifierConfig(path);
  EXPECT_FALSE(declared.automatic_drive_model);
  const Estimate e = identify(samplesOf(data), "wls", declared);
  // Nothing about the drive chosen from the data (the encoder's angle is still smoothed: a sensor).
  EXPECT_EQ(e.drive_model.find("real drive"), std::string::npos) << e.drive_model;
  EXPECT_NE(e.drive_model.find("angle quantised"), std::string::npos) << e.drive_model;
  EXPECT_FALSE(e.fit.consistent);
  EXPECT_FALSE(e.fit.likely_cause.empty());
  for (int p = 0; p < kParameterCount; ++p) EXPECT_FALSE(e.identifiable[p]) << parameterNames()[p];
  // Declaring any of the drive's keys declares the model.
  const std::string delay = test_helpers::writeTemp("delay.yaml", "time: {voltage_delay_samples: 1}\n");
  EXPECT_FALSE(loadIdentifierConfig(delay).automatic_drive_model);
  const std::string none = test_helpers::writeTemp("none.yaml", "method: rls\n");
  EXPECT_TRUE(loadIdentifierConfig(none).automatic_drive_model);
  EXPECT_TRUE(loadIdentifierConfig(test_helpers::sourcePath("config/identifiers/default.yaml")).automatic_drive_model);
  EXPECT_FALSE(loadIdentifierConfig(test_helpers::sourcePath("config/identifiers/real_drive.yaml")).automatic_drive_model);
}

// Noise-free logs: the fit check's floor (fit_floor_relative of the RMS current) covers a model error
// far above the log's noise (none) and far below what moves a parameter by 0.1 %, and the stated
// uncertainty covers it too. Two discretisations other than the identifier's: the plant integrated
// exactly under a zero-order hold (the identifier integrates the currents by the trapezoid), and
// a switching-level PWM without dead time (pulses in the stator frame, its vector centred on the
// period's middle, currents sampled at the carrier valley; the identifier holds a constant vector in
// the rotor frame).
TEST(NoiseFreeLogs, ALogWithAnotherDiscretisationIsIdentified) {
  Scenario exact = test_helpers::scenario("wc1_drive.yaml");
  exact.sensors = {};
  exact.drive.integration_substeps = 40;
  exact.duration = 0.4;
  Scenario pwm = exact;
  pwm.inverter.switching = true;
  pwm.inverter.stationary_hold = true;
  pwm.inverter.angle_prediction = 0.5;
  for (const Scenario& s : {exact, pwm}) {
    const auto data = test_helpers::run(s);
    const std::string label = s.inverter.switching ? "PWM" : "exact ZOH";
    for (const char* method : {"wls", "fbdapso"}) {
      const Estimate e = identify(samplesOf(data), method, IdentifierConfig{});
      EXPECT_TRUE(e.fit.consistent) << label << " " << method << " d " << e.fit.fit_ratio_d << " q " << e.fit.fit_ratio_q;
      for (int p = 0; p < kParameterCount; ++p)
        EXPECT_TRUE(e.identifiable[p]) << label << " " << method << " " << parameterNames()[p] << ": " << e.reason[p];
      expectIdentifiedWithinStated(e, data.back().truth, label + " " + method);
    }
  }
}

TEST(DriveModel, TheDataChooseTheDelayOfTheLogsConvention) {
  // The paper's motor behind the switching-level inverter (k_p = 1.5): a log of the reference
  // computed at t_k (the voltage acts a period later) and a log of the voltage applied over each
  // period. The drive model chosen from the data takes delay 1 for the first and 0 for the second,
  // and identifies L_q and psi_f within their stated uncertainty in both. (0.8 s: the reference
  // log's fit becomes consistent at about 0.6 s, and behind the shape's observer it must hold for
  // two window time constants before anything is identified.)
  for (const bool applied : {false, true}) {
    Scenario s = test_helpers::scenario("wc1_applied_log.yaml");
    s.inverter.log_applied_voltage = applied;
    s.duration = 0.8;
    const auto data = test_helpers::run(s);
    const Estimate e = identify(samplesOf(data), "wls", IdentifierConfig{});
    const std::string label = applied ? "applied" : "reference";
    EXPECT_NE(e.drive_model.find(applied ? "delay 0" : "delay 1"), std::string::npos) << label << ": " << e.drive_model;
    EXPECT_TRUE(e.identifiable[kLq] && e.identifiable[kPsiF]) << label << " " << e.reason[kLq] << " / " << e.reason[kPsiF];
    expectIdentifiedWithinStated(e, data.back().truth, label);
  }
}

TEST(DriveModel, TheDelayIsTriedInTheFullModelWhereTheDriveEffectsFitMissesIt) {
  // robot_joint_realistic (delay 1, stationary hold) with an exact angle and speed: the smooth
  // voltages of its current loop leave the drive-effects fit's first-order delay column at
  // -0.24 +- 0.17 samples, and that delay alone chose 0: every parameter poor_fit ("fits 0.47
  // samples of delay"). Each delay in the full model on the recent samples chooses 1, and the four
  // are identified within their stated uncertainty.
  for (const std::uint64_t seed : {1u, 2u}) {
    Scenario s = test_helpers::scenario("robot_joint_realistic.yaml");
    s.sensors.encoder_lines = 0;
    s.seed = seed;
    const auto data = test_helpers::run(s);
    const Estimate e = identify(samplesOf(data), "wls", IdentifierConfig{});
    const std::string label = "seed " + std::to_string(seed);
    EXPECT_NE(e.drive_model.find("delay 1"), std::string::npos) << label << ": " << e.drive_model;
    EXPECT_TRUE(e.fit.consistent) << label << ": " << e.fit.likely_cause;
    EXPECT_TRUE(e.identifiable[kLq] && e.identifiable[kPsiF]) << label << " " << e.reason[kLq] << " / " << e.reason[kPsiF];
    expectIdentifiedWithinStated(e, data.back().truth, label);
  }
}

TEST(DriveModel, TheDelayWhoseFitnessWindowFitsIsTakenAtTheSwitch) {
  // robot_joint_realistic, seed 2, as shipped (its encoder kept): the drive-effects fit's delay
  // chose 0, and the two delays' slow windows both misfit (9.3 and 7.2 times the noise, within
  // chance of each other); the 50 ms window fits with delay 1 (d residual 3.3) and not with 0 (8.6).
  // The switch takes delay 1 from the start, not 0 turned round 0.35 s later.
  Scenario s = test_helpers::scenario("robot_joint_realistic.yaml");
  s.seed = 2;
  const auto data = test_helpers::run(s);
  const Estimate e = identify(samplesOf(data), "wls", IdentifierConfig{});
  EXPECT_NE(e.drive_model.find("delay 1"), std::string::npos) << e.drive_model;
  EXPECT_EQ(e.drive_model.find("delay 0"), std::string::npos) << e.drive_model;
  expectIdentifiedWithinStated(e, data.back().truth, "seed 2");
}

TEST(DriveModel, WhereTheChosenDelayMisfitsTheOtherIsTakenIfItFitsBothWindowsBetter) {
  // robot_joint_realistic seeds 6 and 8 (delay 1), their encoder's angle smoothed: the drive-effects
  // fit's delay read 0.12 +- 0.12 and 0.09 +- 0.13, so 0 was chosen; its 50 ms window failed the
  // fit check (11.9 and 13.6 times the noise, d + q) where delay 1's fitted both windows better
  // (8.8 and 7.7; slow 9.5 against 11.3 and 9.4 against 12.9), and delay 0 was kept: every
  // parameter poor_fit at the end.
  for (const std::uint64_t seed : {6u, 8u}) {
    Scenario s = test_helpers::scenario("robot_joint_realistic.yaml");
    s.seed = seed;
    const auto data = test_helpers::run(s);
    const Estimate e = identify(samplesOf(data), "wls", IdentifierConfig{});
    EXPECT_NE(e.drive_model.find("delay 1"), std::string::npos) << "seed " << seed << ": " << e.drive_model;
    EXPECT_EQ(e.drive_model.find("delay 0"), std::string::npos) << "seed " << seed << ": " << e.drive_model;
    EXPECT_TRUE(e.fit.consistent) << "seed " << seed << ": " << e.fit.likely_cause;
    expectIdentifiedWithinStated(e, data.back().truth, "seed " + std::to_string(seed));
  }
}

TEST(AngleQuantum, AnEncodersCountIsFoundAndAnExactAngleHasNone) {
  // 2^14 counts per revolution, 14 pole pairs (robot_joint_realistic's encoder): a quantum of
  // 2 pi 14 / 16384 = 5.37 mrad of electrical angle, logged wrapped to (-pi, pi] and as float32
  // (as many drives log it). A standstill first (no steps), a reversal, speeds from a tenth of a
  // count to many counts per sample.
  const double q = 2.0 * M_PI * 14.0 / 16384.0, T = 5e-5;
  AngleQuantum encoder, exact;
  double theta = 0.3;
  bool decided = false;
  for (int k = 0; k < 20000 && !decided; ++k) {
    const double t = k * T;
    const double omega = t < 0.002 ? 0.0 : 2000.0 * std::sin(2.0 * M_PI * 20.0 * t) + 50.0;  // [rad/s]
    theta += omega * T;
    const double counted = (std::floor(theta / q) + 0.5) * q;
    decided = encoder.add(static_cast<float>(std::remainder(counted, 2.0 * M_PI)));
    exact.add(std::remainder(theta, 2.0 * M_PI));
  }
  ASSERT_TRUE(encoder.decided());
  EXPECT_NEAR(encoder.quantum(), q, 1e-3 * q);
  ASSERT_TRUE(exact.decided());
  EXPECT_EQ(exact.quantum(), 0.0);
  AngleQuantum unlogged;
  for (int k = 0; k < 1000; ++k) EXPECT_FALSE(unlogged.add(std::numeric_limits<double>::quiet_NaN()));
  EXPECT_FALSE(unlogged.decided());
  // An exact angle at a constant speed (saturated_map.yaml's imposed 900 rpm at 10 kHz: steps of
  // 28.3 mrad) once read as an encoder of that count; then a speed change shows it is none.
  AngleQuantum steady;
  for (int k = 0; k < 400; ++k) steady.add(std::remainder(0.028274333882308132 * k, 2.0 * M_PI));
  EXPECT_FALSE(steady.decided());
  for (int k = 0; k < 200; ++k) steady.add(std::remainder(11.3 + 0.0271 * k + 1e-5 * k * k, 2.0 * M_PI));
  ASSERT_TRUE(steady.decided());
  EXPECT_EQ(steady.quantum(), 0.0);
  // An encoder at a slow crawl (a count every few samples): steps of one count with pauses between.
  AngleQuantum crawl;
  for (int k = 0; k < 400 && !crawl.decided(); ++k) crawl.add((std::floor(0.3 * k) + 0.5) * q);
  ASSERT_TRUE(crawl.decided());
  EXPECT_NEAR(crawl.quantum(), q, 1e-3 * q);
}

TEST(AngleQuantum, ACountLockedToTheSamplingIsTold) {
  // The industrial drive's encoder (10 000 counts, 3 pole pairs) at 8 kHz: 25 counts every period
  // at 1200 rpm, where the quantisation error stays put and the rotor's wobble by a fifth of a count
  // (a d-axis injection's torque ripple, 100 Hz) leaves the counts as they are; 24.79 and 16.67
  // counts per period (1190, 800 rpm) sweep the error through the count.
  const double q = 2.0 * M_PI * 3.0 / 10000.0, T = 1.25e-4;
  for (const double rate : {25.0, 24.79, 16.667}) {
    CountLock lock;
    double previous = NAN;
    for (int k = 0; k < 24000; ++k) {  // 3 s
      const double t = k * T, wave = std::sin(2.0 * M_PI * 100.0 * t);
      const double theta = (0.5 + rate * k + 0.2 * wave) * q;
      const double counted = std::remainder((std::floor(theta / q) + 0.5) * q, 2.0 * M_PI);
      if (std::isfinite(previous)) lock.add(std::remainder(counted - previous, 2.0 * M_PI), q, T, 0.05, 1.0, wave);
      previous = counted;
    }
    const std::string label = "rate " + std::to_string(rate);
    EXPECT_EQ(lock.locked(), rate == 25.0) << label;
    EXPECT_EQ(lock.window().locked_share > 0.9, rate == 25.0) << label << ": " << lock.window().locked_share;
    EXPECT_EQ(lock.detectionWindow().locked_share, rate == 25.0 ? 1.0 : 0.0) << label;
    EXPECT_NEAR(lock.window().i_d_spread, std::sqrt(0.5), 0.02) << label;  // the injection's 1 A amplitude
    EXPECT_NEAR(lock.window().i_d_mean, 0.0, 0.02) << label;
  }
  CountLock none;  // no quantum: nothing tracked
  for (int k = 0; k < 100; ++k) none.add(25 * 1e-3, 0.0, T, 0.05, 1.0, 1.0);
  EXPECT_FALSE(none.locked());
  EXPECT_EQ(none.window().locked_share, 0.0);
}

TEST(AngleQuantum, ALockedCountWidensTheResistanceItCannotTellFromTheFramesWobble) {
  // The switching-level industrial drive at 1200 rpm: the encoder's 25 counts every period lock, the
  // speed loop holds them, and the rotor's motion within a count, which the d-axis injection shakes,
  // is not seen. The drive's frame then wobbles against the rotor with i_d, which reads as a
  // resistance: on this sequence (800 rpm with a load step, 1200 rpm) the slow R_s read 2.2 % high
  // (median of 30 seeds, 2.7 % at worst) against 0.7 % at 1190 rpm, where the counts sweep through
  // the quantisation error. Where the count is locked the slow estimates state that wobble (half a
  // count in phase with i_d) and name it; at 1190 rpm nothing is said of it.
  for (const double rpm : {1200.0, 1190.0}) {
    Scenario s = test_helpers::scenario("industrial_pwm.yaml");
    s.duration = 7.0;
    s.speed_reference_rpm = Profile::piecewise({0.0, 0.1, 3.0, 3.2}, {0.0, 800.0, 800.0, rpm});
    s.load_torque = Profile::piecewise({0.0, 1.0, 1.001}, {5.0, 5.0, 15.0});
    const auto data = test_helpers::run(s);
    const Estimate e = identify(samplesOf(data), "wls");
    const std::string label = std::to_string(rpm) + " rpm";
    const std::string& why = e.slow.reason[kRs];
    const bool named = why.find("count is locked to the sampling") != std::string::npos;
    EXPECT_EQ(named, rpm == 1200.0) << label << ": " << why;
    const double error = std::abs(e.slow.parameters[kRs] / data.back().truth[kRs] - 1.0);
    EXPECT_LE(error, e.slow.relative_uncertainty[kRs]) << label << ": " << why;
    if (rpm == 1200.0) EXPECT_GT(e.slow.relative_uncertainty[kRs], 0.03) << why;  // half a count: ~5 % of R_s here
    else EXPECT_LT(e.slow.relative_uncertainty[kRs], 0.03) << why;
    // The fast psi_f follows R_s along u_q at one operating point: identified at 1190 rpm, and at
    // 1200 rpm either identified within what it states or not, naming the count.
    if (rpm == 1190.0) EXPECT_EQ(e.status[kPsiF], ParameterStatus::Identified) << label << ": " << e.reason[kPsiF];
    else if (e.status[kPsiF] != ParameterStatus::Identified) {
      EXPECT_NE(e.reason[kPsiF].find("count is locked to the sampling"), std::string::npos) << e.reason[kPsiF];
    }
    expectIdentifiedWithinStated(e, data.back().truth, label);
  }
}

TEST(AngleSmoothing, AnEncodersQuantumNoLongerHidesLqAndLd) {
  // robot_joint_realistic's encoder moves the drive's frame by up to half a count (2.7 mrad): in
  // that frame the jitter cancels between dpsi_q/dt and omega_e psi_d except in psi_f times the
  // rotation, ~0.3 A of q current per block (psi_f / L_q = 133 A/rad); the q noise was 0.15 A
  // against 0.04 on d, and L_q and L_d not identified on seeds 1 and 8. The rotation from the
  // angle's centred mean over 17 samples takes it out. Declared off, the old noise comes back.
  IdentifierConfig off;
  off.window.angle_smoothing_samples = 0;
  for (const std::uint64_t seed : {1u, 8u}) {
    const auto data = drive("robot_joint_realistic.yaml", seed, 0.0);
    const std::string label = "seed " + std::to_string(seed);
    const Estimate e = identify(samplesOf(data), "wls", IdentifierConfig{});
    EXPECT_NE(e.drive_model.find("angle quantised to 5.37 mrad"), std::string::npos) << label << ": " << e.drive_model;
    EXPECT_LT(e.fit.noise_std_q, 0.06) << label;
    for (int p : {kLd, kLq, kPsiF})
      EXPECT_EQ(e.status[p], ParameterStatus::Identified) << label << " " << parameterNames()[p] << ": " << e.reason[p];
    expectIdentifiedWithinStated(e, data.back().truth, label);
    const Estimate raw = identify(samplesOf(data), "wls", off);
    EXPECT_EQ(raw.drive_model.find("angle quantised"), std::string::npos) << label << ": " << raw.drive_model;
    EXPECT_GT(raw.fit.noise_std_q, 0.12) << label;
    EXPECT_NE(raw.status[kLq], ParameterStatus::Identified) << label;
  }
  const std::string bad = test_helpers::writeTemp("smoothing_bad.yaml", "angle_sensor: {smoothing_samples: -2}\n");
  test_helpers::expectRefusedNaming<ConfigError>([&] { loadIdentifierConfig(bad); }, "angle_sensor.smoothing_samples",
                                                 "a negative half-width");
}

TEST(AngleSmoothing, FbdapsoTrailingTheWindowIdentifiesLdWhereTheOptimumDoes) {
  // robot_joint_realistic's L_d is determined to +-0.83 % on seed 1; FBDAPSO's value trails the
  // window's optimum, which moves by a tenth of a percent every few milliseconds, and stated against
  // the current optimum alone it reads more than 1 % (not identified). Against the optima of
  // the last 25 ms, which held still within the noise, it is identified, and right.
  const auto data = drive("robot_joint_realistic.yaml", 1, 0.0);
  const Estimate e = identify(samplesOf(data), "fbdapso", IdentifierConfig{});
  EXPECT_EQ(e.status[kLd], ParameterStatus::Identified) << e.reason[kLd];
  expectIdentifiedWithinStated(e, data.back().truth, "seed 1");
  const AssessmentSettings a;
  const Assessment against_now = assess(e.parameters, e.fit, {}, a);  // no earlier optima
  EXPECT_GT(against_now.relative_uncertainty[kLd], a.max_relative_uncertainty) << against_now.reason[kLd];
}

TEST(AngleSmoothing, ASwarmAtTheOptimumOfItsOwnFitnessIsNotCreditedWhereTheDataHoldAnotherAngle) {
  // telemetry_duty_cycle, FBDAPSO seed 7, at 20.44 s: the data's fit takes the drive's voltage angle
  // from the long window, which moves its L_q from 0.0560 to 0.0510 H and determines it to +-0.9 %;
  // the swarm's fitness still holds the angle of its last refresh, whose optimum the swarm sits at.
  // Credited against that fitness's optima alone it was identified 9.9 % off. Along the run to
  // 20.6 s (an estimate every 10 ms) nothing identified is more than 2 % off.
  const auto data = drive("telemetry_duty_cycle.yaml", 7, 20.6);
  IdentifierConfig c;
  c.method = "fbdapso";
  c.seed = 7;
  auto id = makeIdentifier(c);
  int identified_lq = 0;
  double worst = 0.0;
  for (std::size_t k = 0; k < data.size(); ++k) {
    id->process(data[k].sample);
    if (k % 80 != 79) continue;
    const Estimate e = id->estimate();
    for (int p = 0; p < kParameterCount; ++p) {
      if (!e.identifiable[p]) continue;
      worst = std::max(worst, std::abs(errorPercent(e.parameters[p], data[k].truth[p])));
      if (p == kLq && data[k].sample.t > 20.4) ++identified_lq;
    }
  }
  EXPECT_LT(worst, 2.0);
  EXPECT_GT(identified_lq, 0);  // L_q is identified once the angle is taken
}

TEST(AngleSmoothing, AWindowWhoseOwnAngleContradictsTheRememberedOneCarriesTheDifference) {
  // telemetry_duty_cycle, wls (the data's optimum), seed 5: 20-40 ms after the load drop to 2 N m at
  // 9 s the window fits its own voltage angle, 0.63-0.77 period against the 0.56 a settled window
  // remembered, and its L_q read 2.0-2.3 % off, identified at +-0.73-0.84 %. Every sample from 9.0 to
  // 9.06 s: nothing identified more than 2 % off, and at 9.03 s L_q not identified, its reason
  // naming the disagreement. (Values just outside their stated uncertainty remain on this drive,
  // doc/results.md.)
  const auto data = drive("telemetry_duty_cycle.yaml", 5, 9.06);
  IdentifierConfig c;
  c.method = "wls";
  c.seed = 5;
  auto id = makeIdentifier(c);
  bool named = false;
  for (const auto& d : data) {
    id->process(d.sample);
    if (d.sample.t < 9.0) continue;
    const Estimate e = id->estimate();
    for (int p = 0; p < kParameterCount; ++p)
      if (e.identifiable[p])
        EXPECT_LE(std::abs(e.parameters[p] / d.truth[p] - 1.0), 0.02)
            << "t = " << d.sample.t << " " << parameterNames()[p] << ": " << e.reason[p];
    if (std::abs(d.sample.t - 9.03) < 1e-6) {
      EXPECT_NE(e.status[kLq], ParameterStatus::Identified) << e.reason[kLq];
      named = e.reason[kLq].find("against the drive's remembered one") != std::string::npos;
      EXPECT_TRUE(named) << e.reason[kLq];
    }
  }
  EXPECT_TRUE(named);
}

TEST(DriveModel, ADeclaredDrivesInverterWidthIsMeasuredFromTheData) {
  // real_drive.yaml leaves the inverter error's zero-crossing width to the data. Declared as 0.3 A
  // on robot_joint_realistic with an exact angle (the drive's own: 0.5 A), wls read R_s 2.14 % off
  // along the run of seed 13, identified, and noise-free -0.8 % (L_q +2.2 %) at 0.2 s. Measured, as
  // the automatic model measures it, once the motor has run 0.3 s: nothing is identified before.
  Scenario s = test_helpers::scenario("robot_joint_realistic.yaml");
  s.sensors.encoder_lines = 0;
  s.seed = 13;
  const auto data = test_helpers::run(s);
  IdentifierConfig c = loadIdentifierConfig(test_helpers::sourcePath("config/identifiers/real_drive.yaml"));
  ASSERT_LT(c.window.inverter_zero_crossing_current, 0.0);
  c.method = "wls";
  std::unique_ptr<OnlineIdentifier> id = makeIdentifier(c);
  double worst_R_s = 0.0;
  bool early_identified = false;
  for (std::size_t k = 0; k < data.size(); ++k) {
    id->process(data[k].sample);
    if (k % 200 != 199) continue;  // every 10 ms
    const Estimate e = id->estimate();
    if (data[k].sample.t < 0.3)  // (with a sign for the shape meanwhile, most of the fits fail)
      for (int p = 0; p < kParameterCount; ++p) early_identified = early_identified || e.identifiable[p];
    if (e.identifiable[kRs]) worst_R_s = std::max(worst_R_s, std::abs(errorPercent(e.parameters[kRs], data[k].truth[kRs])));
  }
  EXPECT_FALSE(early_identified);
  EXPECT_LT(worst_R_s, 1.0);
  const Estimate e = id->estimate();
  const std::size_t at = e.drive_model.find("inverter zero-crossing width ");
  ASSERT_NE(at, std::string::npos) << e.drive_model;
  const double width = std::stod(e.drive_model.substr(at + std::string("inverter zero-crossing width ").size()));
  EXPECT_NEAR(width, 0.5, 0.1) << e.drive_model;
  expectIdentifiedWithinStated(e, data.back().truth, "seed 13");
  EXPECT_TRUE(e.identifiable[kPsiF]) << e.reason[kPsiF];
}

TEST(DriveModel, AWideZeroCrossingIsMeasuredBeyondTheLaddersFirstRung) {
  // The automatic model's widths start at a quarter of the currents' RMS (10.6 A at the switch
  // here: 2.65 A) and climb to the RMS where that rung is taken. An average-model inverter whose
  // error passes zero over 6 A (as wide as a light load's ripple can make it on a low-inductance
  // drive) is measured as such: 5.31 A, half the RMS; without the climb, 2.65 A.
  Scenario s = test_helpers::scenario("robot_joint_realistic.yaml");
  s.inverter.zero_crossing_current = 6.0;
  const auto data = test_helpers::run(s);
  IdentifierConfig c;
  c.method = "wls";
  std::unique_ptr<OnlineIdentifier> id = makeIdentifier(c);
  for (const auto& d : data) id->process(d.sample);
  const Estimate e = id->estimate();
  const std::string key = "zero-crossing width ";
  const std::size_t at = e.drive_model.find(key);
  ASSERT_NE(at, std::string::npos) << e.drive_model;
  const double width = std::stod(e.drive_model.substr(at + key.size()));
  EXPECT_GT(width, 4.0) << e.drive_model;
  EXPECT_LT(width, 8.0) << e.drive_model;
  expectIdentifiedWithinStated(e, data.back().truth, "zero-crossing width 6 A");
  EXPECT_TRUE(e.identifiable[kLd]) << e.reason[kLd];
  EXPECT_TRUE(e.identifiable[kPsiF]) << e.reason[kPsiF];
}

TEST(DriveModel, ADeclaredDelayIsCheckedAgainstALogOfTheAppliedVoltage) {
  // real_drive.yaml declares the common convention, a log of the reference that acts a period
  // later. On the same drive's log of the voltage applied over each period the declaration is
  // wrong by one sample: at its steady operating points the voltage angle absorbs most of it and
  // psi_f read 1.2 % low at a stated +-0.8 % while the fit passed. The delay's check now reaches
  // the earlier voltage exactly (the step forward to the period-end voltage), so the declaration is
  // poor_fit with that cause; on the log of the reference it is right and identifies.
  const IdentifierConfig declared = loadIdentifierConfig(test_helpers::sourcePath("config/identifiers/real_drive.yaml"));
  for (const bool applied : {true, false}) {
    Scenario s = test_helpers::scenario("wc1_applied_log.yaml");
    s.inverter.log_applied_voltage = applied;
    const auto data = test_helpers::run(s);
    const std::string label = applied ? "applied" : "reference";
    for (const char* method : {"wls", "fbdapso"}) {
      const Estimate e = identify(samplesOf(data), method, declared);
      if (applied) {
        EXPECT_FALSE(e.fit.consistent) << method;
        for (int p = 0; p < kParameterCount; ++p)
          EXPECT_EQ(e.status[p], ParameterStatus::PoorFit) << method << " " << parameterNames()[p] << ": " << e.reason[p];
        EXPECT_NE(e.fit.likely_cause.find("earlier than the model's delay"), std::string::npos) << method << ": " << e.fit.likely_cause;
      } else {
        EXPECT_TRUE(e.fit.consistent) << method << ": " << e.fit.likely_cause;
        EXPECT_TRUE(e.identifiable[kLq] && e.identifiable[kPsiF]) << method << " " << e.reason[kLq] << " / " << e.reason[kPsiF];
        expectIdentifiedWithinStated(e, data.back().truth, label + " " + method);
      }
    }
  }
}

TEST(DriveModel, ASwitchingInvertersLogChoosesTheSwitchingEdges) {
  // The paper's motor behind the switching-level inverter (wc1_applied_log: 4.5 mH, 10 kHz, 1.5 us
  // dead time) with its sensors: the data choose the edges' shape over the smooth one, and L_d
  // comes out within 0.3 % (the smooth shape left it +1.44 % off; its error voltage changes with
  // the ripple's share of the current, which the d-axis injection turns into an inductance). On the
  // average-model drive (robot_joint_realistic: the error is tanh of the sampled current) they
  // choose the smooth shape. (With exact currents neither shape fits to a noise-free floor: the
  // edges leave 0.3 V RMS per period of a 9.2 V error, and the fit is poor.)
  const Scenario s = test_helpers::scenario("wc1_applied_log.yaml");
  const auto data = test_helpers::run(s);
  const Estimate e = identify(samplesOf(data), "wls", IdentifierConfig{});
  EXPECT_NE(e.drive_model.find("switching edges"), std::string::npos) << e.drive_model;
  EXPECT_NEAR(e.parameters[kLd] / data.back().truth[kLd], 1.0, 0.003);
  EXPECT_NEAR(e.parameters[kPsiF] / data.back().truth[kPsiF], 1.0, 0.002);
  Scenario average = test_helpers::scenario("robot_joint_realistic.yaml");
  average.duration = 0.6;
  const Estimate a = identify(samplesOf(test_helpers::run(average)), "wls", IdentifierConfig{});
  EXPECT_NE(a.drive_model.find("real drive, from the data"), std::string::npos) << a.drive_model;
  EXPECT_EQ(a.drive_model.find("switching edges"), std::string::npos) << a.drive_model;
}

TEST(DriveModel, AShortLogsStepsBeforeTheSwitchStillSeparateTheDrivesConstants) {
  // The robot joint behind its inverter, a 1 s log: its load steps (0.25, 0.45 s) and the start-up
  // come before the identifier has the evidence for the real drive's model (0.33 s). The change of
  // model replays the recent samples into the new statistics, so the long window keeps them, and
  // the drive's angle and inverter voltage are separated from L_q and R_s: both identified (with the
  // statistics started again at the change, neither was, in any of 10 seeds).
  for (std::uint64_t seed : {2u, 3u, 4u}) {
    Scenario s = test_helpers::scenario("robot_joint_realistic.yaml");
    s.seed = seed;
    const auto data = test_helpers::run(s);
    const Estimate e = identify(samplesOf(data), "wls", IdentifierConfig{});
    const std::string label = "seed " + std::to_string(seed);
    EXPECT_NE(e.drive_model.find("real drive, from the data"), std::string::npos) << label << " " << e.drive_model;
    EXPECT_TRUE(e.fit.voltage_angle_from_long_window) << label;
    EXPECT_TRUE(e.identifiable[kRs]) << label << " " << e.reason[kRs];
    EXPECT_TRUE(e.identifiable[kLq]) << label << " " << e.reason[kLq];
    for (int p = 0; p < kParameterCount; ++p) {
      if (e.identifiable[p]) {
        EXPECT_LT(std::abs(e.parameters[p] / data.back().truth[p] - 1.0), 0.01) << label << " " << parameterNames()[p];
      }
    }
    // R_s within what it states (L_q: see doc/results.md, it sits up to 1.2 times its stated
    // uncertainty off in a few seeds of this drive).
    EXPECT_LT(std::abs(e.parameters[kRs] / data.back().truth[kRs] - 1.0), e.relative_uncertainty[kRs]) << label;
  }
}
