#include "pmsm_param_id/identification/block_least_squares.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace pmsm_param_id {

namespace {
// At most 10 parameters: fixed-capacity matrices keep the solver off the heap.
using MatN = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 10, 10>;
using VecN = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 10, 1>;
constexpr int kMaxParameters = 10;

LinearBlockModel base(int extra) {
  LinearBlockModel m;
  m.parameter_names = {"R_s", "L_d", "L_q", "psi_f"};
  const int n = 4 + extra;
  m.G_d = Eigen::MatrixXd::Zero(kBlockSizeD, n);
  m.G_q = Eigen::MatrixXd::Zero(kBlockSizeQ, n);
  m.G_d(kIntegralId, kRs) = 1.0;
  m.G_d(kDeltaId, kLd) = 1.0;
  m.G_d(kIntegralOmegaIq, kLq) = -1.0;
  m.G_q(kIntegralIq, kRs) = 1.0;
  m.G_q(kIntegralOmegaId, kLd) = 1.0;
  m.G_q(kDeltaIq, kLq) = 1.0;
  m.G_q(kIntegralOmega, kPsiF) = 1.0;
  return m;
}

// Appends a parameter with empty columns to m; returns its index in beta.
int addParameter(LinearBlockModel& m, const std::string& name) {
  const int j = m.size();
  m.parameter_names.push_back(name);
  m.G_d.conservativeResize(Eigen::NoChange, j + 1);
  m.G_q.conservativeResize(Eigen::NoChange, j + 1);
  m.G_d.col(j).setZero();
  m.G_q.col(j).setZero();
  return j;
}

// Residual weight vectors v = (G beta - e_U) / L per axis (r = v . z); R block entries, N
// parameters, both known at compile time (the fit is instantiated per model size). Products with
// 1 / L: a division per entry made this a quarter of a fit.
template <int R, int N>
void weights(const Eigen::Matrix<double, R, N>& G, int voltage_row, const Eigen::Matrix<double, N, 1>& beta,
             int inductance, Eigen::Matrix<double, R, 1>& v) {
  Eigen::Matrix<double, R, 1> e = G.lazyProduct(beta);
  e(voltage_row) -= 1.0;
  v = e * (1.0 / beta(inductance));
}
// The same and their Jacobian dv/dbeta = (G - v e_L^T) / L.
template <int R, int N>
void weights(const Eigen::Matrix<double, R, N>& G, int voltage_row, const Eigen::Matrix<double, N, 1>& beta,
             int inductance, Eigen::Matrix<double, R, 1>& v, Eigen::Matrix<double, R, N>& J) {
  weights<R, N>(G, voltage_row, beta, inductance, v);
  const double inverse_L = 1.0 / beta(inductance);
  J = G * inverse_L;
  J.col(inductance) -= v * inverse_L;
}

// J^T S J, J^T S v and v^T S v for the block sums S (R x R) as fixed-size lazy products (S times the
// right-hand factor first), not general matrix products with packing.
template <int R, int N>
Eigen::Matrix<double, N, N> normalMatrix(const Eigen::Matrix<double, R, N>& J, const Eigen::Matrix<double, R, R>& S) {
  const Eigen::Matrix<double, R, N> SJ = S.lazyProduct(J);
  return J.transpose().lazyProduct(SJ);
}
template <int R, int N>
Eigen::Matrix<double, N, 1> gradient(const Eigen::Matrix<double, R, N>& J, const Eigen::Matrix<double, R, R>& S,
                                     const Eigen::Matrix<double, R, 1>& v) {
  const Eigen::Matrix<double, R, 1> Sv = S.lazyProduct(v);
  return J.transpose().lazyProduct(Sv);
}
template <int R>
double quadraticForm(const Eigen::Matrix<double, R, 1>& v, const Eigen::Matrix<double, R, R>& S) {
  const Eigen::Matrix<double, R, 1> Sv = S.lazyProduct(v);
  return v.dot(Sv);
}

/// The mean squares of the block residuals (v^T S v over the window's sums) and of their
/// differences, per axis, for the weight vectors vd, vq.
void residualMeanSquares(const WindowSums& stats, const Eigen::Matrix<double, kBlockSizeD, 1>& vd,
                         const Eigen::Matrix<double, kBlockSizeQ, 1>& vq, double& ms_d, double& ms_q,
                         double& diff_ms_d, double& diff_ms_q) {
  ms_d = std::max(0.0, quadraticForm(vd, stats.mean_d));
  ms_q = std::max(0.0, quadraticForm(vq, stats.mean_q));
  diff_ms_d = std::max(0.0, quadraticForm(vd, stats.mean_difference_d));
  diff_ms_q = std::max(0.0, quadraticForm(vq, stats.mean_difference_q));
}

/// f(std::integral_constant<int, N>{}) for the model's parameter count N, 4 to 8: the fit and the
/// residuals are instantiated per model size, so that every matrix has its size at compile time.
template <class F>
auto forModelSize(const LinearBlockModel& model, F&& f) {
  switch (model.size()) {
    case 4: return f(std::integral_constant<int, 4>{});
    case 5: return f(std::integral_constant<int, 5>{});
    case 6: return f(std::integral_constant<int, 6>{});
    case 7: return f(std::integral_constant<int, 7>{});
    case 8: return f(std::integral_constant<int, 8>{});
    case 9: return f(std::integral_constant<int, 9>{});
    case 10: return f(std::integral_constant<int, 10>{});
  }
  throw std::invalid_argument("a block model has 4 to 10 parameters, not " + std::to_string(model.size()));
}

/// The exact fit of a model with N parameters (BlockLeastSquares::fit).
template <int N>
BlockFit fitModel(const WindowSums& stats, const LinearBlockModel& model, const Eigen::VectorXd& start,
                  const std::vector<bool>& fixed_in, double variance_inflation);
}  // namespace

