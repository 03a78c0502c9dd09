#include "pmsm_param_id/identification/inverter_edges.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace pmsm_param_id {

namespace {
/// E[max(0, X - a)] for X ~ N(mu, sigma^2) (sigma > 0).
double hinge(double mu, double sigma, double a) {
  const double z = (mu - a) / sigma;
  return (mu - a) * 0.5 * std::erfc(-z / std::sqrt(2.0)) + sigma * std::exp(-0.5 * z * z) / std::sqrt(2.0 * M_PI);
}

/// The share of a dead time [0, t_d] that the leg spends low, from the phase current i at its start
/// and its slopes with the leg low and with it high [A/s]: low while the current is positive (the
/// lower diode), high while negative; a current driven to zero by both stays there, the leg
/// chattering at the share that holds it (s_hi / (s_hi - s_lo)). As a function of i this is a ramp
/// from 0 to 1 through at most three knots; with sigma > 0 its mean over i + N(0, sigma^2) (the
/// edge current is known to about the zero-crossing width the data chose).
double lowShare(double i, double s_lo, double s_hi, double t_d, double sigma) {
  double x[3], y[3];
  int n = 0;
  if (s_hi > 0 && s_lo < 0) {  // pinned at zero between the two ramps
    x[0] = -s_hi * t_d, y[0] = 0.0;
    x[1] = 0.0, y[1] = s_hi / (s_hi - s_lo);
    x[2] = -s_lo * t_d, y[2] = 1.0;
    n = 3;
  } else if (s_lo < 0) {  // a positive current falls through zero and stays negative
    x[0] = 0.0, y[0] = 0.0;
    x[1] = -s_lo * t_d, y[1] = 1.0;
    n = 2;
  } else if (s_hi > 0) {  // a negative current rises through zero and stays positive
    x[0] = -s_hi * t_d, y[0] = 0.0;
    x[1] = 0.0, y[1] = 1.0;
    n = 2;
  } else {  // the sign at the edge holds
    x[0] = 0.0, y[0] = 0.0;
    n = 1;
  }
  if (!(sigma > 0)) {
    if (n == 1) return i > x[0] ? 1.0 : 0.0;
    if (i <= x[0]) return 0.0;
    for (int j = 0; j + 1 < n; ++j)
      if (i <= x[j + 1]) return y[j] + (y[j + 1] - y[j]) * (i - x[j]) / (x[j + 1] - x[j]);
    return 1.0;
  }
  // Six sigma beyond the ramp the mean is its end (to 1e-9): most edges, with no erfc or exp.
  if (i < x[0] - 6.0 * sigma) return 0.0;
  if (i > x[n - 1] + 6.0 * sigma) return 1.0;
  if (n == 1) return 0.5 * std::erfc(-(i - x[0]) / (sigma * std::sqrt(2.0)));
  double share = 0.0;
  for (int j = 0; j + 1 < n; ++j) {
    const double width = x[j + 1] - x[j];
    if (width > 0) share += (y[j + 1] - y[j]) / width * (hinge(i, sigma, x[j]) - hinge(i, sigma, x[j + 1]));
    else share += (y[j + 1] - y[j]) * 0.5 * std::erfc(-(i - x[j]) / (sigma * std::sqrt(2.0)));
  }
  return share;
}

double smoothSign(double x, double width) {
  if (width > 0) return std::tanh(x / width);
  return x > 0 ? 1.0 : (x < 0 ? -1.0 : 0.0);
}

// The phases' rows of the inverse Clarke transform.
constexpr double kRow[3][2] = {{1.0, 0.0}, {-0.5, 0.8660254037844386}, {-0.5, -0.8660254037844386}};

/// Each phase's row of L^-1 in the stator frame at the period's rotor angle (a row of the inverse
/// Clarke transform times L^-1, L = Sigma + Delta [[c2, s2], [s2, -c2]]): phase k's ripple for
/// stator-frame volt-seconds lambda is row[k] . lambda. False where there is no inductance.
bool phaseRows(const InverterEdgePeriod& in, double row[3][2]) {
  const double S = 0.5 * (in.L_d + in.L_q), D = 0.5 * (in.L_d - in.L_q);
  const double c2 = in.rotor.c * in.rotor.c - in.rotor.s * in.rotor.s, s2 = 2.0 * in.rotor.s * in.rotor.c;
  const double det = S * S - D * D;
  if (!(S > 0 && det > 0)) return false;
  const double i00 = (S - D * c2) / det, i01 = -D * s2 / det, i11 = (S + D * c2) / det;
  for (std::size_t k = 0; k < 3; ++k) {
    row[k][0] = kRow[k][0] * i00 + kRow[k][1] * i01;
    row[k][1] = kRow[k][0] * i01 + kRow[k][1] * i11;
  }
  return true;
}
}  // namespace

