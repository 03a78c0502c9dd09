// One particle-swarm engine (Eq. 4-5) for PSO, SAPSO and FBDAPSO; the three differ only in the
// acceptance and temperature policy (Eq. 6-8, 15-17).
#pragma once
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "pmsm_param_id/model/motor_model.hpp"
#include "pmsm_param_id/identification/random.hpp"

namespace pmsm_param_id {

/// Temperature state of one particle (the paper's step 6 writes T_j: one per particle).
struct ParticleTemperature {
  double T = 0.0;         ///< current temperature [-] (fitness differences are normalised, see doc)
  int accepted_worse = 0; ///< d of Eq. (8): worse (or equal) positions accepted since the reset
  double c2_power = 1.0;  ///< C2^d, kept incrementally (pow() per acceptance was a third of the cost)
};

/// Metropolis test exp(-x) > r for x >= 0, deciding without exp() wherever the answer is already
/// known from bounds on exp(-x): for x >= 0 the alternating Taylor series gives
///   1 - x + x^2/2 - x^3/6  <=  exp(-x)  <=  1 / (1 + x + x^2/2 + x^3/6 + x^4/24).
/// The margins (1e-12) exceed the rounding of the bounds, so every decision is the one exp() gives;
/// exp() is left for r inside the band between the bounds: 0.3 % of the draws at x = 0.5, 4 % at
/// x = 1, 14 % at x = 2, under 3 % beyond x = 5.
inline bool metropolisAccepts(double x, double r) {
  const double x2 = x * x;
  const double x3 = x2 * x;
  const bool surely_accepted = r < 1.0 - x + 0.5 * x2 - x3 * (1.0 / 6.0) - 1e-12;
  const bool surely_rejected = r * (1.0 + x + 0.5 * x2 + x3 * (1.0 / 6.0) + x2 * x2 * (1.0 / 24.0)) > 1.0 + 1e-12;
  if (surely_accepted || surely_rejected) return surely_accepted;
  return std::exp(-x) > r;  // inside the band; also x = NaN (rejected), x = inf with r = 0 (rejected)
}

class AcceptancePolicy {
 public:
  virtual ~AcceptancePolicy() = default;
  virtual std::string name() const = 0;
  /// Temperature at the start and at every iteration-counter reset.
  virtual void reset(ParticleTemperature& th) const = 0;
  /// Decides whether a particle moves to its new position; delta is the normalised fitness
  /// increase (Eq. 15), r a uniform draw in [0, 1). Updates the temperature as the method says.
  virtual bool accept(double delta, double r, ParticleTemperature& th) const = 0;
  /// Called once per particle at the end of every swarm iteration.
  virtual void endIteration(ParticleTemperature& th) const = 0;
  virtual bool hasTemperature() const { return true; }
};

/// Plain PSO: every new position is taken.
class AlwaysAccept final : public AcceptancePolicy {
 public:
  std::string name() const override { return "pso"; }
  void reset(ParticleTemperature& th) const override { th = {}; }
  bool accept(double, double, ParticleTemperature&) const override { return true; }
  void endIteration(ParticleTemperature&) const override {}
  bool hasTemperature() const override { return false; }
};

/// SAPSO: Metropolis acceptance (Eq. 16) and geometric annealing T <- C1 T every iteration (Eq. 7).
class MetropolisAcceptance final : public AcceptancePolicy {
 public:
  MetropolisAcceptance(double T1, double C1) : T1_(T1), C1_(C1) {}
  std::string name() const override { return "sapso"; }
  void reset(ParticleTemperature& th) const override { th = {T1_, 0, 1.0}; }
  bool accept(double delta, double r, ParticleTemperature& th) const override {
    if (delta <= 0.0) return true;  // Eq. (16)
    return metropolisAccepts(delta / th.T, r);
  }
  void endIteration(ParticleTemperature& th) const override { th.T *= C1_; }