const LinearBlockModel& LinearBlockModel::paper() {
  static const LinearBlockModel model = [] {
    LinearBlockModel m = base(0);
    m.name = "paper";
    return m;
  }();
  return model;
}

const LinearBlockModel& LinearBlockModel::speedScale() {
  static const LinearBlockModel model = [] {
    // beta = {R_s, L_d (Di_d), L_q (Di_q), psi_f (speed term), L_q (speed term), L_d (speed term)}
    LinearBlockModel m = base(2);
    m.name = "speed_scale";
    m.parameter_names.push_back("L_q_speed_term");
    m.parameter_names.push_back("L_d_speed_term");
    m.G_d(kIntegralOmegaIq, kLq) = 0.0;
    m.G_d(kIntegralOmegaIq, 4) = -1.0;
    m.G_q(kIntegralOmegaId, kLd) = 0.0;
    m.G_q(kIntegralOmegaId, 5) = 1.0;
    return m;
  }();
  return model;
}

const LinearBlockModel& LinearBlockModel::delay() {
  static const LinearBlockModel model = [] {
    LinearBlockModel m = withDelay(paper());
    m.name = "delay";
    return m;
  }();
  return model;
}

const LinearBlockModel& LinearBlockModel::inverter() {
  static const LinearBlockModel model = [] {
    LinearBlockModel m = base(1);
    m.name = "inverter";
    m.parameter_names.push_back("inverter_voltage");
    m.G_d(kIntegralInverterD, 4) = 1.0;
    m.G_q(kIntegralInverterQ, 4) = 1.0;
    return m;
  }();
  return model;
}

