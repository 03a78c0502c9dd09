// One particle-swarm engine (Eq. 4-5) for PSO, SAPSO and FBDAPSO; the three differ only in the
// acceptance and temperature policy (Eq. 6-8, 15-17).
#pragma once
#include <array>
#include <cmath>
#include <cstdint>
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
/// The two bounds, for a double or for a vector of doubles (the swarm's four-lane steps use them
/// too): r below the first is surely accepted; r times the second above 1 + 1e-12 surely rejected.
template <class T>
inline T metropolisAcceptBound(T x) {
  const T x2 = x * x;
  const T x3 = x2 * x;
  return 1.0 - x + 0.5 * x2 - x3 * (1.0 / 6.0) - 1e-12;
}
template <class T>
inline T metropolisRejectFactor(T x) {
  const T x2 = x * x;
  const T x3 = x2 * x;
  return 1.0 + x + 0.5 * x2 + x3 * (1.0 / 6.0) + x2 * x2 * (1.0 / 24.0);
}
/// The bounds' verdict: 1 surely accepted, 0 surely rejected, 0.5 between them (exp() decides).
inline double metropolisBoundsVerdict(double x, double r) {
  const bool surely_accepted = r < metropolisAcceptBound(x);
  const bool surely_rejected = r * metropolisRejectFactor(x) > 1.0 + 1e-12;
  return surely_accepted ? 1.0 : (surely_rejected ? 0.0 : 0.5);
}
inline bool metropolisAccepts(double x, double r) {
  const double verdict = metropolisBoundsVerdict(x, r);
  if (verdict != 0.5) return verdict == 1.0;
  return std::exp(-x) > r;  // inside the band; also x = NaN (rejected), x = inf with r = 0 (rejected)
}

/// The temperature state of a whole swarm, field by field (entry i is particle i): what the batch
/// acceptance reads and writes. Sized to a multiple of kSwarmLanes; the entries past the swarm's
/// particles are padding and never read back.
struct SwarmTemperatures {
  std::vector<double> T, c2_power, accepted_worse;
  void resize(std::size_t n) {
    T.assign(n, 0.0);
    c2_power.assign(n, 1.0);
    accepted_worse.assign(n, 0.0);
  }
  ParticleTemperature get(std::size_t i) const { return {T[i], static_cast<int>(accepted_worse[i]), c2_power[i]}; }
  void set(std::size_t i, const ParticleTemperature& th) {
    T[i] = th.T;
    accepted_worse[i] = th.accepted_worse;
    c2_power[i] = th.c2_power;
  }
};
/// The swarm's per-particle arrays are padded to a multiple of this (four doubles: one AVX register),
/// so that the vector loops need no remainder.
constexpr std::size_t kSwarmLanes = 4;

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
  /// accept() for particles [0, n) at once (n a multiple of kSwarmLanes): accepted[i] is 1
  /// (accepted) or 0; the same decisions and temperatures as accept() one particle at a time. The
  /// shipped policies do it in loops the compiler turns into vector instructions; this default
  /// calls accept().
  virtual void acceptAll(std::size_t n, const double* delta, const double* r, SwarmTemperatures& th,
                         double* accepted) const;
  /// endIteration() for particles [0, n).
  virtual void endIterationAll(std::size_t n, SwarmTemperatures& th) const;
};

/// Plain PSO: every new position is taken.
class AlwaysAccept final : public AcceptancePolicy {
 public:
  std::string name() const override { return "pso"; }
  void reset(ParticleTemperature& th) const override { th = {}; }
  bool accept(double, double, ParticleTemperature&) const override { return true; }
  void endIteration(ParticleTemperature&) const override {}
  bool hasTemperature() const override { return false; }
  void acceptAll(std::size_t n, const double* delta, const double* r, SwarmTemperatures& th,
                 double* accepted) const override;
  void endIterationAll(std::size_t, SwarmTemperatures&) const override {}
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
  void acceptAll(std::size_t n, const double* delta, const double* r, SwarmTemperatures& th,
                 double* accepted) const override;
  void endIterationAll(std::size_t n, SwarmTemperatures& th) const override;

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
  void acceptAll(std::size_t n, const double* delta, const double* r, SwarmTemperatures& th,
                 double* accepted) const override;
  void endIterationAll(std::size_t, SwarmTemperatures&) const override {}

