// The swarm engine and its acceptance policies (Eq. 4-8, 15-17).
#include <gtest/gtest.h>

#include <cmath>

#include "pmsm_param_id/identification/particle_swarm.hpp"

using namespace pmsm_param_id;

TEST(Acceptance, PsoTakesEveryMove) {
  AlwaysAccept p;
  ParticleTemperature th;
  EXPECT_TRUE(p.accept(1e9, 0.999, th));
  EXPECT_FALSE(p.hasTemperature());
}

// The bounds that spare exp() must never change a decision: the test against exp() itself over x
// from 0 to beyond 40 and r on a fine grid, with r placed right at exp(-x) and one ulp either side.
TEST(Acceptance, MetropolisBoundsDecideAsExpDoes) {
  int band = 0, total = 0;
  for (double x = 0.0; x < 45.0; x = x < 1e-3 ? x + 1e-5 : x * 1.01) {
    const double e = std::exp(-x);
    for (double r : {0.0, e, std::nextafter(e, 0.0), std::nextafter(e, 1.0), 0.5 * e, 2.0 * e}) {
      if (r >= 1.0) continue;
      EXPECT_EQ(metropolisAccepts(x, r), e > r) << "x = " << x << ", r = " << r;
    }
    for (int k = 0; k < 200; ++k) {
      const double r = (k + 0.5) / 200.0;
      ++total;
      const double x2 = x * x;
      band += !(r < 1.0 - x + 0.5 * x2 - x2 * x / 6.0) && !(r * (1.0 + x + 0.5 * x2 + x2 * x / 6.0 + x2 * x2 / 24.0) > 1.0);
      ASSERT_EQ(metropolisAccepts(x, r), e > r) << "x = " << x << ", r = " << r;
    }
  }
  EXPECT_LT(band, total / 20);  // exp() is rarely needed
  EXPECT_FALSE(metropolisAccepts(std::nan(""), 0.0));
  EXPECT_FALSE(metropolisAccepts(INFINITY, 0.0));
}

TEST(Acceptance, MetropolisFollowsEq16) {
  MetropolisAcceptance p(1000.0, 0.8);
  ParticleTemperature th;
  p.reset(th);
  EXPECT_DOUBLE_EQ(th.T, 1000.0);
  EXPECT_TRUE(p.accept(-1.0, 0.999999, th));  // better: always
  EXPECT_TRUE(p.accept(0.0, 0.999999, th));   // equal: p = 1 (Eq. 16)
  // worse by 693.1 at T = 1000: p = exp(-0.6931) = 0.5
  EXPECT_TRUE(p.accept(693.1, 0.49, th));
  EXPECT_FALSE(p.accept(693.1, 0.51, th));
  p.endIteration(th);
  EXPECT_DOUBLE_EQ(th.T, 800.0);  // Eq. (7) once per iteration
}

TEST(Acceptance, BackfireZeroDeltaUsesEq17) {
  BackfireDoubleAnnealing p(800.0, 500.0, 0.8, 0.9, 0.001);
  ParticleTemperature th;
  p.reset(th);
  th.T = 0.001 / std::log(2.0);  // exp(-0.001 / T) = 0.5
  EXPECT_FALSE(p.accept(0.0, 0.51, th));
  EXPECT_EQ(th.accepted_worse, 0);
  EXPECT_TRUE(p.accept(0.0, 0.49, th));
  EXPECT_EQ(th.accepted_worse, 1);
}

