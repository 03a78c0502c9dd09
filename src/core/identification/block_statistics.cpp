#include "pmsm_param_id/identification/block_statistics.hpp"
#include "pmsm_param_id/identification/inverter_edges.hpp"

#include "pmsm_param_id/model/frames.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include "vector_clones.hpp"

namespace pmsm_param_id {

BlockStatistics::BlockStatistics(const WindowSettings& settings) : settings_(settings) {
  // A width still to be measured (< 0): a sharp sign change until it is.
  settings_.inverter_zero_crossing_current = std::max(0.0, settings_.inverter_zero_crossing_current);
}

void BlockStatistics::reset() {
  block_samples_ = 0;
  nominal_period_ = 0.0;
  ring_.clear();
  head_ = count_ = 0;
  stretch_samples_ = 0;
  smoothing_samples_ = 0;
  angle_phasor_.reset();
  count_lock_.reset();
  S_d_.setZero();
  S_q_.setZero();
  dS_d_.setZero();
  dS_q_.setZero();
  stored_weight_ = stored_difference_weight_ = 0.0;
  weight_ = difference_weight_ = 0.0;
  scale_ = 1.0;
  blocks_ = 0;
  blocks_since_rebase_ = 0;
  have_previous_block_ = false;
  heat_ = 0.0;
  fast_block_weight_ = fast_time_sum_ = fast_heat_sum_ = 0.0;
  long_d_.setZero();
  long_q_.setZero();
  long_weight_ = 0.0;
  have_long_block_ = false;
  long_history_.clear();
  long_history_head_ = 0;
  blocks_since_long_block_ = 0;
  N_.setZero();
  C_d_.setZero();
  C_q_.setZero();
  P_d_.setZero();
  P_q_.setZero();
  projection_stale_ = true;
  projected_blocks_ = 0;
  projected_weight_ = 0.0;
  folded_sums_stale_ = true;
  long_N_.setZero();
  long_C_d_.setZero();
  long_C_q_.setZero();
  resetSlowWindow();
  speed_travel_ = angle_travel_ = pending_speed_travel_ = pending_angle_travel_ = 0.0;
  bus_reference_ = std::numeric_limits<double>::quiet_NaN();
}

double BlockStatistics::loggedSpeedToAngleRatio() const {
  // From two electrical turns within the long window: quantisation enters only at the ends, a speed
  // filter's lag as lag x speed during speed changes (a 100 Hz filter after a ramp to 440 rad/s:
  // 0.7 rad, 5.6 % of two turns, 0.6 % of twenty).
  if (!(angle_travel_ > 4.0 * M_PI)) return std::numeric_limits<double>::quiet_NaN();
  return speed_travel_ / angle_travel_;
}

void BlockStatistics::resetLongWindow() {
  long_d_.setZero();
  long_q_.setZero();
  long_N_.setZero();
  long_C_d_.setZero();
  long_C_q_.setZero();
  long_weight_ = 0.0;
  have_long_block_ = false;
  long_history_.clear();
  long_history_head_ = 0;
  resetSlowWindow();
}

void BlockStatistics::resetSlowWindow() {
  slow_d_.setZero();
  slow_q_.setZero();
  slow_N_.setZero();
  slow_C_d_.setZero();
  slow_C_q_.setZero();
  slow_weight_ = 0.0;
  slow_time_ = std::numeric_limits<double>::quiet_NaN();
  slow_heat_ = slow_ahead_time_ = slow_ahead_heat_ = 0.0;
}

void BlockStatistics::configure(double nominal_period) {
  if (!(nominal_period > 0) || !std::isfinite(nominal_period))
    throw std::invalid_argument("BlockStatistics: nominal period must be > 0");
  reset();
  nominal_period_ = nominal_period;
  // Automatic lengths follow the sampling rate where it is slow: a block of at least 10 periods and
  // a window of at least 500 (at 1 kHz a 50 ms window would hold 50 samples).
  const double block = settings_.block_length > 0 ? settings_.block_length : std::max(0.005, 10.0 * nominal_period);
  forgetting_time_constant_ =
      settings_.forgetting_time_constant > 0 ? settings_.forgetting_time_constant : std::max(0.05, 500.0 * nominal_period);
  block_samples_ = std::max(1, static_cast<int>(std::lround(block / nominal_period)));
  lambda_ = std::exp(-nominal_period / forgetting_time_constant_);
  long_lambda_ = std::exp(-block_samples_ * nominal_period / settings_.long_time_constant);
  slow_lambda_ = std::exp(-block_samples_ * nominal_period / settings_.slow_time_constant);
  const double long_block = block_samples_ * nominal_period;  // one long-window block every block length [s]
  long_spacing_blocks_ = settings_.long_difference_spacing > 0
                             ? static_cast<int>(std::lround(settings_.long_difference_spacing / long_block))
                             : 0;
  if (long_spacing_blocks_ < 2) long_spacing_blocks_ = 0;  // one block apart is the consecutive difference
  smoothing_samples_ = std::clamp(settings_.angle_smoothing_samples, 0, block_samples_);
  ring_.resize(static_cast<std::size_t>(block_samples_ + smoothing_samples_) + 1);
}

void BlockStatistics::setAngleSmoothing(int samples) {
  settings_.angle_smoothing_samples = std::max(0, samples);
  if (!configured()) return;
  smoothing_samples_ = std::min(settings_.angle_smoothing_samples, block_samples_);
  ring_.assign(static_cast<std::size_t>(block_samples_ + smoothing_samples_) + 1, Cumulative{});
  head_ = 0;
  breakContinuity();
}

void BlockStatistics::breakContinuity() {
  count_ = 0;
  count_lock_.breakContinuity();
  stretch_samples_ = 0;
  have_previous_block_ = false;
  have_long_block_ = false;
  long_history_.clear();
  long_history_head_ = 0;
  blocks_since_long_block_ = 0;
}

namespace {
inline double sign(double x) { return x > 0 ? 1.0 : (x < 0 ? -1.0 : 0.0); }

/// The voltage vector held in the stator frame turns by -omega_e t in the rotor frame; its integral
/// over [0, t] is S u + C (u_q, -u_d): int_0^t e^{-j w tau} dtau = S - j C, S = sin(w t) / w,
/// C = (1 - cos(w t)) / w.
struct HeldVectorIntegral {
  double S, C;  // [s]
};
HeldVectorIntegral heldVectorIntegral(double w, double t) {
  const double wt = w * t;
  if (std::abs(wt) > 1e-6) return {std::sin(wt) / w, (1.0 - std::cos(wt)) / w};
  return {t * (1.0 - wt * wt / 6.0), 0.5 * wt * t};
}

/// Over a period h the held vector ramps the d voltage by w t u_q (the q voltage by -w t u_d), so the
/// currents bend, i_d'' = w u_q / L_d, i_q'' = -w u_d / L_q: the trapezoid of each current misses
/// -(h^3 / 12) i'', and at mid-period the current lies -(h^2 / 8) i'' off the chord.
struct HoldBend {
  double missed_d, missed_q;  // [A s]
  double mid_d, mid_q;        // [A]
};
HoldBend holdBend(double h, double w, double u_d, double u_q, double L_d, double L_q) {
  const double k = h * h * h / 12.0 * w, m = -h * h / 8.0 * w;
  return {-k * u_q / L_d, k * u_d / L_q, m * u_q / L_d, -m * u_d / L_q};
}
}  // namespace

namespace {
/// tanh(x) from one exp (the shape's sums need its absolute value to 1e-16, which this gives;
/// std::tanh costs about twice as much: 11 against 6 ns here, and the shape takes nine per sample).
inline double smoothSign(double x) {
  const double a = std::abs(x);
  if (a > 20.0) return std::copysign(1.0, x);
  const double e = std::exp(-2.0 * a);
  return std::copysign((1.0 - e) / (1.0 + e), x);
}

/// The mean of tanh(i / width) over a period by Simpson's rule, from the current at its start, its
/// middle and its end.
inline double simpsonSmoothSign(double i_start, double i_mid, double i_end, double width) {
  return (smoothSign(i_start / width) + 4.0 * smoothSign(i_mid / width) + smoothSign(i_end / width)) / 6.0;
}

/// The wide shape's width: twice the zero-crossing width, or without one 2 % of the current (d, q)
/// (a sharp sign change) [A].
inline double wideShapeWidth(double width, double d, double q) {
  return width > 0 ? 2.0 * width : 0.02 * std::sqrt(d * d + q * q) + 1e-12;
}

/// inverterShape() with the logged angle, given as its phasor: the phase currents from the measured
/// d-q currents, then the d-q image of their signs.
void inverterShapeAt(const Sample& s, Phasor angle, double& shape_d, double& shape_q, std::array<double, 3>* phase) {
  const std::array<double, 3> i = phaseFromDq(s.i_d, s.i_q, angle);
  const Vec2 shape = rotate(clarke(sign(i[0]), sign(i[1]), sign(i[2])), conjugate(angle));
  shape_d = shape.x;
  shape_q = shape.y;
  if (phase) *phase = i;
}
}  // namespace

void inverterShape(const Sample& s, double& shape_d, double& shape_q, std::array<double, 3>* phase) {
  if (std::isfinite(s.theta_e)) {
    inverterShapeAt(s, phasorOf(s.theta_e), shape_d, shape_q, phase);
    return;
  }
  const double magnitude2 = s.i_d * s.i_d + s.i_q * s.i_q;
  const double k = magnitude2 > 0 ? (4.0 / M_PI) / std::sqrt(magnitude2) : 0.0;  // fundamental of the six-step shape
  shape_d = s.i_d * k;
  shape_q = s.i_q * k;
}

void BlockStatistics::inverterShapeIntegral(const Cumulative& p, const Cumulative& c, const Sample& s, double dt,
                                            double width, const std::array<double, 3>& mid_bend, Phasor mid,
                                            double& int_d, double& int_q, std::array<double, 2>* wide) const {
  if (!(std::isfinite(p.theta_e) && std::isfinite(s.theta_e))) {  // no angle: trapezoid of (4/pi) i/|i|
    int_d = 0.5 * dt * (p.shape_d + c.shape_d);
    int_q = 0.5 * dt * (p.shape_q + c.shape_q);
    if (wide) *wide = {int_d, int_q};
    return;
  }
  // The sign of each phase current is piecewise constant; a sign change between the samples is
  // placed where the linearly interpolated current crosses zero (a trapezoid would smear every
  // crossing over a whole period: a misfit of about V T / 2 per crossing).
  const std::array<double, 3>& a = p.phase;
  const std::array<double, 3>& b = c.phase;
  std::array<double, 3> mean{}, mean_wide{};
  for (std::size_t k = 0; k < 3; ++k) {
    const double ia = a[k], ib = b[k];
    if (width > 0) {  // smooth: tanh(i / width), Simpson's rule on the interpolated current
      const double i_mid = 0.5 * (ia + ib) + mid_bend[k];
      if (wide) {  // one tanh per point for both widths
        const double ta = smoothSign(0.5 * ia / width), tm = smoothSign(0.5 * i_mid / width),
                     tb = smoothSign(0.5 * ib / width);
        mean_wide[k] = (ta + 4.0 * tm + tb) / 6.0;
        const auto doubled = [](double t) { return 2.0 * t / (1.0 + t * t); };
        mean[k] = (doubled(ta) + 4.0 * doubled(tm) + doubled(tb)) / 6.0;
      } else {
        mean[k] = simpsonSmoothSign(ia, i_mid, ib, width);
      }
      continue;
    }
    const double sa = sign(ia), sb = sign(ib);
    if (sa == sb) {
      mean[k] = sa;
    } else {
      const double f = ia / (ia - ib);
      mean[k] = f * sa + (1.0 - f) * sb;
    }
  }
  // Into the rotor frame at mid-period (`mid`: the phasor of the rotor angle there).
  const Vec2 v = rotate(clarke(mean[0], mean[1], mean[2]), conjugate(mid));
  int_d = dt * v.x;
  int_q = dt * v.y;
  if (wide) {
    const Vec2 vw = rotate(clarke(mean_wide[0], mean_wide[1], mean_wide[2]), conjugate(mid));
    *wide = {dt * vw.x, dt * vw.y};
  }
}

InverterEdgePeriod BlockStatistics::edgePeriod(const Cumulative& p, double dt, double omega_e, Phasor mid, double L_d,
                                              double L_q) const {
  // The acting vector in the stator frame: turned by the drive's voltage angle where the fit
  // estimates one, held in the stator frame from the period's start (stationary hold) or at mid-period.
  Vec2 acting{p.applied_d, p.applied_q};
  if (voltage_angle_ != 0.0) acting = rotate(acting, voltage_angle_ * omega_e * nominal_period_);
  InverterEdgePeriod e;
  e.voltage = rotate(acting, settings_.stationary_hold ? Phasor{p.cos_theta, p.sin_theta} : mid);
  e.period = dt;
  e.dead_volt_seconds = edge_V_ * dt;
  e.bus_voltage = busVoltageLogged() ? bus_reference_ * (1.0 + p.bus_ratio) : std::numeric_limits<double>::quiet_NaN();
  e.L_d = L_d;
  e.L_q = L_q;
  e.rotor = mid;
  return e;
}

Vec2 BlockStatistics::edgeShapeIntegral(const Cumulative& p, const std::array<double, 3>& i_start,
                                        const std::array<double, 3>& i_end, double dt, Phasor mid,
                                        const std::array<double, 3>& mid_bend) const {
  InverterEdgePeriod e = edgePeriod(p, dt, p.omega_e, mid, edge_L_d_, edge_L_q_);
  e.width = settings_.inverter_zero_crossing_current;
  e.mid_bend = mid_bend;
  // With the bus voltage the period is replayed edge by edge (exact for the chord's currents);
  // without it, the edges' first-order model with the zero-crossing width.
  std::array<double, 3> moments{};
  const std::array<double, 3> m = inverterEdgeReplay(e, i_start, i_end, &moments);
  const Vec2 v = inverterEdgeImage(m, moments, p.omega_e, mid);
  return {dt * v.x, dt * v.y};
}

BlockStatistics::ObservedPeriod BlockStatistics::observePeriod(const Cumulative& p, const Sample& s, double dt,
                                                              double angle_increment, Phasor at_sample,
                                                              double rotor_rate) {
  // The measured currents' noise would enter the shape where a phase current crosses zero (a slope
  // of V / w, about 1 ohm on the robot joint, twelve times its R_s), inside every block where the
  // noise level does not see it, and bias R_s and L_d as an errors-in-variables regressor. Below the
  // current loop's bandwidth that noise is in the true current (the loop makes the measured one
  // follow its reference), so no filter of the measured currents removes it: the observer is the
  // data's model driven by the logged voltages (the same delay, hold and inverter terms as the
  // statistics), pulled towards the measured currents by the gain each sample.
  if (observerFollowsForward()) return observePeriodForward(p, s, dt, angle_increment, at_sample, rotor_rate);
  const double R = observer_model_[kRs], L_d = observer_model_[kLd], L_q = observer_model_[kLq];
  const double psi_f = observer_model_[kPsiF];
  const double width = settings_.inverter_zero_crossing_current;
  const InverterMix mix = inverterMix();
  const double V_narrow = mix.narrow + mix.bus * p.bus_ratio;
  const double V_wide = mix.wide;
  // The inverter error at currents (d, q) and an angle (its cos, sin): the fitted mix, its two
  // shapes (the d-q images of tanh over w and over 2w) and its slope d(error)/d(current) (2x2, row =
  // error axis) = R(-theta) (2/3) sum_k f'(i_k) r_k r_k^T R(theta), r_k the phases' rows of the
  // inverse Clarke transform.
  struct Node {
    double e_d, e_q, narrow_d, narrow_q, wide_d, wide_q;
    double J[2][2];
  };
  // Not inlined: its three copies made this function 13.5 KB of code against 7.6 KB + 2.3 KB, and
  // the inlined form ran 10 % slower per real-drive sample although the calls add 10 % to the
  // observer's instructions (FBDAPSO on industrial_pwm, doc/performance.md).
  const auto evaluate = [&](double d, double q, double cos_t, double sin_t) __attribute__((noinline)) {
    const std::array<double, 3> i = phaseFromDq(d, q, Phasor{cos_t, sin_t});
    const double wide = wideShapeWidth(width, d, q);
    static const double rows[3][2] = {{1.0, 0.0}, {-0.5, 0.8660254037844386}, {-0.5, -0.8660254037844386}};
    std::array<double, 3> narrow{}, wide_shape{};
    double M[2][2] = {{0.0, 0.0}, {0.0, 0.0}};
    for (std::size_t k = 0; k < 3; ++k) {
      const double tw = smoothSign(i[k] / wide);
      wide_shape[k] = tw;
      double slope = V_wide * (1.0 - tw * tw) / wide;
      if (width > 0) {
        const double tn = 2.0 * tw / (1.0 + tw * tw);  // tanh(i / w) from tanh(i / 2w): one tanh, not two
        narrow[k] = tn;
        slope += V_narrow * (1.0 - tn * tn) / width;
      } else {
        narrow[k] = sign(i[k]);
      }
      for (int a = 0; a < 2; ++a)
        for (int b = 0; b < 2; ++b) M[a][b] += (2.0 / 3.0) * slope * rows[k][a] * rows[k][b];
    }
    const auto toDq = [&](const std::array<double, 3>& x) {
      return rotate(clarke(x[0], x[1], x[2]), conjugate(Phasor{cos_t, sin_t}));
    };
    Node out;
    const Vec2 n = toDq(narrow), w = toDq(wide_shape);
    out.narrow_d = n.x;
    out.narrow_q = n.y;
    out.wide_d = w.x;
    out.wide_q = w.y;
    out.e_d = V_narrow * n.x + V_wide * w.x;
    out.e_q = V_narrow * n.y + V_wide * w.y;
    // R(-theta) M R(theta), R(theta) = [[c, -s], [s, c]].
    const double MR[2][2] = {{M[0][0] * cos_t + M[0][1] * sin_t, -M[0][0] * sin_t + M[0][1] * cos_t},
                             {M[1][0] * cos_t + M[1][1] * sin_t, -M[1][0] * sin_t + M[1][1] * cos_t}};
    out.J[0][0] = cos_t * MR[0][0] + sin_t * MR[1][0];
    out.J[0][1] = cos_t * MR[0][1] + sin_t * MR[1][1];
    out.J[1][0] = -sin_t * MR[0][0] + cos_t * MR[1][0];
    out.J[1][1] = -sin_t * MR[0][1] + cos_t * MR[1][1];
    return out;
  };
  // Near a zero crossing the error acts as a resistance V / w, so where T V / (w L) is not small a
  // crossing current settles on a curve within the period, not on the chord between the samples
  // (on the chords L_d read 0.22-0.25 % high on the robot joint with noise-free currents). The
  // period is therefore followed in substeps of T V / (w L) <= 0.3, each an implicit step solved by
  // Newton's method: the currents by the trapezoid, the error by Simpson's rule on the substep's
  // chord (the error's slope makes even a substep stiff; fixed-point corrections did not converge).
  // Along that path the shapes are integrated, and so are the currents: the block integrals of the
  // measured currents take the path's departure from its own chord (the held vector's bend
  // included).
  // The slope that counts is the steepest one the period's path meets: the shapes' slope at the
  // phase current nearest zero, its distance from zero taken as the smaller end's less the phase
  // current's whole change over the period (the path between the ends bends by far less), zero
  // where a phase changes sign. Away from the crossings the error is flat and one step follows the
  // path (on the 36 mH switching-level drive the observer's instructions fell 2.5-fold, callgrind).
  double slope_scale = std::abs(V_narrow) / std::max(width, 1e-3) + std::abs(V_wide) / std::max(2.0 * width, 1e-3);
  if (width > 0) {
    const std::array<double, 3> from = phaseFromDq(observer_i_d_, observer_i_q_, Phasor{p.cos_theta, p.sin_theta});
    const std::array<double, 3> to = phaseFromDq(s.i_d, s.i_q, at_sample);
    double nearest = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < 3; ++k)
      nearest = from[k] * to[k] <= 0.0
                    ? 0.0
                    : std::min(nearest, std::min(std::abs(from[k]), std::abs(to[k])) - std::abs(to[k] - from[k]));
    nearest = std::max(0.0, nearest);
    if (!std::isfinite(nearest)) nearest = 0.0;
    const double tn = smoothSign(nearest / width), tw = smoothSign(0.5 * nearest / width);
    slope_scale = std::abs(V_narrow) * (1.0 - tn * tn) / width + std::abs(V_wide) * (1.0 - tw * tw) / (2.0 * width);
  }
  const int n = std::clamp(static_cast<int>(std::ceil(dt * slope_scale / std::min(L_d, L_q) / 0.3)), 1, 16);
  const double h = dt / n, dtheta = angle_increment / n;
  // The substep's turn and its half (series for small turns: advance()), the angle at the period's
  // start and at the sample from the phasors add() keeps: no cos/sin call in a period.
  const Phasor turn = advance(Phasor{1.0, 0.0}, 0.0, dtheta), half_turn = advance(Phasor{1.0, 0.0}, 0.0, 0.5 * dtheta);
  const double cr = turn.c, sr = turn.s, crh = half_turn.c, srh = half_turn.s;
  // The voltage over [t_a, t_b] of the period: the held vector, turning by -omega_e t in the rotor
  // frame with the stationary hold, else constant; within a substep the held vector's bend of the
  // currents, as in the block integrals.
  const double w = p.omega_e;
  // The acting vector, turned by the drive's voltage angle where the data's fit estimates one.
  Vec2 acting{p.applied_d, p.applied_q};
  if (voltage_angle_ != 0.0) acting = rotate(acting, voltage_angle_ * angle_increment * nominal_period_ / dt);
  const HoldBend bend = settings_.stationary_hold ? holdBend(h, w, acting.x, acting.y, L_d, L_q) : HoldBend{};
  const double missed_d = bend.missed_d, missed_q = bend.missed_q, bend_d = bend.mid_d, bend_q = bend.mid_q;
  const double d_start = observer_i_d_, q_start = observer_i_q_;
  double d0 = d_start, q0 = q_start;
  double cos0 = p.cos_theta, sin0 = p.sin_theta;
  Node e0 = evaluate(d0, q0, cos0, sin0);
  ObservedPeriod out;
  out.valid = true;
  double path_d = 0.0, path_q = 0.0;  // the currents' integrals along the path [A s]
  for (int j = 0; j < n; ++j) {
    double dU_d = h * acting.x, dU_q = h * acting.y;
    if (settings_.stationary_hold) {
      const HeldVectorIntegral a = heldVectorIntegral(w, j * h), b = heldVectorIntegral(w, (j + 1) * h);
      const double dS = b.S - a.S, dC = b.C - a.C;
      dU_d = dS * acting.x + dC * acting.y;
      dU_q = dS * acting.y - dC * acting.x;
    }
    const double cm = cos0 * crh - sin0 * srh, sm = sin0 * crh + cos0 * srh;
    const double c1 = cos0 * cr - sin0 * sr, s1 = sin0 * cr + cos0 * sr;
    double d = d0, q = q0;
    Node em = e0, e1 = e0;
    for (int iteration = 0; iteration < 8; ++iteration) {
      em = evaluate(0.5 * (d0 + d) + bend_d, 0.5 * (q0 + q) + bend_q, cm, sm);
      e1 = evaluate(d, q, c1, s1);
      const double md = 0.5 * (d0 + d), mq = 0.5 * (q0 + q);
      const double ed = (e0.e_d + 4.0 * em.e_d + e1.e_d) / 6.0, eq = (e0.e_q + 4.0 * em.e_q + e1.e_q) / 6.0;
      const double G_d = d - d0 - (dU_d - R * (h * md + missed_d) + L_q * (dtheta * mq + w * missed_q) - ed * h) / L_d;
      const double G_q = q - q0 - (dU_q - R * (h * mq + missed_q) - L_d * (dtheta * md + w * missed_d) -
                                   psi_f * dtheta - eq * h) / L_q;
      if (std::abs(G_d) + std::abs(G_q) < 1e-7) break;  // [A]: the evaluations above are this state's
      // d ed / d x1 = (4 J_mid / 2 + J_1) / 6
      double slope[2][2];
      for (int a = 0; a < 2; ++a)
        for (int b = 0; b < 2; ++b) slope[a][b] = (2.0 * em.J[a][b] + e1.J[a][b]) / 6.0 * h;
      const double A00 = 1.0 + (0.5 * R * h + slope[0][0]) / L_d, A01 = (-0.5 * L_q * dtheta + slope[0][1]) / L_d;
      const double A10 = (0.5 * L_d * dtheta + slope[1][0]) / L_q, A11 = 1.0 + (0.5 * R * h + slope[1][1]) / L_q;
      const double det = A00 * A11 - A01 * A10;
      if (!(std::abs(det) > 1e-12)) break;
      const double step_d = (A11 * G_d - A01 * G_q) / det, step_q = (-A10 * G_d + A00 * G_q) / det;
      d -= step_d;
      q -= step_q;
    }
    out.narrow_d += h / 6.0 * (e0.narrow_d + 4.0 * em.narrow_d + e1.narrow_d);
    out.narrow_q += h / 6.0 * (e0.narrow_q + 4.0 * em.narrow_q + e1.narrow_q);
    out.wide_d += h / 6.0 * (e0.wide_d + 4.0 * em.wide_d + e1.wide_d);
    out.wide_q += h / 6.0 * (e0.wide_q + 4.0 * em.wide_q + e1.wide_q);
    path_d += 0.5 * h * (d0 + d) + missed_d;
    path_q += 0.5 * h * (q0 + q) + missed_q;
    d0 = d;
    q0 = q;
    cos0 = c1;
    sin0 = s1;
    e0 = e1;
  }
  if (edgeModelSet()) {  // the narrow shape from the path's ends, edge by edge
    const Phasor start{p.cos_theta, p.sin_theta}, mid = advance(start, p.theta_e, 0.5 * angle_increment);
    // The path bends within the period as the held vector turns (holdBend over the whole period).
    const HoldBend period_bend = settings_.stationary_hold ? holdBend(dt, w, acting.x, acting.y, L_d, L_q) : HoldBend{};
    const Vec2 v = edgeShapeIntegral(p, phaseFromDq(d_start, q_start, start), phaseFromDq(d0, q0, Phasor{cos0, sin0}), dt,
                                     mid, phaseFromDq(period_bend.mid_d, period_bend.mid_q, mid));
    out.narrow_d = v.x;
    out.narrow_q = v.y;
  }
  out.missed_d = path_d - 0.5 * dt * (d_start + d0);
  out.missed_q = path_q - 0.5 * dt * (q_start + q0);
  return finishPeriod(out, d0, q0, s, at_sample);
}