std::array<double, 3> inverterEdgeShape(const InverterEdgePeriod& in, const std::array<double, 3>& i_start,
                                        const std::array<double, 3>& i_end) {
  const double T = in.period;
  const std::array<double, 3> v = inverseClarke(in.voltage);
  const double v0 = -0.5 * (std::max({v[0], v[1], v[2]}) + std::min({v[0], v[1], v[2]}));
  const bool bus_known = std::isfinite(in.bus_voltage) && in.bus_voltage > 0;
  const double kappa = bus_known ? 1.0 / in.bus_voltage : 0.0;
  const double dead = std::max(0.0, in.dead_volt_seconds);
  const double t_d = bus_known ? dead / in.bus_voltage : 0.0;
  std::array<double, 3> rise{}, fund{};
  std::array<bool, 3> switching{};
  for (std::size_t k = 0; k < 3; ++k) {
    const double duty = 0.5 + (v[k] + v0) * kappa;
    switching[k] = duty > 0.0 && duty < 1.0;
    rise[k] = 0.5 * T * (1.0 - duty);
    fund[k] = (i_end[k] - i_start[k]) / T;
  }
  std::array<double, 3> out{};
  double row[3][2], row_norm[3];
  if (!(T > 0) || !phaseRows(in, row)) {  // no inductance: the sign of the period's mean current
    for (std::size_t k = 0; k < 3; ++k) out[k] = smoothSign(0.5 * (i_start[k] + i_end[k]), in.width);
    return out;
  }
  for (std::size_t k = 0; k < 3; ++k)
    row_norm[k] = std::sqrt(row[k][0] * row[k][0] + row[k][1] * row[k][1]);  // (sqrt, not hypot: finite values)
  const auto ripple = [&](std::size_t k, Vec2 lambda) { return row[k][0] * lambda.x + row[k][1] * lambda.y; };
  // Leg k's slope within a dead time with the legs in `high` and k itself low or high [A/s]; the
  // others' states are taken at the dead time's middle (at a low modulation the three legs switch
  // within a dead time of each other).
  const auto slopes = [&](std::size_t k, std::array<bool, 3> high, Vec2 mean, double& s_lo, double& s_hi) {
    for (int state = 0; state < 2; ++state) {
      high[k] = state == 1;
      const Vec2 u = clarke(high[0] ? in.bus_voltage : 0.0, high[1] ? in.bus_voltage : 0.0, high[2] ? in.bus_voltage : 0.0);
      const double s = fund[k] + ripple(k, {u.x - mean.x, u.y - mean.y});
      (state == 0 ? s_lo : s_hi) = s;
    }
  };
  // Leg k's share of an edge at current i: at a rise the share it loses (low), at a fall the share
  // it gains (high). Beyond `reach` the sign's; within it the dead time's ramp, the other legs high
  // or low by where their own edges fall (`shift(j)`: their dead time's offset at this edge); with
  // no bus voltage the smooth sign.
  const auto edgeShare = [&](std::size_t k, double i, Vec2 mean, double reach_k, bool rising, const auto& shift) {
    if (bus_known && t_d > 0 && std::abs(i) > reach_k) {  // beyond any ramp the dead time can make
      return rising ? (i > 0 ? 1.0 : 0.0) : (i > 0 ? 0.0 : 1.0);
    }
    if (bus_known && t_d > 0) {
      std::array<bool, 3> high{};
      for (std::size_t j = 0; j < 3; ++j)
        high[j] = switching[j] ? (0.5 * T * (v[j] - v[k]) + shift(j) > 0) : (v[j] + v0 > 0);
      double s_lo, s_hi;
      slopes(k, high, mean, s_lo, s_hi);
      const double low = lowShare(i, s_lo, s_hi, t_d, in.width);
      return rising ? low : 1.0 - low;
    }
    return rising ? 0.5 * (1.0 + smoothSign(i, in.width)) : 0.5 * (1.0 - smoothSign(i, in.width));
  };
  // Each edge's share, first guessed from the mean current's sign, then twice from the edges (each
  // pass with the mean vector of the last; on the switching-level 36 mH drive the residual error
  // per period was 0.353, 0.346, 0.341 V after two, three, four passes).
  std::array<double, 3> loss{}, gain{};  // rising edge's share low, falling edge's share high
  for (std::size_t k = 0; k < 3; ++k) {
    const double mean = 0.5 * (i_start[k] + i_end[k]);
    loss[k] = mean > 0 ? 1.0 : 0.0;
    gain[k] = mean < 0 ? 1.0 : 0.0;
  }
  std::array<std::size_t, 3> order{0, 1, 2};  // by falling voltage: the order of the rises
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return v[a] > v[b]; });
  for (int pass = 0; pass < 2; ++pass) {
    // The period's actual mean vector (the ripple is measured from it).
    std::array<double, 3> m{};
    for (std::size_t k = 0; k < 3; ++k) m[k] = switching[k] ? loss[k] - gain[k] : 0.0;
    const Vec2 e = clarke(m[0], m[1], m[2]);
    const Vec2 mean{in.voltage.x - dead / T * e.x, in.voltage.y - dead / T * e.y};
    // How far from zero an edge current can be and still change sign within the dead time: its
    // slope is at most |fund| + |row| (2/3 V_dc + |mean|); six widths beyond that the share is the sign's.
    std::array<double, 3> reach{};
    if (bus_known && t_d > 0) {
      const double volts = 2.0 / 3.0 * in.bus_voltage + std::sqrt(mean.x * mean.x + mean.y * mean.y);
      for (std::size_t k = 0; k < 3; ++k) reach[k] = (std::abs(fund[k]) + row_norm[k] * volts) * t_d + 6.0 * in.width;
    }
    for (std::size_t k : order) {  // rises, earliest first
      if (!switching[k]) continue;
      std::array<double, 3> P{};
      for (std::size_t j = 0; j < 3; ++j)
        if (j != k && switching[j]) P[j] = std::max(0.0, 0.5 * T * (v[j] - v[k]) - dead * loss[j]);
        else if (j != k && v[j] + v0 > 0) P[j] = in.bus_voltage * rise[k];  // a leg held high
      const Vec2 pc = clarke(P[0], P[1], P[2]);
      const double tau = rise[k];
      const double i = i_start[k] + fund[k] * tau + ripple(k, {pc.x - tau * mean.x, pc.y - tau * mean.y});
      loss[k] = edgeShare(k, i, mean, reach[k], true, [&](std::size_t j) { return dead * (0.5 - loss[j]); });
    }
    for (std::size_t k : order) {  // falls, backwards from the period's end: latest first
      if (!switching[k]) continue;
      std::array<double, 3> P{};  // volt-seconds from the fall to the period's end (its own dead time's among them)
      for (std::size_t j = 0; j < 3; ++j)
        if (j == k) P[j] = dead * gain[k];
        else if (switching[j]) P[j] = std::max(0.0, 0.5 * T * (v[j] - v[k]) + dead * gain[j]);
        else if (j != k && v[j] + v0 > 0) P[j] = in.bus_voltage * rise[k];
      const Vec2 pc = clarke(P[0], P[1], P[2]);
      const double to_end = rise[k];  // T_s - tau_f
      const double i = i_end[k] - fund[k] * to_end - ripple(k, {pc.x - to_end * mean.x, pc.y - to_end * mean.y});
      gain[k] = edgeShare(k, i, mean, reach[k], false, [&](std::size_t j) { return dead * (gain[j] - 0.5); });
    }
  }
  for (std::size_t k = 0; k < 3; ++k) out[k] = switching[k] ? loss[k] - gain[k] : 0.0;
  return out;
}