TEST(Acceptance, BackfireTemperingAndAnnealingFollowEq7And8) {
  BackfireDoubleAnnealing p(800.0, 500.0, 0.8, 0.9, 0.001);
  ParticleTemperature th;
  p.reset(th);
  EXPECT_DOUBLE_EQ(th.T, 800.0);
  // Better move: general annealing only.
  EXPECT_TRUE(p.accept(-0.5, 0.0, th));
  EXPECT_DOUBLE_EQ(th.T, 640.0);
  // Worse move accepted (d = 1): T <- C1 (T + C2^1 T2) = 0.8 (640 + 450).
  EXPECT_TRUE(p.accept(1.0, 0.0, th));
  EXPECT_EQ(th.accepted_worse, 1);
  EXPECT_DOUBLE_EQ(th.T, 0.8 * (640.0 + 450.0));
  // Second worse acceptance (d = 2): C2^2 T2 = 405.
  const double before = th.T;
  EXPECT_TRUE(p.accept(1.0, 0.0, th));
  EXPECT_DOUBLE_EQ(th.T, 0.8 * (before + 405.0));
  // Rejected move: temperature untouched.
  const double t2 = th.T;
  EXPECT_FALSE(p.accept(1e9, 0.5, th));
  EXPECT_DOUBLE_EQ(th.T, t2);
  p.endIteration(th);
  EXPECT_DOUBLE_EQ(th.T, t2);
  p.reset(th);  // the counter reset restores T1 and d = 0
  EXPECT_DOUBLE_EQ(th.T, 800.0);
  EXPECT_EQ(th.accepted_worse, 0);
}

namespace {
// A shifted, badly scaled quadratic with its minimum inside the box.
double bowl(const ParameterVector& p) {
  const double a = p[0] - 2.0, b = (p[1] - 0.004) / 0.001, c = (p[2] - 0.012) / 0.001, d = (p[3] - 0.2) / 0.05;
  return a * a + b * b + c * c + d * d + 0.5 * a * d;
}
}  // namespace

class SwarmFindsMinimum : public ::testing::TestWithParam<const char*> {};

TEST_P(SwarmFindsMinimum, OfAKnownFunction) {
  std::shared_ptr<AcceptancePolicy> policy;
  const std::string m = GetParam();
  if (m == "pso") policy = std::make_shared<AlwaysAccept>();
  if (m == "sapso") policy = std::make_shared<MetropolisAcceptance>(1000.0, 0.8);
  if (m == "fbdapso") policy = std::make_shared<BackfireDoubleAnnealing>(800.0, 500.0, 0.8, 0.9, 0.001);
  ParticleSwarm swarm(SwarmSettings{}, policy, {0.5, 0.0005, 0.0005, 0.02}, {10.0, 0.03, 0.03, 0.6}, 7);
  for (int i = 0; i < 1500; ++i) swarm.iterate(bowl);
  const ParameterVector b = swarm.best();
  EXPECT_NEAR(b[0], 2.0, 0.01) << m;
  EXPECT_NEAR(b[1], 0.004, 0.00001) << m;
  EXPECT_NEAR(b[2], 0.012, 0.00001) << m;
  EXPECT_NEAR(b[3], 0.2, 0.0005) << m;
  EXPECT_LT(swarm.bestFitness(), 1e-3) << m;
  EXPECT_EQ(swarm.iterations(), 1500u);
}
INSTANTIATE_TEST_SUITE_P(Policies, SwarmFindsMinimum, ::testing::Values("pso", "sapso", "fbdapso"));

TEST(ParticleSwarm, SameSeedSameTrajectoryOtherSeedOther) {
  auto run = [](std::uint64_t seed) {
    ParticleSwarm s(SwarmSettings{}, std::make_shared<BackfireDoubleAnnealing>(800.0, 500.0, 0.8, 0.9, 0.001),
                    {0.5, 0.0005, 0.0005, 0.02}, {10.0, 0.03, 0.03, 0.6}, seed);
    for (int i = 0; i < 30; ++i) s.iterate(bowl);
    return s.best();
  };
  EXPECT_EQ(run(3), run(3));
  EXPECT_NE(run(3), run(4));
}

TEST(ParticleSwarm, StaysInsideTheBounds) {
  ParticleSwarm s(SwarmSettings{}, std::make_shared<AlwaysAccept>(), {1, 1, 1, 1}, {2, 2, 2, 2}, 1);
  // Minimum far outside the box: the best must sit on the boundary, never beyond it.
  const auto f = [](const ParameterVector& p) { return -(p[0] + p[1] + p[2] + p[3]); };
  for (int i = 0; i < 200; ++i) s.iterate(f);
  for (double v : s.best()) {
    EXPECT_LE(v, 2.0);
    EXPECT_GE(v, 1.0);
    EXPECT_NEAR(v, 2.0, 1e-6);
  }
}