BlockStatistics::ObservedPeriod BlockStatistics::finishPeriod(ObservedPeriod out, double end_d, double end_q,
                                                              const Sample& s, Phasor at_sample) {
  const double gain = settings_.inverter_shape_observer_gain;
  observer_i_d_ = end_d + gain * (s.i_d - end_d);
  observer_i_q_ = end_q + gain * (s.i_q - end_q);
  if (!(std::isfinite(observer_i_d_) && std::isfinite(observer_i_q_) && std::isfinite(out.narrow_d + out.narrow_q) &&
        std::isfinite(out.wide_d + out.wide_q) && std::isfinite(out.missed_d + out.missed_q))) {
    observer_i_d_ = s.i_d;
    observer_i_q_ = s.i_q;
    out = ObservedPeriod{};
  }
  out.phase = phaseFromDq(observer_i_d_, observer_i_q_, at_sample);
  return out;
}

BlockStatistics::ObservedPeriod BlockStatistics::observePeriodForward(const Cumulative& p, const Sample& s, double dt,
                                                                     double angle_increment, Phasor at_sample,
                                                                     double rotor_rate) {
  // Near a zero crossing a leg's loss moves by about 1 / (the current's sweep within one dead time)
  // per ampere of its current at the edge (2.75 per A on the robot joint), so the edge current must
  // be known to milliamperes. Pinning both ends of the period (the chord: observePeriod's path and
  // inverterEdgeReplay's mean vector) lets a change of the loss move the period's mean vector and
  // through it that same edge current, about 0.36 A per unit of loss there: a feedback near one
  // that amplified every error of the ends (with exact currents and the true model 0.39 / 0.21 A of
  // block error against 0.05 A of noise). Followed forward from the observer's start current, with
  // the back EMF turning within the period and the resistive drop along the path, the same periods
  // left 0.021 / 0.014 A and the end current to 0.4 mA (doc/algorithm.md section 8).
  const double R = observer_model_[kRs], L_d = observer_model_[kLd], L_q = observer_model_[kLq];
  const double psi_f = observer_model_[kPsiF];
  const double w = rotor_rate;
  const Phasor start{p.cos_theta, p.sin_theta}, mid = advance(start, p.theta_e, 0.5 * angle_increment);
  const double d_start = observer_i_d_, q_start = observer_i_q_;
  const std::array<double, 3> i0 = phaseFromDq(d_start, q_start, start);
  const InverterEdgePeriod e = edgePeriod(p, dt, w, mid, L_d, L_q);
  InverterEdgeForward f;
  f.drift = rotate(Vec2{R * d_start + w * (L_d - L_q) * q_start, R * q_start + w * (L_d - L_q) * d_start + w * psi_f}, mid);
  const Vec2 emf = rotate(Vec2{0.0, w * psi_f}, mid);
  f.drift_rate = {-w * emf.y, w * emf.x};
  f.resistance = R;
  f.drift_current = phaseFromDq(d_start, q_start, mid);
  std::array<double, 3> moments{};
  const std::array<double, 3> m = inverterEdgeReplay(e, i0, i0, &moments, &f);
  ObservedPeriod out;
  out.valid = true;
  const Vec2 v = inverterEdgeImage(m, moments, w, mid);
  out.narrow_d = dt * v.x;
  out.narrow_q = dt * v.y;
  const Vec2 end = rotate(clarke(f.i_end[0], f.i_end[1], f.i_end[2]), conjugate(at_sample));
  const Vec2 path = rotate(clarke(f.integral[0], f.integral[1], f.integral[2]), conjugate(mid));
  out.missed_d = path.x - 0.5 * dt * (d_start + end.x);
  out.missed_q = path.y - 0.5 * dt * (q_start + end.y);
  const double width = settings_.inverter_zero_crossing_current;
  const double wide = wideShapeWidth(width, end.x, end.y);
  std::array<double, 3> shape{};
  for (std::size_t k = 0; k < 3; ++k) shape[k] = simpsonSmoothSign(i0[k], 0.5 * (i0[k] + f.i_end[k]), f.i_end[k], wide);
  const Vec2 wv = rotate(clarke(shape[0], shape[1], shape[2]), conjugate(mid));
  out.wide_d = dt * wv.x;
  out.wide_q = dt * wv.y;
  return finishPeriod(out, end.x, end.y, s, at_sample);
}

