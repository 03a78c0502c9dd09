#include <algorithm>
#include <stdexcept>

#include "pmsm_param_id/identification/identifiers.hpp"

namespace pmsm_param_id {

std::shared_ptr<const AcceptancePolicy> makeAcceptancePolicy(const IdentifierConfig& c) {
  if (c.method == "sapso") return std::make_shared<MetropolisAcceptance>(c.sapso_T1, c.sapso_C1);
  if (c.method == "fbdapso")
    return std::make_shared<BackfireDoubleAnnealing>(c.fbdapso_T1, c.fbdapso_T2, c.fbdapso_C1, c.fbdapso_C2,
                                                     c.fbdapso_zero_delta);
  if (c.method == "pso") return std::make_shared<AlwaysAccept>();
  throw std::invalid_argument("no acceptance policy for method '" + c.method + "'");
}

SwarmIdentifier::SwarmIdentifier(const IdentifierConfig& config) : OnlineIdentifier(config) {
  if (config.fitness != FitnessKind::Block)
    output_error_ = std::make_unique<OutputErrorWindow>(config.fitness, config.fitness_window_samples,
                                                        config.window.voltage_delay_samples);
}

double SwarmIdentifier::fitnessAt(const ParameterVector& p) const {
  if (!output_error_) return OnlineIdentifier::fitnessAt(p);
  return output_error_->ready() ? (*output_error_)(p) : std::numeric_limits<double>::quiet_NaN();
}

namespace {
/// The paper's fitness as the swarm sees it: one vector or every particle at once.
struct OutputErrorFitness {
  const OutputErrorWindow* window;
  double operator()(const ParameterVector& p) const { return (*window)(p); }
  void batch(const ParameterVector* p, std::size_t n, double* out) const { window->batch(p, n, out); }
};
/// The block fitness (or its cross-saturation form) as the swarm sees it: a whole iteration's moves
/// in one call into the statistics, where the point-by-point form is inlined.
template <bool kCrossSaturation>
struct BlockFitness {
  const BlockStatistics* stats;
  double operator()(const ParameterVector& p) const {
    return kCrossSaturation ? stats->fitnessWithCrossSaturation(p) : stats->fitness(p);
  }
  void batch(const ParameterVector* p, std::size_t n, double* out) const {
    if constexpr (kCrossSaturation) stats->fitnessWithCrossSaturation(p, n, out);
    else stats->fitness(p, n, out);
  }
};
}  // namespace

void SwarmIdentifier::restart() {
  face_restarts_ = 0;  // the start (again, after a reset): the configured seed's stream
  newSwarm();
}

void SwarmIdentifier::newSwarm() {
  // Particle 0 starts at the configured initial values when there are any (the paper's "far away"
  // start); otherwise every particle starts at random in the data-driven box. A start again off a
  // face draws from another stream of the same seed.
  const std::uint64_t seed = config_.seed + face_restarts_ * 0x9E3779B97F4A7C15ull;
  swarm_ = std::make_unique<ParticleSwarm>(config_.swarm, makeAcceptancePolicy(config_), box_.lower, box_.upper, seed,
                                           config_.search.has_initial ? &config_.search.initial : nullptr);
}

void SwarmIdentifier::searchBoxMoved() {
  if (swarm_) swarm_->setBounds(box_.lower, box_.upper);
}

double SwarmIdentifier::temperature() const {
  return swarm_ ? swarm_->temperature() : std::numeric_limits<double>::quiet_NaN();
}

std::array<bool, kParameterCount> SwarmIdentifier::atBound() const {
  return swarm_ ? swarm_->bestAtBound() : std::array<bool, kParameterCount>{};
}

void SwarmIdentifier::update(const Sample& s, bool, bool continuity_broken) {
  if (output_error_) {
    if (continuity_broken) output_error_->clear();
    output_error_->push(s);
    if (!output_error_->ready() || !swarm_) return;
    iterate(OutputErrorFitness{output_error_.get()});
    return;
  }
  if (!stats_.hasBlocks() || !swarm_) return;
  if (stats_.crossSaturationSet()) iterate(BlockFitness<true>{&stats_});
  else iterate(BlockFitness<false>{&stats_});
}

template <class F>
void SwarmIdentifier::iterate(const F& fitness) {
  for (int i = 0; i < config_.iterations_per_sample; ++i) {
    swarm_->iterate(fitness);
    // At a new cycle whose best sits on a face of the box: does the box still hold the data's
    // optimum? (The base class also checks every ten cycles' worth of samples.)
    if (swarm_->iterationInCycle() == 0) {
      const auto edge = swarm_->bestAtBound();
      if (std::find(edge.begin(), edge.end(), true) == edge.end()) continue;
      if (refreshSearchBox()) continue;  // the box followed the data
      // The box holds the data's optimum well inside, and a consistent fit determines it, yet the
      // swarm's best sits on a face: the swarm followed a transient there (the optimum crossed the
      // face while the fit was poor) and is held by it, its particles along a narrow ridge of the
      // fitness (R_s against psi_f at one operating point) that the cycle's velocity kicks do not
      // climb. Measured: FBDAPSO's R_s on the face for 1.3 s after a 4 % demagnetisation, psi_f
      // 7 % off. The swarm starts again at random in the box, as at the start.
      bool held = false;
      for (int p = 0; p < kParameterCount; ++p) held = held || (edge[static_cast<std::size_t>(p)] && optimumInside(p));
      if (held) {
        ++face_restarts_;
        newSwarm();
      }
    }
  }
}

ParameterVector SwarmIdentifier::current() const { return swarm_ ? swarm_->best() : nanVector(); }

WlsIdentifier::WlsIdentifier(const IdentifierConfig& config) : OnlineIdentifier(config) {}

void WlsIdentifier::restart() {
  parameters_ = box_.centre;
  blocks_at_fit_ = 0;
}

ParameterVector WlsIdentifier::current() const {
  if (stats_.blocks() == blocks_at_fit_) return parameters_;
  blocks_at_fit_ = stats_.blocks();
  const FitCheck fit = checkFit(stats_, config_.assessment, parameters_, false, config_.inverter.estimate_voltage,
                                stats_.inverterVoltage(), config_.magnetics.cross_saturation);
  if (!fit.available) return parameters_;
  for (int p = 0; p < kParameterCount; ++p)
    if (fit.determined[p] && plausible(p, fit.optimum[p])) parameters_[p] = fit.optimum[p];
  return parameters_;
}

std::unique_ptr<OnlineIdentifier> makeIdentifier(const IdentifierConfig& config) {
  validate(config);
  if (config.method == "wls") return std::make_unique<WlsIdentifier>(config);
  if (config.method == "ekf") return std::make_unique<EkfIdentifier>(config);
  if (config.method == "rls") return std::make_unique<RlsIdentifier>(config);
  return std::make_unique<SwarmIdentifier>(config);
}

}  // namespace pmsm_param_id
