// bench's runs and tables: one (method, seed) run against the truth, what the condition monitor
// made of it, the paper's reference rows, and the tables bench prints from them.
#pragma once
#include <array>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "pmsm_param_id/identification/monitor.hpp"
#include "pmsm_param_id/model/flux_map.hpp"
#include "reference_optimum.hpp"
#include "tool_common.hpp"

namespace pmsm_param_id::tool {

struct MonitorResult {
  std::vector<double> winding_error, magnet_error;  ///< |estimated - true| [K] whenever reported
  int estimates = 0, winding_reported = 0, magnet_reported = 0;
  int winding_outside_stated = 0, magnet_outside_stated = 0;  ///< reported, |error| > the stated uncertainty
  std::vector<AlarmEvent> events;
};

/// Identified estimates along the run (every kEstimatePeriod) against the truth of their moment,
/// and the map of the motor they make (doc/algorithm.md section 12).
struct AlongRunResult {
  std::array<int, kParameterCount> identified{}, wrong{};  ///< estimates identified; of them > 2 % off
  std::array<int, kParameterCount> outside_stated{};        ///< of them |error| > their stated uncertainty
  ParameterVector worst{};                                  ///< largest |error| of an identified one [%]
  ParameterVector worst_over_stated{};                      ///< largest |error| / stated uncertainty [-]
  /// The same for the slow estimates (R_s and psi_f; Estimate::slow).
  std::array<int, kParameterCount> slow_identified{}, slow_wrong{}, slow_outside_stated{};
  ParameterVector slow_worst{}, slow_worst_over_stated{};
  int map_cells = 0, map_cells_complete = 0;                ///< cells; with L_d, L_q, psi_f identified
  ParameterVector map_worst{};  ///< largest |error| of a cell's latest identified value vs the truth then [%]
  std::shared_ptr<const FluxTable> map_table;               ///< exported map (null when none)
  std::string map_problem;                                  ///< why not
  std::string map_note;                                     ///< MotorMap::coverageNote()
  double map_roundtrip = NAN;   ///< RMS current difference, re-simulated with the map / original [-]
};

struct RunResult {
  MonitorResult monitor;
  AlongRunResult along;
  std::string method;
  std::uint64_t seed = 0;
  Estimate final;
  ParameterVector truth{};
  double recognition_time = NAN;
  double cpu_s = 0.0;
  std::uint64_t samples = 0;
};

struct PaperRow {
  ParameterVector value{}, error{};
  double recognition_time = NAN, fitness = NAN;
};

/// The paper's rows for one condition from its tables as CSV.
std::map<std::string, PaperRow> readPaperTable(const std::string& path, const std::string& condition);
/// One method over one recorded run: the final estimate, the recognition time, along-run checks,
/// and with monitor the condition monitor's temperatures and alarms.
RunResult runOne(const std::vector<SimulatedSample>& data, IdentifierConfig config, const std::string& method,
                 std::uint64_t seed, bool monitor = false);
/// Parameter p reported identified yet more than 2 % from the truth (the count must be zero).
bool confidentlyWrong(const RunResult& r, int p);
int confidentlyWrong(const std::vector<RunResult>& runs, int p);
/// The first time a fault profile leaves its initial value by more than 0.5 %; NaN on a healthy run.
double faultOnset(const Scenario& s);
double medianOrNan(std::vector<double> v);

/// bench --monitor: temperature errors and alarm counts per method, over seeds.
void printMonitor(const std::vector<std::string>& methods, const std::vector<std::vector<RunResult>>& results,
                  double onset);
/// FBDAPSO's recognition time against SAPSO's and PSO's, seed by seed.
void printPairedRecognition(const std::vector<std::string>& methods, const std::vector<std::vector<RunResult>>& results);
/// bench --fitness paper: the reference optimum of each seed's final window and each method's gap to it.
void printReference(const std::vector<std::string>& methods, const std::vector<std::vector<RunResult>>& results,
                    const std::vector<ReferenceOptimum>& references, const IdentifierConfig& config);
/// Every identified estimate along the run against the truth of its moment, and the map it made.
void printAlongRun(const std::vector<std::string>& methods, const std::vector<std::vector<RunResult>>& results,
                   bool roundtrip);

}  // namespace pmsm_param_id::tool