namespace {
/// Zeroes a trivially copyable object with straight-line 16-byte stores. (`x = T{}` became `rep
/// stos` here; for a 336-byte ring entry its start-up cost showed as ~7 % of a statistics update.)
template <class T, std::size_t... K>
inline void zeroStores(T& x, std::index_sequence<K...>) {
  typedef double Pair __attribute__((vector_size(16)));
  const Pair zero = {0.0, 0.0};
  char* bytes = reinterpret_cast<char*>(&x);
  (std::memcpy(bytes + 16 * K, &zero, 16), ...);
}
template <class T>
inline void zeroFill(T& x) {
  static_assert(std::is_trivially_copyable<T>::value && sizeof(T) % 16 == 0, "zeroFill: 16-byte chunks of plain data");
  zeroStores(x, std::make_index_sequence<sizeof(T) / 16>{});
}
// Upper triangle of S += alpha z z^T (small fixed sizes: plain loops beat the general routine).
// K: only the first K entries of z (the rest are zero: the blocks' rate and heat entries).
template <int N, int K = N>
inline void rankOneUpper(Eigen::Matrix<double, N, N>& S, const Eigen::Matrix<double, N, 1>& z, double alpha) {
  // Unrolled whole (N is a small compile-time size): the triangle's loops of varying length otherwise
  // compile to a vector loop with a scalar remainder per column.
#pragma GCC unroll 16
  for (int j = 0; j < K; ++j) {
    const double azj = alpha * z(j);
#pragma GCC unroll 16
    for (int i = 0; i <= j; ++i) S(i, j) += azj * z(i);
  }
}
/// M += alpha a b^T, unrolled whole (Eigen's general outer product runs column by column through a
/// call per column: the sensors' three updates cost more than the 12 x 12 sums' two).
template <int R, int C, int K = R>
inline void rankOne(Eigen::Matrix<double, R, C>& M, const Eigen::Matrix<double, R, 1>& a,
                    const Eigen::Matrix<double, C, 1>& b, double alpha) {
  const Eigen::Matrix<double, R, 1> aa = alpha * a;  // (alpha a_i) b_j, as Eigen's product rounds it
#pragma GCC unroll 16
  for (int j = 0; j < C; ++j) {
#pragma GCC unroll 16
    for (int i = 0; i < K; ++i) M(i, j) += aa(i) * b(j);
  }
}
}  // namespace