std::array<double, 3> inverterEdgeReplay(const InverterEdgePeriod& in, const std::array<double, 3>& i_start,
                                         const std::array<double, 3>& i_end, std::array<double, 3>* moments,
                                         InverterEdgeForward* forward) {
  if (moments) *moments = {};
  if (forward) forward->i_end.fill(std::numeric_limits<double>::quiet_NaN());  // until replayed
  const double T = in.period, V = in.bus_voltage;
  const double t_d = std::isfinite(V) && V > 0 ? std::max(0.0, in.dead_volt_seconds) / V : 0.0;
  double row[3][2];
  if (!(t_d > 0 && T > 0) || !phaseRows(in, row)) return inverterEdgeShape(in, i_start, i_end);
  const std::array<double, 3> v = inverseClarke(in.voltage);
  const double v0 = -0.5 * (std::max({v[0], v[1], v[2]}) + std::min({v[0], v[1], v[2]}));
  std::array<double, 3> rise{}, fall{}, fund{};
  std::array<int, 3> fixed{};
  std::array<double, 14> breaks{};
  std::size_t nb = 0;
  breaks[nb++] = 0.0;
  breaks[nb++] = T;
  for (std::size_t k = 0; k < 3; ++k) {
    const double duty = 0.5 + (v[k] + v0) / V;
    fund[k] = forward ? 0.0 : (i_end[k] - i_start[k]) / T;
    if (!(duty > 0.0 && duty < 1.0)) {
      fixed[k] = duty >= 1.0 ? 1 : 0;
      continue;
    }
    fixed[k] = -1;
    rise[k] = 0.5 * T * (1.0 - duty);
    fall[k] = T - rise[k];
    for (double b : {rise[k], rise[k] + t_d, fall[k], fall[k] + t_d})
      if (b > 0.0 && b < T) breaks[nb++] = b;
  }
  std::sort(breaks.begin(), breaks.begin() + static_cast<std::ptrdiff_t>(nb));
  std::array<double, 3> own{};  // the pole's own coefficient in its phase's slope [A/s per V]
  for (std::size_t k = 0; k < 3; ++k) {
    std::array<double, 3> e{};
    e[k] = 1.0;
    const Vec2 u = clarke(e[0], e[1], e[2]);
    own[k] = row[k][0] * u.x + row[k][1] * u.y;
  }
  std::array<double, 3> out{};
  for (std::size_t k = 0; k < 3; ++k) {
    const double mean = 0.5 * (i_start[k] + i_end[k]);
    out[k] = fixed[k] >= 0 ? 0.0 : (mean > 0 ? 1.0 : -1.0);
  }
  const double dead_volts = in.dead_volt_seconds / T;
  if (!forward) {
    // Where no phase current can reach zero within the period, each leg loses (positive current) or
    // gains its whole dead time at one edge, which is what the replay would find: its currents' signs,
    // and the loss's moment at that edge. Then the replay is skipped (on the 36 mH industrial drive
    // most periods; on the robot joint none). The path leaves the chord between the ends by at most
    // |row_k| min(t, T - t) |u - v_mean| (it closes at both ends) plus the bend, and
    // |u - v_mean| <= 2/3 V_dc + |v| + 4/3 dead_volts (the legs' vector, the commanded one, the losses).
    // (sqrt, not hypot: finite values, and this runs every period)
    const double volts =
        2.0 / 3.0 * V + std::sqrt(in.voltage.x * in.voltage.x + in.voltage.y * in.voltage.y) + 4.0 / 3.0 * dead_volts;
    std::array<double, 3> at_edge{};
    bool clear = true;
    for (std::size_t k = 0; k < 3 && clear; ++k) {
      if (fixed[k] >= 0) continue;
      const double row_norm = std::sqrt(row[k][0] * row[k][0] + row[k][1] * row[k][1]);
      const double reach = 0.5 * T * row_norm * volts + std::abs(in.mid_bend[k]);
      clear = i_start[k] * i_end[k] > 0 && std::min(std::abs(i_start[k]), std::abs(i_end[k])) > reach &&
              fall[k] + t_d < T;
      at_edge[k] = i_start[k] > 0 ? rise[k] + 0.5 * t_d - 0.5 * T : rise[k] - 0.5 * t_d - 0.5 * T;
    }
    if (clear) {
      if (moments) *moments = at_edge;
      return out;
    }
  }
  const auto replay = [&](Vec2 mean0) {
    Vec2 mean = mean0;
    std::array<double, 3> i = i_start, volt_seconds{}, moment{}, integral{};
    std::array<bool, 3> pinned{};
    double bend_at = 0.0;  // the bend's share of the slope at the step's middle: 4 (1 - 2 t / T) / T
    const double R = forward ? forward->resistance : 0.0;
    const auto slopesAt = [&](const std::array<double, 3>& p, const std::array<double, 3>& at, std::array<double, 3>& s) {
      Vec2 u = clarke(p[0], p[1], p[2]);
      if (R > 0) {
        const Vec2 di = clarke(at[0] - forward->drift_current[0], at[1] - forward->drift_current[1],
                               at[2] - forward->drift_current[2]);
        u = {u.x - R * di.x, u.y - R * di.y};
      }
      for (std::size_t k = 0; k < 3; ++k)
        s[k] = fund[k] + bend_at * in.mid_bend[k] + row[k][0] * (u.x - mean.x) + row[k][1] * (u.y - mean.y);
    };
    const auto slopesFor = [&](const std::array<double, 3>& p, std::array<double, 3>& s) { slopesAt(p, i, s); };
    for (std::size_t b = 0; b + 1 < nb; ++b) {
      double t = breaks[b];
      const double t1 = breaks[b + 1];
      if (!(t1 > t)) continue;
      const double middle = 0.5 * (t + t1);
      std::array<int, 3> state{};
      for (std::size_t k = 0; k < 3; ++k) {
        if (fixed[k] >= 0) state[k] = fixed[k];
        else if (middle < rise[k]) state[k] = 0;
        else if (middle < rise[k] + t_d) state[k] = 2;
        else if (middle < fall[k]) state[k] = 1;
        else if (middle < fall[k] + t_d) state[k] = 2;
        else state[k] = 0;
        if (state[k] != 2) pinned[k] = false;
      }
      for (int guard = 0; guard < 8 && t < t1; ++guard) {
        bend_at = forward ? 0.0 : 4.0 * (1.0 - (t + t1) / T) / T;
        if (forward) {
          const double from_mid = 0.5 * (t + t1) - 0.5 * T;
          mean = {mean0.x + from_mid * forward->drift_rate.x, mean0.y + from_mid * forward->drift_rate.y};
        }
        std::array<double, 3> pole{};
        for (std::size_t k = 0; k < 3; ++k)
          pole[k] = state[k] == 2 ? (pinned[k] ? 0.5 * V : (i[k] > 0 ? 0.0 : V)) : (state[k] == 1 ? V : 0.0);
        std::array<double, 3> slope{};
        for (std::size_t k = 0; k < 3; ++k) {
          if (state[k] != 2 || pinned[k] || i[k] != 0.0) continue;
          std::array<double, 3> s_lo{}, s_hi{};
          pole[k] = 0.0;
          slopesFor(pole, s_lo);
          pole[k] = V;
          slopesFor(pole, s_hi);
          if (s_lo[k] > 0) pole[k] = 0.0, i[k] = 1e-15;
          else if (s_hi[k] < 0) i[k] = -1e-15;
          else pinned[k] = true, pole[k] = 0.5 * V;
        }
        slopesFor(pole, slope);
        for (std::size_t k = 0; k < 3; ++k)
          if (state[k] == 2 && pinned[k] && own[k] != 0) {
            pole[k] = std::clamp(pole[k] - slope[k] / own[k], 0.0, V);
            slopesFor(pole, slope);
          }
        double step = t1 - t;
        std::size_t crossing = 3;
        const auto findCrossing = [&]() {
          step = t1 - t;
          crossing = 3;
          for (std::size_t k = 0; k < 3; ++k) {
            if (state[k] != 2 || pinned[k] || i[k] == 0.0 || i[k] * slope[k] >= 0) continue;
            const double to_zero = -i[k] / slope[k];
            if (to_zero < step) step = to_zero, crossing = k;
          }
        };
        findCrossing();
        if (R > 0) {  // the resistive drop at the step's middle (predictor), the pinned currents held
          std::array<double, 3> half = i;
          for (std::size_t k = 0; k < 3; ++k)
            if (!(state[k] == 2 && pinned[k])) half[k] += 0.5 * step * slope[k];
          slopesAt(pole, half, slope);
          for (std::size_t k = 0; k < 3; ++k)
            if (state[k] == 2 && pinned[k]) slope[k] = 0.0;
          findCrossing();
        }
        for (std::size_t k = 0; k < 3; ++k) {
          integral[k] += (i[k] + 0.5 * slope[k] * step) * step;
          i[k] += slope[k] * step;
          volt_seconds[k] += pole[k] * step;
          moment[k] += pole[k] * step * (t + 0.5 * step - 0.5 * T);
        }
        t += step;
        if (crossing < 3) i[crossing] = 0.0;
      }
    }
    std::array<double, 3> losses{};
    for (std::size_t k = 0; k < 3; ++k)
      losses[k] = fixed[k] >= 0 ? 0.0 : (V * (fall[k] - rise[k]) - volt_seconds[k]) / in.dead_volt_seconds;
    if (moments)  // the ideal pole's moment is zero (high from rise to fall, symmetric about mid-period)
      for (std::size_t k = 0; k < 3; ++k) (*moments)[k] = fixed[k] >= 0 ? 0.0 : -moment[k] / in.dead_volt_seconds;
    if (forward) {
      forward->i_end = i;
      forward->integral = integral;
    }
    return losses;
  };
  // The period's mean vector is the commanded one less the losses' image, and the losses follow
  // from it: a root of r(m) = commanded - dead_volts clarke(replay(m)) - m in two dimensions,
  // piecewise linear in m (the events move linearly with it). Broyden's method from the fixed-point
  // step (its first step); one replay where the first guess holds.
  const auto meanOf = [&](const std::array<double, 3>& losses) {
    const Vec2 e = clarke(losses[0], losses[1], losses[2]);
    return Vec2{in.voltage.x - dead_volts * e.x, in.voltage.y - dead_volts * e.y};
  };
  if (forward) return replay(forward->drift);
  Vec2 m = meanOf(out);
  out = replay(m);
  Vec2 r{meanOf(out).x - m.x, meanOf(out).y - m.y};
  double H[2][2] = {{1.0, 0.0}, {0.0, 1.0}};  // minus the inverse Jacobian of r
  const double tolerance = 1e-7 * dead_volts;
  for (int pass = 1; pass < 40 && std::hypot(r.x, r.y) > tolerance; ++pass) {
    const Vec2 dm{H[0][0] * r.x + H[0][1] * r.y, H[1][0] * r.x + H[1][1] * r.y};
    m = {m.x + dm.x, m.y + dm.y};
    out = replay(m);
    const Vec2 next = meanOf(out);
    const Vec2 r_new{next.x - m.x, next.y - m.y};
    const Vec2 dr{r_new.x - r.x, r_new.y - r.y};
    // Broyden's ("good") update of J^-1, J the Jacobian of r, kept as H = -J^-1:
    // J^-1 += (dm - J^-1 dr) dm^T J^-1 / (dm^T J^-1 dr).
    const double Jdr[2] = {-(H[0][0] * dr.x + H[0][1] * dr.y), -(H[1][0] * dr.x + H[1][1] * dr.y)};
    const double dmJ[2] = {-(dm.x * H[0][0] + dm.y * H[1][0]), -(dm.x * H[0][1] + dm.y * H[1][1])};
    const double denominator = dm.x * Jdr[0] + dm.y * Jdr[1];
    if (std::abs(denominator) > 1e-300) {
      const double u0 = dm.x - Jdr[0], u1 = dm.y - Jdr[1];
      for (int a = 0; a < 2; ++a)
        for (int b = 0; b < 2; ++b) H[a][b] -= (a == 0 ? u0 : u1) * dmJ[b] / denominator;
    }
    r = r_new;
  }
  return out;
}

Vec2 inverterEdgeImage(const std::array<double, 3>& shares, const std::array<double, 3>& moments, double omega_e,
                       Phasor mid) {
  const Vec2 c = clarke(shares[0], shares[1], shares[2]), cm = clarke(moments[0], moments[1], moments[2]);
  return rotate(Vec2{c.x + omega_e * cm.y, c.y - omega_e * cm.x}, conjugate(mid));
}

}  // namespace pmsm_param_id
