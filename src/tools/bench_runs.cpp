// bench's runs: one (method, seed) over a recorded run against the truth; the paper's rows.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "bench_runs.hpp"
#include "pmsm_param_id/identification/metrics.hpp"
#include "pmsm_param_id/io/config_error.hpp"

namespace pmsm_param_id::tool {

std::map<std::string, PaperRow> readPaperTable(const std::string& path, const std::string& condition) {
  std::map<std::string, PaperRow> rows;
  std::ifstream in(path);
  if (!in || std::filesystem::is_directory(path)) throw ConfigError("--reference: cannot read '" + path + "'");
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#' || line.rfind("condition", 0) == 0) continue;
    std::vector<std::string> c;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) c.push_back(cell);
    if (c.size() < 11 || c[0] != condition) continue;  // an empty trailing fitness cell is not split off
    PaperRow r;
    for (int p = 0; p < kParameterCount; ++p) {
      r.value[p] = std::stod(c[2 + 2 * p]);
      r.error[p] = std::stod(c[3 + 2 * p]);
    }
    r.recognition_time = c[10].empty() ? NAN : std::stod(c[10]);
    r.fitness = c.size() > 11 && !c[11].empty() ? std::stod(c[11]) : NAN;
    std::string m = c[1];
    std::transform(m.begin(), m.end(), m.begin(), ::tolower);
    rows[m] = r;
  }
  return rows;
}