// Cloned for AVX2 (vector_clones.hpp): the two rank-one updates of the 11 x 11 sums take four
// doubles per instruction instead of two; no FMA in either clone, so the same numbers.
PMSM_VECTOR_CLONES bool BlockStatistics::add(const Sample& s) {
  if (block_samples_ == 0) throw std::logic_error("BlockStatistics::add before configure()");
  // The new entry is written in place: into the free slot, or over the oldest entry once the ring
  // is full (nothing below reads the oldest before it is dropped).
  // (Ring positions wrap by a comparison: five integer divisions per sample were ~4 % of this update.)
  const std::size_t cap = ring_.size();
  const auto wrap = [cap](std::size_t k) { return k < cap ? k : k - cap; };  // k < 2 cap
  Cumulative& c = ring_[wrap(head_ + count_)];
  zeroFill(c);  // = Cumulative{}
  c.t = s.t;
  c.i_d = s.i_d;
  c.i_q = s.i_q;
  c.omega_e = s.omega_e;
  c.u_d = s.u_d;
  c.u_q = s.u_q;
  c.theta_e = s.theta_e;
  // With the logged angle: its cos and sin (the inverter shape, the sensor terms and the next
  // sample's mid-period angle take them from here; advanced from the previous sample's, a cos/sin
  // call every 64 samples: PhasorTracker), and the phase currents.
  if (std::isfinite(s.theta_e)) {
    const Phasor angle = angle_phasor_.next(s.theta_e);
    c.cos_theta = angle.c;
    c.sin_theta = angle.s;
    if (settings_.sensor_gains) {
      const double c2 = c.cos_theta * c.cos_theta - c.sin_theta * c.sin_theta, s2 = 2.0 * c.sin_theta * c.cos_theta;
      c.P = c2 * s.i_d - s2 * s.i_q;
      c.Q = s2 * s.i_d + c2 * s.i_q;
    }
    inverterShapeAt(s, angle, c.shape_d, c.shape_q, &c.phase);
  } else {
    angle_phasor_.reset();
    inverterShape(s, c.shape_d, c.shape_q, &c.phase);
  }
  // The bus voltage relative to the first one logged (a fixed reference, so that every block's
  // entry means the same); a sample without it counts as the reference.
  if (std::isfinite(s.v_dc) && s.v_dc > 0 && !std::isfinite(bus_reference_)) bus_reference_ = s.v_dc;
  c.bus_ratio = std::isfinite(s.v_dc) && s.v_dc > 0 ? s.v_dc / bus_reference_ - 1.0 : 0.0;
  if (count_ > 0) {
    const Cumulative& p = ring_[wrap(head_ + count_ - 1)];
    const bool delayed = settings_.voltage_delay_samples > 0;
    const double dt = s.t - p.t;
    c.applied_d = delayed ? p.u_d : s.u_d;
    c.applied_q = delayed ? p.u_q : s.u_q;
    if (delayed && std::isfinite(p.theta_e) && std::isfinite(s.theta_e)) {
      const double miss = wrappedAngle(p.theta_e + p.omega_e * dt - s.theta_e);
      const Vec2 applied = rotate({p.u_d, p.u_q}, miss);
      c.applied_d = applied.x;
      c.applied_q = applied.y;
    }
    if (settings_.declared_voltage_angle != 0.0) {  // a declared angle prediction beyond the delay's own
      const Vec2 turned = rotate({c.applied_d, c.applied_q}, settings_.declared_voltage_angle * s.omega_e * nominal_period_);
      c.applied_d = turned.x;
      c.applied_q = turned.y;
    }
    c.applied_prev_d = p.applied_d;
    c.applied_prev_q = p.applied_q;
    const double h = 0.5 * dt;
    c.I_d = p.I_d + h * (p.i_d + s.i_d);
    c.I_q = p.I_q + h * (p.i_q + s.i_q);
    heat_ += h * (p.i_d * p.i_d + p.i_q * p.i_q + s.i_d * s.i_d + s.i_q * s.i_q);
    if (std::isfinite(p.theta_e) && std::isfinite(s.theta_e)) {
      // With the logged angle, omega_e dt is the angle's increment (below half the sampling rate
      // in electrical frequency): what filters and quantises the logged speed does not enter. The
      // logged speed is checked against it instead (loggedSpeedToAngleRatio).
      double dtheta = s.theta_e - p.theta_e;
      if (dtheta > M_PI) dtheta -= 2.0 * M_PI;
      else if (dtheta < -M_PI) dtheta += 2.0 * M_PI;
      const double g = 0.5 * dtheta;
      c.OmIq = p.OmIq + g * (p.i_q + s.i_q);
      c.OmId = p.OmId + g * (p.i_d + s.i_d);
      c.Om = p.Om + dtheta;
      if (settings_.angle_quantum > 0)  // weighed per nominal period (a sample's own dt jitters in its last bits)
        count_lock_.add(dtheta, settings_.angle_quantum, nominal_period_, forgetting_time_constant_,
                        settings_.slow_time_constant, s.i_d);
      const double mean_speed = 0.5 * (p.omega_e + s.omega_e);
      pending_speed_travel_ += std::abs(mean_speed) * dt;
      pending_angle_travel_ += mean_speed >= 0 ? dtheta : -dtheta;
    } else {
      c.OmIq = p.OmIq + h * (p.omega_e * p.i_q + s.omega_e * s.i_q);
      c.OmId = p.OmId + h * (p.omega_e * p.i_d + s.omega_e * s.i_d);
      c.Om = p.Om + h * (p.omega_e + s.omega_e);
    }
    if (settings_.stationary_hold) {
      const HeldVectorIntegral held = heldVectorIntegral(p.omega_e, dt);
      c.U_d = p.U_d + held.S * p.applied_d + held.C * p.applied_q;
      c.U_q = p.U_q + held.S * p.applied_q - held.C * p.applied_d;
    } else {
      c.U_d = p.U_d + dt * p.applied_d;  // zero-order hold over [t_j, t_j+1) in the rotor frame
      c.U_q = p.U_q + dt * p.applied_q;
    }
    // The inverter shape's observer (observePeriod): where it runs, its path gives the shapes'
    // integrals and what the chords of the currents miss (the held vector's bend included).
    ObservedPeriod observed;
    if (shapeObserverActive() && std::isfinite(p.theta_e) && std::isfinite(s.theta_e)) {
      // The rotor's speed within the period, for the forward observer's back EMF: the counted
      // angle's increment. An encoder's period holds a whole number of counts (8 or 9 of 3.07 mrad
      // on the robot joint at 600 rpm: up to 12 % off, 0.15 V of back EMF), so with a quantum the
      // increment over the last kObserverRatePeriods periods (doc/algorithm.md section 8). Only the
      // forward observer reads it.
      const std::size_t back =
          smoothing_samples_ > 0 && observerFollowsForward() ? std::min<std::size_t>(kObserverRatePeriods, count_) : 1;
      const Cumulative& from = ring_[wrap(head_ + count_ - back)];
      const double span = c.t - from.t;
      const double rotor_rate = span > 0 && std::isfinite(from.theta_e) ? (c.Om - from.Om) / span : (c.Om - p.Om) / dt;
      observed = observePeriod(p, s, dt, c.Om - p.Om, Phasor{c.cos_theta, c.sin_theta}, rotor_rate);
    } else {
      observer_i_d_ = s.i_d;
      observer_i_q_ = s.i_q;
    }
    // The rotor angle at mid-period, as a phasor advanced from the previous sample's.
    const Phasor mid = std::isfinite(p.theta_e) ? advance({p.cos_theta, p.sin_theta}, p.theta_e, 0.5 * dt * p.omega_e)
                                                : Phasor{};
    std::array<double, 3> mid_bend{};  // the phase currents' departure from the chord at mid-period
    if (observed.valid) {
      const double omega = (c.Om - p.Om) / dt;
      c.I_d += observed.missed_d;
      c.I_q += observed.missed_q;
      c.OmId += omega * observed.missed_d;
      c.OmIq += omega * observed.missed_q;
      c.phase = observed.phase;
    } else if (settings_.stationary_hold && hold_L_d_ > 0 && hold_L_q_ > 0) {
      // The held vector bends the currents within the period (holdBend), with the inductances of the
      // data's last exact fit; on the robot joint at 300 rpm and 20 kHz, R_s times the missed 7 mA of
      // i_d read as L_q 1 % high.
      const HoldBend bend = holdBend(dt, p.omega_e, p.applied_d, p.applied_q, hold_L_d_, hold_L_q_);
      c.I_d += bend.missed_d;
      c.I_q += bend.missed_q;
      c.OmId += p.omega_e * bend.missed_d;
      c.OmIq += p.omega_e * bend.missed_q;
      // Where a phase current crosses zero, the inverter error's shape follows the bent current (on
      // the robot joint a 10 mA bend across a +-0.5 A crossing was the largest misfit left).
      if (std::isfinite(p.theta_e)) mid_bend = phaseFromDq(bend.mid_d, bend.mid_q, mid);
    }
    c.I_cos = p.I_cos + h * (p.cos_theta + c.cos_theta);
    c.I_sin = p.I_sin + h * (p.sin_theta + c.sin_theta);
    if (settings_.sensor_gains) {
      c.I_P = p.I_P + h * (p.P + c.P);
      c.I_Q = p.I_Q + h * (p.Q + c.Q);
      const double period_angle = c.Om - p.Om;  // omega_e dt of this period (from the angle when logged)
      c.W_P = p.W_P + 0.5 * period_angle * (p.P + c.P);
      c.W_Q = p.W_Q + 0.5 * period_angle * (p.Q + c.Q);
    }
    {  // the period's turn omega_e dt times T_s and the acting voltage (estimated, or the declaration's check)
      const double turn = (c.Om - p.Om) * nominal_period_;
      c.A_d = p.A_d + turn * p.applied_q;
      c.A_q = p.A_q + turn * p.applied_d;
    }
    // The delay's check: the step of the acting voltage, a coefficient a meaning "acts a samples later".
    // With no delay declared the step back (u_k - u_k-1: a = 1 is the voltage one period late); with a
    // delay declared the step forward to the voltage of the period's end, which is known without
    // looking ahead (the next logged voltage: a = -1 is exactly the voltage one period earlier, the
    // log of the applied voltage that a declared delay misreads; the step back reached only
    // -0.3 +- 0.09 there, an extrapolation the controller's noisy references do not follow).
    if (settings_.voltage_delay_samples > 0) {
      c.Ustep_d = p.Ustep_d + dt * (c.applied_d - p.applied_d);
      c.Ustep_q = p.Ustep_q + dt * (c.applied_q - p.applied_q);
    } else {
      c.Ustep_d = p.Ustep_d + dt * (p.applied_d - p.applied_prev_d);
      c.Ustep_q = p.Ustep_q + dt * (p.applied_q - p.applied_prev_q);
    }
    double inv_d = 0.0, inv_q = 0.0;
    const double width = settings_.inverter_zero_crossing_current;
    std::array<double, 2> wide_integral{};
    const bool both = !observed.valid && settings_.inverter_wide_shape && width > 0;  // one pass for the two shapes
    if (observed.valid) {
      inv_d = observed.narrow_d;
      inv_q = observed.narrow_q;
    } else {
      inverterShapeIntegral(p, c, s, dt, width, mid_bend, mid, inv_d, inv_q, both ? &wide_integral : nullptr);
      if (edgeModelSet() && std::isfinite(p.theta_e) && std::isfinite(s.theta_e)) {  // the narrow shape edge by edge
        const Vec2 v = edgeShapeIntegral(p, p.phase, c.phase, dt, mid, mid_bend);
        inv_d = v.x;
        inv_q = v.y;
      }
    }
    c.Inv_d = p.Inv_d + inv_d;
    c.Inv_q = p.Inv_q + inv_q;
    // The dead-time part of the error follows the bus voltage of the period (logged at its start):
    // V_bus (v_dc / v_ref - 1) times the same shape integral.
    c.Bus_d = p.Bus_d + p.bus_ratio * inv_d;
    c.Bus_q = p.Bus_q + p.bus_ratio * inv_q;
    // The same with twice the width (a sharp sign change: a width of 2 % of the current): the
    // second shape of the mix the zero-crossing shape is fitted as (nobody logs the true width).
    if (settings_.inverter_wide_shape) {
      const double wide = wideShapeWidth(width, c.i_d, c.i_q);
      if (observed.valid) {
        inv_d = observed.wide_d;
        inv_q = observed.wide_q;
      } else if (both) {
        inv_d = wide_integral[0];
        inv_q = wide_integral[1];
      } else {
        inverterShapeIntegral(p, c, s, dt, wide, mid_bend, mid, inv_d, inv_q);
      }
      c.Wide_d = p.Wide_d + inv_d;
      c.Wide_q = p.Wide_q + inv_q;
    }
  } else {
    // First sample of a stretch: with a declared delay the voltage acting now is unknown; the
    // commanded one stands in for the first period only (one period in a block of M).
    observer_i_d_ = s.i_d;  // the shape's observer starts from the measured currents
    observer_i_q_ = s.i_q;
    c.applied_d = c.applied_prev_d = s.u_d;
    c.applied_q = c.applied_prev_q = s.u_q;
  }
  c.heat = heat_;
  // The rotation's centred mean (angle_smoothing_samples): the entry m samples back has its m
  // successors now; a stretch's first entries take the widest centred window they have.
  c.Om_mean = c.Om;
  const int m = smoothing_samples_;
  if (m > 0 && stretch_samples_ >= static_cast<std::uint64_t>(m)) {
    const int h = static_cast<int>(std::min<std::uint64_t>(m, stretch_samples_ - m));
    double sum = 0.0;
    for (int back = m - h; back <= m + h; ++back) sum += ring_[wrap(head_ + count_ - back)].Om;
    ring_[wrap(head_ + count_ - m)].Om_mean = sum / (2 * h + 1);
  }
  ++stretch_samples_;
  if (count_ == cap) head_ = wrap(head_ + 1);  // the oldest was dropped
  else ++count_;
  if (count_ < cap) return false;

  // The block: its start M + m periods back, its end m periods back (the newest with no smoothing).
  const Cumulative& a = ring_[head_];
  const Cumulative& e = ring_[wrap(head_ + static_cast<std::size_t>(block_samples_))];
  BlockD zd;
  BlockQ zq;
  zd << e.i_d - a.i_d, e.I_d - a.I_d, e.OmIq - a.OmIq, e.U_d - a.U_d, e.Inv_d - a.Inv_d, e.Ustep_d - a.Ustep_d,
      e.Wide_d - a.Wide_d, e.Bus_d - a.Bus_d, e.i_q - a.i_q, e.OmId - a.OmId, e.Om_mean - a.Om_mean, e.A_d - a.A_d, 0.0, 0.0;
  zq << e.i_q - a.i_q, e.I_q - a.I_q, e.OmId - a.OmId, e.U_q - a.U_q, e.Om_mean - a.Om_mean, e.Inv_q - a.Inv_q,
      e.Ustep_q - a.Ustep_q, e.Wide_q - a.Wide_q, e.Bus_q - a.Bus_q, e.i_d - a.i_d, e.OmIq - a.OmIq, e.A_q - a.A_q, 0.0, 0.0;
  constexpr int kComputedD = kBlockSizeD - kRateEntries, kComputedQ = kBlockSizeQ - kRateEntries;
  // Forgetting: every stored sum is implicitly multiplied by lambda; new terms enter with scale_.
  scale_ /= lambda_;
  // The blocks' weighted mean time and copper-loss clock (the slow window's snapshots are at them).
  fast_block_weight_ = lambda_ * fast_block_weight_ + 1.0;
  fast_time_sum_ = lambda_ * fast_time_sum_ + 0.5 * (a.t + e.t);
  fast_heat_sum_ = lambda_ * fast_heat_sum_ + 0.5 * (a.heat + e.heat);
  rankOneUpper<kBlockSizeD, kComputedD>(S_d_, zd, scale_);
  rankOneUpper<kBlockSizeQ, kComputedQ>(S_q_, zq, scale_);
  stored_weight_ += scale_;
  OffsetBlock zn = OffsetBlock::Zero();
  if (settings_.sensor_offsets) {
    zn(kDeltaCos) = e.cos_theta - a.cos_theta;
    zn(kDeltaSin) = e.sin_theta - a.sin_theta;
    zn(kIntegralCos) = e.I_cos - a.I_cos;
    zn(kIntegralSin) = e.I_sin - a.I_sin;
    if (settings_.sensor_gains) {
      zn(kDeltaP) = e.P - a.P;
      zn(kDeltaQ) = e.Q - a.Q;
      zn(kIntegralP) = e.I_P - a.I_P;
      zn(kIntegralQ) = e.I_Q - a.I_Q;
      zn(kIntegralOmegaP) = e.W_P - a.W_P;
      zn(kIntegralOmegaQ) = e.W_Q - a.W_Q;
    }
    rankOneUpper(N_, zn, scale_);  // its upper triangle: offsetPseudoInverse reads no other
    rankOne<kBlockSizeD, kOffsetBlockSize, kComputedD>(C_d_, zd, zn, scale_);
    rankOne<kBlockSizeQ, kOffsetBlockSize, kComputedQ>(C_q_, zq, zn, scale_);
  }
  // The noise level needs the mean square of consecutive-block differences, not every one of
  // them: every fourth difference is an unbiased sample and costs a quarter.
  if (have_previous_block_ && (blocks_ & 3u) == 0) {
    const BlockD dd = zd - last_d_;
    const BlockQ dq = zq - last_q_;
    rankOneUpper<kBlockSizeD, kComputedD>(dS_d_, dd, scale_);
    rankOneUpper<kBlockSizeQ, kComputedQ>(dS_q_, dq, scale_);
    stored_difference_weight_ += scale_;
  }
  weight_ = stored_weight_ / scale_;
  difference_weight_ = stored_difference_weight_ / scale_;
  last_d_ = zd;
  last_q_ = zq;
  have_previous_block_ = true;
  ++blocks_;
  if (scale_ > 1e150) rescale();
  projection_stale_ = true;
  // The folded sums follow the sums they are folded from: with the sensor terms, the projection
  // (refreshed once per block length for the swarm), else every block's sums.
  if (!settings_.sensor_offsets) folded_sums_stale_ = true;
  // Every M-th block of a stretch: consecutive non-overlapping blocks, and the long window keeps
  // their differences. Differencing removes what varies slowly (a drifting R_s or psi_f would
  // otherwise bias a constant-parameter fit over seconds) and keeps the steps. The differences of
  // blocks long_difference_spacing apart join them: a step then enters through every pair that
  // straddles it. A block takes part in up to four differences, so each difference counts half
  // (the noise of the pairs that share a block is correlated; half keeps the information at or
  // below what the differences hold).
  if (++blocks_since_long_block_ == static_cast<std::uint64_t>(block_samples_)) {
    blocks_since_long_block_ = 0;
    const double share = long_spacing_blocks_ > 0 ? 0.5 : 1.0;
    const auto addDifference = [&](const BlockD& dd, const BlockQ& dq, const OffsetBlock& dn) {
      long_d_.noalias() += share * dd * dd.transpose();
      long_q_.noalias() += share * dq * dq.transpose();
      if (settings_.sensor_offsets) {
        long_N_.noalias() += share * dn * dn.transpose();
        long_C_d_.noalias() += share * dd * dn.transpose();
        long_C_q_.noalias() += share * dq * dn.transpose();
      }
    };
    // The slow window: the fitness window's mean products (every block, overlapping, with its
    // offset terms) averaged once more over slow_time_constant; the M blocks since the last
    // update count as M blocks. (Non-overlapping blocks alone would hold a tenth of the noise
    // averaging; each block added at every sample would cost a rank-one update per sample.)
    // Each snapshot's blocks count as of their weighted mean time t_n and copper-loss clock Q_n:
    // their rate entries are (t_n - t_ref) times their int i entries, t_ref the newest snapshot's
    // t_n, their heat entries (Q_n - Q_ref) times them. Moving t_ref by D takes D times the int i
    // entry off the rate entry (z' = T z, T = I - D e_rate e_I': every product T M T', every cross
    // T C), and Q_ref the same; the new snapshot then enters with both entries 0. slowWindow()
    // moves the reference on to the newest block's end.
    if (stored_weight_ > 0) {
      const double t_n = fast_time_sum_ / fast_block_weight_, Q_n = fast_heat_sum_ / fast_block_weight_;
      double D = std::isfinite(slow_time_) ? t_n - slow_time_ : 0.0;
      if (!(D >= 0.0)) {  // the clock went back: the snapshots' times are unknown, the window starts again
        resetSlowWindow();
        D = 0.0;
      }
      const double DQ = std::isfinite(slow_time_) ? Q_n - slow_heat_ : 0.0;
      moveSlowReference(slow_d_, slow_q_, slow_C_d_, slow_C_q_, D, DQ);
      slow_time_ = t_n;
      slow_heat_ = Q_n;
      slow_ahead_time_ = e.t - t_n;
      slow_ahead_heat_ = e.heat - Q_n;
      const double n = static_cast<double>(block_samples_);
      const double k = n / stored_weight_;
      slow_d_ = slow_lambda_ * slow_d_ + k * ProductD(S_d_.selfadjointView<Eigen::Upper>());
      slow_q_ = slow_lambda_ * slow_q_ + k * ProductQ(S_q_.selfadjointView<Eigen::Upper>());
      if (settings_.sensor_offsets) {
        slow_N_ = slow_lambda_ * slow_N_ + k * N_;
        slow_C_d_ = slow_lambda_ * slow_C_d_ + k * C_d_;
        slow_C_q_ = slow_lambda_ * slow_C_q_ + k * C_q_;
      }
      slow_weight_ = slow_lambda_ * slow_weight_ + n;
    }
    if (have_long_block_) {
      long_d_ *= long_lambda_;
      long_q_ *= long_lambda_;
      if (settings_.sensor_offsets) {
        long_N_ *= long_lambda_;
        long_C_d_ *= long_lambda_;
        long_C_q_ *= long_lambda_;
      }
      long_weight_ = long_lambda_ * long_weight_ + 1.0;
      addDifference(zd - long_last_d_, zq - long_last_q_, zn - long_last_n_);
      if (long_spacing_blocks_ > 0 && long_history_.size() == static_cast<std::size_t>(long_spacing_blocks_)) {
        const LongBlock& old = long_history_[long_history_head_];
        addDifference(zd - old.d, zq - old.q, zn - old.n);
      }
    }
    if (long_spacing_blocks_ > 0) {
      if (long_history_.size() < static_cast<std::size_t>(long_spacing_blocks_)) {
        long_history_.push_back({zd, zq, zn});
      } else {
        long_history_[long_history_head_] = {zd, zq, zn};
        long_history_head_ = (long_history_head_ + 1) % long_history_.size();
      }
    }
    long_last_d_ = zd;
    long_last_q_ = zq;
    long_last_n_ = zn;
    speed_travel_ = long_lambda_ * speed_travel_ + pending_speed_travel_;
    angle_travel_ = long_lambda_ * angle_travel_ + pending_angle_travel_;
    pending_speed_travel_ = pending_angle_travel_ = 0.0;
    have_long_block_ = true;
  }
  // Keep the running integrals small: rebase on the oldest entry once per block length (exact).
  if (++blocks_since_rebase_ == cap) {
    blocks_since_rebase_ = 0;
    const Cumulative base = ring_[head_];
    for (Cumulative& r : ring_) {
      r.I_d -= base.I_d; r.I_q -= base.I_q; r.OmIq -= base.OmIq; r.OmId -= base.OmId;
      r.U_d -= base.U_d; r.U_q -= base.U_q; r.Om -= base.Om; r.Om_mean -= base.Om; r.Ustep_d -= base.Ustep_d;
      r.Ustep_q -= base.Ustep_q; r.Inv_d -= base.Inv_d; r.Inv_q -= base.Inv_q;
      r.Wide_d -= base.Wide_d; r.Wide_q -= base.Wide_q; r.Bus_d -= base.Bus_d; r.Bus_q -= base.Bus_q;
      r.I_cos -= base.I_cos; r.I_sin -= base.I_sin;
      r.I_P -= base.I_P; r.I_Q -= base.I_Q; r.W_P -= base.W_P; r.W_Q -= base.W_Q;
      r.A_d -= base.A_d; r.A_q -= base.A_q;
    }
  }
  return true;
}

