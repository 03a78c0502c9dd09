#include "pmsm_param_id/identification/steady_state.hpp"

#include "pmsm_param_id/identification/slow_estimate.hpp"
#include "pmsm_param_id/io/config_error.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

namespace pmsm_param_id {

namespace {
constexpr int kV = 4, kTiming = 5, kColumns = 6;  // after R_s, L_d, L_q, psi_f
using Vector = Eigen::Matrix<double, kColumns, 1>;
using Matrix = Eigen::Matrix<double, kColumns, kColumns>;

// The zero-crossing widths tried: the currents' RMS down by quarter octaves to 1/256 of it (below
// that the fundamental is a sharp sign's to within the noise of any log seen).
constexpr int kWidthSteps = 32;

struct Row {
  Vector d = Vector::Zero(), q = Vector::Zero();
  double u_d = 0.0, u_q = 0.0;
};

struct LinearFit {
  bool ok = false;
  Vector beta = Vector::Zero();
  Matrix covariance = Matrix::Zero();
  std::array<bool, kColumns> determined{};
  double mean_square_d = 0.0, mean_square_q = 0.0;  // [V^2]
  double noise_d = 0.0, noise_q = 0.0;              // from consecutive residual differences [V^2]
};

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const auto at = v.begin() + static_cast<std::ptrdiff_t>(std::min(v.size() - 1, static_cast<std::size_t>(q * v.size())));
  std::nth_element(v.begin(), at, v.end());
  return *at;
}

Row rowOf(const Sample& s, double width) {
  Row r;
  const double magnitude = std::hypot(s.i_d, s.i_q);
  const double shape = magnitude > 0 ? inverterFundamental(magnitude, width) / magnitude : 0.0;
  r.d << s.i_d, 0.0, -s.omega_e * s.i_q, 0.0, shape * s.i_d, s.omega_e * s.u_q;
  r.q << s.i_q, s.omega_e * s.i_d, 0.0, s.omega_e, shape * s.i_q, -s.omega_e * s.u_d;
  r.u_d = s.u_d;
  r.u_q = s.u_q;
  return r;
}

// The covariance of a weighted least-squares fit from its information matrix A (fixed or dynamic
// size): equilibrated by the diagonal, a column without information (all zero, or not free) left
// out; directions below 1e-12 of the largest eigenvalue are numerically null, and a parameter that
// loads on one is not determined at all (its standard deviation infinite), the others from the
// rest. False where the eigen-solver fails or A holds nothing.
template <class M>
bool informationInverse(const M& A, const std::vector<bool>& free, M& covariance, std::vector<bool>& determined) {
  using V = Eigen::Matrix<double, M::RowsAtCompileTime, 1>;
  const Eigen::Index n = A.rows();
  V scale = V::Zero(n);
  for (Eigen::Index j = 0; j < n; ++j)
    if (free[static_cast<std::size_t>(j)] && A(j, j) > 0 && std::isfinite(A(j, j))) scale(j) = 1.0 / std::sqrt(A(j, j));
  const M scaled = scale.asDiagonal() * A * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<M> eig(scaled);
  if (eig.info() != Eigen::Success) return false;
  const V values = eig.eigenvalues();
  const double largest = values.maxCoeff();
  if (!(largest > 0)) return false;
  V inverse = V::Zero(n);
  determined.assign(static_cast<std::size_t>(n), false);
  for (Eigen::Index j = 0; j < n; ++j) determined[static_cast<std::size_t>(j)] = scale(j) > 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (values(i) > 1e-12 * largest) {
      inverse(i) = 1.0 / values(i);
      continue;
    }
    for (Eigen::Index j = 0; j < n; ++j)
      if (scale(j) > 0 && std::abs(eig.eigenvectors()(j, i)) > 1e-3) determined[static_cast<std::size_t>(j)] = false;
  }
  const M pinv = eig.eigenvectors() * inverse.asDiagonal() * eig.eigenvectors().transpose();
  covariance = scale.asDiagonal() * pinv * scale.asDiagonal();
  return true;
}

// Weighted least squares over the rows with `free` columns (the others zero); `pairs`: consecutive
// rows of one stretch, for the noise from residual differences.
LinearFit solve(const std::vector<Row>& rows, const std::vector<std::size_t>& pairs, const std::array<bool, kColumns>& free,
                double weight_d, double weight_q) {
  LinearFit out;
  Matrix A = Matrix::Zero();
  Vector b = Vector::Zero();
  for (const Row& r : rows) {
    A.noalias() += weight_d * r.d * r.d.transpose() + weight_q * r.q * r.q.transpose();
    b.noalias() += weight_d * r.d * r.u_d + weight_q * r.q * r.u_q;
  }
  std::vector<bool> determined;
  if (!informationInverse(A, std::vector<bool>(free.begin(), free.end()), out.covariance, determined)) return out;
  out.beta = out.covariance * b;
  for (int j = 0; j < kColumns; ++j) out.determined[static_cast<std::size_t>(j)] = determined[static_cast<std::size_t>(j)];
  std::vector<double> r_d(rows.size()), r_q(rows.size());
  for (std::size_t k = 0; k < rows.size(); ++k) {
    r_d[k] = rows[k].u_d - rows[k].d.dot(out.beta);
    r_q[k] = rows[k].u_q - rows[k].q.dot(out.beta);
    out.mean_square_d += r_d[k] * r_d[k];
    out.mean_square_q += r_q[k] * r_q[k];
  }
  out.mean_square_d /= static_cast<double>(rows.size());
  out.mean_square_q /= static_cast<double>(rows.size());
  for (std::size_t k : pairs) {
    out.noise_d += (r_d[k] - r_d[k - 1]) * (r_d[k] - r_d[k - 1]);
    out.noise_q += (r_q[k] - r_q[k - 1]) * (r_q[k] - r_q[k - 1]);
  }
  // White noise: a difference carries twice the variance.
  out.noise_d = pairs.empty() ? out.mean_square_d : 0.5 * out.noise_d / static_cast<double>(pairs.size());
  out.noise_q = pairs.empty() ? out.mean_square_q : 0.5 * out.noise_q / static_cast<double>(pairs.size());
  out.ok = out.beta.allFinite();
  return out;
}

// A fitted entry's standard deviation (infinite where the data do not determine it).
double stdOf(const LinearFit& f, int j) {
  return f.determined[static_cast<std::size_t>(j)] ? std::sqrt(std::max(0.0, f.covariance(j, j)))
                                                   : std::numeric_limits<double>::infinity();
}

// Two passes: unweighted (volts alike on both axes), then each axis weighted by the larger of its
// residual and its noise (a misfit widens the standard deviations instead of hiding behind them).
LinearFit weightedFit(const std::vector<Row>& rows, const std::vector<std::size_t>& pairs, const std::array<bool, kColumns>& free,
                      double floor2) {
  LinearFit f = solve(rows, pairs, free, 1.0, 1.0);
  if (!f.ok) return f;
  const double var_d = std::max({f.mean_square_d, f.noise_d, floor2}), var_q = std::max({f.mean_square_q, f.noise_q, floor2});
  if (!(var_d > 0 && var_q > 0)) return f;
  return solve(rows, pairs, free, 1.0 / var_d, 1.0 / var_q);
}

