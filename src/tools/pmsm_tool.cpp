// pmsm_tool: simulate a drive, identify from a log, benchmark the methods. ROS-free.
// The command line; each subcommand lives in its own file (commands.hpp).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "commands.hpp"
#include "pmsm_param_id/io/config_error.hpp"
#include "pmsm_param_id/io/log_format.hpp"
#include "tool_common.hpp"

using namespace pmsm_param_id;

int main(int argc, char** argv) {
  // A seed is a non-negative integer (a negative one would mean "the scenario's or config's own").
  const CLI::Validator non_negative(
      [](std::string& text) {
        const bool digits = !text.empty() && text.size() <= 18 && text.find_first_not_of("0123456789") == std::string::npos;
        return digits ? std::string() : std::string("must be an integer from 0 to 999999999999999999");
      },
      "INTEGER >= 0");
  CLI::App app{"pmsm_tool: IPMSM drive simulator and online parameter identification (ROS-free core)"};
  app.require_subcommand(1);

  std::string scenario, csv, method, config, json_out, methods = "fbdapso,sapso,pso,ekf,rls,wls", reference;
  long seed = -1;
  double duration = 0;
  int seeds = 30, threads = 2;

  auto* sim = app.add_subcommand("simulate", "run the drive simulator and write every sample to CSV");
  sim->add_option("--scenario", scenario, "scenario YAML")->required();
  sim->add_option("--csv", csv, "output CSV")->required();
  sim->add_option("--seed", seed, "override run.seed")->check(non_negative);
  sim->add_option("--duration", duration, "override run.duration [s]");
  double telemetry_period = 0;
  sim->add_option("--telemetry-period", telemetry_period,
                  "write means over intervals of this many seconds instead (a drive's telemetry stream) [s]");
  std::string sim_format;
  double clock_start = 0;
  sim->add_option("--format", sim_format, "write in this log format's layout (a shipped name: vesc, or a YAML file)");
  sim->add_option("--clock-start", clock_start, "the log clock's reading at t = 0 [s] (e.g. seconds since midnight)");

  auto* ident = app.add_subcommand("identify", "identify R_s, L_d, L_q, psi_f from a drive log");
  ident->add_option("--csv", csv, "log with header t,u_d,u_q,i_d,i_q,omega_e")->required();
  ident->add_option("--method", method, "fbdapso|sapso|pso|ekf|rls|wls|steady_state (overrides the config)");
  std::string data_kind = "auto";
  ident->add_option("--data", data_kind,
                    "auto | current_loop | telemetry (auto: telemetry where the log is sampled slower than 2 ms)");
  ident->add_option("--config", config, "identifier YAML (bounds, initial values, tuning)");
  ident->add_option("--seed", seed, "random seed (swarm methods)")->check(non_negative);
  ident->add_option("--json", json_out, "write the final estimate as JSON");
  ident->add_option("--fitness", tool::fitness_override, "block | paper | paper_one_step (swarm methods; overrides the config)");
  std::string map_csv;
  ident->add_option("--map-csv", map_csv, "write the map of the motor learnt from the log as a flux-map CSV");
  std::string trace_csv;
  ident->add_option("--trace", trace_csv,
                    "write the estimate every " + std::to_string(std::lround(tool::kEstimatePeriod * 1e3)) +
                        " ms of log time as CSV (values, statuses, stated uncertainties, slow estimates, temperatures)");
  std::string thermal_state;
  ident->add_option("--thermal-state", thermal_state,
                    "YAML of the thermal references a cold start learnt: read if it exists, written when learnt");
  std::string format_path, time_unit, speed_unit, current_unit, voltage_unit, dq_scaling;
  std::vector<std::string> column_names;
  int pole_pairs = 0;
  ident->add_option("--format", format_path, "log-format YAML: column names, units, pole pairs, dq scaling");
  ident->add_option("--column", column_names, "QUANTITY=HEADER, e.g. --column omega_e=speed (repeatable)");
  ident->add_option("--time-unit", time_unit, "s | ms | us");
  ident->add_option("--speed-unit", speed_unit, "rad/s (electrical) | mech_rad/s | rpm | hz");
  ident->add_option("--current-unit", current_unit, "A | mA");
  ident->add_option("--voltage-unit", voltage_unit, "V | mV");
  ident->add_option("--pole-pairs", pole_pairs, "pole pairs (for mechanical speed units)");
  ident->add_option("--dq-scaling", dq_scaling, "amplitude_invariant | power_invariant");

  auto* bench = app.add_subcommand("bench", "every method over N simulated seeds, in the paper's table layout");
  bench->add_option("--scenario", scenario, "scenario YAML")->required();
  bench->add_option("--seeds", seeds, "number of seeds (default 30)");
  bench->add_option("--methods", methods, "comma-separated list");
  bench->add_option("--config", config, "identifier YAML");
  bench->add_option("--json", json_out, "one record per (method, seed)");
  bench->add_option("--reference", reference, "the paper's tables as CSV")->required();
  bench->add_option("--threads", threads, "worker threads (default 2)");
  bench->add_option("--fitness", tool::fitness_override, "block | paper | paper_one_step (swarm methods; overrides the config)");
  bool monitor = false;
  bench->add_flag("--monitor", monitor, "also run the condition monitor: temperature errors, alarm counts and latencies");
  bool map_roundtrip = false;
  bench->add_flag("--map-roundtrip", map_roundtrip,
                  "re-simulate every seed with the flux map each method learnt; print the currents' RMS difference");

  int repeat = 20;
  auto* perf = app.add_subcommand("perf", "samples/s of every method on one core over a recorded run");
  perf->add_option("--scenario", scenario, "scenario YAML (recorded once, then replayed)")->required();
  perf->add_option("--methods", methods, "comma-separated list");
  perf->add_option("--config", config, "identifier YAML");
  perf->add_option("--repeat", repeat, "passes over the recording (default 20)");
  perf->add_option("--json", json_out, "one record per method");
  std::string paper_scenario;
  perf->add_option("--paper-scenario", paper_scenario, "a second recording for the paper fitness (e.g. 1 MHz wc1.yaml)");
  std::string drive_scenario;
  perf->add_option("--drive-scenario", drive_scenario,
                   "a real drive's recording: FBDAPSO's cost there against the first (e.g. industrial_pwm.yaml)");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help prints and exits 0; any other command-line error is a user error: exit status 2
    // (CLI11's own codes, 100-120, are not the README's).
    if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) return app.exit(e);
    std::fprintf(stderr, "error: %s\nRun with --help for more information.\n", e.what());
    return 2;
  }
  try {
    if (*sim) return tool::runSimulate(scenario, csv, seed, duration, telemetry_period, sim_format, clock_start);
    if (*ident) {
      LogFormat format = format_path.empty() ? LogFormat{} : loadLogFormat(format_path);
      for (const std::string& c : column_names) {
        const auto eq = c.find('=');
        if (eq == std::string::npos || !format.columns.count(c.substr(0, eq)))
          throw ConfigError("--column: expected QUANTITY=HEADER with QUANTITY one of t, u_d, u_q, i_d, i_q, omega_e, "
                            "theta_e, v_dc; got '" + c + "'");
        format.columns[c.substr(0, eq)] = c.substr(eq + 1);
      }
      if (!time_unit.empty()) format.time_unit = time_unit;
      if (!speed_unit.empty()) format.speed_unit = speed_unit;
      if (!current_unit.empty()) format.current_unit = current_unit;
      if (!voltage_unit.empty()) format.voltage_unit = voltage_unit;
      if (!dq_scaling.empty()) format.dq_scaling = dq_scaling;
      if (pole_pairs != 0) format.pole_pairs = pole_pairs;
      format.validate(format_path.empty() ? "command line" : format_path + " and the command line");
      return tool::runIdentify(csv, method, config, seed, json_out, format, map_csv, thermal_state, data_kind, trace_csv);
    }
    if (*bench) return tool::runBench(scenario, seeds, methods, config, json_out, reference, threads, monitor, map_roundtrip);
    if (*perf) return tool::runPerf(scenario, methods, config, std::max(1, repeat), json_out, paper_scenario, drive_scenario);
  } catch (const UserError& e) {  // bad configuration or input: exit status 2
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