void BlockStatistics::rescale() {
  const double k = 1.0 / scale_;
  S_d_ *= k;
  S_q_ *= k;
  dS_d_ *= k;
  dS_q_ *= k;
  stored_weight_ *= k;
  stored_difference_weight_ *= k;
  N_ *= k;
  C_d_ *= k;
  C_q_ *= k;
  scale_ = 1.0;
}

namespace {
// Pseudo-inverse of the offset entries' sums (positive semidefinite; singular at standstill or
// without the angle), equilibrated by their diagonal.
template <int K>
Eigen::Matrix<double, K, K> pseudoInverseOf(const Eigen::Matrix<double, K, K>& N) {
  using Vector = Eigen::Matrix<double, K, 1>;
  using Matrix = Eigen::Matrix<double, K, K>;
  Vector scale;
  for (int i = 0; i < K; ++i) scale(i) = N(i, i) > 0 ? 1.0 / std::sqrt(N(i, i)) : 0.0;
  const Matrix scaled = scale.asDiagonal() * N * scale.asDiagonal();
  // Where every eigenvalue is above the cut (1e-3 of the largest) the pseudo-inverse is the inverse:
  // an LDLT solve, accepted when the 1-norm condition number from the inverse itself, an upper
  // bound of lambda_max / lambda_min, is below 1e3. (The eigen-decomposition below was a fifth of a
  // real-drive sample's cost: the swarm's fitness reads the projection every sample.)
  bool all_scaled = true;
  for (int i = 0; i < K; ++i) all_scaled = all_scaled && scale(i) > 0;
  if (all_scaled) {
    const Eigen::LDLT<Matrix> ldlt(scaled);
    if (ldlt.info() == Eigen::Success && ldlt.isPositive()) {
      const Matrix inverse = ldlt.solve(Matrix::Identity());
      const double condition = scaled.cwiseAbs().colwise().sum().maxCoeff() * inverse.cwiseAbs().colwise().sum().maxCoeff();
      if (std::isfinite(condition) && condition < 1e3)
        return scale.asDiagonal() * (0.5 * (inverse + inverse.transpose())) * scale.asDiagonal();
    }
  }
  const Eigen::SelfAdjointEigenSolver<Matrix> eig(scaled);
  const Vector values = eig.eigenvalues();
  const double largest = values.maxCoeff();
  Vector inverse = Vector::Zero();
  for (int i = 0; i < K; ++i)
    if (largest > 0 && values(i) > 1e-3 * largest) inverse(i) = 1.0 / values(i);
  const Matrix pinv = eig.eigenvectors() * inverse.asDiagonal() * eig.eigenvectors().transpose();
  return scale.asDiagonal() * pinv * scale.asDiagonal();
}
// Offsets only: the four offset entries (the gain entries are zero), at a fraction of the cost.
OffsetProduct offsetPseudoInverse(const OffsetProduct& N_upper, bool gains) {
  const OffsetProduct N = N_upper.selfadjointView<Eigen::Upper>();  // the sample sums keep the upper triangle
  if (gains) return pseudoInverseOf<kOffsetBlockSize>(N);
  OffsetProduct out = OffsetProduct::Zero();
  out.topLeftCorner<kDeltaP, kDeltaP>() = pseudoInverseOf<kDeltaP>(N.topLeftCorner<kDeltaP, kDeltaP>());
  return out;
}
// S - C N^+ C^T: the sums of an axis with its offset terms fitted out (a Schur complement).
template <class Product, class Cross>
Product projectOffsets(const Product& S_full, const Cross& C, const OffsetProduct& N_pinv) {
  const Cross CN = C.lazyProduct(N_pinv);  // fixed-size lazy products: no packing for a general product
  Product P = S_full - CN.lazyProduct(C.transpose());
  // What the offsets explain almost entirely (a window of a few blocks) leaves rounding noise:
  // below 1e-10 of the unprojected entries' scale it is zero, not information.
  for (int j = 0; j < P.cols(); ++j)
    for (int i = 0; i < P.rows(); ++i)
      if (std::abs(P(i, j)) <= 1e-10 * std::sqrt(S_full(i, i) * S_full(j, j))) P(i, j) = 0.0;
  return P;
}
}  // namespace

