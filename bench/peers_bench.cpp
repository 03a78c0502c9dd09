// peers_bench: our PSO, SAPSO and FBDAPSO against pagmo2's pso and simulated_annealing and Ceres
// Levenberg-Marquardt on the same problem: the same recorded samples, the same fitness (the
// block statistics of a wc1_drive run), the same search box, 30 seeds, equal evaluation budget.
// An optional tool: built only when libpagmo-dev and libceres-dev are installed.
#include <ceres/ceres.h>

#include <CLI/CLI.hpp>
#include <Eigen/Cholesky>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <pagmo/algorithms/pso.hpp>
#include <pagmo/algorithms/simulated_annealing.hpp>
#include <pagmo/population.hpp>
#include <pagmo/problem.hpp>
#include <random>

#include "pmsm_param_id/simulation/drive_simulator.hpp"
#include "pmsm_param_id/identification/block_statistics.hpp"
#include "pmsm_param_id/identification/identifier_config.hpp"
#include "pmsm_param_id/identification/identifiers.hpp"
#include "pmsm_param_id/identification/metrics.hpp"

using namespace pmsm_param_id;
using Clock = std::chrono::steady_clock;

namespace {

/// Counts evaluations; notes when the best point so far first lies within 1 % on all four.
struct Tracker {
  ParameterVector truth{};
  ParameterVector lower{}, span{};
  const BlockStatistics* stats = nullptr;
  long evals = 0, evals_to_1pct = -1;
  double best = INFINITY, wall_to_1pct = NAN;
  ParameterVector best_p{};
  Clock::time_point t0 = Clock::now();

  ParameterVector toParameters(const double* u) const {
    ParameterVector p;
    for (int d = 0; d < 4; ++d) p[d] = lower[d] + u[d] * span[d];
    return p;
  }
  double operator()(const ParameterVector& p) {
    const double f = stats->fitness(p);
    note(p, f);
    return f;
  }
  void note(const ParameterVector& p, double f) {
    ++evals;
    if (f < best) {
      best = f;
      best_p = p;
      if (evals_to_1pct < 0 && within(p)) {
        evals_to_1pct = evals;
        wall_to_1pct = std::chrono::duration<double>(Clock::now() - t0).count();
      }
    }
  }
  bool within(const ParameterVector& p) const {
    for (int d = 0; d < 4; ++d)
      if (!(std::abs(p[d] - truth[d]) <= 0.01 * truth[d])) return false;
    return true;
  }
};

struct PagmoProblem {
  std::shared_ptr<Tracker> tracker;
  pagmo::vector_double fitness(const pagmo::vector_double& u) const {
    return {(*tracker)(tracker->toParameters(u.data()))};
  }
  std::pair<pagmo::vector_double, pagmo::vector_double> get_bounds() const { return {{0, 0, 0, 0}, {1, 1, 1, 1}}; }
};

/// Ceres: |r|^2 = fitness, r = [L_d^T w_d ; L_q^T w_q] with S = L L^T (Cholesky of each block).
struct BlockResidual {
  Eigen::Matrix4d Ld;                 // transposed Cholesky factors, scaled by sqrt(2 / weight)
  Eigen::Matrix<double, 5, 5> Lq;
  std::array<double, 4> lower, span;
  template <class T>
  bool operator()(const T* u, T* r) const {
    const T R = T(lower[0]) + u[0] * T(span[0]), Ld_ = T(lower[1]) + u[1] * T(span[1]);
    const T Lq_ = T(lower[2]) + u[2] * T(span[2]), psi = T(lower[3]) + u[3] * T(span[3]);
    const T wd[4] = {T(1.0), R / Ld_, -Lq_ / Ld_, T(-1.0) / Ld_};
    const T wq[5] = {T(1.0), R / Lq_, Ld_ / Lq_, T(-1.0) / Lq_, psi / Lq_};
    for (int i = 0; i < 4; ++i) {
      r[i] = T(0.0);
      for (int j = 0; j < 4; ++j) r[i] += T(Ld(i, j)) * wd[j];
    }
    for (int i = 0; i < 5; ++i) {
      r[4 + i] = T(0.0);
      for (int j = 0; j < 5; ++j) r[4 + i] += T(Lq(i, j)) * wq[j];
    }
    return true;
  }
};

/// Wraps the AutoDiff cost so that every evaluation (with or without Jacobian) is counted.
class CountingCost : public ceres::CostFunction {
 public:
  CountingCost(ceres::CostFunction* inner, Tracker* tracker) : inner_(inner), tracker_(tracker) {
    set_num_residuals(9);
    mutable_parameter_block_sizes()->push_back(4);
  }
  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override {
    const bool ok = inner_->Evaluate(params, residuals, jacobians);
    double f = 0;
    for (int i = 0; i < 9; ++i) f += residuals[i] * residuals[i];
    tracker_->note(tracker_->toParameters(params[0]), f);
    return ok;
  }

