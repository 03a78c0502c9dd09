// What the pmsm_tool commands share: the simulator run, the estimate as text and JSON, the
// identifier configuration with the command line's overrides, the --methods list.
#pragma once
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "pmsm_param_id/identification/identifier_config.hpp"
#include "pmsm_param_id/identification/motor_map.hpp"
#include "pmsm_param_id/identification/online_identifier.hpp"
#include "pmsm_param_id/simulation/drive_simulator.hpp"
#include "pmsm_param_id/simulation/scenario.hpp"

namespace pmsm_param_id::tool {

using nlohmann::json;

/// bench and identify take an estimate every this much drive time: checked against the truth, filed
/// in the map of the motor, fed to the condition monitor (adds at most 10 ms to an alarm's latency).
/// The node publishes every 1 ms by default; 10 ms keeps ten-minute benches affordable.
constexpr double kEstimatePeriod = 0.01;  // [s]

/// Every sample of one simulated run.
std::vector<SimulatedSample> simulate(const Scenario& scenario);
/// A finite number, else JSON null.
json numberOrNull(double v);
/// The estimate as the JSON record identify --json writes and bench's records extend.
json estimateJson(const Estimate& e);
/// Writes through a temporary file: a reader never sees half a file.
void writeJson(const std::string& path, const json& j);
/// --fitness given on the command line (overrides the config's fitness:); empty: the config's.
extern std::string fitness_override;
/// The identifier configuration of config_path (defaults when empty) with the command line's
/// method, seed and --fitness; validated.
IdentifierConfig configFor(const std::string& config_path, const std::string& method, long seed);
void printEstimate(const Estimate& e, bool thermal_enabled = false);
/// The map of the motor as a table on stdout (doc/algorithm.md section 12).
void printMap(const MotorMap& map);
std::vector<std::string> splitList(const std::string& s);
/// The comma-separated --methods list; ConfigError on an unknown name.
std::vector<std::string> methodsFrom(const std::string& list);

/// While alive, the first Ctrl-C (SIGINT) only asks the running job to stop after what is under
/// way (requested() turns true, one line on stderr); a second one ends the process as usual.
class InterruptGuard {
 public:
  InterruptGuard();
  ~InterruptGuard();
  InterruptGuard(const InterruptGuard&) = delete;
  InterruptGuard& operator=(const InterruptGuard&) = delete;
  bool requested() const;

 private:
  void (*previous_)(int);
};

}  // namespace pmsm_param_id::tool
