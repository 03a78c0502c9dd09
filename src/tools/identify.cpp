// pmsm_tool identify: R_s, L_d, L_q, psi_f (and the map of the motor) from a drive log.
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include "commands.hpp"
#include "pmsm_param_id/identification/motor_map.hpp"
#include "pmsm_param_id/identification/steady_state.hpp"
#include "pmsm_param_id/io/config_error.hpp"
#include "pmsm_param_id/io/sample_csv.hpp"
#include "pmsm_param_id/io/thermal_state.hpp"
#include "pmsm_param_id/model/flux_map.hpp"
#include "tool_common.hpp"

namespace pmsm_param_id::tool {

namespace {
// Telemetry: the steady-state fit of the whole log (identification/steady_state.hpp).
int runSteadyState(const std::string& csv, const SampleLog& log, const IdentifierConfig& config,
                   const std::string& method, const std::string& json_out) {
  const SteadyStateFit f = fitSteadyState(log.samples, config);
  if (!method.empty() && method != "steady_state")
    std::fprintf(stderr, "%s: --method %s follows the current loop's own samples and does not apply to telemetry; "
                 "the steady-state fit ran instead\n", csv.c_str(), method.c_str());
  if (!f.note.empty()) {
    std::fprintf(stderr, "%s: %s; no estimate\n", csv.c_str(), f.note.c_str());
    return 2;
  }
  const Estimate& e = f.estimate;
  std::printf("method %s (telemetry: averaged dq equations across operating points)\n", e.method.c_str());
  const char* units[] = {"ohm", "H", "H", "Wb"};
  for (int p = 0; p < kParameterCount; ++p)
    std::printf("  %-6s = %-12.6g %-3s %-13s %s\n", parameterNames()[p].c_str(), e.parameters[p], units[p],
                toString(e.status[p]), e.reason[p].c_str());
  std::printf("  fit: %s; residual / noise %.3g (d) %.3g (q); voltage noise %.3g V (d) %.3g V (q)\n",
              e.fit.consistent ? "consistent with the noise" : "POOR", e.fit.fit_ratio_d, e.fit.fit_ratio_q, f.noise_std_d,
              f.noise_std_q);
  if (!e.fit.likely_cause.empty()) std::printf("  likely cause: %s\n", e.fit.likely_cause.c_str());
  if (f.from_trajectory)
    std::printf("  one set of parameters does not hold across the log (the motor heats): the values are the thermal "
                "trajectory's at its end (doc/algorithm.md section 13)\n");
  std::printf("  inverter voltage = %.4g V %s %s (zero-crossing width %.3g A)\n", e.inverter_voltage,
              toString(e.inverter_status), e.inverter_reason.c_str(), f.zero_crossing_current);
  std::printf("  voltage timing (data's fit) = %.3g +- %.2g s: the applied vector turned by that times omega_e\n",
              f.voltage_timing, f.voltage_timing_std);
  std::printf("  operating points: i_d = %.4g A (spread %.2g), i_q = %.4g A (spread %.2g), mean omega_e = %.4g rad/s\n",
              e.operating_point.i_d, e.operating_point.i_d_spread, e.operating_point.i_q, e.operating_point.i_q_spread,
              e.operating_point.omega_e);
  std::printf("  sampling period %.4g s; samples = %zu, steady = %zu, transients left out = %zu, non-finite = %llu, "
              "gaps = %llu, time resets = %llu\n",
              f.sample_period, f.samples, f.steady, f.transients, static_cast<unsigned long long>(e.counters.skipped_nonfinite),
              static_cast<unsigned long long>(e.counters.gaps), static_cast<unsigned long long>(e.counters.time_resets));
  if (config.thermal.enabled) {
    const auto line = [](const char* name, const Temperature& t) {
      if (std::isfinite(t.value)) std::printf("  %s temperature = %.1f degC +- %.1f K (at the log's end)\n", name, t.value, t.uncertainty);
      else std::printf("  %s temperature: not determined to thermal.max_uncertainty\n", name);
    };
    line("winding", e.winding_temperature);
    line("magnet", e.magnet_temperature);
    std::printf("  thermal trajectory: %zu load or speed changes pin psi_f; R_s's knots every %.3g s%s%s\n",
                f.thermal_changes, f.thermal_knot_spacing, f.thermal_note.empty() ? "" : "; ", f.thermal_note.c_str());
  }
  if (!json_out.empty()) {
    json j = estimateJson(e);
    j["steady_state"] = {{"samples", f.samples}, {"steady", f.steady}, {"transients", f.transients},
                         {"zero_crossing_current", f.zero_crossing_current},
                         {"voltage_timing", numberOrNull(f.voltage_timing)},
                         {"voltage_timing_std", numberOrNull(f.voltage_timing_std)},
                         {"thermal_changes", f.thermal_changes},
                         {"thermal_knot_spacing", f.thermal_knot_spacing},
                         {"thermal_note", f.thermal_note},
                         {"from_thermal_trajectory", f.from_trajectory}};
    writeJson(json_out, j);
  }
  return 0;
}

// --trace: the estimate every kEstimatePeriod of stamp time, one CSV row each (what the node
// would have published along the log).
class TraceWriter {
 public:
  explicit TraceWriter(const std::string& path) : path_(path) {
    if (path.empty()) return;
    f_ = std::fopen(path.c_str(), "w");
    if (!f_) throw ConfigError("--trace: cannot write " + path);
    std::fprintf(f_, "t");
    for (const std::string& n : parameterNames()) std::fprintf(f_, ",%s,%s_status,%s_relative_uncertainty", n.c_str(), n.c_str(), n.c_str());
    for (const char* n : {"slow_R_s", "slow_psi_f"}) std::fprintf(f_, ",%s,%s_status,%s_relative_uncertainty", n, n, n);
    std::fprintf(f_, ",inverter_voltage,fit_consistent,residual_over_noise_d,residual_over_noise_q,"
                 "winding_temperature,winding_temperature_uncertainty,magnet_temperature,magnet_temperature_uncertainty\n");
  }
  ~TraceWriter() {
    if (f_) std::fclose(f_);
  }
  TraceWriter(const TraceWriter&) = delete;
  TraceWriter& operator=(const TraceWriter&) = delete;
  bool active() const { return f_ != nullptr; }
  void write(const Estimate& e) {
    std::fprintf(f_, "%.9g", e.t);
    for (int p = 0; p < kParameterCount; ++p) row(e.parameters[p], e.status[p], e.relative_uncertainty[p]);
    const double nan = std::numeric_limits<double>::quiet_NaN();  // an empty field
    const bool slow_fitted = std::isfinite(e.slow.t);  // the slow window has been fitted at all
    for (int p : {kRs, kPsiF})
      row(slow_fitted ? e.slow.parameters[p] : nan, e.slow.status[p], e.slow.relative_uncertainty[p]);
    number(e.inverter_voltage);
    if (e.fit.available) std::fprintf(f_, ",%d", e.fit.consistent ? 1 : 0);
    else std::fprintf(f_, ",");
    for (double v : {e.fit.available ? e.fit.fit_ratio_d : nan, e.fit.available ? e.fit.fit_ratio_q : nan,
                     e.winding_temperature.value, e.winding_temperature.uncertainty, e.magnet_temperature.value,
                     e.magnet_temperature.uncertainty})
      number(v);
    std::fprintf(f_, "\n");
  }
  void close() {
    if (f_ && std::fclose(f_) != 0) throw ConfigError("--trace: writing " + path_ + " failed");
    f_ = nullptr;
  }