void BlockStatistics::updateOffsetProjection() const {
  const OffsetProduct pinv = offsetPseudoInverse(N_, settings_.sensor_gains);
  P_d_ = projectOffsets(ProductD(S_d_.selfadjointView<Eigen::Upper>()), C_d_, pinv);
  P_q_ = projectOffsets(ProductQ(S_q_.selfadjointView<Eigen::Upper>()), C_q_, pinv);
  projection_stale_ = false;
  projected_blocks_ = blocks_;
  projected_weight_ = stored_weight_;
  folded_sums_stale_ = true;
}

WindowSums BlockStatistics::window() const {
  WindowSums w;
  w.mean_d = meanProductD();
  w.mean_q = meanProductQ();
  w.mean_difference_d = meanDifferenceProductD();
  w.mean_difference_q = meanDifferenceProductQ();
  w.weight = weight_;
  w.has_differences = difference_weight_ > 0;
  w.block_duration = blockDuration();
  w.block_samples = block_samples_;
  return w;
}

WindowSums BlockStatistics::searchedWindow() const {
  WindowSums w;
  if (weight_ <= 0 || crossSaturationSet()) return w;
  const auto [d, q] = fitnessSums();
  const double weight = fitnessWeight();
  if (!(weight > 0)) return w;
  w.mean_d = ProductD(d.selfadjointView<Eigen::Upper>()) / weight;
  w.mean_q = ProductQ(q.selfadjointView<Eigen::Upper>()) / weight;
  w.weight = weight_;
  w.block_duration = blockDuration();
  w.block_samples = block_samples_;
  return w;
}