TEST(ParticleSwarm, RefusesBadSettings) {
  SwarmSettings one;
  one.particles = 1;
  EXPECT_THROW(ParticleSwarm(one, std::make_shared<AlwaysAccept>(), {1, 1, 1, 1}, {2, 2, 2, 2}, 1),
               std::invalid_argument);
  EXPECT_THROW(ParticleSwarm(SwarmSettings{}, std::make_shared<AlwaysAccept>(), {1, 1, 3, 1}, {2, 2, 2, 2}, 1),
               std::invalid_argument);
}

// The three methods differ only in how often they take a worse position. On the same landscape
// from the same seed: PSO takes every worse move, SAPSO fewer as it cools within each cycle, and
// FBDAPSO's tempering (T rises after each accepted worse move) keeps it taking more than SAPSO.
TEST(ParticleSwarm, AcceptanceStatisticsTellThePoliciesApart) {
  const auto rate = [](std::shared_ptr<AcceptancePolicy> policy, int iterations) {
    ParticleSwarm s(SwarmSettings{}, std::move(policy), {0.5, 0.0005, 0.0005, 0.02}, {10.0, 0.03, 0.03, 0.6}, 11);
    for (int i = 0; i < iterations; ++i) s.iterate(bowl);
    return static_cast<double>(s.worseAccepted()) / static_cast<double>(s.worseProposed());
  };
  const double pso = rate(std::make_shared<AlwaysAccept>(), 500);
  const double sapso = rate(std::make_shared<MetropolisAcceptance>(1000.0, 0.8), 500);
  const double fbdapso = rate(std::make_shared<BackfireDoubleAnnealing>(800.0, 500.0, 0.8, 0.9, 0.001), 500);
  EXPECT_DOUBLE_EQ(pso, 1.0);
  EXPECT_LT(sapso, 0.5);
  EXPECT_GT(sapso, 0.005);
  EXPECT_GT(fbdapso, 1.2 * sapso) << "sapso " << sapso << " fbdapso " << fbdapso;
  EXPECT_LT(fbdapso, 1.0);
}

// Every reset_iterations iterations the counter, the inertia schedule and the temperature restart.
TEST(ParticleSwarm, CycleRestartRestoresTheTemperatureSchedule) {
  SwarmSettings settings;
  settings.reset_iterations = 50;
  ParticleSwarm s(settings, std::make_shared<MetropolisAcceptance>(1000.0, 0.8), {0.5, 0.0005, 0.0005, 0.02},
                  {10.0, 0.03, 0.03, 0.6}, 5);
  EXPECT_DOUBLE_EQ(s.temperature(), 1000.0);
  for (int i = 0; i < 10; ++i) s.iterate(bowl);
  EXPECT_NEAR(s.temperature(), 1000.0 * std::pow(0.8, 10), 1e-9);  // Eq. (7) once per iteration
  EXPECT_EQ(s.iterationInCycle(), 10);
  for (int i = 10; i < 50; ++i) s.iterate(bowl);
  EXPECT_EQ(s.iterationInCycle(), 0);
  EXPECT_DOUBLE_EQ(s.temperature(), 1000.0);  // restarted with the counter
  s.iterate(bowl);
  EXPECT_NEAR(s.temperature(), 800.0, 1e-9);
}

// A cycle restart re-evaluates what the data have changed and takes the rest from this iteration
// (accepted moves, personal bests at their position). The fitness here grows with time, so a value
// left from older data is lower than the present one: kept by mistake, it would win the global
// best, and the best's value would differ from the present fitness at the best.
TEST(ParticleSwarm, ARestartLeavesNoStaleFitness) {
  double t = 0.0;
  const auto f = [&t](const ParameterVector& p) { return (1.0 + t) * bowl(p) + t; };
  const std::vector<std::shared_ptr<AcceptancePolicy>> policies{
      std::make_shared<AlwaysAccept>(), std::make_shared<MetropolisAcceptance>(1000.0, 0.8),
      std::make_shared<BackfireDoubleAnnealing>(800.0, 500.0, 0.8, 0.9, 0.001)};
  for (const auto& policy : policies) {
    ParticleSwarm s(SwarmSettings{}, policy, {0.5, 0.0005, 0.0005, 0.02}, {10.0, 0.03, 0.03, 0.6}, 3);
    int restarts = 0;
    for (int i = 0; i < 500; ++i) {
      t = 0.01 * i;
      s.iterate(f);
      if (s.iterationInCycle() != 0) continue;
      ++restarts;
      EXPECT_EQ(s.bestFitness(), f(s.best())) << policy->name() << " iteration " << i;
    }
    EXPECT_EQ(restarts, 10) << policy->name();
  }
}