 private:
  double T1_, T2_, C1_, C2_, zero_delta_;
};

struct SwarmSettings {
  int particles = 20;
  double c1 = 1.6, c2 = 1.6;
  double w_max = 0.9, w_min = 0.4;
  int reset_iterations = 50;   ///< k_max of Eq. (5); the counter (and temperature) restarts here
  double v_max = 0.2;          ///< velocity limit per dimension, fraction of the search range
  double restart_velocity = 0.002;  ///< velocities re-drawn in +-this (fraction of range) each cycle
};

/// Minimises f over the box [lower, upper] in coordinates normalised to [0, 1] per dimension.
class ParticleSwarm {
 public:
  ParticleSwarm(const SwarmSettings& settings, std::shared_ptr<const AcceptancePolicy> policy,
                const ParameterVector& lower, const ParameterVector& upper, std::uint64_t seed,
                const ParameterVector* initial_guess = nullptr);

  /// Moves the search box: positions, bests and velocities keep their parameter values (clamped
  /// into the new box); everything is re-evaluated at the next iteration.
  void setBounds(const ParameterVector& lower, const ParameterVector& upper);
  /// The global best lies on a face of the box, per dimension.
  std::array<bool, kParameterCount> bestAtBound() const;
  /// Re-evaluates every position and personal best with f (the fitness changes as data arrives),
  /// then the personal and global bests. A personal best equal to its position takes the
  /// position's value (the same point: the same number) instead of a second evaluation.
  template <class F>
  void evaluateAll(const F& f) {
    evaluateStale(f, false);
  }
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
  /// The swarm is stored by dimension (structure of arrays): entry [d * padded_ + i] is particle i's
  /// coordinate d, so that each step of an iteration is one loop over all particles that the
  /// compiler turns into vector instructions.
  std::size_t n_ = 0;
  double& at(std::vector<double>& a, int d, std::size_t i) { return a[static_cast<std::size_t>(d) * padded_ + i]; }
  double at(const std::vector<double>& a, int d, std::size_t i) const {
    return a[static_cast<std::size_t>(d) * padded_ + i];
  }
  ParameterVector toParameters(const Point& u) const {
    ParameterVector p;
    for (int d = 0; d < kParameterCount; ++d) p[d] = lower_[d] + u[d] * span_[d];
    return p;
  }
  Point pointOf(const std::vector<double>& a, std::size_t i) const {
    Point u;
    for (int d = 0; d < kParameterCount; ++d) u[d] = at(a, d, i);
    return u;
  }
  ParameterVector parametersOf(const std::vector<double>& a, std::size_t i) const { return toParameters(pointOf(a, i)); }
  /// evaluateAll(), where `moves_current` leaves out the positions this iteration's accepted moves
  /// reached: their fitness was computed on the present data (the cycle restart, right after an
  /// iteration on the same sample).
  template <class F>
  void evaluateStale(const F& f, bool moves_current) {
    const std::size_t m = gatherStale(moves_current);
    evaluate(f, batch_points_.data(), m, stale_f_.data());
    takeStale(moves_current);
  }
  /// The points evaluateStale() evaluates, in batch_points_, particle by particle (the position,
  /// then the personal best); their count.
  std::size_t gatherStale(bool moves_current);
  /// Their values (stale_f_) into f_ and f_pbest_, then the personal and global bests.
  void takeStale(bool moves_current);
  /// What gatherStale() evaluates and takeStale() takes back, in the same order: particle i's
  /// position unless its move was accepted on the present data, and its personal best where it is
  /// not at the position.
  bool positionStale(std::size_t i, bool moves_current) const { return !(moves_current && accepted_[i] > 0.5); }
  bool bestApart(std::size_t i) const { return pointOf(pbest_, i) != pointOf(x_, i); }
  /// f at points[0, m) into out: in one call where F has batch().
  template <class F>
  void evaluate(const F& f, const ParameterVector* points, std::size_t m, double* out) {
    if constexpr (HasBatch<F>::value) {
      f.batch(points, m, out);
    } else {
      for (std::size_t i = 0; i < m; ++i) out[i] = f(points[i]);
    }
    evaluations_ += m;
  }
  /// A new cycle: the stale values re-evaluated, temperatures reset, velocities re-drawn.
  template <class F>
  void restartCycle(const F& f) {
    evaluateStale(f, true);
    restartTemperaturesAndVelocities();
  }
  void restartTemperaturesAndVelocities();
  /// Eq. (4) for every particle: velocities and candidate positions (move_x_, move_v_, and in
  /// parameter units batch_points_) from this iteration's draws r_.
  void proposeMoves(double inertia);
  /// Eq. (15)-(17) for every particle (move_f_ holds the candidates' fitness), then the moves,
  /// personal bests and the global best.
  void acceptMoves();
  std::size_t padded_ = 0;  // n_ rounded up to kSwarmLanes: the length of every per-particle array