// |p(V + dV) - p(V)| per parameter with V held (the inverter model's spread dV moved through the
// fit, everything else refitted) [SI].
Vector shiftWithInverterHeld(const std::vector<Row>& rows, const std::vector<std::size_t>& pairs, std::array<bool, kColumns> free,
                             double V, double dV, double floor2) {
  free[kV] = false;
  const auto fitAt = [&](double v) {
    std::vector<Row> held = rows;
    for (Row& r : held) {
      r.u_d -= v * r.d(kV);
      r.u_q -= v * r.q(kV);
    }
    return weightedFit(held, pairs, free, floor2);
  };
  const LinearFit base = fitAt(V), moved = fitAt(V + dV);
  if (!base.ok || !moved.ok) return Vector::Constant(std::numeric_limits<double>::infinity());
  return (moved.beta - base.beta).cwiseAbs();
}

// The standard deviations with the columns in `held` fixed: the inverse of the free part of the
// information matrix (what the data would give if those were known).
Vector stdWithHeld(const std::vector<Row>& rows, const std::vector<std::size_t>& pairs, std::array<bool, kColumns> free,
                   int held, double floor2) {
  free[static_cast<std::size_t>(held)] = false;
  const LinearFit f = weightedFit(rows, pairs, free, floor2);
  Vector sd = Vector::Constant(std::numeric_limits<double>::infinity());
  if (!f.ok) return sd;
  for (int j = 0; j < kColumns; ++j)
    if (free[static_cast<std::size_t>(j)]) sd(j) = stdOf(f, j);
  return sd;
}

// Where a fit determines the drive's constants (otherwise they are held at zero for the values
// reported): V positive to 50 %, the timing k to 0.1 rad of turn at the RMS speed.
bool inverterDetermined(double V, double V_std) { return V > 0 && V_std < 0.5 * V; }
bool timingDetermined(double k_std, double omega_ms) { return k_std * std::sqrt(omega_ms) < 0.1; }

// ---- The thermal trajectory (doc/algorithm.md section 13) ----------------------------------------
// Between load and speed changes R_s and psi_f enter the averaged q equation only as
// R_s i_q + omega_e psi_f, and heating moves both; at a change the two operating points split them.
// So psi_f (the magnet: heated through the winding and by its own losses, it changes slower) is
// taken as piecewise linear between the changes, constant after the last (before the first: see
// thermalTrajectory), and R_s (the winding) as piecewise linear on a uniform grid whose spacing the
// data choose (BIC) and at each change; the inductances and the drive's constants are the log's.
// What psi_f's real drift between and beyond its knots could move is added to the stated
// uncertainty (the largest rate its knots show, over the distance to the nearest knot).

// A stretch needs this many steady samples on each side of a change for the change to pin psi_f.
constexpr std::size_t kThermalStretch = 10;

struct Sparse {  // one row of the trajectory's design: at most 2 + 2 + 4 entries
  std::array<int, 8> index{};
  std::array<double, 8> value{};
  int size = 0;
  void add(int j, double v) {
    if (v == 0.0) return;
    index[static_cast<std::size_t>(size)] = j;
    value[static_cast<std::size_t>(size)] = v;
    ++size;
  }
  double dot(const Eigen::VectorXd& b) const {
    double s = 0.0;
    for (int k = 0; k < size; ++k) s += value[static_cast<std::size_t>(k)] * b(index[static_cast<std::size_t>(k)]);
    return s;
  }
  void accumulate(double y, double w, Eigen::MatrixXd& A, Eigen::VectorXd& b) const {
    for (int i = 0; i < size; ++i) {
      const int r = index[static_cast<std::size_t>(i)];
      const double wv = w * value[static_cast<std::size_t>(i)];
      b(r) += wv * y;
      for (int j = 0; j < size; ++j) A(r, index[static_cast<std::size_t>(j)]) += wv * value[static_cast<std::size_t>(j)];
    }
  }
};

// Hat functions on knots (constant beyond the ends; before the first, with `extend_back`, the first
// interval's line extended): the two knots and weights at t.
struct Hat {
  int j0 = 0, j1 = 0;
  double w0 = 1.0, w1 = 0.0;
};
Hat hatAt(const std::vector<double>& knots, double t, bool extend_back = false) {
  Hat h;
  if (knots.size() < 2) return h;
  if (t <= knots.front()) {
    if (extend_back) {
      const double u = (t - knots[0]) / (knots[1] - knots[0]);
      h.j1 = 1;
      h.w0 = 1.0 - u;
      h.w1 = u;
    }
    return h;
  }
  if (t >= knots.back()) {
    h.j0 = h.j1 = static_cast<int>(knots.size()) - 1;
    return h;
  }
  const int j = static_cast<int>(std::upper_bound(knots.begin(), knots.end(), t) - knots.begin()) - 1;
  const std::size_t u = static_cast<std::size_t>(j);
  const double f = (t - knots[u]) / (knots[u + 1] - knots[u]);
  h.j0 = j;
  h.j1 = j + 1;
  h.w0 = 1.0 - f;
  h.w1 = f;
  return h;
}

struct TrajectoryFit {
  bool ok = false;
  Eigen::VectorXd beta;
  Eigen::MatrixXd covariance;
  std::vector<bool> determined;
  double mean_square_d = 0.0, mean_square_q = 0.0, chi2 = 0.0;
  int columns = 0;
};