RunResult runOne(const std::vector<SimulatedSample>& data, IdentifierConfig config, const std::string& method,
                 std::uint64_t seed, bool monitor) {
  config.method = method;
  config.seed = seed;
  auto id = makeIdentifier(config);
  RunResult r;
  r.method = method;
  r.seed = seed;
  std::vector<TracePoint> trace;
  const double Ts = data.size() > 1 ? data[1].sample.t - data[0].sample.t : 1e-4;
  const std::size_t stride = std::max<std::size_t>(1, static_cast<std::size_t>(std::lround(1e-4 / Ts)));
  trace.reserve(data.size() / stride + 1);
  double cpu = 0.0;
  ConditionMonitor condition = ConditionMonitor::forConfig(config);
  MotorMap map(config.map);
  std::vector<ParameterVector> cell_truth;  // per cell: the truth when its latest identified value was filed
  const std::size_t estimate_stride = std::max<std::size_t>(1, static_cast<std::size_t>(std::lround(kEstimatePeriod / Ts)));
  for (std::size_t k = 0; k < data.size(); ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    id->process(data[k].sample);
    cpu += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (k % stride == 0 || k + 1 == data.size()) trace.push_back({data[k].sample.t, id->parameters(), data[k].truth});
    if (k % estimate_stride != estimate_stride - 1) continue;
    const Estimate e = id->estimate();
    for (int p = 0; p < kParameterCount; ++p) {
      if (!e.identifiable[p]) continue;
      const double error = std::abs(errorPercent(e.parameters[p], data[k].truth[p]));
      ++r.along.identified[p];
      r.along.wrong[p] += !(error <= 2.0);
      r.along.worst[p] = std::max(r.along.worst[p], std::isfinite(error) ? error : INFINITY);
      const double over = error / (100.0 * e.relative_uncertainty[p]);
      r.along.outside_stated[p] += !(over <= 1.0);
      r.along.worst_over_stated[p] = std::max(r.along.worst_over_stated[p], std::isfinite(over) ? over : INFINITY);
    }
    for (int p : {kRs, kPsiF}) {
      if (!e.slow.identifiable[p]) continue;
      const double error = std::abs(errorPercent(e.slow.parameters[p], data[k].truth[p]));
      ++r.along.slow_identified[p];
      r.along.slow_wrong[p] += !(error <= 2.0);
      r.along.slow_worst[p] = std::max(r.along.slow_worst[p], std::isfinite(error) ? error : INFINITY);
      const double over = error / (100.0 * e.slow.relative_uncertainty[p]);
      r.along.slow_outside_stated[p] += !(over <= 1.0);
      r.along.slow_worst_over_stated[p] = std::max(r.along.slow_worst_over_stated[p], std::isfinite(over) ? over : INFINITY);
    }
    const int cell = map.add(e);
    if (cell >= 0) {
      cell_truth.resize(map.cells().size(), ParameterVector{});
      for (int p = 0; p < kParameterCount; ++p)
        if (e.identifiable[p]) cell_truth[static_cast<std::size_t>(cell)][p] = data[k].truth[p];
    }
    if (monitor) {
      MonitorResult& m = r.monitor;
      ++m.estimates;
      if (std::isfinite(e.winding_temperature.value)) {
        ++m.winding_reported;
        if (std::isfinite(data[k].winding_temperature)) {
          const double error = std::abs(e.winding_temperature.value - data[k].winding_temperature);
          m.winding_error.push_back(error);
          m.winding_outside_stated += !(error <= e.winding_temperature.uncertainty);
        }
      }
      if (std::isfinite(e.magnet_temperature.value)) {
        ++m.magnet_reported;
        if (std::isfinite(data[k].magnet_temperature)) {
          const double error = std::abs(e.magnet_temperature.value - data[k].magnet_temperature);
          m.magnet_error.push_back(error);
          m.magnet_outside_stated += !(error <= e.magnet_temperature.uncertainty);
        }
      }
      for (const AlarmEvent& ev : condition.update(e)) m.events.push_back(ev);
    }
  }
  r.along.map_cells = static_cast<int>(map.cells().size());
  for (std::size_t c = 0; c < map.cells().size(); ++c) {
    const MotorMapCell& cell = map.cells()[c];
    r.along.map_cells_complete += cell.hasIdentified(kLd) && cell.hasIdentified(kLq) && cell.hasIdentified(kPsiF);
    for (int p = 0; p < kParameterCount; ++p)
      if (cell.hasIdentified(p))
        r.along.map_worst[p] = std::max(r.along.map_worst[p], std::abs(errorPercent(cell.identified[p], cell_truth[c][p])));
  }
  r.along.map_note = map.coverageNote();
  try {
    r.along.map_table = std::make_shared<const FluxTable>(map.fluxTable());
  } catch (const UserError& e) {
    r.along.map_problem = e.what();
  }
  r.final = id->estimate();
  r.truth = data.back().truth;
  r.recognition_time = recognitionTime(trace, r.final.identifiable);
  r.cpu_s = cpu;
  r.samples = data.size();
  return r;
}

/// Parameter p reported identified yet more than 2 % from the truth; the count over seeds must be
/// zero ("never a confident wrong number"). A value on a search bound is never identified: the
/// assessment gives it at_bound first.
bool confidentlyWrong(const RunResult& r, int p) {
  return r.final.identifiable[p] && !(std::abs(errorPercent(r.final.parameters[p], r.truth[p])) <= 2.0);
}
int confidentlyWrong(const std::vector<RunResult>& runs, int p) {
  int n = 0;
  for (const auto& r : runs) n += confidentlyWrong(r, p);
  return n;
}

/// The first time a fault profile (R_s_scale, psi_f_scale, L_d_scale, L_q_scale) leaves its initial
/// value by more than 0.5 %; NaN when none does (a healthy run). Temperatures are not faults.
double faultOnset(const Scenario& s) {
  const Profile* profiles[] = {&s.R_s_scale, &s.psi_f_scale, &s.L_d_scale, &s.L_q_scale};
  const double Ts = s.drive.sample_period;
  for (double t = 0.0; t <= s.duration; t += Ts)
    for (const Profile* p : profiles)
      if (std::abs((*p)(t) / (*p)(0.0) - 1.0) > 0.005) return t;
  return NAN;
}

double medianOrNan(std::vector<double> v) { return v.empty() ? NAN : median(std::move(v)); }

}  // namespace pmsm_param_id::tool