 private:
  double T1_, C1_;
};

/// FBDAPSO: Eq. (17) acceptance (delta = 0 counts as zero_delta); accepting a worse position
/// tempers T <- T + C2^d T2 (Eq. 8); every accepted move anneals T <- C1 T (Eq. 7, step 9);
/// a rejected move leaves T as it is (step 6 returns to step 4).
class BackfireDoubleAnnealing final : public AcceptancePolicy {
 public:
  BackfireDoubleAnnealing(double T1, double T2, double C1, double C2, double zero_delta)
      : T1_(T1), T2_(T2), C1_(C1), C2_(C2), zero_delta_(zero_delta) {}
  std::string name() const override { return "fbdapso"; }
  void reset(ParticleTemperature& th) const override { th = {T1_, 0, 1.0}; }
  bool accept(double delta, double r, ParticleTemperature& th) const override {
    if (delta < 0.0) {  // better: accepted, general annealing (Eq. 7)
      th.T *= C1_;
      return true;
    }
    const double d = delta == 0.0 ? zero_delta_ : delta;  // Eq. (17)
    if (metropolisAccepts(d / th.T, r)) {
      ++th.accepted_worse;  // tempering (Eq. 8), then general annealing (step 9)
      th.c2_power *= C2_;   // = C2^d
      th.T = C1_ * (th.T + th.c2_power * T2_);
      return true;
    }
    return false;
  }
  void endIteration(ParticleTemperature&) const override {}

 private:
  double T1_, T2_, C1_, C2_, zero_delta_;
};

struct SwarmSettings {
  int particles = 20;
  double c1 = 1.6, c2 = 1.6;
  double w_max = 0.9, w_min = 0.4;
  int reset_iterations = 50;   ///< k_max of Eq. (5); the counter (and temperature) restarts here
  double v_max = 0.2;          ///< velocity limit per dimension, fraction of the search range
  double restart_velocity = 0.02;  ///< velocities re-drawn in +-this (fraction of range) each cycle
};

/// Minimises f over the box [lower, upper] in coordinates normalised to [0, 1] per dimension.
class ParticleSwarm {
 public:
  using Fitness = std::function<double(const ParameterVector&)>;

  ParticleSwarm(const SwarmSettings& settings, std::shared_ptr<const AcceptancePolicy> policy,
                const ParameterVector& lower, const ParameterVector& upper, std::uint64_t seed,
                const ParameterVector* initial_guess = nullptr);

  /// Moves the search box: positions, bests and velocities keep their parameter values (clamped
  /// into the new box); everything is re-evaluated at the next iteration.
  void setBounds(const ParameterVector& lower, const ParameterVector& upper);
  /// The global best lies on a face of the box, per dimension.
  std::array<bool, kParameterCount> bestAtBound() const;
  /// Re-evaluates every position and personal best with f (the fitness changes as data arrives).
  void evaluateAll(const Fitness& f);
  /// One iteration of Eq. (4) with the policy's acceptance; counter reset every reset_iterations.
  template <class F>
  void iterate(const F& f);

  ParameterVector best() const { return toParameters(gbest_); }
  double bestFitness() const { return f_gbest_; }
  int iterationInCycle() const { return k_; }
  std::uint64_t iterations() const { return total_iterations_; }
  std::uint64_t evaluations() const { return evaluations_; }
  /// Moves to a worse position proposed and accepted so far: what tells the policies apart.
  std::uint64_t worseProposed() const { return worse_proposed_; }
  std::uint64_t worseAccepted() const { return worse_accepted_; }
  /// Mean temperature over the particles (NaN for PSO).
  double temperature() const;
  const AcceptancePolicy& policy() const { return *policy_; }

  using Point = std::array<double, kParameterCount>;  // normalised [0, 1]

 private:
  struct Particle {
    Point x{}, v{}, pbest{};
    double f = std::numeric_limits<double>::infinity();
    double f_pbest = std::numeric_limits<double>::infinity();
    ParticleTemperature th;
  };
  ParameterVector toParameters(const Point& u) const {
    ParameterVector p;
    for (int d = 0; d < kParameterCount; ++d) p[d] = lower_[d] + u[d] * span_[d];
    return p;
  }
  void restartCycle(const Fitness& f);
  /// One iteration with the policy's concrete type: the shipped policies are final classes, so
  /// accept() and endIteration() are inlined into the loop (in a profile of FBDAPSO's iteration
  /// the 40 virtual calls and exp() were a fifth of its time); any other policy goes through the
  /// base class.
  template <class F, class Policy>
  void iterateWith(const F& f, const Policy& policy);
  enum class PolicyKind { Pso, Sapso, Fbdapso, Other };
  PolicyKind policy_kind_ = PolicyKind::Other;