// Columns: R_s knots [0, nR), psi_f knots [nR, nR + nP), then L_d, L_q, V, k (where free; V held
// at V_held otherwise).
TrajectoryFit fitTrajectory(const std::vector<Sample>& steady, const std::vector<double>& r_knots,
                            const std::vector<double>& p_knots, bool p_extend_back, double width,
                            const std::array<bool, kColumns>& free, double V_held, double weight_d, double weight_q) {
  const int nR = static_cast<int>(r_knots.size()), nP = static_cast<int>(std::max<std::size_t>(1, p_knots.size()));
  const int n = nR + nP + 4, cLd = nR + nP, cLq = cLd + 1, cV = cLd + 2, cK = cLd + 3;
  TrajectoryFit out;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(n);
  std::vector<Sparse> rd(steady.size()), rq(steady.size());
  std::vector<double> yd(steady.size()), yq(steady.size());
  for (std::size_t k = 0; k < steady.size(); ++k) {
    const Sample& s = steady[k];
    const Row r = rowOf(s, width);
    const Hat hr = hatAt(r_knots, s.t), hp = hatAt(p_knots, s.t, p_extend_back);
    Sparse& d = rd[k];
    Sparse& q = rq[k];
    d.add(hr.j0, hr.w0 * s.i_d);
    q.add(hr.j0, hr.w0 * s.i_q);
    if (hr.j1 != hr.j0) {
      d.add(hr.j1, hr.w1 * s.i_d);
      q.add(hr.j1, hr.w1 * s.i_q);
    }
    q.add(nR + hp.j0, hp.w0 * s.omega_e);
    if (hp.j1 != hp.j0) q.add(nR + hp.j1, hp.w1 * s.omega_e);
    if (free[kLd]) q.add(cLd, r.q(kLd));
    if (free[kLq]) d.add(cLq, r.d(kLq));
    if (free[kV]) {
      d.add(cV, r.d(kV));
      q.add(cV, r.q(kV));
    }
    if (free[kTiming]) {
      d.add(cK, r.d(kTiming));
      q.add(cK, r.q(kTiming));
    }
    yd[k] = r.u_d - (free[kV] ? 0.0 : V_held * r.d(kV));
    yq[k] = r.u_q - (free[kV] ? 0.0 : V_held * r.q(kV));
    d.accumulate(yd[k], weight_d, A, b);
    q.accumulate(yq[k], weight_q, A, b);
  }
  if (!informationInverse(A, std::vector<bool>(static_cast<std::size_t>(n), true), out.covariance, out.determined)) return out;
  out.beta = out.covariance * b;
  if (!out.beta.allFinite()) return out;
  for (std::size_t k = 0; k < steady.size(); ++k) {
    const double ed = yd[k] - rd[k].dot(out.beta), eq = yq[k] - rq[k].dot(out.beta);
    out.mean_square_d += ed * ed;
    out.mean_square_q += eq * eq;
  }
  out.chi2 = weight_d * out.mean_square_d + weight_q * out.mean_square_q;
  out.mean_square_d /= static_cast<double>(steady.size());
  out.mean_square_q /= static_cast<double>(steady.size());
  for (int j = 0; j < n; ++j) out.columns += A(j, j) > 0 && std::isfinite(A(j, j));
  out.ok = true;
  return out;
}

// A knot trajectory's value at t, its gradient over the columns added to `gradient`.
double trajectoryAt(const std::vector<double>& knots, int offset, const Eigen::VectorXd& beta, double t,
                    Eigen::VectorXd& gradient, bool extend_back = false) {
  const Hat h = hatAt(knots, t, extend_back);
  gradient(offset + h.j0) += h.w0;
  if (h.j1 != h.j0) gradient(offset + h.j1) += h.w1;
  return h.w0 * beta(offset + h.j0) + (h.j1 != h.j0 ? h.w1 * beta(offset + h.j1) : 0.0);
}

// The load and speed changes of a log: the steps between neighbours (step[k]: from k - 1 to k),
// those within kThermalStretch samples of each other one change, at its middle [s].
std::vector<double> changeTimes(const std::vector<Sample>& samples, const std::vector<bool>& step) {
  std::vector<double> changes;
  std::size_t cluster_end = 0;
  double cluster_start_t = 0.0, cluster_end_t = 0.0;
  bool open = false;
  for (std::size_t k = 1; k < samples.size(); ++k) {
    if (!step[k]) continue;
    const double t = 0.5 * (samples[k - 1].t + samples[k].t);
    if (open && k <= cluster_end + kThermalStretch) {
      cluster_end = k;
      cluster_end_t = t;
      continue;
    }
    if (open) changes.push_back(0.5 * (cluster_start_t + cluster_end_t));
    open = true;
    cluster_end = k;
    cluster_start_t = cluster_end_t = t;
  }
  if (open) changes.push_back(0.5 * (cluster_start_t + cluster_end_t));
  return changes;
}

// The index of the first of the (time-ordered) samples at or after t.
std::size_t firstAtOrAfter(const std::vector<Sample>& samples, double t) {
  return static_cast<std::size_t>(
      std::lower_bound(samples.begin(), samples.end(), t, [](const Sample& s, double x) { return s.t < x; }) -
      samples.begin());
}

// R_s's knots: a uniform grid of `intervals` over the steady samples' span, and a knot at each of
// psi_f's (the load and speed changes), where the winding's heating rate steps with its copper loss
// (at a load change the loss steps with i^2; a grid knot cannot bend there, and the fit then moves
// psi_f's knot instead: on healthy_long_run at 2 Hz, noise-free, the winding read 2.3 K low at
// 320 s, 1.4 K with these knots). A grid knot with fewer than kThermalStretch steady samples
// between it and a change is left out: with no data between the two, R_s could jump there and the
// change would no longer split R_s from psi_f. The grid's ends stay.
std::vector<double> resistanceKnots(const std::vector<Sample>& steady, double spacing, int intervals,
                                    const std::vector<double>& changes) {
  const double t0 = steady.front().t;
  const auto index = [&](double t) { return static_cast<std::ptrdiff_t>(firstAtOrAfter(steady, t)); };
  std::vector<double> knots(changes);
  for (int i = 0; i <= intervals; ++i) {
    const double k = i == intervals ? steady.back().t : t0 + spacing * i;
    bool apart = i == 0 || i == intervals;
    if (!apart) {
      apart = true;
      for (double c : changes)
        if (std::abs(index(k) - index(c)) < static_cast<std::ptrdiff_t>(kThermalStretch)) apart = false;
    }
    if (apart) knots.push_back(k);
  }
  std::sort(knots.begin(), knots.end());
  knots.erase(std::unique(knots.begin(), knots.end()), knots.end());
  return knots;
}

// The thermal trajectory's parameters at the last steady sample (R_s and psi_f there, the
// inductances and drive constants of the log), as the constant fit's FitCheck would state them.
struct TrajectoryEstimate {
  bool consistent = false;
  ParameterVector value{}, relative_std{}, model_floor{};
  std::array<bool, kParameterCount> determined{};
  double fit_ratio_d = 0.0, fit_ratio_q = 0.0;
  double V = std::numeric_limits<double>::quiet_NaN(), V_relative_std = std::numeric_limits<double>::infinity();
  double timing = std::numeric_limits<double>::quiet_NaN(), timing_std = std::numeric_limits<double>::infinity();
};

