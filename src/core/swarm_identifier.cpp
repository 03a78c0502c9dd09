#include "pmsm_param_id/identifiers.hpp"

#include <stdexcept>

namespace pmsm_param_id {

std::shared_ptr<const AcceptancePolicy> makeAcceptancePolicy(const IdentifierConfig& c) {
  if (c.method == "sapso") return std::make_shared<MetropolisAcceptance>(c.sapso_T1, c.sapso_C1);
  if (c.method == "fbdapso")
    return std::make_shared<BackfireDoubleAnnealing>(c.fbdapso_T1, c.fbdapso_T2, c.fbdapso_C1, c.fbdapso_C2,
                                                     c.fbdapso_zero_delta);
  if (c.method == "pso") return std::make_shared<AlwaysAccept>();
  throw std::invalid_argument("no acceptance policy for method '" + c.method + "'");
}

SwarmIdentifier::SwarmIdentifier(const IdentifierConfig& config) : OnlineIdentifier(config) { restart(); }

void SwarmIdentifier::restart() {
  swarm_ = std::make_unique<ParticleSwarm>(config_.swarm, makeAcceptancePolicy(config_), config_.lower, config_.upper,
                                           config_.seed, &config_.initial);
}

void SwarmIdentifier::update(const Sample&, bool, bool) {
  if (!stats_.hasBlocks()) return;
  const HorizonStatistics& stats = stats_;
  const auto fitness = [&stats](const ParameterVector& p) { return stats.fitness(p); };
  for (int i = 0; i < config_.iterations_per_sample; ++i) swarm_->iterate(fitness);
}

ParameterVector SwarmIdentifier::current() const {
  return stats_.hasBlocks() ? swarm_->best() : config_.initial;
}

std::unique_ptr<OnlineIdentifier> makeIdentifier(const IdentifierConfig& config) {
  validate(config);
  if (config.method == "ekf") return std::make_unique<EkfIdentifier>(config);
  if (config.method == "rls") return std::make_unique<RlsIdentifier>(config);
  return std::make_unique<SwarmIdentifier>(config);
}

}  // namespace pmsm_param_id
