// pmsm_tool bench: every method over N simulated seeds, in the paper's table layout (and JSON).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <thread>
#include <mutex>
#include <atomic>
#include <chrono>

#include "bench_runs.hpp"
#include "pmsm_param_id/identification/metrics.hpp"
#include "pmsm_param_id/io/config_error.hpp"
#include "commands.hpp"

namespace pmsm_param_id::tool {

int runBench(const std::string& scenario_path, int seeds, const std::string& methods_arg, const std::string& config_path,
             const std::string& json_out, const std::string& reference, int threads, bool monitor, bool map_roundtrip) {
  const Scenario base = loadScenario(scenario_path);
  const IdentifierConfig config = configFor(config_path, "", -1);
  const std::vector<std::string> methods = methodsFrom(methods_arg);
  if (seeds < 1) throw ConfigError("--seeds: must be >= 1");

  // Paper condition: the scenario file's base name up to the first '_' or '.' (wc1, wc2).
  const std::string stem = scenario_path.substr(scenario_path.find_last_of('/') + 1);
  const std::string condition = stem.substr(0, stem.find_first_of("_."));
  const auto paper = readPaperTable(reference, condition);  // before the runs: a bad path fails at once

  std::vector<std::vector<RunResult>> results(methods.size(), std::vector<RunResult>(static_cast<std::size_t>(seeds)));
  std::vector<ReferenceOptimum> references(static_cast<std::size_t>(seeds));
  std::atomic<int> next{0}, done{0};
  std::mutex progress_mutex;
  const auto started = std::chrono::steady_clock::now();
  auto last_report = started;
  InterruptGuard interrupt;  // Ctrl-C: the seeds under way finish, the tables cover the finished ones
  auto worker = [&]() {
    for (int s; !interrupt.requested() && (s = next++) < seeds;) {
      Scenario sc = base;
      sc.seed = base.seed + static_cast<std::uint64_t>(s);
      const std::vector<SimulatedSample> data = simulate(sc);
      if (config.fitness != FitnessKind::Block) {  // the paper fitness's optimum over the final window
        OutputErrorWindow window(config.fitness, config.fitness_window_samples, config.window.voltage_delay_samples);
        const std::size_t keep = static_cast<std::size_t>(window.windowSamples()) + 1;
        for (std::size_t k = data.size() > keep ? data.size() - keep : 0; k < data.size(); ++k) window.push(data[k].sample);
        references[static_cast<std::size_t>(s)] = paperReferenceOptimum(window.samples(), data.back().truth);
      }
      for (std::size_t m = 0; m < methods.size(); ++m) {
        RunResult& r = results[m][static_cast<std::size_t>(s)];
        r = runOne(data, config, methods[m], static_cast<std::uint64_t>(s) + 1, monitor);
        if (map_roundtrip && r.along.map_table) {  // the same run, the plant's magnetics from the learnt map
          r.along.map_roundtrip = currentDifference(data, simulate(withFluxMap(sc, r.along.map_table))).relative_rms;
        }
      }
      // Progress on stderr: seeds done and the time left, at most once a second (and at the end).
      const int finished = ++done;
      const std::lock_guard<std::mutex> lock(progress_mutex);
      const auto now = std::chrono::steady_clock::now();
      if (finished == seeds || now - last_report >= std::chrono::seconds(1)) {
        last_report = now;
        const double elapsed = std::chrono::duration<double>(now - started).count();
        std::fprintf(stderr, "[bench %s] %d of %d seeds done, about %.0f s left\n", base.name.c_str(), finished, seeds,
                     elapsed / finished * (seeds - finished));
      }
    }
  };
  std::vector<std::thread> pool;
  for (int i = 0; i < std::max(1, threads); ++i) pool.emplace_back(worker);
  for (auto& t : pool) t.join();
  // Seeds are taken in order and every taken seed finishes: the first `done` seeds are complete.
  const bool interrupted = done < seeds;
  if (interrupted) {
    if (done == 0) {
      std::fprintf(stderr, "interrupted: no seed finished\n");
      return 130;
    }
    std::fprintf(stderr, "interrupted: %d of %d seeds finished; the tables cover those\n", done.load(), seeds);
    seeds = done;
    for (auto& per_method : results) per_method.resize(static_cast<std::size_t>(seeds));
    references.resize(static_cast<std::size_t>(seeds));
  }

  json records = json::array();
  std::printf("\nScenario %s: %d seeds, T_s = %.3g s, %.3g s of drive time. Median over seeds; [worst |error|]\n",
              base.name.c_str(), seeds, base.drive.sample_period, base.duration);
  if (!paper.empty()) std::printf("Paper columns: the seed paper's Table for %s (mean of 5 runs, T_s = 1e-6 s).\n", condition.c_str());
  std::printf("%-24s", "");
  for (const auto& m : methods) std::printf("%-24s", m.c_str());
  std::printf("\n");
  const char* units[] = {"[ohm]", "[H]", "[H]", "[Wb]"};
  for (int p = 0; p < kParameterCount; ++p) {
    std::printf("%-6s %-17s", parameterNames()[p].c_str(), units[p]);
    for (std::size_t m = 0; m < methods.size(); ++m) {
      std::vector<double> v;
      for (const auto& r : results[m]) v.push_back(r.final.parameters[p]);
      std::printf("%-24.6g", median(v));
    }
    std::printf("\n%-24s", "  error % [worst]");
    for (std::size_t m = 0; m < methods.size(); ++m) {
      std::vector<double> e;
      double worst = 0;
      for (const auto& r : results[m]) {
        const double x = errorPercent(r.final.parameters[p], r.truth[p]);
        e.push_back(x);
        worst = std::max(worst, std::abs(x));
      }
      char buf[64];
      std::snprintf(buf, sizeof buf, "%+.3f [%.3f]", median(e), worst);
      std::printf("%-24s", buf);
    }
    std::printf("\n%-24s", "  identified");
    for (std::size_t m = 0; m < methods.size(); ++m) {
      int n = 0;
      std::map<std::string, int> other;
      for (const auto& r : results[m]) {
        n += r.final.identifiable[p];
        if (!r.final.identifiable[p]) ++other[toString(r.final.status[p])];
      }
      std::string text = std::to_string(n) + "/" + std::to_string(seeds);
      for (const auto& [status, count] : other) text += " " + status.substr(0, 6) + ":" + std::to_string(count);
      std::printf("%-24s", text.c_str());
    }
    std::printf("\n%-24s", "  identified, wrong>2%");
    for (std::size_t m = 0; m < methods.size(); ++m) std::printf("%-24d", confidentlyWrong(results[m], p));
    if (!paper.empty()) {
      std::printf("\n%-24s", "  paper value (err %)");
      for (const auto& m : methods) {
        const auto it = paper.find(m);
        char buf[64] = "-";
        if (it != paper.end()) std::snprintf(buf, sizeof buf, "%.6g (%+.2f)", it->second.value[p], it->second.error[p]);
        std::printf("%-24s", buf);
      }
    }
    std::printf("\n");
  }
  std::printf("%-24s", "recognition time [s]");
  for (std::size_t m = 0; m < methods.size(); ++m) {
    std::vector<double> t;
    int never = 0;
    double lo = INFINITY, hi = 0;
    for (const auto& r : results[m]) {
      if (std::isnan(r.recognition_time)) { ++never; continue; }
      t.push_back(r.recognition_time);
      lo = std::min(lo, r.recognition_time);
      hi = std::max(hi, r.recognition_time);
    }
    char buf[64];
    if (t.empty()) std::snprintf(buf, sizeof buf, "never");
    else std::snprintf(buf, sizeof buf, "%.4f (%.3f-%.3f)%s", median(t), lo, hi, never ? "*" : "");
    std::printf("%-24s", buf);
  }
  if (!paper.empty()) {
    std::printf("\n%-24s", "  paper");
    for (const auto& m : methods) {
      const auto it = paper.find(m);
      char buf[32] = "-";
      if (it != paper.end()) std::snprintf(buf, sizeof buf, "%.3f", it->second.recognition_time);
      std::printf("%-24s", buf);
    }
  }
  std::printf("\n%-24s", "fitness [A^2]");
  for (std::size_t m = 0; m < methods.size(); ++m) {
    std::vector<double> f;
    for (const auto& r : results[m]) f.push_back(r.final.fitness);
    std::printf("%-24.4g", median(f));
  }
  std::printf("\n%-24s", "CPU per sample [us]");
  for (std::size_t m = 0; m < methods.size(); ++m) {
    std::vector<double> c;
    for (const auto& r : results[m]) c.push_back(1e6 * r.cpu_s / static_cast<double>(r.samples));
    std::printf("%-24.3f", median(c));
  }
  // Every method against the exact optimum of the same window (wls), paired by seed.
  const auto wls_it = std::find(methods.begin(), methods.end(), std::string("wls"));
  std::vector<std::vector<json>> gaps(methods.size(), std::vector<json>(static_cast<std::size_t>(seeds)));
  if (wls_it != methods.end()) {
    const auto& ref = results[static_cast<std::size_t>(wls_it - methods.begin())];
    std::printf("\n%-24s", "gap to wls: fitness %");
    for (std::size_t m = 0; m < methods.size(); ++m) {
      std::vector<double> g;
      for (std::size_t k = 0; k < static_cast<std::size_t>(seeds); ++k) {
        const double f = results[m][k].final.fitness, f0 = ref[k].final.fitness;
        g.push_back(100.0 * (f - f0) / f0);
        gaps[m][k]["fitness_percent"] = numberOrNull(g.back());
      }
      std::printf("%-24.3g", median(g));
    }
    std::printf("\n%-24s", "  parameters % [worst]");
    for (std::size_t m = 0; m < methods.size(); ++m) {
      std::vector<double> g;
      double worst = 0;
      for (std::size_t k = 0; k < static_cast<std::size_t>(seeds); ++k) {
        double largest = 0;
        for (int p = 0; p < kParameterCount; ++p) {
          if (!ref[k].final.identifiable[p]) continue;  // only where the data determine the parameter
          const double d = std::abs(errorPercent(results[m][k].final.parameters[p], ref[k].final.parameters[p]));
          gaps[m][k][parameterNames()[p] + "_percent"] = numberOrNull(d);
          largest = std::max(largest, d);
        }
        g.push_back(largest);
        worst = std::max(worst, largest);
      }
      char buf[64];
      std::snprintf(buf, sizeof buf, "%.3f [%.3f]", median(g), worst);
      std::printf("%-24s", buf);
    }
  }
  std::printf("\n%-24s", "confidently wrong");
  for (std::size_t m = 0; m < methods.size(); ++m) {
    int n = 0;
    for (int p = 0; p < kParameterCount; ++p) n += confidentlyWrong(results[m], p);
    std::printf("%-24d", n);
  }
  std::printf("\n(gap to wls: each method's final fitness and parameters against the exact optimum of the same window,"
              " median over seeds [worst]; parameters where wls reports identified)");
  std::printf("\n(confidently wrong: (seed, parameter) pairs reported identified with |error| > 2 %%)");
  std::printf("\n(* some seeds never stayed within 1 %%; recognition time = first time after which every parameter "
              "flagged identifiable at the end stays within 1 %% of truth)\n");

  printPairedRecognition(methods, results);
  printAlongRun(methods, results, map_roundtrip);
  if (config.fitness != FitnessKind::Block) printReference(methods, results, references, config);
  const double onset = faultOnset(base);
  if (monitor) printMonitor(methods, results, onset);

  for (std::size_t m = 0; m < methods.size(); ++m)
    for (std::size_t k = 0; k < results[m].size(); ++k) {
      const RunResult& r = results[m][k];
      json j = estimateJson(r.final);
      if (monitor) {
        json mon;
        mon["winding_temperature_error_median"] = numberOrNull(medianOrNan(r.monitor.winding_error));
        mon["magnet_temperature_error_median"] = numberOrNull(medianOrNan(r.monitor.magnet_error));
        mon["estimates"] = r.monitor.estimates;
        mon["winding_temperature_reported"] = r.monitor.winding_reported;
        mon["magnet_temperature_reported"] = r.monitor.magnet_reported;
        mon["winding_temperature_outside_stated"] = r.monitor.winding_outside_stated;
        mon["magnet_temperature_outside_stated"] = r.monitor.magnet_outside_stated;
        mon["fault_onset"] = numberOrNull(onset);
        mon["alarms"] = json::array();
        for (const AlarmEvent& ev : r.monitor.events)
          mon["alarms"].push_back({{"t", ev.t}, {"kind", toString(ev.kind)}, {"raised", ev.raised}, {"text", ev.text}});
        j["monitor"] = mon;
      }
      if (!gaps[m][k].is_null()) j["gap_to_wls"] = gaps[m][k];
      j["seed"] = r.seed;
      for (int p = 0; p < kParameterCount; ++p)
        j["err_" + parameterNames()[p]] = errorPercent(r.final.parameters[p], r.truth[p]);
      j["recognition_time"] = numberOrNull(r.recognition_time);
      j["cpu_s"] = r.cpu_s;
      j["scenario"] = base.name;
      j["fitness_kind"] = toString(r.method == "ekf" || r.method == "rls" || r.method == "wls" ? FitnessKind::Block : config.fitness);
      j["confidently_wrong"] = json::object();
      for (int p = 0; p < kParameterCount; ++p)
        j["confidently_wrong"][parameterNames()[p]] = confidentlyWrong(r, p);
      json along, map_json;
      for (int p = 0; p < kParameterCount; ++p) {
        const std::string name = parameterNames()[p];
        along["identified"][name] = r.along.identified[p];
        along["wrong"][name] = r.along.wrong[p];
        along["worst_error_percent"][name] = numberOrNull(r.along.identified[p] ? r.along.worst[p] : NAN);
        along["outside_stated"][name] = r.along.outside_stated[p];
        along["worst_error_over_stated"][name] = numberOrNull(r.along.identified[p] ? r.along.worst_over_stated[p] : NAN);
        map_json["worst_cell_error_percent"][name] = numberOrNull(r.along.map_worst[p]);
      }
      for (int p : {kRs, kPsiF}) {
        const std::string name = parameterNames()[p];
        along["slow"]["identified"][name] = r.along.slow_identified[p];
        along["slow"]["wrong"][name] = r.along.slow_wrong[p];
        along["slow"]["worst_error_percent"][name] = numberOrNull(r.along.slow_identified[p] ? r.along.slow_worst[p] : NAN);
        along["slow"]["outside_stated"][name] = r.along.slow_outside_stated[p];
        along["slow"]["worst_error_over_stated"][name] =
            numberOrNull(r.along.slow_identified[p] ? r.along.slow_worst_over_stated[p] : NAN);
      }
      along["period"] = kEstimatePeriod;
      j["along_run"] = along;
      map_json["cells"] = r.along.map_cells;
      map_json["cells_identified"] = r.along.map_cells_complete;
      map_json["exported"] = static_cast<bool>(r.along.map_table);
      if (!r.along.map_problem.empty()) map_json["problem"] = r.along.map_problem;
      if (!r.along.map_note.empty()) map_json["coverage_note"] = r.along.map_note;
      map_json["roundtrip_current_rms_difference"] = numberOrNull(r.along.map_roundtrip);
      j["map"] = map_json;
      records.push_back(j);
    }
  for (std::size_t k = 0; k < references.size() && config.fitness != FitnessKind::Block; ++k) {
    const ReferenceOptimum& ref = references[k];
    json j;
    j["method"] = "reference";
    j["seed"] = k + 1;
    j["scenario"] = base.name;
    j["fitness_kind"] = toString(config.fitness);
    j["available"] = ref.available;
    j["solver"] = ref.message;
    j["fitness"] = numberOrNull(ref.available ? ref.fitness : NAN);
    for (int p = 0; p < kParameterCount; ++p) {
      j[parameterNames()[p]] = numberOrNull(ref.available ? ref.parameters[p] : NAN);
      j["err_" + parameterNames()[p]] =
          numberOrNull(ref.available ? errorPercent(ref.parameters[p], results[0][k].truth[p]) : NAN);
    }
    records.push_back(j);
  }
  if (!json_out.empty()) writeJson(json_out, records);
  return interrupted ? 130 : 0;
}

}  // namespace pmsm_param_id::tool