// The thermal trajectory: its parameters at the last steady sample into `now`; with a thermal:
// block the temperatures there into out.estimate and the references it determines at the first
// sample into out.thermal_references.
void thermalTrajectory(const std::vector<Sample>& steady, const std::vector<double>& change_times, double width,
                       std::array<bool, kColumns> free, double var_d, double var_q, double floor2, double omega_ms,
                       const IdentifierConfig& config, const LearntReferences* given, SteadyStateFit& out,
                       TrajectoryEstimate& now) {
  const ThermalSettings& th = config.thermal;
  const AssessmentSettings& a = config.assessment;
  Estimate& e = out.estimate;
  const double t0 = steady.front().t, span = steady.back().t - t0;
  // psi_f's knots: the changes with kThermalStretch steady samples on each side (and between two).
  std::vector<double> p_knots;
  std::size_t last = 0;
  for (double c : change_times) {
    const std::size_t before = firstAtOrAfter(steady, c);
    if (before < last + kThermalStretch || before + kThermalStretch > steady.size()) continue;
    p_knots.push_back(c);
    last = before;
  }
  out.thermal_changes = p_knots.size();
  if (p_knots.size() < 2) {
    out.thermal_note = p_knots.empty()
                           ? "no load or speed change in the log: R_s and psi_f enter it only as R_s i_q + omega_e psi_f, and "
                             "heating moves both; load or speed changes split them"
                           : "one load or speed change: how psi_f drifts is not known; a second change shows it";
    return;
  }
  // psi_f before the first change. From a cold start (the log's first sample is the motor at rest
  // at the reference temperature, nothing declared or kept in its place) the magnet is warming from
  // the start: the first interval's line is extended back to it. Held constant instead, psi_f
  // there reads the first change's value, and R_s at the first sample high by omega_e / i_q times
  // the drift (noise-free at 2 Hz, the worst winding error over the log cut every 20 s: 3.0 K
  // against 2.1 K on healthy_long_run, 7.6 K against 2.9 K on thermal_duty_cycle, whose first
  // interval is at a lighter load). Any other start may be warming or cooling: constant. Either
  // way the stated uncertainty holds psi_f's largest rate over the distance.
  const bool p_extend_back =
      th.enabled && given == nullptr && !(th.R_s_at_reference > 0) && !(th.psi_f_at_reference > 0);
  // R_s's grid: span / 2^j with at least kThermalStretch steady samples per interval on average;
  // the spacing of least BIC (chi^2 at the log's noise + columns x ln(rows)).
  const double rows = 2.0 * static_cast<double>(steady.size());
  TrajectoryFit best;
  std::vector<double> r_knots;
  double best_bic = std::numeric_limits<double>::infinity();
  for (int j = 0; j <= 8; ++j) {
    if (j > 0 && static_cast<double>(steady.size()) / std::exp2(j) < static_cast<double>(kThermalStretch)) break;
    const double spacing = span / std::exp2(j);
    const std::vector<double> knots = resistanceKnots(steady, spacing, 1 << j, p_knots);
    const TrajectoryFit f = fitTrajectory(steady, knots, p_knots, p_extend_back, width, free, 0.0, 1.0 / var_d, 1.0 / var_q);
    if (!f.ok) continue;
    const double bic = f.chi2 + f.columns * std::log(rows);
    if (bic < best_bic) {
      best_bic = bic;
      best = f;
      r_knots = knots;
      out.thermal_knot_spacing = spacing;
    }
  }
  if (!best.ok) {
    out.thermal_note = "the thermal trajectory's fit failed";
    return;
  }
  // Weighted by the larger of each axis's residual and noise, as the constant fit; the drive's
  // constants held at zero where this fit does not determine them, by the constant fit's rules (V
  // positive to 50 %, the timing to 0.1 rad of turn at the RMS speed).
  const double wd = std::max({best.mean_square_d, var_d, floor2}), wq = std::max({best.mean_square_q, var_q, floor2});
  TrajectoryFit f = fitTrajectory(steady, r_knots, p_knots, p_extend_back, width, free, 0.0, 1.0 / wd, 1.0 / wq);
  {
    const int cV = static_cast<int>(r_knots.size() + p_knots.size()) + 2, cK = cV + 1;
    const auto sd = [&](int j) {
      return f.ok && f.determined[static_cast<std::size_t>(j)] ? std::sqrt(std::max(0.0, f.covariance(j, j)))
                                                               : std::numeric_limits<double>::infinity();
    };
    std::array<bool, kColumns> held = free;
    if (free[kV] && !(f.ok && inverterDetermined(f.beta(cV), sd(cV)))) held[kV] = false;
    if (free[kTiming] && !timingDetermined(sd(cK), omega_ms)) held[kTiming] = false;
    if (held != free) {
      free = held;
      f = fitTrajectory(steady, r_knots, p_knots, p_extend_back, width, free, 0.0, 1.0 / wd, 1.0 / wq);
    }
  }
  if (!f.ok) {
    out.thermal_note = "the thermal trajectory's fit failed";
    return;
  }
  if (!(f.mean_square_d <= a.max_fit_ratio * var_d + floor2 && f.mean_square_q <= a.max_fit_ratio * var_q + floor2)) {
    out.thermal_note = "the thermal trajectory does not fit the log (a fault, a saturating machine, a change of the "
                       "drive): no temperature";
    return;
  }
  const int nR = static_cast<int>(r_knots.size()), n = static_cast<int>(f.beta.size());
  // psi_f's largest drift rate between its knots, each to its upper bound (the change plus
  // confidence_sigmas of its standard deviation: two knots alone gave a rate too low in 6 % of the
  // estimates on healthy_long_run), and what it may have drifted at t.
  double rate = 0.0;
  for (std::size_t i = 1; i < p_knots.size(); ++i) {
    const int j = nR + static_cast<int>(i), k = j - 1;
    const double change = std::abs(f.beta(j) - f.beta(k));
    const double sd = std::sqrt(std::max(0.0, f.covariance(j, j) + f.covariance(k, k) - 2.0 * f.covariance(j, k)));
    rate = std::max(rate, (change + a.confidence_sigmas * sd) / (p_knots[i] - p_knots[i - 1]));
  }
  const auto psiDrift = [&](double t) {
    double d = std::numeric_limits<double>::infinity();
    for (double k : p_knots) d = std::min(d, std::abs(t - k));
    return rate * d;
  };
  // The inverter model's own error (kInverterModelFloor of V, as the constant fit states it): what
  // it moves the trajectory by.
  Eigen::VectorXd inverter_shift = Eigen::VectorXd::Zero(n);
  const int cV = nR + static_cast<int>(p_knots.size()) + 2;
  if (free[kV] && f.determined[static_cast<std::size_t>(cV)] && f.beta(cV) > 0) {
    std::array<bool, kColumns> held = free;
    held[kV] = false;
    const double V = f.beta(cV);
    const TrajectoryFit at = fitTrajectory(steady, r_knots, p_knots, p_extend_back, width, held, V, 1.0 / wd, 1.0 / wq);
    const TrajectoryFit moved =
        fitTrajectory(steady, r_knots, p_knots, p_extend_back, width, held, V * (1.0 + kInverterModelFloor), 1.0 / wd, 1.0 / wq);
    if (at.ok && moved.ok) inverter_shift = moved.beta - at.beta;
    else inverter_shift.setConstant(std::numeric_limits<double>::infinity());
  }
  const Sample& first = steady.front();
  const Sample& now_sample = steady.back();
  {  // the parameters at the last sample, their statistical spread and what psi_f's drift and V's floor add
    const int cLd = nR + static_cast<int>(p_knots.size()), cLq = cLd + 1, cK = cLd + 3;
    const auto spread = [&](const Eigen::VectorXd& g) { return std::sqrt(std::max(0.0, g.dot(f.covariance * g))); };
    const auto settled = [&](const Eigen::VectorXd& g) {
      for (int j = 0; j < n; ++j)
        if (g(j) != 0 && !f.determined[static_cast<std::size_t>(j)]) return false;
      return true;
    };
    Eigen::VectorXd gR = Eigen::VectorXd::Zero(n), gP = Eigen::VectorXd::Zero(n);
    now.value[kRs] = trajectoryAt(r_knots, 0, f.beta, now_sample.t, gR);
    now.value[kPsiF] = trajectoryAt(p_knots, nR, f.beta, now_sample.t, gP, p_extend_back);
    now.value[kLd] = free[kLd] ? f.beta(cLd) : std::numeric_limits<double>::quiet_NaN();
    now.value[kLq] = free[kLq] ? f.beta(cLq) : std::numeric_limits<double>::quiet_NaN();
    const double drift = psiDrift(now_sample.t);
    const double moved_R = drift * std::abs(now_sample.omega_e / now_sample.i_q);
    now.determined[kRs] = settled(gR) && std::isfinite(moved_R);
    now.determined[kPsiF] = settled(gP) && std::isfinite(drift);
    now.determined[kLd] = free[kLd] && f.determined[static_cast<std::size_t>(cLd)];
    now.determined[kLq] = free[kLq] && f.determined[static_cast<std::size_t>(cLq)];
    const double spread_p[] = {spread(gR), std::sqrt(std::max(0.0, f.covariance(cLd, cLd))),
                               std::sqrt(std::max(0.0, f.covariance(cLq, cLq))), spread(gP)};
    const double shift_p[] = {std::abs(gR.dot(inverter_shift)), std::abs(inverter_shift(cLd)), std::abs(inverter_shift(cLq)),
                              std::abs(gP.dot(inverter_shift))};
    const double drift_p[] = {moved_R, 0.0, 0.0, drift};
    for (int p = 0; p < kParameterCount; ++p) {
      now.relative_std[p] = now.determined[p] ? spread_p[p] / std::abs(now.value[p]) : std::numeric_limits<double>::infinity();
      now.model_floor[p] = (drift_p[p] + shift_p[p]) / std::abs(now.value[p]);
    }
    now.fit_ratio_d = f.mean_square_d / var_d;
    now.fit_ratio_q = f.mean_square_q / var_q;
    now.consistent = true;
    if (free[kV] && f.determined[static_cast<std::size_t>(cV)]) {
      now.V = f.beta(cV);
      now.V_relative_std = std::sqrt(std::max(0.0, f.covariance(cV, cV))) / std::abs(now.V);
    }
    if (free[kTiming] && f.determined[static_cast<std::size_t>(cK)]) {
      now.timing = f.beta(cK);
      now.timing_std = std::sqrt(std::max(0.0, f.covariance(cK, cK)));
    }
  }
  if (!th.enabled) return;
  LearntReferences& learnt = out.thermal_references;
  learnt.reference_temperature = th.reference_temperature;
  const LearntReferences none;
  const LearntReferences& kept = given ? *given : none;
  // resistance: R_s (psi_f's drift enters it as omega_e / i_q times itself) or psi_f.
  const auto temperature = [&](const std::vector<double>& knots, int offset, bool extend_back, double coefficient,
                               double configured, double kept_value, double kept_u, bool resistance,
                               double& reference_out, double& reference_u_out, double& learnt_at) {
    Temperature result;
    Eigen::VectorXd g_now = Eigen::VectorXd::Zero(n), g_ref = Eigen::VectorXd::Zero(n);
    const double now = trajectoryAt(knots, offset, f.beta, now_sample.t, g_now, extend_back);
    const double at_start = trajectoryAt(knots, offset, f.beta, first.t, g_ref, extend_back);
    const auto determined = [&](const Eigen::VectorXd& g) {
      for (int j = 0; j < n; ++j)
        if (g(j) != 0 && !f.determined[static_cast<std::size_t>(j)]) return false;
      return true;
    };
    const double drift_now = psiDrift(now_sample.t) * (resistance ? std::abs(now_sample.omega_e / now_sample.i_q) : 1.0);
    const double drift_start = psiDrift(first.t) * (resistance ? std::abs(first.omega_e / first.i_q) : 1.0);
    if (determined(g_ref) && at_start > 0 && std::isfinite(drift_start)) {
      reference_out = at_start;
      reference_u_out = (a.confidence_sigmas * std::sqrt(std::max(0.0, g_ref.dot(f.covariance * g_ref))) + drift_start) / at_start;
      learnt_at = first.t;
    }
    if (!determined(g_now) || !(now > 0)) return result;
    double reference = 0.0, sigma2 = 0.0, bound = 0.0, shift = 0.0;
    if (given && configured == 0.0 && !(kept_value > 0)) return result;  // the cold start was let go unlearnt
    if (configured > 0 || kept_value > 0) {  // declared, or kept from earlier in the stream
      reference = configured > 0 ? configured : kept_value;
      sigma2 = g_now.dot(f.covariance * g_now) / (reference * reference);
      bound = drift_now / reference + (configured > 0 ? 0.0 : kept_u * now / reference);
      shift = std::abs(g_now.dot(inverter_shift)) / reference;
    } else {
      if (!determined(g_ref) || !(at_start > 0)) return result;
      reference = at_start;
      // d(now / start) = g_now / start - now g_ref / start^2, with the covariance of both.
      const Eigen::VectorXd g = g_now / at_start - (now / (at_start * at_start)) * g_ref;
      sigma2 = g.dot(f.covariance * g);
      bound = drift_now / at_start + drift_start * now / (at_start * at_start);
      shift = std::abs(g.dot(inverter_shift));
    }
    if (!std::isfinite(shift) || !std::isfinite(bound)) return result;
    result.value = th.reference_temperature + (now / reference - 1.0) / coefficient;
    result.uncertainty = (a.confidence_sigmas * std::sqrt(std::max(0.0, sigma2)) + bound + shift) / std::abs(coefficient);
    if (!(result.uncertainty <= th.max_uncertainty)) result = Temperature{};
    return result;
  };
  e.winding_temperature = temperature(r_knots, 0, false, th.copper_coefficient, th.R_s_at_reference, kept.R_s,
                                      kept.R_s_relative_uncertainty, true, learnt.R_s, learnt.R_s_relative_uncertainty,
                                      learnt.R_s_learnt_at);
  e.magnet_temperature = temperature(p_knots, nR, p_extend_back, th.magnet_coefficient, th.psi_f_at_reference, kept.psi_f,
                                     kept.psi_f_relative_uncertainty, false, learnt.psi_f,
                                     learnt.psi_f_relative_uncertainty, learnt.psi_f_learnt_at);
  if (!std::isfinite(e.winding_temperature.value) && !std::isfinite(e.magnet_temperature.value))
    out.thermal_note = "the data determine neither temperature to thermal.max_uncertainty";
}
}  // namespace