 private:
  void number(double v) {  // NaN and inf as an empty field
    if (std::isfinite(v)) std::fprintf(f_, ",%.9g", v);
    else std::fprintf(f_, ",");
  }
  void row(double value, ParameterStatus status, double relative_uncertainty) {
    number(status == ParameterStatus::NoData ? std::numeric_limits<double>::quiet_NaN() : value);
    std::fprintf(f_, ",%s", toString(status));
    number(relative_uncertainty);
  }
  std::string path_;
  std::FILE* f_ = nullptr;
};
}  // namespace

int runIdentify(const std::string& csv, const std::string& method, const std::string& config_path, long seed,
                const std::string& json_out, const LogFormat& format, const std::string& map_csv,
                const std::string& thermal_state, const std::string& data_kind, const std::string& trace_csv) {
  const bool steady_method = method == "steady_state";
  const IdentifierConfig config = configFor(config_path, steady_method ? std::string() : method, seed);
  if (!thermal_state.empty() && !config.thermal.enabled)
    throw ConfigError("--thermal-state needs a thermal: block in the identifier config (--config)");
  if (data_kind != "auto" && data_kind != "current_loop" && data_kind != "telemetry")
    throw ConfigError("--data: expected auto, current_loop or telemetry, got '" + data_kind + "'");
  const SampleLog log = readSampleCsv(csv, format);
  // Telemetry or the current loop's own samples: from the sampling period (the median spacing),
  // unless the user says which.
  bool telemetry = data_kind == "telemetry" || steady_method;
  if (data_kind == "auto" && !steady_method) {
    const double T = medianSpacing(log.samples);
    telemetry = T > kTelemetryPeriod;
    if (telemetry)
      std::fprintf(stderr, "%s: sampled every %.3g s, slower than any current loop: telemetry, the steady-state fit "
                   "(--data current_loop if the time column's unit is wrong instead: --time-unit)\n", csv.c_str(), T);
  }
  if (telemetry) {
    if (!thermal_state.empty() || !map_csv.empty() || !trace_csv.empty())
      throw ConfigError("--thermal-state, --map-csv and --trace need the current loop's samples; this log is telemetry");
    return runSteadyState(csv, log, config, method, json_out);
  }
  auto id = makeIdentifier(config);
  const LearntReferences restored = loadThermalStateFor(thermal_state, config.thermal.reference_temperature);
  if (restored.any()) {
    id->restoreReferences(restored);
    std::fprintf(stderr, "thermal references from %s (not learnt again)\n", thermal_state.c_str());
  }
  MotorMap map(config.map);
  TraceWriter trace(trace_csv);
  double next_estimate = -INFINITY;  // an estimate into the map (and the trace) every kEstimatePeriod of stamp time
  std::size_t warnings = 0;
  for (std::size_t k = 0; k < log.samples.size(); ++k) {
    const SampleStatus st = id->process(log.samples[k]);
    if (st != SampleStatus::Used && warnings++ < 20)
      std::fprintf(stderr, "%s:%zu: %s\n", csv.c_str(), log.line_numbers[k], toString(st));
    if (st == SampleStatus::Used && log.samples[k].t >= next_estimate && id->statistics().hasBlocks()) {
      const Estimate e = id->estimate();
      map.add(e);
      if (trace.active()) trace.write(e);
      next_estimate = log.samples[k].t + kEstimatePeriod;
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
  if (trace.active()) {
    trace.close();
    std::printf("estimates along the log written to %s\n", trace_csv.c_str());
  }
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