LinearBlockModel LinearBlockModel::withCrossSaturation(const LinearBlockModel& base_model, double i_bar) {
  // + {L_qq, L_dq} after the model's own parameters. The flux linkages at i_d = 0 are lines in i_q
  // about i_bar: psi_q(0, i_q) = L_q i_bar + L_qq (i_q - i_bar) (L_q the secant at i_bar, L_qq the
  // incremental inductance), psi_d(0, i_q) = psi + L_dq (i_q - i_bar) (psi the flux at i_bar, L_dq
  // by reciprocity the slope of psi_d in i_q as of psi_q in i_d):
  //   d: int u_d = R int i_d + L_dd Di_d + L_dq (Di_q - int omega i_d)
  //               - L_qq int omega i_q - i_bar (L_q - L_qq) int omega + ...
  //   q: int u_q = R int i_q + L_qq Di_q + L_dq (Di_d + int omega i_q - i_bar int omega)
  //               + L_dd int omega i_d + psi int omega + ...
  // With i_q steady (torque control) int omega i_q = i_bar int omega and this is the model with
  // L_q in the speed term; under a speed loop i_q moves with the torque ripple, and only the lines
  // keep L_d and psi unbiased.
  LinearBlockModel m = base_model;
  m.name = base_model.name + "+cross_saturation";
  const int L_qq = addParameter(m, "L_qq"), L_dq = addParameter(m, "L_dq");
  m.G_q(kDeltaIq, kLq) = 0.0;
  m.G_q(kDeltaIq, L_qq) = 1.0;
  m.G_d(kIntegralOmegaIq, kLq) = 0.0;
  m.G_d(kIntegralOmegaInD, kLq) = -i_bar;
  m.G_d(kIntegralOmegaIq, L_qq) = -1.0;
  m.G_d(kIntegralOmegaInD, L_qq) = i_bar;
  m.G_d(kDeltaIqInD, L_dq) = 1.0;
  m.G_d(kIntegralOmegaIdInD, L_dq) = -1.0;
  m.G_q(kDeltaIdInQ, L_dq) = 1.0;
  m.G_q(kIntegralOmegaIqInQ, L_dq) = 1.0;
  m.G_q(kIntegralOmega, L_dq) = -i_bar;
  m.q_inductance = L_qq;  // r_q = e_q / L_qq: the measured Di_q keeps the coefficient 1 (its noise is the output's)
  return m;
}

LinearBlockModel LinearBlockModel::crossSaturation(double i_bar) { return withCrossSaturation(paper(), i_bar); }

LinearBlockModel LinearBlockModel::crossSaturationSpeedScale(double i_bar) {
  // {R_s, L_dd, L_q, psi_f, L_qq, L_dq, L_dd in the speed term}: with L_q's speed and step terms
  // legitimately apart on a saturating machine, the unit is tested on the linear d axis.
  LinearBlockModel m = withCrossSaturation(paper(), i_bar);
  m.name = "cross_saturation_speed_scale";
  const int L_d_speed = addParameter(m, "L_d_speed_term");  // 6: measureSpeedScale reads beta(6)
  m.G_q(kIntegralOmegaId, kLd) = 0.0;
  m.G_q(kIntegralOmegaId, L_d_speed) = 1.0;
  return m;
}

const LinearBlockModel& LinearBlockModel::inverterWithShape() {
  // V (s - s_wide) + V_wide s_wide = V s + V_wide (s_wide - s): V the amplitude whatever the shape.
  static const LinearBlockModel model = [] {
    LinearBlockModel m = inverter();
    m.name = "inverter_with_shape";
    const int wide = addParameter(m, "inverter_voltage_wide_share");
    m.G_d(kIntegralInverterWideD, wide) = 1.0;
    m.G_d(kIntegralInverterD, wide) = -1.0;
    m.G_q(kIntegralInverterWideQ, wide) = 1.0;
    m.G_q(kIntegralInverterQ, wide) = -1.0;
    return m;
  }();
  return model;
}

const LinearBlockModel& LinearBlockModel::inverterWithShapeAndBus() {
  // + V_bus (v_dc / v_ref - 1) s: the dead-time part of V follows the logged bus voltage, the
  // device drops do not; V stays the amplitude at the reference bus voltage.
  static const LinearBlockModel model = [] {
    LinearBlockModel m = inverterWithShape();
    m.name = "inverter_with_shape_and_bus";
    const int bus = addParameter(m, "inverter_voltage_bus_share");
    m.G_d(kIntegralInverterBusD, bus) = 1.0;
    m.G_q(kIntegralInverterBusQ, bus) = 1.0;
    return m;
  }();
  return model;
}