double medianSpacing(const std::vector<Sample>& samples) {
  std::vector<double> steps;
  for (std::size_t k = 1; k < samples.size(); ++k) {
    const double dt = samples[k].t - samples[k - 1].t;
    if (dt > 0 && std::isfinite(dt)) steps.push_back(dt);
  }
  return median(steps);
}

double inverterFundamental(double current, double width) {
  if (!(current > 0)) return 0.0;
  if (!(width > 0)) return 4.0 / M_PI;
  // (4/pi) int_0^{pi/2} tanh(I cos t / w) cos t dt by Simpson's rule on 64 intervals (the integrand
  // is smooth; 1e-7 relative at I = w, far below what moves a fit).
  constexpr int n = 64;
  const double h = 0.5 * M_PI / n;
  double sum = 0.0;
  for (int k = 0; k <= n; ++k) {
    const double t = k * h, c = std::cos(t);
    const double f = std::tanh(current * c / width) * c;
    sum += (k == 0 || k == n ? 1.0 : (k % 2 ? 4.0 : 2.0)) * f;
  }
  return 4.0 / M_PI * sum * h / 3.0;
}

SteadyStateFit fitSteadyState(const std::vector<Sample>& samples, const IdentifierConfig& config,
                              const LearntReferences* references) {
  const AssessmentSettings& a = config.assessment;
  SteadyStateFit out;
  Estimate& e = out.estimate;
  e.method = "steady_state";
  e.parameters.fill(std::numeric_limits<double>::quiet_NaN());
  e.relative_uncertainty.fill(std::numeric_limits<double>::infinity());
  e.inverter_voltage = std::numeric_limits<double>::quiet_NaN();
  std::vector<Sample> finite;
  finite.reserve(samples.size());
  for (const Sample& s : samples) {
    if (std::isfinite(s.t) && std::isfinite(s.u_d) && std::isfinite(s.u_q) && std::isfinite(s.i_d) && std::isfinite(s.i_q) &&
        std::isfinite(s.omega_e))
      finite.push_back(s);
    else
      ++e.counters.skipped_nonfinite;
  }
  out.samples = finite.size();
  // The sampling period: the median spacing; a step back in time or a gap of more than three
  // periods starts a new stretch (no neighbour across it).
  out.sample_period = medianSpacing(finite);
  e.sample_period = out.sample_period;
  const std::size_t n = finite.size();
  std::vector<bool> linked(n, false);  // sample k continues sample k - 1's stretch
  for (std::size_t k = 1; k < n; ++k) {
    const double dt = finite[k].t - finite[k - 1].t;
    linked[k] = dt > 0 && dt <= 3.0 * out.sample_period;
    if (!linked[k]) ++(dt <= 0 ? e.counters.time_resets : e.counters.gaps);
  }
  // Transients: a step of the currents or the speed between neighbours beyond kTransientSigmas
  // robust standard deviations of the log's own changes (the larger of 1.4826 x their median and
  // half their upper quartile: quantised telemetry repeats values, and its median change is zero).
  std::vector<std::array<double, 3>> change(n);  // |x_k - x_(k-1)| of i_d, i_q, omega_e where linked
  std::array<std::vector<double>, 3> changes;
  for (std::size_t k = 1; k < n; ++k) {
    if (!linked[k]) continue;
    change[k] = {std::abs(finite[k].i_d - finite[k - 1].i_d), std::abs(finite[k].i_q - finite[k - 1].i_q),
                 std::abs(finite[k].omega_e - finite[k - 1].omega_e)};
    for (std::size_t j = 0; j < 3; ++j) changes[j].push_back(change[k][j]);
  }
  std::array<double, 3> limit{};
  for (std::size_t j = 0; j < 3; ++j) {
    const double sigma = std::max(1.4826 * median(changes[j]), 0.5 * quantile(changes[j], 0.75));
    limit[j] = sigma > 0 ? kTransientSigmas * sigma : 0.0;
  }
  std::vector<bool> step(n, false);  // the change from k - 1 to k is a step
  for (std::size_t k = 1; k < n; ++k)
    for (std::size_t j = 0; j < 3 && linked[k]; ++j) step[k] = step[k] || change[k][j] > limit[j];
  std::vector<Sample> steady;
  std::vector<bool> steady_linked;  // the steady sample before it is its neighbour in the log
  std::size_t last_kept = n;
  for (std::size_t k = 0; k < n; ++k) {
    const bool transient = (k > 0 && step[k]) || (k + 1 < n && step[k + 1]);
    if (transient) {
      ++out.transients;
      continue;
    }
    steady_linked.push_back(k > 0 && linked[k] && last_kept == k - 1);
    steady.push_back(finite[k]);
    last_kept = k;
  }
  out.steady = steady.size();
  e.counters.used = steady.size();
  if (steady.size() < 2 * kColumns) {
    out.note = "fewer steady samples (" + std::to_string(steady.size()) + ") than the fit needs (" +
               std::to_string(2 * kColumns) + ")";
    Assessment none = assess(e.parameters, e.fit, {}, a);
    e.status = none.status;
    e.reason = none.reason;
    return out;
  }
  std::vector<std::size_t> pairs;
  for (std::size_t k = 1; k < steady.size(); ++k)
    if (steady_linked[k]) pairs.push_back(k);
  e.t = steady.back().t;
  // The operating point: means and spreads of the steady samples.
  double sd = 0, sq = 0, sw = 0, sdd = 0, sqq = 0, su = 0;
  for (const Sample& s : steady) {
    sd += s.i_d;
    sq += s.i_q;
    sw += s.omega_e;
    sdd += s.i_d * s.i_d;
    sqq += s.i_q * s.i_q;
    su += s.u_d * s.u_d + s.u_q * s.u_q;
  }
  const double m = static_cast<double>(steady.size());
  e.operating_point.i_d = sd / m;
  e.operating_point.i_q = sq / m;
  e.operating_point.omega_e = sw / m;
  e.operating_point.i_d_spread = std::sqrt(std::max(0.0, sdd / m - sd * sd / (m * m)));
  e.operating_point.i_q_spread = std::sqrt(std::max(0.0, sqq / m - sq * sq / (m * m)));
  const double si = std::sqrt((sdd + sqq) / m);  // RMS current [A]
  // A residual below fit_floor_relative of the RMS voltage is a fit even without noise.
  const double floor2 = a.fit_floor_relative * a.fit_floor_relative * su / m;
  const std::array<bool, kColumns> all{true, true, true, true, true, true};
  const auto rowsFor = [&](double width) {
    std::vector<Row> rows;
    rows.reserve(steady.size());
    for (const Sample& s : steady) rows.push_back(rowOf(s, width));
    return rows;
  };
  // The zero-crossing width, a nonlinear parameter of the shape: the profile of the fit's weighted
  // residual (chi^2, the axes weighted by a first fit's variances) over the grid; the minimum among
  // widths giving a physical error (V > 0), and the widths within chi^2 + 1 of it (the width's own
  // 1-sigma range) are kept for the uncertainty below.
  const LinearFit first = weightedFit(rowsFor(si / 16.0), pairs, all, floor2);
  const double var_d = first.ok ? std::max({first.mean_square_d, first.noise_d, floor2}) : 1.0;
  const double var_q = first.ok ? std::max({first.mean_square_q, first.noise_q, floor2}) : 1.0;
  struct Profile {
    double width, chi2;
    Vector beta;
  };
  std::vector<Profile> profile;
  for (int j = 0; j <= kWidthSteps && si > 0; ++j) {
    const double w = si * std::exp2(-j / 4.0);
    const LinearFit g = solve(rowsFor(w), pairs, all, 1.0 / var_d, 1.0 / var_q);
    if (!g.ok || !(g.beta(kV) > 0)) continue;
    profile.push_back({w, m * (g.mean_square_d / var_d + g.mean_square_q / var_q), g.beta});
  }
  double width = si / 16.0, chi2_min = std::numeric_limits<double>::infinity();
  const Profile* at_min = nullptr;
  for (const Profile& p : profile)
    if (p.chi2 < chi2_min) {
      chi2_min = p.chi2;
      width = p.width;
      at_min = &p;
    }
  out.zero_crossing_current = width;
  const std::vector<Row> rows = rowsFor(width);
  const LinearFit f = weightedFit(rows, pairs, all, floor2);
  FitCheck& fit = e.fit;
  if (!f.ok) {
    out.note = "the steady-state fit failed (no finite solution)";
    Assessment none = assess(e.parameters, fit, {}, a);
    e.status = none.status;
    e.reason = none.reason;
    return out;
  }
  const Vector known_inverter = stdWithHeld(rows, pairs, all, kV, floor2);
  const Vector known_timing = stdWithHeld(rows, pairs, all, kTiming, floor2);
  // The values reported: where the data do not determine a drive constant (V, positive, to 50 %; the timing
  // to 0.1 rad of turn at the RMS speed), it is held at zero, so that the motor's parameters read
  // as the apparent ones (R_s with the inverter's voltage in it, L_q with the timing) instead of a
  // collinear fit's arbitrary split (at one operating point: R_s -18 ohm, V -124 V). Their stated
  // uncertainty stays the full fit's: they are not identified there, with the reason.
  double omega_ms = 0.0;
  for (const Sample& s : steady) omega_ms += s.omega_e * s.omega_e / m;
  std::array<bool, kColumns> reported_free = all;
  LinearFit reported = f;
  if (!inverterDetermined(reported.beta(kV), stdOf(reported, kV))) {
    reported_free[kV] = false;
    reported = weightedFit(rows, pairs, reported_free, floor2);
  }
  if (reported.ok && !timingDetermined(stdOf(reported, kTiming), omega_ms)) {
    reported_free[kTiming] = false;
    reported = weightedFit(rows, pairs, reported_free, floor2);
  }
  if (!reported.ok) reported = f;
  fit.available = true;
  for (int p = 0; p < kParameterCount; ++p) {
    const std::size_t i = static_cast<std::size_t>(p);
    const double value = reported.beta(p);
    fit.optimum[p] = value;
    fit.determined[i] = f.determined[i];
    fit.relative_std[p] = stdOf(f, p) / std::abs(value);
    fit.relative_std_known_inverter[p] = known_inverter(p) / std::abs(value);
    fit.relative_std_known_timing[p] = known_timing(p) / std::abs(value);
  }
  out.noise_std_d = std::sqrt(f.noise_d);
  out.noise_std_q = std::sqrt(f.noise_q);
  fit.fit_ratio_d = f.mean_square_d / std::max(f.noise_d, 1e-300);
  fit.fit_ratio_q = f.mean_square_q / std::max(f.noise_q, 1e-300);
  fit.consistent = f.mean_square_d <= a.max_fit_ratio * f.noise_d + floor2 && f.mean_square_q <= a.max_fit_ratio * f.noise_q + floor2;
  if (!fit.consistent)
    fit.likely_cause = "the steady-state equations do not hold across these samples: a parameter that changed within the "
                       "log (temperature over minutes, a fault), a saturating machine across its loads, or transients "
                       "the step test did not catch";
  // The inverter model's own error: the shape of the average error is a model (the fundamental of a
  // smoothed sign at one width for all operating points; a real drive's error also changes with the
  // ripple's share of the current), so V stands for the error to no better than kInverterModelFloor
  // of itself (as the slow window states, slow_estimate.hpp): what that moves each parameter by is
  // added to its stated uncertainty. (Measured before this term: R_s 1.1 % off at a stated 0.36 %
  // on telemetry_duty_cycle.yaml at 50 Hz.)
  // The width is known only to its profile's range: what the widths within chi^2 + 1 of the minimum
  // move each parameter by counts as well (the larger of the two terms). (On telemetry_duty_cycle
  // at 50 Hz the profile is flat below a quarter of an ampere while R_s moves by 0.4 %.)
  if (f.determined[kV] && f.beta(kV) > 0) {
    const Vector shift = shiftWithInverterHeld(rows, pairs, all, f.beta(kV), kInverterModelFloor * f.beta(kV), floor2);
    Vector width_shift = Vector::Zero();
    for (const Profile& p : profile)
      if (at_min && p.chi2 <= chi2_min + 1.0) width_shift = width_shift.cwiseMax((p.beta - at_min->beta).cwiseAbs());
    for (int p = 0; p < kParameterCount; ++p) fit.model_floor[p] = std::max(shift(p), width_shift(p)) / std::abs(fit.optimum[p]);
  }
  fit.inverter_modelled = true;
  fit.inverter_voltage = f.beta(kV);
  fit.inverter_relative_std = stdOf(f, kV) / std::abs(f.beta(kV));
  fit.voltage_angle_modelled = true;  // k: the reasons name the drive's timing where it hides L_q
  out.voltage_timing = f.beta(kTiming);
  out.voltage_timing_std = stdOf(f, kTiming);
  fit.voltage_angle = std::numeric_limits<double>::quiet_NaN();  // in omega_e T_s: the PWM period is not in the log
  fit.voltage_angle_std = std::numeric_limits<double>::quiet_NaN();
  // A motor that heats within the log does not hold one set of parameters: where the constant fit
  // fails, and with a thermal: block in any case (its temperatures), the thermal trajectory; where
  // it fits and the constant fit does not, the values at the log's end are its.
  TrajectoryEstimate trajectory;
  if (config.thermal.enabled || !fit.consistent) {
    const std::vector<double> changes = changeTimes(finite, step);
    bool ordered = true;
    for (std::size_t k = 1; k < steady.size(); ++k) ordered = ordered && steady[k].t > steady[k - 1].t;
    if (!ordered) {
      out.thermal_note = "the log's time goes back: the thermal trajectory needs one stretch of time";
    } else {
      thermalTrajectory(steady, changes, width, all, std::max(f.noise_d, floor2), std::max(f.noise_q, floor2),
                        floor2, omega_ms, config, references, out, trajectory);
    }
  }
  if (!fit.consistent && trajectory.consistent) {
    fit.optimum = trajectory.value;
    fit.determined = trajectory.determined;
    fit.relative_std = trajectory.relative_std;
    fit.relative_std_known_inverter = trajectory.relative_std;
    fit.relative_std_known_timing = trajectory.relative_std;
    fit.model_floor = trajectory.model_floor;
    fit.fit_ratio_d = trajectory.fit_ratio_d;
    fit.fit_ratio_q = trajectory.fit_ratio_q;
    fit.consistent = true;
    fit.likely_cause.clear();
    fit.inverter_voltage = trajectory.V;
    fit.inverter_relative_std = trajectory.V_relative_std;
    reported_free[kV] = std::isfinite(trajectory.V);
    reported_free[kTiming] = std::isfinite(trajectory.timing);
    out.voltage_timing = trajectory.timing;
    out.voltage_timing_std = trajectory.timing_std;
    out.from_trajectory = true;
  }
  e.parameters = fit.optimum;
  const Assessment as = assess(e.parameters, fit, {}, a);
  e.status = as.status;
  e.reason = as.reason;
  e.relative_uncertainty = as.relative_uncertainty;
  // A value outside every motor's range that the data do not determine to the tolerance (a
  // collinear split at one operating point: R_s i_q and omega_e psi_f are one constant voltage
  // there, and the fluctuations around it, whose dynamics the averaged equations do not hold, pick
  // the split) is not determined rather than implausible: the data say nothing against the motor.
  for (int p = 0; p < kParameterCount; ++p) {
    const double statistical = a.confidence_sigmas * fit.relative_std[p];
    if (e.status[p] != ParameterStatus::Implausible || !std::isfinite(e.parameters[p]) ||
        statistical <= a.max_relative_uncertainty)
      continue;
    char buf[200];
    std::snprintf(buf, sizeof buf,
                  "the data determine it only to +-%.3g %% (need %.3g %%), and its value lies outside every motor's range: "
                  "one operating point, or too few apart; load and speed levels further apart determine it",
                  100 * statistical, 100 * a.max_relative_uncertainty);
    e.status[p] = ParameterStatus::NotExcited;
    e.reason[p] = buf;
  }
  if (out.from_trajectory)
    for (int p = 0; p < kParameterCount; ++p)
      e.reason[p] += p == kRs || p == kPsiF
                         ? "; at the log's end, from the thermal trajectory (one set of parameters does not hold: it drifts, "
                           "psi_f's possible drift since the last load or speed change included)"
                         : "; from the thermal trajectory (one set of parameters does not hold: R_s and psi_f drift)";
  for (int p = 0; p < kParameterCount; ++p) e.identifiable[static_cast<std::size_t>(p)] = e.status[p] == ParameterStatus::Identified;
  const InverterAssessment inv = assessInverter(fit, a, config.inverter.max_relative_uncertainty);
  e.inverter_voltage = fit.inverter_voltage;
  e.inverter_status = inv.status;
  e.inverter_reason = inv.reason;
  e.inverter_relative_uncertainty = inv.relative_uncertainty;
  if (!reported_free[kV]) {  // held at zero for the values reported
    e.inverter_voltage = std::numeric_limits<double>::quiet_NaN();
    e.inverter_status = ParameterStatus::NotExcited;
    e.inverter_reason = "the data do not determine it (to 50 %): at one current magnitude it acts as a resistance, "
                        "and R_s reads with it; current magnitudes further apart separate them";
  }
  if (!reported_free[kTiming]) {
    out.voltage_timing = std::numeric_limits<double>::quiet_NaN();
    out.voltage_timing_std = std::numeric_limits<double>::infinity();
  }
  return out;
}