 private:
  std::unique_ptr<ceres::CostFunction> inner_;
  Tracker* tracker_;
};

struct Result {
  std::string solver;
  int seed;
  std::array<double, 4> err{};
  bool success = false;
  long evals = 0, evals_to_1pct = -1;
  double wall = 0, wall_to_1pct = NAN, fitness = NAN;
};

Result finish(const std::string& solver, int seed, const Tracker& t) {
  Result r;
  r.solver = solver;
  r.seed = seed;
  for (int d = 0; d < 4; ++d) r.err[d] = errorPercent(t.best_p[d], t.truth[d]);
  r.success = t.within(t.best_p);
  r.evals = t.evals;
  r.evals_to_1pct = t.evals_to_1pct;
  r.wall = std::chrono::duration<double>(Clock::now() - t.t0).count();
  r.wall_to_1pct = t.wall_to_1pct;
  r.fitness = t.best;
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"peers_bench: our swarms against pagmo2 and Ceres on the same fitness"};
  std::string scenario_path, json_out;
  int seeds = 30, budget = 10000;
  app.add_option("--scenario", scenario_path, "scenario YAML")->required();
  app.add_option("--seeds", seeds, "seeds (default 30)");
  app.add_option("--budget", budget, "fitness evaluations per solver and seed (default 10000)");
  app.add_option("--json", json_out, "one record per (solver, seed)");
  CLI11_PARSE(app, argc, argv);

  const IdentifierConfig config = loadIdentifierConfig(std::string(PMSM_SOURCE_DIR) + "/config/identifiers/paper.yaml");
  std::vector<Result> results;
  for (int seed = 1; seed <= seeds; ++seed) {
    Scenario sc = loadScenario(scenario_path);
    sc.seed = static_cast<std::uint64_t>(seed);
    DriveSimulator sim(sc);
    BlockStatistics stats(config.window);
    stats.configure(sc.drive.sample_period);
    ParameterVector truth{};
    while (!sim.done()) {
      const SimulatedSample s = sim.step();
      stats.add(s.sample);
      truth = s.truth;
    }
    auto fresh = [&]() {
      auto t = std::make_shared<Tracker>();
      t->truth = truth;
      t->stats = &stats;
      for (int d = 0; d < 4; ++d) {
        t->lower[d] = config.search.lower[d];
        t->span[d] = config.search.upper[d] - config.search.lower[d];
      }
      t->t0 = Clock::now();
      return t;
    };
    // Ours: the online engine iterated on the fixed fitness, budget / 20 iterations.
    for (const std::string m : {"pso", "sapso", "fbdapso"}) {
      auto t = fresh();
      IdentifierConfig c = config;
      c.method = m;
      ParticleSwarm swarm(c.swarm, makeAcceptancePolicy(c), c.search.lower, c.search.upper, static_cast<std::uint64_t>(seed));
      Tracker& tr = *t;
      const auto f = [&tr](const ParameterVector& p) { return tr(p); };
      while (tr.evals < budget) swarm.iterate(f);
      results.push_back(finish("ours_" + m, seed, tr));
    }
    // pagmo2 pso: 20 particles, budget / 20 generations, its defaults otherwise.
    {
      auto t = fresh();
      pagmo::problem prob{PagmoProblem{t}};
      pagmo::population pop(prob, 20, static_cast<unsigned>(seed));
      pagmo::pso algo(static_cast<unsigned>(budget / 20 - 1), 0.7298, 2.05, 2.05, 0.5, 5u, 2u, 4u, false,
                      static_cast<unsigned>(seed));
      algo.evolve(pop);
      results.push_back(finish("pagmo_pso", seed, *t));
    }
    // pagmo2 simulated_annealing (Corana): n_T_adj x n_range_adj x bin_size x 4 = budget.
    {
      auto t = fresh();
      pagmo::problem prob{PagmoProblem{t}};
      pagmo::population pop(prob, 1, static_cast<unsigned>(seed));
      const unsigned n_T = 25, n_range = 5, bin = static_cast<unsigned>(std::max(1, budget / static_cast<int>(n_T * n_range * 4)));
      pagmo::simulated_annealing algo(10.0, 1e-5, n_T, n_range, bin, 1.0, static_cast<unsigned>(seed));
      algo.evolve(pop);
      results.push_back(finish("pagmo_sa", seed, *t));
    }
    // Ceres Levenberg-Marquardt from a far-away random start inside the same box.
    {
      auto t = fresh();
      BlockResidual res;
      // fitness = w^T S w with S the mean block product = L L^T, so fitness = |L^T w|^2.
      const Eigen::Matrix4d Sd = stats.meanProductD().topLeftCorner<4, 4>();
      const Eigen::Matrix<double, 5, 5> Sq = stats.meanProductQ().topLeftCorner<5, 5>();
      res.Ld = Sd.llt().matrixU();
      res.Lq = Sq.llt().matrixU();
      for (int d = 0; d < 4; ++d) {
        res.lower[d] = t->lower[d];
        res.span[d] = t->span[d];
      }
      std::mt19937_64 rng(static_cast<std::uint64_t>(seed));
      std::uniform_real_distribution<double> uni(0.0, 1.0);
      double u[4] = {uni(rng), uni(rng), uni(rng), uni(rng)};
      ceres::Problem problem;
      problem.AddResidualBlock(
          new CountingCost(new ceres::AutoDiffCostFunction<BlockResidual, 9, 4>(new BlockResidual(res)), t.get()),
          nullptr, u);
      for (int d = 0; d < 4; ++d) {
        problem.SetParameterLowerBound(u, d, 0.0);
        problem.SetParameterUpperBound(u, d, 1.0);
      }
      ceres::Solver::Options options;
      options.linear_solver_type = ceres::DENSE_QR;
      options.max_num_iterations = budget;
      options.function_tolerance = 1e-15;
      options.gradient_tolerance = 1e-20;
      options.parameter_tolerance = 1e-15;
      ceres::Solver::Summary summary;
      ceres::Solve(options, &problem, &summary);
      results.push_back(finish("ceres_lm", seed, *t));
    }
  }

