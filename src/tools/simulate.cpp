// pmsm_tool simulate: one scenario's run, every sample to CSV.
#include <cstdio>

#include "commands.hpp"
#include "pmsm_param_id/io/sample_csv.hpp"
#include "tool_common.hpp"

namespace pmsm_param_id::tool {

int runSimulate(const std::string& scenario_path, const std::string& csv, long seed, double duration) {
  Scenario s = loadScenario(scenario_path);
  if (seed >= 0) s.seed = static_cast<std::uint64_t>(seed);
  if (duration > 0) s.duration = duration;
  const std::vector<SimulatedSample> samples = simulate(s);
  writeSampleCsv(csv, samples);
  std::printf("wrote %zu samples (%.4g s at T_s = %.3g s) to %s\n", samples.size(), s.duration,
              s.drive.sample_period, csv.c_str());
  return 0;
}

}  // namespace pmsm_param_id::tool