TelemetryIdentifier::TelemetryIdentifier(IdentifierConfig config, std::size_t max_samples)
    : config_(std::move(config)), max_samples_(max_samples) {
  if (max_samples_ < static_cast<std::size_t>(2 * kColumns))
    throw ConfigError("telemetry: at most " + std::to_string(max_samples_) + " samples kept; the fit needs " +
                      std::to_string(2 * kColumns));
  fit_ = fitSteadyState({}, config_);
}

SampleStatus TelemetryIdentifier::process(const Sample& s) {
  SampleStatus status = SampleStatus::Used;
  if (!samples_.empty() && std::isfinite(s.t) && std::isfinite(samples_.back().t) && s.t < samples_.back().t) {
    samples_.clear();
    references_ = LearntReferences{};
    start_kept_ = true;
    ++time_resets_;
    status = SampleStatus::TimeReset;
  }
  if (!(std::isfinite(s.t) && std::isfinite(s.u_d) && std::isfinite(s.u_q) && std::isfinite(s.i_d) &&
        std::isfinite(s.i_q) && std::isfinite(s.omega_e)))
    status = SampleStatus::SkippedNonFinite;
  if (samples_.size() >= max_samples_) {  // the oldest quarter goes at once (no shift per sample)
    const std::size_t drop = std::max<std::size_t>(1, max_samples_ / 4);
    samples_.erase(samples_.begin(), samples_.begin() + static_cast<std::ptrdiff_t>(drop));
    forgotten_ += drop;
    start_kept_ = false;
  }
  samples_.push_back(s);
  stale_ = true;
  return status;
}

