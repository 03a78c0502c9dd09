#include "pmsm_param_id/identification/particle_swarm.hpp"

#include <cmath>
#include <stdexcept>

namespace pmsm_param_id {

ParticleSwarm::ParticleSwarm(const SwarmSettings& settings, std::shared_ptr<const AcceptancePolicy> policy,
                             const ParameterVector& lower, const ParameterVector& upper, std::uint64_t seed,
                             const ParameterVector* initial_guess)
    : s_(settings), policy_(std::move(policy)), lower_(lower), rng_(seed) {
  if (s_.particles < 2) throw std::invalid_argument("swarm needs at least 2 particles");
  if (dynamic_cast<const AlwaysAccept*>(policy_.get())) policy_kind_ = PolicyKind::Pso;
  else if (dynamic_cast<const MetropolisAcceptance*>(policy_.get())) policy_kind_ = PolicyKind::Sapso;
  else if (dynamic_cast<const BackfireDoubleAnnealing*>(policy_.get())) policy_kind_ = PolicyKind::Fbdapso;
  for (int d = 0; d < kParameterCount; ++d) {
    if (!(upper[d] > lower[d])) throw std::invalid_argument("swarm bounds: lower must be < upper");
    span_[d] = upper[d] - lower[d];
  }
  swarm_.resize(static_cast<std::size_t>(s_.particles));
  for (Particle& p : swarm_) {
    for (int d = 0; d < kParameterCount; ++d) {
      p.x[d] = rng_.uniform();
      p.v[d] = (2.0 * rng_.uniform() - 1.0) * s_.v_max;
    }
    p.pbest = p.x;
    policy_->reset(p.th);
  }
  if (initial_guess) {  // particle 0 starts at the shared initial values
    for (int d = 0; d < kParameterCount; ++d)
      swarm_[0].x[d] = std::min(1.0, std::max(0.0, ((*initial_guess)[d] - lower_[d]) / span_[d]));
    swarm_[0].pbest = swarm_[0].x;
  }
  gbest_ = swarm_[0].x;
}

void ParticleSwarm::evaluateAll(const Fitness& f) {
  f_gbest_ = std::numeric_limits<double>::infinity();
  for (Particle& p : swarm_) {
    p.f = f(toParameters(p.x));
    p.f_pbest = f(toParameters(p.pbest));
    evaluations_ += 2;
    if (p.f < p.f_pbest) {
      p.f_pbest = p.f;
      p.pbest = p.x;
    }
    if (p.f_pbest < f_gbest_) {
      f_gbest_ = p.f_pbest;
      gbest_ = p.pbest;
    }
  }
  evaluated_ = true;
}

void ParticleSwarm::restartCycle(const Fitness& f) {
  // A new cycle starts like the algorithm itself: inertia w_max (via k_ = 0), temperature T1 and
  // velocities drawn at random, warm-started from the current positions and bests. Without the
  // fresh velocities a swarm that has collapsed (x = pbest = gbest, v ~ 0) can never move again,
  // even when new data show that its point is wrong (doc/algorithm.md).
  evaluateAll(f);
  for (Particle& p : swarm_) {
    policy_->reset(p.th);
    for (int d = 0; d < kParameterCount; ++d) p.v[d] = (2.0 * rng_.uniform() - 1.0) * s_.restart_velocity;
  }
}

void ParticleSwarm::setBounds(const ParameterVector& lower, const ParameterVector& upper) {
  ParameterVector span;
  for (int d = 0; d < kParameterCount; ++d) {
    if (!(upper[d] > lower[d])) throw std::invalid_argument("swarm bounds: lower must be < upper");
    span[d] = upper[d] - lower[d];
  }
  const auto remap = [&](Point& u) {
    for (int d = 0; d < kParameterCount; ++d) {
      const double value = lower_[d] + u[d] * span_[d];
      u[d] = std::min(1.0, std::max(0.0, (value - lower[d]) / span[d]));
    }
  };
  for (Particle& p : swarm_) {
    remap(p.x);
    remap(p.pbest);
    for (int d = 0; d < kParameterCount; ++d)
      p.v[d] = std::min(s_.v_max, std::max(-s_.v_max, p.v[d] * span_[d] / span[d]));
  }
  remap(gbest_);
  lower_ = lower;
  span_ = span;
  evaluated_ = false;
}

std::array<bool, kParameterCount> ParticleSwarm::bestAtBound() const {
  std::array<bool, kParameterCount> out{};
  for (int d = 0; d < kParameterCount; ++d) out[d] = gbest_[d] <= 1e-9 || gbest_[d] >= 1.0 - 1e-9;
  return out;
}

double ParticleSwarm::temperature() const {
  if (!policy_->hasTemperature()) return std::numeric_limits<double>::quiet_NaN();
  double sum = 0.0;
  for (const Particle& p : swarm_) sum += p.th.T;
  return sum / static_cast<double>(swarm_.size());
}

}  // namespace pmsm_param_id
