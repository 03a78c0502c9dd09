#include "tool_common.hpp"

#include "pmsm_param_id/io/sample_csv.hpp"

#include <algorithm>
#include <atomic>
#include <csignal>
#include <unistd.h>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "pmsm_param_id/io/config_error.hpp"
#include "pmsm_param_id/identification/metrics.hpp"

namespace pmsm_param_id::tool {

std::vector<SimulatedSample> simulate(const Scenario& scenario) {
  DriveSimulator sim(scenario);
  std::vector<SimulatedSample> out;
  out.reserve(static_cast<std::size_t>(scenario.duration / scenario.drive.sample_period) + 1);
  while (!sim.done()) out.push_back(sim.step());
  return out;
}

json numberOrNull(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

json estimateJson(const Estimate& e) {
  json j;
  j["method"] = e.method;
  for (int p = 0; p < kParameterCount; ++p) {
    const std::string& name = parameterNames()[p];
    j[name] = numberOrNull(e.parameters[p]);
    j["identifiable"][name] = e.identifiable[p];
    j["status"][name] = toString(e.status[p]);
    j["reason"][name] = e.reason[p];
    j["relative_uncertainty"][name] = numberOrNull(e.relative_uncertainty[p]);
    j["source"][name] = e.from_slow_window[p] ? "slow_window" : "fitness_window";
    j["data_optimum"][name] = e.fit.available ? numberOrNull(e.fit.optimum[p]) : json(nullptr);
  }
  if (e.fit.cross_saturation_modelled)
    j["cross_saturation"] = {{"L_qq", numberOrNull(e.fit.L_qq)}, {"L_qq_std", numberOrNull(e.fit.L_qq_std)},
                             {"L_dq", numberOrNull(e.fit.L_dq)}, {"L_dq_std", numberOrNull(e.fit.L_dq_std)}};
  j["operating_point"] = {{"i_d", numberOrNull(e.operating_point.i_d)}, {"i_q", numberOrNull(e.operating_point.i_q)},
                          {"omega_e", numberOrNull(e.operating_point.omega_e)},
                          {"i_d_spread", numberOrNull(e.operating_point.i_d_spread)},
                          {"i_q_spread", numberOrNull(e.operating_point.i_q_spread)}};
  j["fit"] = {{"consistent", e.fit.consistent},
              {"ratio_d", numberOrNull(e.fit.fit_ratio_d)},
              {"ratio_q", numberOrNull(e.fit.fit_ratio_q)},
              {"noise_std_d", numberOrNull(e.fit.noise_std_d)},
              {"noise_std_q", numberOrNull(e.fit.noise_std_q)},
              {"speed_scale_short", numberOrNull(e.fit.speed_scale_short)},
              {"speed_scale_long", numberOrNull(e.fit.speed_scale_long)},
              {"speed_unit_verified", e.fit.speed_unit_verified},
              {"likely_cause", e.fit.likely_cause.empty() ? json(nullptr) : json(e.fit.likely_cause)}};
  {
    json slow;
    for (int p : {kRs, kPsiF}) {
      const std::string& name = parameterNames()[p];
      slow[name] = numberOrNull(e.slow.parameters[p]);
      slow["identifiable"][name] = e.slow.identifiable[p];
      slow["status"][name] = toString(e.slow.status[p]);
      slow["reason"][name] = e.slow.reason[p];
      slow["relative_uncertainty"][name] = numberOrNull(e.slow.relative_uncertainty[p]);
    }
    slow["window_time_constant"] = e.slow.window_time_constant;
    slow["t"] = numberOrNull(e.slow.t);
    j["slow"] = slow;
  }
  j["sample_period"] = numberOrNull(e.sample_period);
  j["winding_temperature"] = numberOrNull(e.winding_temperature.value);
  j["winding_temperature_uncertainty"] = numberOrNull(e.winding_temperature.uncertainty);
  j["magnet_temperature"] = numberOrNull(e.magnet_temperature.value);
  j["magnet_temperature_uncertainty"] = numberOrNull(e.magnet_temperature.uncertainty);
  j["torque_constant"] = numberOrNull(e.torque_constant);
  j["speed_constant"] = numberOrNull(e.speed_constant);
  j["motor_constant_relative_uncertainty"] = numberOrNull(e.motor_constant_relative_uncertainty);
  j["inverter_voltage"] = {{"value", numberOrNull(e.inverter_voltage)},
                           {"status", toString(e.inverter_status)},
                           {"reason", e.inverter_reason},
                           {"relative_uncertainty", numberOrNull(e.inverter_relative_uncertainty)},
                           {"bus_share", numberOrNull(e.fit.inverter_bus_share)}};
  j["drive_model"] = e.drive_model.empty() ? json("as configured") : json(e.drive_model);
  if (e.fit.voltage_angle_modelled)
    j["voltage_angle"] = {{"value", numberOrNull(e.fit.voltage_angle)},
                          {"standard_deviation", numberOrNull(e.fit.voltage_angle_std)},
                          {"from_long_window", e.fit.voltage_angle_from_long_window},
                          {"remembered_from_t", e.fit.voltage_angle_remembered ? json(e.fit.voltage_angle_remembered_t) : json(nullptr)},
                          {"own_value", numberOrNull(e.fit.own_voltage_angle)},
                          {"own_standard_deviation", numberOrNull(e.fit.own_voltage_angle_std)}};
  j["fitness"] = numberOrNull(e.fitness);
  j["samples"] = e.counters.used;
  j["skipped"] = e.counters.skipped();
  j["skipped_nonfinite"] = e.counters.skipped_nonfinite;
  j["skipped_too_close"] = e.counters.skipped_too_close;
  j["time_resets"] = e.counters.time_resets;
  j["gaps"] = e.counters.gaps;
  j["period_changes"] = e.counters.period_changes;
  j["iterations"] = e.iteration;
  j["temperature"] = numberOrNull(e.temperature);
  j["t"] = e.t;
  return j;
}

void writeJson(const std::string& path, const json& j) {
  const std::string text = j.dump(1) + "\n";
  writeFileAtomically(path, [&](std::FILE* f) { std::fwrite(text.data(), 1, text.size(), f); });
}

std::string fitness_override;

IdentifierConfig configFor(const std::string& config_path, const std::string& method, long seed) {
  IdentifierConfig c = config_path.empty() ? IdentifierConfig{} : loadIdentifierConfig(config_path);
  if (!fitness_override.empty() && !fitnessKindFrom(fitness_override, c.fitness))
    throw ConfigError("--fitness: expected block, paper or paper_one_step, got '" + fitness_override + "'");
  if (!method.empty()) c.method = method;
  if (seed >= 0) c.seed = static_cast<std::uint64_t>(seed);
  validate(c, config_path.empty() ? "--method" : config_path);
  return c;
}

void printEstimate(const Estimate& e, bool thermal_enabled) {
  std::printf("method %s\n", e.method.c_str());
  const char* units[] = {"ohm", "H", "H", "Wb"};
  for (int p = 0; p < kParameterCount; ++p)
    std::printf("  %-6s = %-12.6g %-3s %-13s %s\n", parameterNames()[p].c_str(), e.parameters[p], units[p],
                toString(e.status[p]), e.reason[p].c_str());
  if (e.fit.available)
    std::printf("  fit: %s; residual / noise %.3g (d) %.3g (q); current noise %.3g A (d) %.3g A (q)\n",
                e.fit.consistent ? "consistent with the noise" : "POOR", e.fit.fit_ratio_d, e.fit.fit_ratio_q,
                e.fit.noise_std_d, e.fit.noise_std_q);
  if (!e.fit.likely_cause.empty()) std::printf("  likely cause: %s\n", e.fit.likely_cause.c_str());
  for (int p : {kRs, kPsiF})
    std::printf("  %-6s = %-12.6g %-3s %-13s slow window: %s\n", parameterNames()[p].c_str(), e.slow.parameters[p],
                units[p], toString(e.slow.status[p]), e.slow.reason[p].c_str());
  const auto temperature = [](const char* name, const Temperature& t) {
    if (std::isfinite(t.value)) std::printf("  %s temperature = %.1f degC +- %.1f K\n", name, t.value, t.uncertainty);
    else std::printf("  %s temperature unknown (its parameter is not identified)\n", name);
  };
  if (std::isfinite(e.winding_temperature.value) || std::isfinite(e.magnet_temperature.value) || thermal_enabled) {
    temperature("winding", e.winding_temperature);
    temperature("magnet", e.magnet_temperature);
  }
  if (std::isfinite(e.torque_constant))
    std::printf("  torque constant K_t = %.5g N m/A, speed constant K_v = %.5g rpm/V (+-%.3g %%, from psi_f)\n",
                e.torque_constant, e.speed_constant, 100 * e.motor_constant_relative_uncertainty);
  if (e.fit.inverter_modelled)
    std::printf("  inverter voltage = %.4g V %s %s\n", e.inverter_voltage, toString(e.inverter_status), e.inverter_reason.c_str());
  if (!e.drive_model.empty()) std::printf("  drive model: %s\n", e.drive_model.c_str());
  if (e.fit.voltage_angle_modelled) {
    char from[96] = "";
    if (e.fit.voltage_angle_from_long_window) std::snprintf(from, sizeof from, " (from the long window)");
    if (e.fit.voltage_angle_remembered)
      std::snprintf(from, sizeof from, " (this window's own, %.3g, combined with the fitness window's at t = %.4g s)",
                    e.fit.own_voltage_angle, e.fit.voltage_angle_remembered_t);
    std::printf("  voltage angle (data's fit) = %.3g +- %.2g omega_e T_s beyond the declared timing%s\n", e.fit.voltage_angle,
                e.fit.voltage_angle_std, from);
  }
  if (e.fit.cross_saturation_modelled)
    std::printf("  saturation (data's fit): incremental L_qq = %.4g H +- %.2g, cross L_dq = %.4g H +- %.2g\n", e.fit.L_qq,
                e.fit.L_qq_std, e.fit.L_dq, e.fit.L_dq_std);
  std::printf("  operating point (window means): i_d = %.4g A (spread %.2g), i_q = %.4g A (spread %.2g), omega_e = %.4g rad/s\n",
              e.operating_point.i_d, e.operating_point.i_d_spread, e.operating_point.i_q, e.operating_point.i_q_spread,
              e.operating_point.omega_e);
  std::printf("  sampling period %.4g s; fitness = %.4g A^2, samples = %llu, skipped = %llu, time resets = %llu, gaps = %llu\n",
              e.sample_period, e.fitness,
              static_cast<unsigned long long>(e.counters.used), static_cast<unsigned long long>(e.counters.skipped()),
              static_cast<unsigned long long>(e.counters.time_resets),
              static_cast<unsigned long long>(e.counters.gaps));
}

void printMap(const MotorMap& map) {
  std::printf("  map of the motor: %zu cell(s), %llu estimate(s) not filed (window across a load change)\n",
              map.cells().size(), static_cast<unsigned long long>(map.transientEstimates()));
  for (const MotorMapCell& c : map.cells()) {
    std::printf("    i_d %7.3g A, i_q %7.3g A, %5llu estimates:", c.i_d, c.i_q, static_cast<unsigned long long>(c.estimates));
    for (int p = 0; p < kParameterCount; ++p)
      if (c.hasIdentified(p)) std::printf("  %s %.5g", parameterNames()[p].c_str(), c.identified[p]);
      else std::printf("  %s -", parameterNames()[p].c_str());
    std::printf("\n");
  }
}

std::vector<std::string> splitList(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    item.erase(std::remove(item.begin(), item.end(), ' '), item.end());
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

std::vector<std::string> methodsFrom(const std::string& list) {
  const std::vector<std::string> methods = splitList(list);
  if (methods.empty()) throw ConfigError("--methods: no method named (expected a comma-separated list of " + methodList() + ")");
  for (const std::string& m : methods)
    if (!isKnownMethod(m)) throw ConfigError("--methods: unknown method '" + m + "' (expected " + methodList() + ")");
  return methods;
}

namespace {
std::atomic<bool> g_interrupt_requested{false};
extern "C" void onInterrupt(int) {
  if (g_interrupt_requested.exchange(true)) {  // the second Ctrl-C: end now
    std::signal(SIGINT, SIG_DFL);
    std::raise(SIGINT);
    return;
  }
  const char text[] = "\ninterrupt: finishing what is under way (Ctrl-C again to stop at once)\n";
  [[maybe_unused]] const auto n = ::write(STDERR_FILENO, text, sizeof text - 1);  // async-signal-safe
}
}  // namespace

InterruptGuard::InterruptGuard() : previous_(std::signal(SIGINT, onInterrupt)) { g_interrupt_requested = false; }
InterruptGuard::~InterruptGuard() { std::signal(SIGINT, previous_ == SIG_ERR ? SIG_DFL : previous_); }
bool InterruptGuard::requested() const { return g_interrupt_requested.load(); }

}  // namespace pmsm_param_id::tool