LinearBlockModel LinearBlockModel::withDelay(const LinearBlockModel& base_model) {
  LinearBlockModel m = base_model;
  m.name = base_model.name + "+delay";
  const int a = addParameter(m, "voltage_delay");
  m.G_d(kIntegralUdStep, a) = 1.0;
  m.G_q(kIntegralUqStep, a) = 1.0;
  return m;
}

LinearBlockModel LinearBlockModel::withVoltageAngle(const LinearBlockModel& base_model) {
  // + {a}: the acting vector is the logged one turned by a omega_e T_s (to first order
  // u + a omega_e T_s J u), so int u_d = ... + a int omega T_s u_q, int u_q = ... - a int omega T_s u_d.
  LinearBlockModel m = base_model;
  m.name = base_model.name + "+voltage_angle";
  const int a = addParameter(m, "voltage_angle");
  m.G_d(kIntegralAngleUqInD, a) = 1.0;
  m.G_q(kIntegralAngleUdInQ, a) = -1.0;
  return m;
}

LinearBlockModel LinearBlockModel::withResistanceRate(const LinearBlockModel& base_model) {
  // + {rho, kappa}: R_s(t) = R_s + rho (t - t_ref) + kappa (Q(t) - Q_ref), so int R_s(t) i dt =
  // R_s int i + rho int (t - t_ref) i + kappa int (Q(t) - Q_ref) i.
  LinearBlockModel m = base_model;
  m.name = base_model.name + "+resistance_rate";
  const int rho = addParameter(m, "resistance_rate");
  m.G_d(kIntegralIdRate, rho) = 1.0;
  m.G_q(kIntegralIqRate, rho) = 1.0;
  const int kappa = addParameter(m, "resistance_heating");
  m.G_d(kIntegralIdHeat, kappa) = 1.0;
  m.G_q(kIntegralIqHeat, kappa) = 1.0;
  return m;
}

namespace {
template <int N>
void residualsOf(const WindowSums& stats, const LinearBlockModel& model, const Eigen::VectorXd& beta, double& ms_d,
                 double& ms_q, double& diff_ms_d, double& diff_ms_q) {
  Eigen::Matrix<double, kBlockSizeD, 1> vd;
  Eigen::Matrix<double, kBlockSizeQ, 1> vq;
  const Eigen::Matrix<double, N, 1> b = beta;
  weights<kBlockSizeD, N>(model.G_d, kIntegralUd, b, model.d_inductance, vd);
  weights<kBlockSizeQ, N>(model.G_q, kIntegralUq, b, model.q_inductance, vq);
  residualMeanSquares(stats, vd, vq, ms_d, ms_q, diff_ms_d, diff_ms_q);
}
}  // namespace

void BlockLeastSquares::residuals(const WindowSums& stats, const LinearBlockModel& model,
                                  const Eigen::VectorXd& beta, double& ms_d, double& ms_q, double& diff_ms_d,
                                  double& diff_ms_q) {
  forModelSize(model, [&](auto size) {
    residualsOf<decltype(size)::value>(stats, model, beta, ms_d, ms_q, diff_ms_d, diff_ms_q);
  });
}

BlockFit BlockLeastSquares::fit(const WindowSums& stats, const LinearBlockModel& model,
                                const Eigen::VectorXd& start, const std::vector<bool>& fixed_in,
                                double variance_inflation) {
  // One instance per model size: the small products are unrolled loops instead of general matrix
  // products with packing (the fit ran every 500 samples and was ~8 % of a swarm's per-sample time).
  return forModelSize(model, [&](auto size) {
    return fitModel<decltype(size)::value>(stats, model, start, fixed_in, variance_inflation);
  });
}