WindowSums BlockStatistics::windowOf(const ProductD& d, const ProductQ& q, const OffsetProduct& N, const OffsetCrossD& C_d,
                                     const OffsetCrossQ& C_q, double weight) const {
  WindowSums w;
  if (weight <= 0) return w;
  if (settings_.sensor_offsets) {
    const OffsetProduct pinv = offsetPseudoInverse(N, settings_.sensor_gains);
    w.mean_d = projectOffsets(d, C_d, pinv) / weight;
    w.mean_q = projectOffsets(q, C_q, pinv) / weight;
  } else {
    w.mean_d = d / weight;
    w.mean_q = q / weight;
  }
  w.weight = weight;
  w.block_duration = blockDuration();
  w.block_samples = block_samples_;
  return w;
}

WindowSums BlockStatistics::longWindow() const {
  return windowOf(long_d_, long_q_, long_N_, long_C_d_, long_C_q_, long_weight_);
}

void BlockStatistics::moveSlowReference(ProductD& d, ProductQ& q, OffsetCrossD& C_d, OffsetCrossQ& C_q, double by_time,
                                        double by_heat) const {
  const auto shift = [&](double by, int d_entry, int q_entry) {
    if (by == 0.0) return;
    const auto move = [by](auto& M, int entry, int integral) {
      M.row(entry) -= by * M.row(integral);
      M.col(entry) -= by * M.col(integral);
    };
    move(d, d_entry, kIntegralId);
    move(q, q_entry, kIntegralIq);
    if (settings_.sensor_offsets) {
      C_d.row(d_entry) -= by * C_d.row(kIntegralId);
      C_q.row(q_entry) -= by * C_q.row(kIntegralIq);
    }
  };
  shift(by_time, kIntegralIdRate, kIntegralIqRate);
  shift(by_heat, kIntegralIdHeat, kIntegralIqHeat);
}

