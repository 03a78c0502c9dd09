// Microbenchmarks (Google Benchmark): the pieces that run per sample.
#include <benchmark/benchmark.h>

#include "pmsm_param_id/simulation/drive_simulator.hpp"
#include "pmsm_param_id/identification/block_statistics.hpp"
#include "pmsm_param_id/identification/identifier_config.hpp"
#include "pmsm_param_id/identification/identifiers.hpp"
#include "pmsm_param_id/identification/online_identifier.hpp"
#include "../src/tools/perf_points.hpp"

using namespace pmsm_param_id;

namespace {
const std::vector<SimulatedSample>& recording() {
  static const std::vector<SimulatedSample> data = [] {
    Scenario s = loadScenario(std::string(PMSM_SOURCE_DIR) + "/config/scenarios/wc1_drive.yaml");
    DriveSimulator sim(s);
    std::vector<SimulatedSample> out;
    while (!sim.done()) out.push_back(sim.step());
    return out;
  }();
  return data;
}
/// The recording over and over, with stamps that keep increasing (one pass after the other).
class EndlessRecording {
 public:
  Sample next() {
    const auto& data = recording();
    Sample s = data[k_].sample;
    s.t += offset_;
    if (++k_ == data.size()) {
      k_ = 0;
      offset_ += data.back().sample.t + 1e-4;
    }
    return s;
  }

 private:
  std::size_t k_ = 0;
  double offset_ = 0.0;
};
IdentifierConfig paperBox() {
  return loadIdentifierConfig(std::string(PMSM_SOURCE_DIR) + "/config/identifiers/paper.yaml");
}
BlockStatistics filledStatistics() {
  BlockStatistics stats;
  stats.configure(1e-4);
  for (const auto& s : recording()) stats.add(s.sample);
  return stats;
}
}  // namespace

// One fitness evaluation over the default window (independent of its length), at points that
// differ in every parameter as a swarm's do (perf_points.hpp).
static void BM_FitnessEvaluation(benchmark::State& state) {
  const BlockStatistics stats = filledStatistics();
  const std::vector<ParameterVector> points = perfPoints({2.9, 0.0046, 0.0134, 0.178}, 20);
  std::size_t k = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(stats.fitness(points[k]));
    k = k + 1 == points.size() ? 0 : k + 1;
  }
}
BENCHMARK(BM_FitnessEvaluation);

// Adding one sample to the block statistics (block integrals + rank-1 updates).
static void BM_StatisticsUpdate(benchmark::State& state) {
  BlockStatistics stats;
  stats.configure(1e-4);
  EndlessRecording samples;
  for (auto _ : state) stats.add(samples.next());
}
BENCHMARK(BM_StatisticsUpdate);

// One swarm iteration (20 particles: 20 evaluations, velocity and acceptance updates).
static void BM_SwarmIteration(benchmark::State& state, const char* method) {
  const BlockStatistics stats = filledStatistics();
  IdentifierConfig c = paperBox();
  c.method = method;
  ParticleSwarm swarm(c.swarm, makeAcceptancePolicy(c), c.search.lower, c.search.upper, 1);
  const auto f = [&stats](const ParameterVector& p) { return stats.fitness(p); };
  for (auto _ : state) swarm.iterate(f);
}
BENCHMARK_CAPTURE(BM_SwarmIteration, pso, "pso");
BENCHMARK_CAPTURE(BM_SwarmIteration, sapso, "sapso");
BENCHMARK_CAPTURE(BM_SwarmIteration, fbdapso, "fbdapso");

// One full online update per method (what the identifier node pays per sample).
static void BM_OnlineUpdate(benchmark::State& state, const char* method) {
  IdentifierConfig c;
  c.method = method;
  auto id = makeIdentifier(c);
  EndlessRecording samples;
  for (auto _ : state) id->process(samples.next());
}
BENCHMARK_CAPTURE(BM_OnlineUpdate, fbdapso, "fbdapso");
BENCHMARK_CAPTURE(BM_OnlineUpdate, sapso, "sapso");
BENCHMARK_CAPTURE(BM_OnlineUpdate, pso, "pso");
BENCHMARK_CAPTURE(BM_OnlineUpdate, ekf, "ekf");
BENCHMARK_CAPTURE(BM_OnlineUpdate, rls, "rls");

BENCHMARK_MAIN();