// The swarm decides for all particles at once with vector loops; every decision and temperature
// must be the one the policy's accept() gives particle by particle (better, equal, worse, NaN,
// draws near the Metropolis boundary where exp() decides).
TEST(Acceptance, BatchDecisionsEqualOneByOne) {
  const std::vector<std::shared_ptr<AcceptancePolicy>> policies{
      std::make_shared<AlwaysAccept>(), std::make_shared<MetropolisAcceptance>(2.0, 0.8),
      std::make_shared<BackfireDoubleAnnealing>(2.0, 1.5, 0.8, 0.9, 0.001)};
  BlockRandom rng(11);
  const std::size_t n = 64;
  for (const auto& policy : policies) {
    SwarmTemperatures batch;
    batch.resize(n);
    std::vector<ParticleTemperature> single(n);
    for (std::size_t i = 0; i < n; ++i) {
      policy->reset(single[i]);
      single[i].T *= 0.2 + rng.uniform();
      batch.set(i, single[i]);
    }
    int accepted_worse = 0, rejected = 0, near_boundary = 0;
    for (int round = 0; round < 200; ++round) {
      std::vector<double> delta(n), r(n), accepted(n);
      for (std::size_t i = 0; i < n; ++i) {
        const double u = rng.uniform();
        delta[i] = u < 0.3 ? -u : (u < 0.4 ? 0.0 : (u < 0.42 ? std::nan("") : 5.0 * (u - 0.4)));
        r[i] = rng.uniform();
        if (i % 7 == 0 && delta[i] > 0) {  // right at exp(-x): only exp() can tell
          r[i] = std::exp(-delta[i] / single[i].T);
          ++near_boundary;
        }
      }
      policy->acceptAll(n, delta.data(), r.data(), batch, accepted.data());
      for (std::size_t i = 0; i < n; ++i) {
        const bool one = policy->accept(delta[i], r[i], single[i]);
        ASSERT_EQ(accepted[i] == 1.0, one) << policy->name() << " particle " << i << " delta " << delta[i];
        ASSERT_TRUE(accepted[i] == 1.0 || accepted[i] == 0.0);
        accepted_worse += one && delta[i] > 0;
        rejected += !one;
      }
      policy->endIterationAll(n, batch);
      for (std::size_t i = 0; i < n; ++i) {
        policy->endIteration(single[i]);
        ASSERT_EQ(batch.get(i).T, single[i].T) << policy->name();
        ASSERT_EQ(batch.get(i).c2_power, single[i].c2_power) << policy->name();
        ASSERT_EQ(batch.get(i).accepted_worse, single[i].accepted_worse) << policy->name();
      }
    }
    EXPECT_GT(accepted_worse, 20) << policy->name();  // every branch of the decision was exercised
    if (policy->hasTemperature()) {
      EXPECT_GT(rejected, 20) << policy->name();
    }
    EXPECT_GT(near_boundary, 100);
  }
}

TEST(BlockRandom, UniformInTheUnitIntervalAndRepeatable) {
  BlockRandom a(5), b(5), c(6);
  std::vector<double> x(BlockRandom::blockCount(100000)), y(x.size()), z(x.size());
  a.fill(x.data(), x.size());
  b.fill(y.data(), y.size());
  c.fill(z.data(), z.size());
  EXPECT_EQ(x, y);
  EXPECT_NE(x, z);
  double sum = 0.0, below_tenth = 0.0;
  for (double v : x) {
    ASSERT_GE(v, 0.0);
    ASSERT_LT(v, 1.0);
    sum += v;
    below_tenth += v < 0.1;
  }
  const double count = static_cast<double>(x.size());
  EXPECT_NEAR(sum / count, 0.5, 0.005);        // sd of the mean 0.0009
  EXPECT_NEAR(below_tenth / count, 0.1, 0.003);  // sd 0.00095
}