namespace {
template <int N>
BlockFit fitModel(const WindowSums& stats, const LinearBlockModel& model, const Eigen::VectorXd& start,
                  const std::vector<bool>& fixed_in, double variance_inflation) {
  static_assert(N <= kMaxParameters, "the covariance step works on at most kMaxParameters entries");
  using Vec = Eigen::Matrix<double, N, 1>;
  using Mat = Eigen::Matrix<double, N, N>;
  const int n = N;
  BlockFit out;
  out.beta = start;
  out.determined.assign(static_cast<std::size_t>(n), false);
  out.standard_deviation = Eigen::VectorXd::Constant(n, std::numeric_limits<double>::infinity());
  out.correlation = Eigen::MatrixXd::Identity(n, n);
  if (!stats.hasBlocks() || start.size() != n || !(start(model.d_inductance) > 0) || !(start(model.q_inductance) > 0))
    return out;
  std::vector<bool> fixed = fixed_in;
  fixed.resize(static_cast<std::size_t>(n), false);
  const ProductD& Sd = stats.mean_d;
  const ProductQ& Sq = stats.mean_q;

  const Eigen::Matrix<double, kBlockSizeD, N> G_d = model.G_d;
  const Eigen::Matrix<double, kBlockSizeQ, N> G_q = model.G_q;
  Vec beta = start;
  Eigen::Matrix<double, kBlockSizeD, 1> vd;
  Eigen::Matrix<double, kBlockSizeQ, 1> vq;
  Eigen::Matrix<double, kBlockSizeD, N> Jd;
  Eigen::Matrix<double, kBlockSizeQ, N> Jq;
  // The fitness at b (v at b); the Jacobians at beta, once per iteration and at the end.
  const auto objective = [&](const Vec& b) {
    if (!(b(model.d_inductance) > 0) || !(b(model.q_inductance) > 0)) return std::numeric_limits<double>::infinity();
    weights<kBlockSizeD, N>(G_d, kIntegralUd, b, model.d_inductance, vd);
    weights<kBlockSizeQ, N>(G_q, kIntegralUq, b, model.q_inductance, vq);
    return quadraticForm(vd, Sd) + quadraticForm(vq, Sq);
  };
  const auto jacobians = [&] {
    weights<kBlockSizeD, N>(G_d, kIntegralUd, beta, model.d_inductance, vd, Jd);
    weights<kBlockSizeQ, N>(G_q, kIntegralUq, beta, model.q_inductance, vq, Jq);
  };
  // Gauss-Newton on the exact residuals r = v(beta) . z, with the normal matrix equilibrated and
  // pseudo-inverted: eigen-directions the data do not determine get no update.
  Mat A;
  Vec g;
  Vec scale;
  double f = objective(beta);
  for (int iteration = 0; iteration < 30; ++iteration) {
    jacobians();
    A = normalMatrix(Jd, Sd) + normalMatrix(Jq, Sq);
    g = gradient(Jd, Sd, vd) + gradient(Jq, Sq, vq);
    double amax = 0.0;
    for (int j = 0; j < n; ++j) amax = std::max(amax, fixed[j] ? 0.0 : A(j, j));
    if (!(amax > 0) || !std::isfinite(amax)) break;
    for (int j = 0; j < n; ++j) scale(j) = fixed[j] || !(A(j, j) > 1e-30 * amax) ? 0.0 : 1.0 / std::sqrt(A(j, j));
    Mat As = scale.asDiagonal() * A * scale.asDiagonal();
    const Vec gs = scale.asDiagonal() * g;
    Vec step;
    // Well conditioned (the usual case), the pseudo-inverse is the inverse: an LDLT solve gives the
    // step at a fraction of an eigen-decomposition's cost (the fit every 500 samples takes about six
    // steps; the decompositions were 2.4 % of an FBDAPSO update). An entry left out (scale 0: its
    // row, column and gradient are zero) gets a unit diagonal, which leaves its step at zero. The
    // condition number in the 1-norm, from the inverse itself (N <= 7: a few solves), bounds the
    // 2-norm's, lambda_max / lambda_min, from above for a symmetric matrix: below 1e6, every
    // eigenvalue lies four decades above the other path's 1e-10 cut.
    for (int j = 0; j < n; ++j)
      if (scale(j) == 0.0) As(j, j) = 1.0;
    const Eigen::LDLT<Mat> ldlt(As);
    bool direct = ldlt.info() == Eigen::Success && ldlt.isPositive();
    if (direct) {
      const Mat inverse = ldlt.solve(Mat::Identity());
      const double condition = As.cwiseAbs().colwise().sum().maxCoeff() * inverse.cwiseAbs().colwise().sum().maxCoeff();
      direct = condition < 1e6;  // false for NaN too
    }
    if (direct) {
      step = -(scale.asDiagonal() * ldlt.solve(gs));
    } else {
      for (int j = 0; j < n; ++j)
        if (scale(j) == 0.0) As(j, j) = 0.0;
      Eigen::SelfAdjointEigenSolver<Mat> eig(As);
      const Vec ev = eig.eigenvalues();
      const double evmax = ev.maxCoeff();
      Vec coeffs = eig.eigenvectors().transpose().lazyProduct(gs);
      for (int j = 0; j < n; ++j) coeffs(j) = ev(j) > 1e-10 * evmax ? coeffs(j) / ev(j) : 0.0;
      step = -(scale.asDiagonal() * eig.eigenvectors().lazyProduct(coeffs));
    }
    // Backtracking keeps the inductances positive and the fitness falling.
    double t = 1.0;
    Vec trial = beta + step;
    double ft = objective(trial);
    while (!(ft <= f) && t > 1e-6) {
      t *= 0.5;
      trial = beta + t * step;
      ft = objective(trial);
    }
    if (!(ft <= f)) break;
    const double improvement = f - ft;
    beta = trial;
    f = ft;
    double relative_step = 0.0;
    for (int j = 0; j < n; ++j) relative_step = std::max(relative_step, std::abs(t * step(j)) / std::max(std::abs(beta(j)), 1e-300));
    if (improvement <= 1e-14 * f || relative_step < 1e-10) break;
  }
  jacobians();  // v and J at the optimum
  out.beta = beta;
  out.ok = std::isfinite(f);
  residualMeanSquares(stats, vd, vq, out.mean_square_d, out.mean_square_q, out.noise_variance_d,
                      out.noise_variance_q);
  // White noise n on the currents: r_k carries n_k - n_(k-M), and r_k - r_(k-1) carries four
  // noise terms, so the residual variance that noise explains is half the difference variance.
  out.noise_variance_d *= 0.5;
  out.noise_variance_q *= 0.5;
  // That holds for the noise at a block's two ends (Di). The current noise inside the block also
  // enters through the integrals of the currents, T v_j n per sample, M - 1/2 samples' worth, and
  // blocks one sample apart share all but one of those: their differences do not show it. With
  // a = T R / L per sample, r carries sigma^2 (2 + (M - 1/2) a^2) while half the difference
  // variance is ~2 sigma^2. On the robot joint (0.08 ohm, 35 uH, 20 kHz, M = 100) that is a factor
  // 1.65 in d: a right model read 1.4-1.6 times the noise. Added here with the speed terms' share
  // (omega at its RMS over the window).
  out.current_noise_variance_d = 0.5 * out.noise_variance_d;  // Di carries two samples' noise
  out.current_noise_variance_q = 0.5 * out.noise_variance_q;
  if (stats.has_differences && stats.block_samples > 1 && stats.block_duration > 0) {
    const double M = stats.block_samples, T = stats.block_duration / M;
    const double omega2 = std::max(0.0, stats.mean_q(kIntegralOmega, kIntegralOmega)) /
                          (stats.block_duration * stats.block_duration);
    const double inside_d = vd(kIntegralId) * vd(kIntegralId) +
                            omega2 * (vd(kIntegralOmegaIq) * vd(kIntegralOmegaIq) +
                                      vd(kIntegralOmegaIdInD) * vd(kIntegralOmegaIdInD));
    const double inside_q = vq(kIntegralIq) * vq(kIntegralIq) +
                            omega2 * (vq(kIntegralOmegaId) * vq(kIntegralOmegaId) +
                                      vq(kIntegralOmegaIqInQ) * vq(kIntegralOmegaIqInQ));
    out.noise_variance_d *= 1.0 + 0.5 * (M - 0.5) * T * T * inside_d;
    out.noise_variance_q *= 1.0 + 0.5 * (M - 0.5) * T * T * inside_q;
  }
  if (!stats.has_differences)
    out.noise_variance_d = out.noise_variance_q = out.current_noise_variance_d = out.current_noise_variance_q = 0.0;
  if (stats.noise_variance_d >= 0) out.noise_variance_d = stats.noise_variance_d;
  if (stats.noise_variance_q >= 0) out.noise_variance_q = stats.noise_variance_q;

  // Information of the window: effective block count x J^T S J / sigma^2 per axis.
  // sigma^2 is at least the residual the fit leaves (a misfit the fit check still accepts, up to
  // max_fit_ratio times the noise, widens the uncertainty instead of biasing a stated +-0.9 %), and
  // at least the fit floor of noise-free data (WindowSums::min_noise_variance).
  const double floor_d = std::max({out.noise_variance_d, out.mean_square_d, stats.min_noise_variance, 1e-30});
  const double floor_q = std::max({out.noise_variance_q, out.mean_square_q, stats.min_noise_variance, 1e-30});
  A = stats.weight * (normalMatrix(Jd, Sd) / floor_d + normalMatrix(Jq, Sq) / floor_q);
  // Covariance over the free entries. A direction with (almost) no information makes the entry
  // that dominates it undetermined; that entry is set aside and the rest are evaluated without it
  // (e.g. L_d without d-axis excitation leaves R_s, L_q, psi_f determined by the q axis).
  std::vector<int> free;
  for (int j = 0; j < n; ++j)
    if (!fixed[j]) free.push_back(j);
  while (!free.empty()) {
    const int m = static_cast<int>(free.size());
    MatN Af(m, m);
    VecN s(m);
    for (int a = 0; a < m; ++a) s(a) = std::max(std::abs(beta(free[a])), 1e-300);
    for (int a = 0; a < m; ++a)
      for (int b = 0; b < m; ++b) Af(a, b) = A(free[a], free[b]) * s(a) * s(b);
    if (!Af.allFinite()) break;
    Eigen::SelfAdjointEigenSolver<MatN> eig(Af);
    const VecN ev = eig.eigenvalues();  // ascending
    const double evmax = ev(m - 1);
    if (!(evmax > 0)) break;
    if (!(ev(0) > 1e-14 * evmax)) {
      int worst = 0;
      eig.eigenvectors().col(0).cwiseAbs().maxCoeff(&worst);
      free.erase(free.begin() + worst);
      continue;
    }
    const MatN cov = eig.eigenvectors() * ev.cwiseInverse().asDiagonal() * eig.eigenvectors().transpose();
    for (int a = 0; a < m; ++a) {
      out.standard_deviation(free[a]) = std::sqrt(variance_inflation * std::max(0.0, cov(a, a))) * s(a);
      out.determined[free[a]] = true;
    }
    for (int a = 0; a < m; ++a)
      for (int b = 0; b < m; ++b)
        if (a != b && cov(a, a) > 0 && cov(b, b) > 0) out.correlation(free[a], free[b]) = cov(a, b) / std::sqrt(cov(a, a) * cov(b, b));
    break;
  }
  return out;
}
}  // namespace

}  // namespace pmsm_param_id
