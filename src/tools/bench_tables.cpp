// bench's tables beyond the paper's: the condition monitor, paired recognition times, the
// reference optimum, the estimates along the run and the map of the motor.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "bench_runs.hpp"
#include "pmsm_param_id/identification/metrics.hpp"
#include "pmsm_param_id/io/config_error.hpp"

namespace pmsm_param_id::tool {

/// bench --monitor: temperature errors and alarm counts per method, over seeds.
void printMonitor(const std::vector<std::string>& methods, const std::vector<std::vector<RunResult>>& results,
                  double onset) {
  const int seeds = static_cast<int>(results.front().size());
  std::printf("\nCondition monitor (an estimate every %.0f ms; temperatures need a thermal: block in the config)\n",
              1e3 * kEstimatePeriod);
  std::printf("%-26s", "");
  for (const auto& m : methods) std::printf("%-24s", m.c_str());
  const auto temperature_row = [&](const char* label, bool winding) {
    std::printf("\n%-26s", label);
    for (std::size_t m = 0; m < methods.size(); ++m) {
      std::vector<double> per_seed;
      double reported = 0, estimates = 0;
      for (const RunResult& r : results[m]) {
        const auto& e = winding ? r.monitor.winding_error : r.monitor.magnet_error;
        if (!e.empty()) per_seed.push_back(median(e));
        reported += winding ? r.monitor.winding_reported : r.monitor.magnet_reported;
        estimates += r.monitor.estimates;
      }
      char buf[64] = "never reported";
      if (per_seed.empty() && reported > 0)
        std::snprintf(buf, sizeof buf, "no truth, %.0f%%", 100.0 * reported / std::max(1.0, estimates));
      if (!per_seed.empty())
        std::snprintf(buf, sizeof buf, "%.2f [%.2f] %.0f%%", median(per_seed),
                      *std::max_element(per_seed.begin(), per_seed.end()), 100.0 * reported / std::max(1.0, estimates));
      std::printf("%-24s", buf);
    }
  };
  temperature_row("winding T |err| [K]", true);
  temperature_row("magnet T |err| [K]", false);
  std::printf("\n%-26s", "T outside stated w/m");
  for (std::size_t m = 0; m < methods.size(); ++m) {
    double w_out = 0, w_rep = 0, m_out = 0, m_rep = 0;
    for (const RunResult& r : results[m]) {
      w_out += r.monitor.winding_outside_stated;
      w_rep += r.monitor.winding_error.size();
      m_out += r.monitor.magnet_outside_stated;
      m_rep += r.monitor.magnet_error.size();
    }
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.1f%% / %.1f%%", 100.0 * w_out / std::max(1.0, w_rep), 100.0 * m_out / std::max(1.0, m_rep));
    std::printf("%-24s", buf);
  }
  if (std::isfinite(onset)) std::printf("\nfault at t = %.4g s (first change of a fault profile)", onset);
  else std::printf("\nno fault in the scenario: every alarm is a false alarm");
  for (AlarmKind kind : {AlarmKind::WindingOverTemperature, AlarmKind::Demagnetisation, AlarmKind::ParameterJump,
                         AlarmKind::FastDrift}) {
    std::printf("\n%-26s", toString(kind));
    for (std::size_t m = 0; m < methods.size(); ++m) {
      int before = 0, after = 0;
      std::vector<double> latency;
      for (const RunResult& r : results[m]) {
        bool b = false;
        double first_after = NAN;
        for (const AlarmEvent& ev : r.monitor.events) {
          if (ev.kind != kind || !ev.raised) continue;
          if (std::isfinite(onset) && ev.t >= onset) {
            if (std::isnan(first_after)) first_after = ev.t - onset;
          } else {
            b = true;
          }
        }
        before += b;
        if (std::isfinite(first_after)) {
          ++after;
          latency.push_back(first_after);
        }
      }
      char buf[64];
      if (!std::isfinite(onset)) std::snprintf(buf, sizeof buf, "%d/%d seeds", before, seeds);
      else if (latency.empty()) std::snprintf(buf, sizeof buf, "0/%d, early %d", seeds, before);
      else
        std::snprintf(buf, sizeof buf, "%d/%d %.3f [%.3f]s e%d", after, seeds, median(latency),
                      *std::max_element(latency.begin(), latency.end()), before);
      std::printf("%-24s", buf);
    }
  }
  std::printf("\n(temperatures: median over seeds of each seed's median |error| [worst seed], %% of estimates that"
              " carried one;\n outside stated: of the reported ones with a truth, |error| beyond the stated uncertainty;\n alarms: seeds that raised it after the fault, latency median [worst] from the fault,"
              " e = seeds that raised it before the fault)\n");
}

/// FBDAPSO's recognition time against SAPSO's and PSO's, seed by seed (the paper's claim of a faster
/// convergence is a paired one): in how many seeds it was faster, and the ratio's quartiles over the
/// seeds where both recognised.
void printPairedRecognition(const std::vector<std::string>& methods, const std::vector<std::vector<RunResult>>& results) {
  const auto index = [&methods](const char* name) {
    return static_cast<std::size_t>(std::find(methods.begin(), methods.end(), std::string(name)) - methods.begin());
  };
  const std::size_t a = index("fbdapso");
  if (a == methods.size()) return;
  bool header = false;
  for (const char* other : {"sapso", "pso"}) {
    const std::size_t b = index(other);
    if (b == methods.size()) continue;
    if (!header) std::printf("\nRecognition time paired by seed (FBDAPSO against each; ratio = FBDAPSO / other):\n");
    header = true;
    std::vector<double> ratio;
    int faster = 0, never_a = 0, never_b = 0;
    for (std::size_t k = 0; k < results[a].size() && k < results[b].size(); ++k) {
      const double ta = results[a][k].recognition_time, tb = results[b][k].recognition_time;
      never_a += std::isnan(ta);
      never_b += std::isnan(tb);
      if (std::isnan(ta) || std::isnan(tb) || !(tb > 0)) continue;
      faster += ta < tb;
      ratio.push_back(ta / tb);
    }
    std::sort(ratio.begin(), ratio.end());
    const std::size_t n = ratio.size();
    std::printf("  fbdapso/%-6s faster in %d of %zu seeds where both recognised (never: fbdapso %d, %s %d)", other, faster,
                n, never_a, other, never_b);
    if (n > 0) std::printf("; ratio median %.2f, quartiles %.2f-%.2f", median(ratio), ratio[n / 4], ratio[3 * n / 4]);
    std::printf("\n");
  }
}

/// bench --fitness paper: the reference optimum of each seed's final window and each method's gap to it.
void printReference(const std::vector<std::string>& methods, const std::vector<std::vector<RunResult>>& results,
                    const std::vector<ReferenceOptimum>& references, const IdentifierConfig& config) {
  const int window_samples = config.fitness == FitnessKind::PaperOneStep ? 2 : config.fitness_window_samples;
  std::printf("\nReference optimum of the %s fitness (N = %d samples) over each seed's final window: Ceres "
              "(Levenberg-Marquardt) started at the truth\n", toString(config.fitness), window_samples);
  int available = 0;
  for (const auto& r : references) available += r.available;
  if (available == 0) {
    std::printf("  not available: %s\n", references.empty() ? "no seed" : references.front().message.c_str());
    return;
  }
  for (int p = 0; p < kParameterCount; ++p) {
    std::vector<double> e;
    double worst = 0;
    for (std::size_t k = 0; k < references.size(); ++k) {
      if (!references[k].available) continue;
      e.push_back(errorPercent(references[k].parameters[p], results[0][k].truth[p]));
      worst = std::max(worst, std::abs(e.back()));
    }
    std::printf("  %-6s error %% against truth %+.4f [worst %.4f]\n", parameterNames()[p].c_str(), median(e), worst);
  }
  std::vector<double> f;
  for (const auto& r : references)
    if (r.available) f.push_back(r.fitness);
  std::printf("  fitness %.4g A^2 (median; %d/%zu seeds solved)\n", median(f), available, references.size());
  std::printf("%-24s", "gap to reference:");
  for (const auto& m : methods) std::printf("%-24s", m.c_str());
  std::printf("\n%-24s", "  fitness excess [A^2]");  // absolute: the optimum of noise-free data is ~0
  for (std::size_t m = 0; m < methods.size(); ++m) {
    std::vector<double> g;
    for (std::size_t k = 0; k < references.size(); ++k)
      if (references[k].available) g.push_back(results[m][k].final.fitness - references[k].fitness);
    std::printf("%-24.3g", median(g));
  }
  std::printf("\n%-24s", "  parameters % [worst]");
  for (std::size_t m = 0; m < methods.size(); ++m) {
    std::vector<double> g;
    for (std::size_t k = 0; k < references.size(); ++k) {
      if (!references[k].available) continue;
      double largest = 0;
      for (int p = 0; p < kParameterCount; ++p)
        largest = std::max(largest, std::abs(errorPercent(results[m][k].final.parameters[p], references[k].parameters[p])));
      g.push_back(largest);
    }
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.3f [%.3f]", median(g), *std::max_element(g.begin(), g.end()));
    std::printf("%-24s", buf);
  }
  std::printf("\n(ekf, rls and wls minimise their own criteria, not this fitness; their gap is shown for comparison)\n");
}

/// Every identified estimate along the run against the truth of its moment, and the map it made.
void printAlongRun(const std::vector<std::string>& methods, const std::vector<std::vector<RunResult>>& results,
                   bool roundtrip) {
  std::printf("\nAlong the run (an estimate every %.0f ms against the truth of its moment; a saturating machine's\n"
              "truth is that of the operating point, doc/algorithm.md section 11):\n%-24s", 1e3 * kEstimatePeriod, "");
  for (const auto& m : methods) std::printf("%-24s", m.c_str());
  for (int p = 0; p < kParameterCount; ++p) {
    std::printf("\n  %-20s", (parameterNames()[p] + " wrong/ident.").c_str());
    for (std::size_t m = 0; m < methods.size(); ++m) {
      int wrong = 0, identified = 0;
      double worst = 0.0;
      for (const RunResult& r : results[m]) {
        wrong += r.along.wrong[p];
        identified += r.along.identified[p];
        if (r.along.identified[p]) worst = std::max(worst, r.along.worst[p]);
      }
      char buf[64];
      std::snprintf(buf, sizeof buf, "%d/%d [%.2f%%]", wrong, identified, worst);
      std::printf("%-24s", buf);
    }
  }
  std::printf("\n  %-20s", "outside stated");
  for (std::size_t m = 0; m < methods.size(); ++m) {
    int outside = 0;
    double worst = 0.0;
    for (const RunResult& r : results[m])
      for (int p = 0; p < kParameterCount; ++p) {
        outside += r.along.outside_stated[p];
        if (r.along.identified[p]) worst = std::max(worst, r.along.worst_over_stated[p]);
      }
    char buf[64];
    std::snprintf(buf, sizeof buf, "%d [%.2f]", outside, worst);
    std::printf("%-24s", buf);
  }
  for (int p : {kRs, kPsiF}) {  // the slow window's R_s and psi_f (Estimate::slow)
    std::printf("\n  %-20s", ("slow " + parameterNames()[p] + " w/i/o").c_str());
    for (std::size_t m = 0; m < methods.size(); ++m) {
      int wrong = 0, identified = 0, outside = 0;
      double worst = 0.0;
      for (const RunResult& r : results[m]) {
        wrong += r.along.slow_wrong[p];
        identified += r.along.slow_identified[p];
        outside += r.along.slow_outside_stated[p];
        if (r.along.slow_identified[p]) worst = std::max(worst, r.along.slow_worst[p]);
      }
      char buf[64];
      std::snprintf(buf, sizeof buf, "%d/%d/%d [%.2f%%]", wrong, identified, outside, worst);
      std::printf("%-24s", buf);
    }
  }
  std::printf("\n  %-20s", "map cells (full)");
  for (std::size_t m = 0; m < methods.size(); ++m) {
    std::vector<double> cells, complete;
    for (const RunResult& r : results[m]) {
      cells.push_back(r.along.map_cells);
      complete.push_back(r.along.map_cells_complete);
    }
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.0f (%.0f) [min %.0f]", median(cells), median(complete),
                  *std::min_element(complete.begin(), complete.end()));
    std::printf("%-24s", buf);
  }
  std::printf("\n  %-20s", "map worst cell %");
  for (std::size_t m = 0; m < methods.size(); ++m) {
    std::vector<double> worst;
    for (const RunResult& r : results[m])
      worst.push_back(*std::max_element(r.along.map_worst.begin(), r.along.map_worst.end()));
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.2f [%.2f]", median(worst), *std::max_element(worst.begin(), worst.end()));
    std::printf("%-24s", buf);
  }
  if (roundtrip) {
    std::printf("\n  %-20s", "map round trip %");
    for (std::size_t m = 0; m < methods.size(); ++m) {
      std::vector<double> d;
      int missing = 0;
      for (const RunResult& r : results[m]) {
        if (std::isfinite(r.along.map_roundtrip)) d.push_back(100.0 * r.along.map_roundtrip);
        else ++missing;
      }
      char buf[64];
      int partial = 0;
      for (const RunResult& r : results[m]) partial += !r.along.map_note.empty();
      if (d.empty()) std::snprintf(buf, sizeof buf, "no map (%d)", missing);
      else std::snprintf(buf, sizeof buf, "%.3f [%.3f]%s%s", median(d), *std::max_element(d.begin(), d.end()),
                         missing ? " *" : "", partial ? (" p" + std::to_string(partial)).c_str() : "");
      std::printf("%-24s", buf);
    }
  }
  std::printf("\n(wrong/ident.: estimates reported identified and > 2 %% off / reported identified, all seeds [worst |error|];"
              "\n outside stated: identified estimates, all four parameters, whose |error| exceeds their stated uncertainty"
              " [largest ratio];"
              "\n slow w/i/o: the slow window's estimates > 2 %% off / identified / outside their stated uncertainty [worst |error|];"
              "\n map cells: cells of operating points (full: with L_d, L_q, psi_f identified) median [fewest]; worst cell: a cell's latest"
              "\n identified value against the truth when it was filed, median over seeds [worst]%s)\n",
              roundtrip ? ";\n round trip: RMS current difference, the same run re-simulated with the learnt map, median [worst]; "
                          "* some seeds exported no map;\n pN: in N seeds the map was partial (cells visited where L_d or psi_f "
                          "was never identified: the map is extrapolated there)" : "");
}

}  // namespace pmsm_param_id::tool