  SwarmSettings s_;
  std::shared_ptr<const AcceptancePolicy> policy_;
  ParameterVector lower_, span_;
  std::vector<Particle> swarm_;
  struct Move {
    Point x{}, v{};
    double f = 0.0;
  };
  std::vector<Move> moves_;  // this iteration's candidate positions (reused, no allocation per sample)
  std::vector<ParameterVector> batch_points_;  // the same in parameter units, for a batch fitness
  std::vector<double> batch_fitness_;
  /// F has batch(const ParameterVector*, size_t, double*): every particle in one call.
  template <class F, class = void>
  struct HasBatch : std::false_type {};
  template <class F>
  struct HasBatch<F, std::void_t<decltype(std::declval<const F&>().batch(nullptr, std::size_t{}, nullptr))>>
      : std::true_type {};
  Point gbest_{};
  double f_gbest_ = std::numeric_limits<double>::infinity();
  FastRandom rng_;
  int k_ = 0;
  bool evaluated_ = false;
  std::uint64_t total_iterations_ = 0, evaluations_ = 0, worse_proposed_ = 0, worse_accepted_ = 0;
};

template <class F>
void ParticleSwarm::iterate(const F& f) {
  switch (policy_kind_) {
    case PolicyKind::Pso: return iterateWith(f, static_cast<const AlwaysAccept&>(*policy_));
    case PolicyKind::Sapso: return iterateWith(f, static_cast<const MetropolisAcceptance&>(*policy_));
    case PolicyKind::Fbdapso: return iterateWith(f, static_cast<const BackfireDoubleAnnealing&>(*policy_));
    case PolicyKind::Other: break;
  }
  iterateWith(f, *policy_);
}

template <class F, class Policy>
void ParticleSwarm::iterateWith(const F& f, const Policy& policy) {
  if (!evaluated_) evaluateAll(f);
  const double w = s_.w_max - (s_.w_max - s_.w_min) * static_cast<double>(k_) / s_.reset_iterations;
  const double scale = std::max(std::abs(f_gbest_), 1e-300);  // Delta f is relative to the best
  const bool thermal = policy.hasTemperature();
  const std::size_t n = swarm_.size();
  // 1. Every particle's move (Eq. 4) and its fitness, before any acceptance decision: the update is
  //    synchronous (gbest changes at the end of the iteration), so the order does not matter, and
  //    20 independent evaluations back to back keep the CPU busy between unpredictable branches.
  moves_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    Particle& p = swarm_[i];
    Move& m = moves_[i];
    for (int d = 0; d < kParameterCount; ++d) {
      double r1, r2;
      rng_.uniformPair(r1, r2);
      double v = w * p.v[d] + s_.c1 * r1 * (p.pbest[d] - p.x[d]) + s_.c2 * r2 * (gbest_[d] - p.x[d]);
      v = std::min(std::max(v, -s_.v_max), s_.v_max);
      double x = p.x[d] + v;
      if (x < 0.0) { x = 0.0; v = 0.0; }
      if (x > 1.0) { x = 1.0; v = 0.0; }
      m.x[d] = x;
      m.v[d] = v;
    }
  }
  if constexpr (HasBatch<F>::value) {  // all particles at once (the output-error fitness)
    batch_points_.resize(n);
    batch_fitness_.resize(n);
    for (std::size_t i = 0; i < n; ++i) batch_points_[i] = toParameters(moves_[i].x);
    f.batch(batch_points_.data(), n, batch_fitness_.data());
    for (std::size_t i = 0; i < n; ++i) moves_[i].f = batch_fitness_[i];
  } else {
    for (Move& m : moves_) m.f = f(toParameters(m.x));
  }
  evaluations_ += n;
  // 2. Acceptance (Eq. 15-17), temperatures (Eq. 7-8), personal and global bests.
  Point best = gbest_;
  for (std::size_t i = 0; i < n; ++i) {
    Particle& p = swarm_[i];
    const Move& m = moves_[i];
    const double delta = (m.f - p.f) / scale;
    const double r = thermal && delta >= 0 ? rng_.uniform() : 0.0;
    const bool accepted = policy.accept(delta, r, p.th);
    const bool worse = delta > 0;  // counted without a branch: the outcome is random
    worse_proposed_ += worse;
    worse_accepted_ += worse & accepted;
    if (accepted) {
      p.x = m.x;
      p.v = m.v;
      p.f = m.f;
      if (m.f < p.f_pbest) {
        p.f_pbest = m.f;
        p.pbest = m.x;
        if (m.f < f_gbest_) {
          f_gbest_ = m.f;
          best = m.x;
        }
      }
    }
    policy.endIteration(p.th);
  }
  gbest_ = best;
  ++total_iterations_;
  if (++k_ >= s_.reset_iterations) {
    k_ = 0;
    restartCycle(f);
  }
}

}  // namespace pmsm_param_id
