// pmsm_tool simulate: one scenario's run, every sample to CSV.
#include <cstdio>

#include "commands.hpp"
#include "pmsm_param_id/io/config_error.hpp"
#include "pmsm_param_id/io/sample_csv.hpp"
#include "pmsm_param_id/simulation/telemetry.hpp"
#include "tool_common.hpp"

namespace pmsm_param_id::tool {

int runSimulate(const std::string& scenario_path, const std::string& csv, long seed, double duration,
                double telemetry_period, const std::string& format, double clock_start) {
  Scenario s = loadScenario(scenario_path);
  if (seed >= 0) s.seed = static_cast<std::uint64_t>(seed);
  if (duration > 0) s.duration = duration;
  if (telemetry_period != 0 && !(telemetry_period >= s.drive.sample_period && telemetry_period <= s.duration))
    throw ConfigError("--telemetry-period: expected from the drive's sample period to the run's duration [s]");
  std::vector<SimulatedSample> samples = simulate(s);
  if (telemetry_period > 0) {
    samples = averageToTelemetry(samples, telemetry_period);
    if (format.empty()) writeSampleCsv(csv, samples);
    else writeSampleCsv(csv, samples, loadLogFormat(format), clock_start);
    std::printf("wrote %zu telemetry samples (means over %.3g s of a %.4g s run) to %s\n", samples.size(),
                telemetry_period, s.duration, csv.c_str());
    return 0;
  }
  if (format.empty()) writeSampleCsv(csv, samples);
  else writeSampleCsv(csv, samples, loadLogFormat(format), clock_start);
  std::printf("wrote %zu samples (%.4g s at T_s = %.3g s) to %s\n", samples.size(), s.duration,
              s.drive.sample_period, csv.c_str());
  return 0;
}

}  // namespace pmsm_param_id::tool
