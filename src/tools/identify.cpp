// pmsm_tool identify: R_s, L_d, L_q, psi_f (and the map of the motor) from a drive log.
#include <cmath>
#include <cstdio>
#include <string>

#include "commands.hpp"
#include "pmsm_param_id/identification/motor_map.hpp"
#include "pmsm_param_id/io/config_error.hpp"
#include "pmsm_param_id/io/sample_csv.hpp"
#include "pmsm_param_id/io/thermal_state.hpp"
#include "pmsm_param_id/model/flux_map.hpp"
#include "tool_common.hpp"

namespace pmsm_param_id::tool {

int runIdentify(const std::string& csv, const std::string& method, const std::string& config_path, long seed,
                const std::string& json_out, const LogFormat& format, const std::string& map_csv,
                const std::string& thermal_state) {
  const IdentifierConfig config = configFor(config_path, method, seed);
  if (!thermal_state.empty() && !config.thermal.enabled)
    throw ConfigError("--thermal-state needs a thermal: block in the identifier config (--config)");
  const SampleLog log = readSampleCsv(csv, format);
  auto id = makeIdentifier(config);
  const LearntReferences restored = loadThermalStateFor(thermal_state, config.thermal.reference_temperature);
  if (restored.any()) {
    id->restoreReferences(restored);
    std::fprintf(stderr, "thermal references from %s (not learnt again)\n", thermal_state.c_str());
  }
  MotorMap map(config.map);
  double next_map = -INFINITY;  // an estimate into the map every kEstimatePeriod of stamp time
  std::size_t warnings = 0;
  for (std::size_t k = 0; k < log.samples.size(); ++k) {
    const SampleStatus st = id->process(log.samples[k]);
    if (st != SampleStatus::Used && warnings++ < 20)
      std::fprintf(stderr, "%s:%zu: %s\n", csv.c_str(), log.line_numbers[k], toString(st));
    if (st == SampleStatus::Used && log.samples[k].t >= next_map && id->statistics().hasBlocks()) {
      map.add(id->estimate());
      next_map = log.samples[k].t + kEstimatePeriod;
    }
  }
  if (warnings > 20) std::fprintf(stderr, "%s: %zu more warnings not shown\n", csv.c_str(), warnings - 20);
  const Estimate e = id->estimate();
  if (!id->statistics().hasBlocks()) {
    const double block = id->statistics().configured() ? id->statistics().blockDuration() : config.window.block_length;
    std::fprintf(stderr, "%s: only %llu usable samples: fewer than one fitness block (%s) needs; no estimate\n",
                 csv.c_str(), static_cast<unsigned long long>(e.counters.used),
                 block > 0 ? (std::to_string(block) + " s").c_str() : "at least 5 ms and 10 samples");
    return 2;
  }
  printEstimate(e, config.thermal.enabled);
  if (!thermal_state.empty() && id->learntReferences().any() && id->learntReferences() != restored) {
    writeThermalState(thermal_state, id->learntReferences(), config.method);
    std::printf("thermal references written to %s\n", thermal_state.c_str());
  }
  printMap(map);
  if (!json_out.empty()) writeJson(json_out, estimateJson(e));
  if (!map_csv.empty()) {
    const std::string note = map.coverageNote();
    writeFluxTable(map.fluxTable(), map_csv,
                   "flux map learnt by " + config.method + " from " + csv + (note.empty() ? "" : "; " + note));
    std::printf("map written to %s\n", map_csv.c_str());
    if (!note.empty()) std::fprintf(stderr, "warning: %s: %s\n", map_csv.c_str(), note.c_str());
  }
  return 0;
}

}  // namespace pmsm_param_id::tool
