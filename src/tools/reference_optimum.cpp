#include "reference_optimum.hpp"

#include <cmath>

#ifdef PMSM_HAVE_CERES
#include <ceres/ceres.h>
#endif

namespace pmsm_param_id {

#ifdef PMSM_HAVE_CERES
namespace {
/// Eq. (11) over the window from the measured current at its start; residuals are the current
/// errors divided by sqrt(N - 1), so that their sum of squares is Eq. (12). The unknowns are the
/// parameters relative to the start (x = p / start), which puts the four on one scale.
struct PaperWindowResiduals {
  const std::vector<Sample>* window;
  ParameterVector scale;
  template <typename T>
  bool operator()(const T* const x, T* residual) const {
    const std::vector<Sample>& w = *window;
    const T R = x[0] * scale[kRs], Ld = x[1] * scale[kLd], Lq = x[2] * scale[kLq], psi = x[3] * scale[kPsiF];
    const double weight = 1.0 / std::sqrt(static_cast<double>(w.size() - 1));
    T id = T(w[0].i_d), iq = T(w[0].i_q);
    for (std::size_t k = 0; k + 1 < w.size(); ++k) {
      const double dt = w[k + 1].t - w[k].t, omega = w[k].omega_e;
      const T did = (w[k].u_d - R * id + omega * Lq * iq) / Ld;
      const T diq = (w[k].u_q - R * iq - omega * (Ld * id + psi)) / Lq;
      id = id + dt * did;
      iq = iq + dt * diq;
      residual[2 * k] = (w[k + 1].i_d - id) * weight;
      residual[2 * k + 1] = (w[k + 1].i_q - iq) * weight;
    }
    return true;
  }
};
}  // namespace

ReferenceOptimum paperReferenceOptimum(const std::vector<Sample>& window, const ParameterVector& start) {
  ReferenceOptimum r;
  if (window.size() < 2) {
    r.message = "window shorter than two samples";
    return r;
  }
  double x[4] = {1.0, 1.0, 1.0, 1.0};
  ceres::Problem problem;
  const int residuals = static_cast<int>(2 * (window.size() - 1));
  problem.AddResidualBlock(new ceres::AutoDiffCostFunction<PaperWindowResiduals, ceres::DYNAMIC, 4>(
                               new PaperWindowResiduals{&window, start}, residuals),
                           nullptr, x);
  for (int i = 0; i < 4; ++i) problem.SetParameterLowerBound(x, i, 1e-3);
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = 200;
  options.function_tolerance = 1e-15;
  options.gradient_tolerance = 1e-20;
  options.parameter_tolerance = 1e-12;
  options.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  r.available = summary.IsSolutionUsable();
  r.iterations = static_cast<int>(summary.iterations.size());
  for (int i = 0; i < 4; ++i) r.parameters[i] = x[i] * start[i];
  r.fitness = 2.0 * summary.final_cost;
  r.message = summary.BriefReport();
  return r;
}
#else
ReferenceOptimum paperReferenceOptimum(const std::vector<Sample>&, const ParameterVector&) {
  ReferenceOptimum r;
  r.message = "built without Ceres (libceres-dev): no reference optimum";
  return r;
}
#endif

}  // namespace pmsm_param_id