WindowSums BlockStatistics::slowWindow() const {
  ProductD d = slow_d_;
  ProductQ q = slow_q_;
  OffsetCrossD C_d = slow_C_d_;
  OffsetCrossQ C_q = slow_C_q_;
  moveSlowReference(d, q, C_d, C_q, slow_ahead_time_, slow_ahead_heat_);
  return windowOf(d, q, slow_N_, C_d, C_q, slow_weight_);
}

ProductD BlockStatistics::meanProductD() const {
  if (stored_weight_ <= 0) return ProductD::Zero();
  if (settings_.sensor_offsets) {
    refreshProjection();
    return P_d_ / stored_weight_;
  }
  return ProductD(S_d_.selfadjointView<Eigen::Upper>()) / stored_weight_;
}
ProductQ BlockStatistics::meanProductQ() const {
  if (stored_weight_ <= 0) return ProductQ::Zero();
  if (settings_.sensor_offsets) {
    refreshProjection();
    return P_q_ / stored_weight_;
  }
  return ProductQ(S_q_.selfadjointView<Eigen::Upper>()) / stored_weight_;
}
ProductD BlockStatistics::meanDifferenceProductD() const {
  if (stored_difference_weight_ <= 0) return ProductD::Zero();
  return ProductD(dS_d_.selfadjointView<Eigen::Upper>()) / stored_difference_weight_;
}
ProductQ BlockStatistics::meanDifferenceProductQ() const {
  if (stored_difference_weight_ <= 0) return ProductQ::Zero();
  return ProductQ(dS_q_.selfadjointView<Eigen::Upper>()) / stored_difference_weight_;
}

double BlockStatistics::crossLinearisationCurrent() const {
  const double w = S_d_(kIntegralOmegaInD, kIntegralOmegaInD);  // upper triangle: row <= column
  return w > 0 ? S_d_(kIntegralOmegaIq, kIntegralOmegaInD) / w : 0.0;
}

// The point-by-point form inlined into the loop (flatten): one call for a whole swarm iteration.
[[gnu::flatten]] void BlockStatistics::fitness(const ParameterVector* p, std::size_t n, double* out) const {
  for (std::size_t i = 0; i < n; ++i) out[i] = fitness(p[i]);
}

[[gnu::flatten]] void BlockStatistics::fitnessWithCrossSaturation(const ParameterVector* p, std::size_t n,
                                                                   double* out) const {
  for (std::size_t i = 0; i < n; ++i) out[i] = fitnessWithCrossSaturation(p[i]);
}

void BlockStatistics::updateFoldedSums(const ProductD& d, const ProductQ& q) const {
  // z' = T z with the voltage entry U' = U + sum_m k_m A_m: T S T^T changes only the voltage
  // entry's row and column (upper triangles read; the result full).
  const InverterMix mix = inverterMix();
  const auto fold = [](const auto& S, auto& out, int U, const std::array<std::pair<int, double>, 4>& terms) {
    out = S.template selfadjointView<Eigen::Upper>();
    double UU = out(U, U);
    for (const auto& [A, k] : terms) UU += 2.0 * k * out(U, A);
    for (const auto& [A, k] : terms)
      for (const auto& [B, l] : terms) UU += k * l * out(A, B);
    for (int j = 0; j < out.cols(); ++j) {
      if (j == U) continue;
      double row = out(U, j);
      for (const auto& [A, k] : terms) row += k * out(A, j);
      out(U, j) = out(j, U) = row;
    }
    out(U, U) = UU;
  };
  fold(d, folded_d_, kIntegralUd,
       {{{kIntegralAngleUqInD, -voltage_angle_}, {kIntegralInverterD, -mix.narrow}, {kIntegralInverterWideD, -mix.wide},
         {kIntegralInverterBusD, -mix.bus}}});
  fold(q, folded_q_, kIntegralUq,
       {{{kIntegralAngleUdInQ, voltage_angle_}, {kIntegralInverterQ, -mix.narrow}, {kIntegralInverterWideQ, -mix.wide},
         {kIntegralInverterBusQ, -mix.bus}}});
  folded_sums_stale_ = false;
}

double BlockStatistics::fitnessWithCrossSaturation(const ParameterVector& p) const {
  if (weight_ <= 0) return std::numeric_limits<double>::infinity();
  // psi_q(0, i_q) and psi_d(0, i_q) linear in i_q about i_bar, where L_q and psi_f are the secant and
  // the flux (LinearBlockModel::withCrossSaturation); the q residual divided by L_qq.
  const double inv_Ld = 1.0 / p[kLd], inv_Lq = 1.0 / cross_L_qq_, Ldq = cross_L_dq_, Lqq = cross_L_qq_;
  const double i_bar = crossLinearisationCurrent();
  // (The known inverter error and voltage angle are folded into the voltage entries: fitnessSums().)
  // r_d = [L_dd Di_d + L_dq (Di_q - int omega i_d) + R int i_d - L_qq int omega i_q
  //        - i_bar (L_q - L_qq) int omega - int u_d] / L_dd
  // r_q = [L_qq Di_q + L_dq (Di_d + int omega i_q) + R int i_q + L_dd int omega i_d
  //        + (psi - i_bar L_dq) int omega - int u_q] / L_qq
  std::array<double, kBlockSizeD> wd{};
  std::array<double, kBlockSizeQ> wq{};
  wd[kDeltaId] = 1.0;
  wd[kIntegralId] = p[kRs] * inv_Ld;
  wd[kIntegralOmegaIq] = -Lqq * inv_Ld;
  wd[kIntegralOmegaInD] = -i_bar * (p[kLq] - Lqq) * inv_Ld;
  wd[kIntegralUd] = -inv_Ld;
  wd[kDeltaIqInD] = Ldq * inv_Ld;
  wd[kIntegralOmegaIdInD] = -Ldq * inv_Ld;
  wq[kDeltaIq] = 1.0;
  wq[kIntegralIq] = p[kRs] * inv_Lq;
  wq[kIntegralOmegaId] = p[kLd] * inv_Lq;
  wq[kIntegralUq] = -inv_Lq;
  wq[kIntegralOmega] = (p[kPsiF] - i_bar * Ldq) * inv_Lq;
  wq[kDeltaIdInQ] = Ldq * inv_Lq;
  wq[kIntegralOmegaIqInQ] = Ldq * inv_Lq;
  const auto [Sd, Sq] = fitnessSums();
  const double f = upperForm<kBlockSizeQ>(Sq, wq.data(), upperForm<kBlockSizeD>(Sd, wd.data(), 0.0));
  return std::max(0.0, 2.0 * f / fitnessWeight());
}

}  // namespace pmsm_param_id