const SteadyStateFit& TelemetryIdentifier::fit() {
  if (stale_) {
    // While the first sample since the start is kept, the thermal trajectory's references are of
    // that sample (a declared cold start): the best determined of them is kept; once the sample is
    // let go, the kept ones stand in.
    const bool from_start = start_kept_;
    fit_ = fitSteadyState(samples_, config_, from_start ? nullptr : &references_);
    if (from_start) {
      const LearntReferences& r = fit_.thermal_references;
      references_.reference_temperature = r.reference_temperature;
      if (r.R_s > 0 && !(references_.R_s > 0 && references_.R_s_relative_uncertainty <= r.R_s_relative_uncertainty)) {
        references_.R_s = r.R_s;
        references_.R_s_relative_uncertainty = r.R_s_relative_uncertainty;
        references_.R_s_learnt_at = r.R_s_learnt_at;
      }
      if (r.psi_f > 0 && !(references_.psi_f > 0 && references_.psi_f_relative_uncertainty <= r.psi_f_relative_uncertainty)) {
        references_.psi_f = r.psi_f;
        references_.psi_f_relative_uncertainty = r.psi_f_relative_uncertainty;
        references_.psi_f_learnt_at = r.psi_f_learnt_at;
      }
    }
    fit_.estimate.counters.time_resets += time_resets_;
    stale_ = false;
  }
  return fit_;
}

void TelemetryIdentifier::reset() {
  samples_.clear();
  references_ = LearntReferences{};
  start_kept_ = true;
  stale_ = true;
}

}  // namespace pmsm_param_id