  SwarmSettings s_;
  std::shared_ptr<const AcceptancePolicy> policy_;
  ParameterVector lower_, span_;
  std::vector<double> x_, v_, pbest_;          // positions, velocities, personal bests (by dimension)
  std::vector<double> f_, f_pbest_;            // fitness at x_ and at pbest_
  SwarmTemperatures th_;
  std::vector<double> delta_;                  // this iteration's normalised fitness increase (Eq. 15)
  std::vector<double> accepted_;               // this iteration's decisions: 1 or 0
  std::vector<double> move_x_, move_v_, move_f_;  // this iteration's candidates (reused, no allocation)
  std::vector<double> r_;  // this iteration's draws: r1, r2 (by dimension), the Metropolis r per particle
  // The points to evaluate in parameter units: the candidates (padded), or the stale positions and
  // personal bests (up to two per particle).
  std::vector<ParameterVector> batch_points_;
  std::vector<double> stale_f_;  // the values of the stale points
  /// F has batch(const ParameterVector*, size_t, double*): every particle in one call.
  template <class F, class = void>
  struct HasBatch : std::false_type {};
  template <class F>
  struct HasBatch<F, std::void_t<decltype(std::declval<const F&>().batch(nullptr, std::size_t{}, nullptr))>>
      : std::true_type {};
  Point gbest_{};
  double f_gbest_ = std::numeric_limits<double>::infinity();
  BlockRandom rng_;
  int k_ = 0;
  bool evaluated_ = false;
  std::uint64_t total_iterations_ = 0, evaluations_ = 0, worse_proposed_ = 0, worse_accepted_ = 0;
};

template <class F>
void ParticleSwarm::iterate(const F& f) {
  if (!evaluated_) evaluateAll(f);
  const double w = s_.w_max - (s_.w_max - s_.w_min) * static_cast<double>(k_) / s_.reset_iterations;
  const std::size_t n = n_;
  // 1. Every particle's move (Eq. 4) and its fitness, before any acceptance decision: the update is
  //    synchronous (gbest changes at the end of the iteration), so the order does not matter, and
  //    20 independent evaluations back to back keep the CPU busy.
  proposeMoves(w);
  evaluate(f, batch_points_.data(), n, move_f_.data());  // all particles in one call where f can
  // 2. Acceptance (Eq. 15-17), temperatures (Eq. 7-8), personal and global bests.
  acceptMoves();
  ++total_iterations_;
  if (++k_ >= s_.reset_iterations) {
    k_ = 0;
    restartCycle(f);
  }
}

}  // namespace pmsm_param_id