  // Table: medians over seeds, success rate, ratios to our FBDAPSO.
  std::map<std::string, std::vector<Result>> by;
  for (const auto& r : results) by[r.solver].push_back(r);
  auto med = [](std::vector<double> v) { return median(std::move(v)); };
  const auto& fb = by["ours_fbdapso"];
  std::vector<double> fb_e, fb_w;
  for (const auto& r : fb) {
    if (r.evals_to_1pct > 0) fb_e.push_back(static_cast<double>(r.evals_to_1pct));
    if (std::isfinite(r.wall_to_1pct)) fb_w.push_back(r.wall_to_1pct);
  }
  const double fb_evals = med(fb_e), fb_wall = med(fb_w);
  std::printf("\nSame fitness, same samples (%s), same box, %d seeds, budget %d evaluations.\n", scenario_path.c_str(),
              seeds, budget);
  std::printf("%-14s %8s %28s %14s %10s %14s %10s\n", "solver", "success", "median |err| % R_s/L_d/L_q/psi",
              "evals to 1 %", "x FBDAPSO", "wall to 1 % [ms]", "x FBDAPSO");
  for (const std::string name : {"ours_fbdapso", "ours_sapso", "ours_pso", "pagmo_pso", "pagmo_sa", "ceres_lm"}) {
    const auto& v = by[name];
    int ok = 0;
    std::array<std::vector<double>, 4> e;
    std::vector<double> ev, wl;
    for (const auto& r : v) {
      ok += r.success;
      for (int d = 0; d < 4; ++d) e[d].push_back(std::abs(r.err[d]));
      if (r.evals_to_1pct > 0) ev.push_back(static_cast<double>(r.evals_to_1pct));
      if (std::isfinite(r.wall_to_1pct)) wl.push_back(r.wall_to_1pct);
    }
    char errs[64];
    std::snprintf(errs, sizeof errs, "%.3f/%.3f/%.3f/%.3f", med(e[0]), med(e[1]), med(e[2]), med(e[3]));
    std::printf("%-14s %5d/%-2d %28s %14.0f %10.2f %14.3f %10.2f\n", name.c_str(), ok, seeds, errs, med(ev),
                med(ev) / fb_evals, 1e3 * med(wl), med(wl) / fb_wall);
  }
  std::printf("(evals/wall to 1 %%: first evaluation at which the best point so far is within 1 %% on all four; "
              "medians over the seeds that got there)\n");
  if (!json_out.empty()) {
    nlohmann::json j = nlohmann::json::array();
    for (const auto& r : results)
      j.push_back({{"solver", r.solver}, {"seed", r.seed}, {"err_R_s", r.err[0]}, {"err_L_d", r.err[1]},
                   {"err_L_q", r.err[2]}, {"err_psi_f", r.err[3]}, {"success", r.success},
                   {"evals_to_1pct", r.evals_to_1pct > 0 ? nlohmann::json(r.evals_to_1pct) : nlohmann::json(nullptr)},
                   {"wall_s_to_1pct", std::isfinite(r.wall_to_1pct) ? nlohmann::json(r.wall_to_1pct) : nlohmann::json(nullptr)},
                   {"evals", r.evals}, {"fitness", r.fitness}});
    std::ofstream(json_out) << j.dump(1) << "\n";
  }
  return 0;
}
