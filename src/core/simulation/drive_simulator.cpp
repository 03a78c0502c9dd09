#include "pmsm_param_id/simulation/drive_simulator.hpp"

#include "pmsm_param_id/model/frames.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>
#include <utility>
#include <vector>

namespace pmsm_param_id {

DriveSimulator::DriveSimulator(const Scenario& scenario) : scenario_(scenario), rng_(scenario.seed) {
  winding_temperature_ = magnet_temperature_ = scenario_.thermal.ambient_temperature;
  const MotorParameters& m = scenario_.motor;
  const double Ts = scenario_.drive.sample_period;
  sample_count_ = static_cast<std::uint64_t>(std::floor(scenario_.duration / Ts + 1e-9));
  // Current loops: PI zero cancels the R/L pole, crossover at the requested bandwidth.
  const double wc = 2.0 * M_PI * scenario_.drive.current_loop_bandwidth_hz;
  kp_d_ = wc * m.L_d;
  kp_q_ = wc * m.L_q;
  ki_current_ = wc * m.R_s;
  // Speed loop: J dw/dt = k_t i_q; crossover ws, integral zero at ws/4.
  const double ws = 2.0 * M_PI * scenario_.drive.speed_loop_bandwidth_hz;
  const double k_t = 1.5 * m.pole_pairs * m.psi_f;
  kp_speed_ = m.inertia * ws / k_t;
  ki_speed_ = kp_speed_ * ws / 4.0;
}

bool DriveSimulator::done() const { return k_ >= sample_count_; }

double DriveSimulator::voltageLimit() const { return scenario_.drive.dc_bus_voltage / std::sqrt(3.0); }

MotorParameters DriveSimulator::trueMotorAt(double t) const {
  MotorParameters m = scenario_.motor;
  m.R_s *= scenario_.R_s_scale(t);
  m.psi_f *= scenario_.psi_f_scale(t);
  m.L_d *= scenario_.L_d_scale(t);
  m.L_q *= scenario_.L_q_scale(t);
  const ThermalModelSettings& th = scenario_.thermal;
  if (th.enabled) {  // the temperatures of the present sample
    m.R_s *= 1.0 + th.copper_coefficient * (winding_temperature_ - th.reference_temperature);
    m.psi_f *= 1.0 + th.magnet_coefficient * (magnet_temperature_ - th.reference_temperature);
  }
  return m;
}

double DriveSimulator::measure(double true_current) {
  double v = true_current;
  if (scenario_.sensors.current_noise_sigma > 0) v += scenario_.sensors.current_noise_sigma * noise_(rng_);
  if (scenario_.sensors.adc_bits > 0) {
    const double range = scenario_.sensors.adc_range;
    const double lsb = 2.0 * range / std::ldexp(1.0, scenario_.sensors.adc_bits);
    v = std::clamp(std::round(v / lsb) * lsb, -range, range);
  }
  return v;
}


double DriveSimulator::busVoltage(double t) const {
  const InverterSettings& inv = scenario_.inverter;
  return scenario_.drive.dc_bus_voltage * (1.0 + inv.dc_ripple * std::sin(2.0 * M_PI * inv.dc_ripple_frequency * t));
}

SimulatedSample DriveSimulator::step() {
  const Scenario& s = scenario_;
  const double Ts = s.drive.sample_period;
  const double t = static_cast<double>(k_) * Ts;
  const MotorParameters nominal = s.motor;
  const MotorParameters plant = trueMotorAt(t);
  const int p = nominal.pole_pairs;

  // Torque control: a load machine holds the speed on its profile (a dyno); the speed loop is idle.
  if (s.drive.torque_control) x_.omega_m = s.speed_reference_rpm(t) * 2.0 * M_PI / 60.0;

  SimulatedSample out;
  out.truth = plant.electrical();
  out.magnetics = magneticState(plant, s.saturation, x_.i_d, x_.i_q);
  if (s.saturation.enabled)  // what each estimate stands for at this operating point (doc/simulator.md)
    out.truth = {plant.R_s, out.magnetics.L_dd, out.magnetics.L_q_secant, out.magnetics.psi_d_at_zero_i_d};
  // Behind a bridge with an on-state resistance R_s stands for what the inverter's terminals see:
  // the winding's resistance and the conducting device's, in series with every phase at every instant.
  out.truth[kRs] += s.inverter.device_resistance;
  out.i_d_true = x_.i_d;
  out.i_q_true = x_.i_q;

  // Angle and speed as the controller sees them: exact, or an incremental encoder (4 counts per
  // line) with the speed from filtered position differences.
  double theta_e_measured = x_.theta_e, omega_m_measured = x_.omega_m;
  if (s.sensors.encoder_lines > 0) {
    const double counts_per_rad = 4.0 * s.sensors.encoder_lines / (2.0 * M_PI);
    const double theta_m = std::floor(x_.theta_e / p * counts_per_rad) / counts_per_rad + 0.5 / counts_per_rad;
    if (k_ == 0) encoder_previous_ = theta_m;
    const int window = s.sensors.speed_window_periods;
    if (window > 0) {  // count difference over the window (the first samples: over what there is)
      if (encoder_history_.empty()) encoder_history_.assign(static_cast<std::size_t>(window), theta_m);
      const std::size_t slot = static_cast<std::size_t>(k_ % static_cast<std::uint64_t>(window));
      const double periods = static_cast<double>(std::min<std::uint64_t>(k_, static_cast<std::uint64_t>(window)));
      speed_estimate_ = periods > 0 ? (theta_m - encoder_history_[slot]) / (periods * Ts) : 0.0;
      encoder_history_[slot] = theta_m;
    } else {
      const double alpha = 1.0 - std::exp(-2.0 * M_PI * s.sensors.speed_filter_hz * Ts);
      speed_estimate_ += alpha * ((theta_m - encoder_previous_) / Ts - speed_estimate_);
    }
    encoder_previous_ = theta_m;
    theta_e_measured = p * theta_m;
    omega_m_measured = speed_estimate_;
  }
  const double omega_e = p * omega_m_measured;

  // Currents: errors on d and q, or on the phase currents (gain, offset, noise, ADC), then the
  // Park transform with the measured angle, as the drive computes them.
  double i_d = 0, i_q = 0;
  if (s.sensors.phase_currents) {
    const std::array<double, 3> abc = phaseFromDq(x_.i_d, x_.i_q, x_.theta_e);
    std::array<double, 3> m{};
    for (int k = 0; k < 3; ++k)
      m[static_cast<std::size_t>(k)] = measure(s.sensors.phase_gain[static_cast<std::size_t>(k)] * abc[static_cast<std::size_t>(k)] +
                                               s.sensors.phase_offset[static_cast<std::size_t>(k)]);
    const Vec2 dq = rotate(clarke(m[0], m[1], m[2]), -theta_e_measured);
    i_d = dq.x;
    i_q = dq.y;
  } else {
    const Vec2 dq = rotate(rotate({x_.i_d, x_.i_q}, x_.theta_e), -theta_e_measured);  // exact angle: identity
    i_d = measure(dq.x);
    i_q = measure(dq.y);
  }

  // Speed loop -> i_q reference, limited so that |i_ref| <= max_current (conditional integration).
  const double i_d_ref = s.d_current_injection(t);
  const double i_q_limit = std::sqrt(std::max(0.0, s.drive.max_current * s.drive.max_current - i_d_ref * i_d_ref));
  const double speed_error = s.speed_reference_rpm(t) * 2.0 * M_PI / 60.0 - omega_m_measured;
  double i_q_ref = kp_speed_ * speed_error + speed_integral_ + ki_speed_ * Ts * speed_error;
  if (s.drive.torque_control) {
    i_q_ref = std::clamp(s.q_current_reference(t), -i_q_limit, i_q_limit);
  } else if (std::abs(i_q_ref) < i_q_limit) {
    speed_integral_ += ki_speed_ * Ts * speed_error;
  } else {
    i_q_ref = std::copysign(i_q_limit, i_q_ref);
  }

  // Current loops with decoupling feed-forward from the nominal (controller's) parameters.
  const double e_d = i_d_ref - i_d, e_q = i_q_ref - i_q;
  const double ff_d = -omega_e * nominal.L_q * i_q;
  const double ff_q = omega_e * (nominal.L_d * i_d + nominal.psi_f);
  double u_d = kp_d_ * e_d + d_integral_ + ki_current_ * Ts * e_d + ff_d;
  double u_q = kp_q_ * e_q + q_integral_ + ki_current_ * Ts * e_q + ff_q;
  const double v_dc = busVoltage(t);
  const double limit = v_dc / std::sqrt(3.0);
  const double magnitude = std::hypot(u_d, u_q);
  if (magnitude > limit) {
    u_d *= limit / magnitude;
    u_q *= limit / magnitude;
    out.voltage_limited = true;  // anti-windup: hold both integrators
  } else {
    d_integral_ += ki_current_ * Ts * e_d;
    q_integral_ += ki_current_ * Ts * e_q;
  }

  // The log holds what a drive logs: the reference voltage, measured currents, speed and angle.
  out.sample = Sample{t, u_d, u_q, i_d, i_q, omega_e};
  out.sample.theta_e = wrappedAngle(theta_e_measured);
  out.sample.v_dc = v_dc;  // the drive measures its bus (for the modulator); logged as it is
  out.i_d_reference = i_d_ref;
  out.i_q_reference = i_q_ref;
  out.load_torque = s.load_torque(t);

  // Actuation. The reference computed now acts from now on, or one period later; it is turned into
  // the stator frame at the predicted angle theta_k + k_p omega_e T_s (measured angle and speed) and
  // held there (stationary hold, and always by the PWM) or in the rotor frame.
  const InverterSettings& inv = s.inverter;
  const double k_p = inv.anglePrediction();
  Vec2 reference{u_d, u_q};
  double conversion_angle = theta_e_measured + k_p * omega_e * Ts;
  if (inv.computation_delay > 0) {
    const Vec2 computed = reference;
    const double computed_angle = conversion_angle;
    reference = k_ == 0 ? Vec2{0.0, 0.0} : Vec2{pending_u_d_, pending_u_q_};  // nothing before the first
    conversion_angle = k_ == 0 ? theta_e_measured : pending_angle_;
    pending_u_d_ = computed.x;
    pending_u_q_ = computed.y;
    pending_angle_ = computed_angle;
  }
  const Vec2 stator = rotate(reference, conversion_angle);
  if (inv.log_applied_voltage) {
    // The log holds the vector acting over [t_k, t_k+1) in the rotor frame at the drive's own
    // mid-period angle (the rotor-frame hold: at the period's start).
    const Vec2 logged = rotate(stator, -(theta_e_measured + (inv.stationary_hold ? 0.5 * omega_e * Ts : 0.0)));
    out.sample.u_d = logged.x;
    out.sample.u_q = logged.y;
  }
  const double v_err = inv.errorVoltage(v_dc, Ts);
  const double i0 = inv.zero_crossing_current;
  const double theta_start = x_.theta_e;

  // Switching level: each leg's duty from the stator vector with the min-max zero sequence (SVPWM),
  // centre-aligned (high around mid-period, the carrier's valley at the period's ends); the switch
  // that turns on waits the dead time, during which the leg's voltage follows the sign of the
  // actual phase current. A dead time reaching past the period's end is cut there.
  enum LegState : int { kLow = 0, kHigh = 1, kDead = 2 };
  struct Leg {
    bool switching = false, high = false;
    double rise = 0, rise_end = 0, fall = 0, fall_end = 0;  // [s] from the period's start
    LegState at(double tau) const {
      if (!switching) return high ? kHigh : kLow;
      if (tau < rise) return kLow;
      if (tau < fall) return tau < rise_end ? kDead : kHigh;
      return tau < fall_end ? kDead : kLow;
    }
  };
  std::array<Leg, 3> legs{};
  // The period's ends and at most four switching instants per leg (no allocation per sample).
  std::array<double, 14> breaks{};
  std::size_t break_count = 0;
  breaks[break_count++] = 0.0;
  breaks[break_count++] = Ts;
  if (inv.switching) {
    const std::array<double, 3> v = inverseClarke(stator);
    const double zero_sequence = -0.5 * (std::max({v[0], v[1], v[2]}) + std::min({v[0], v[1], v[2]}));
    for (std::size_t k = 0; k < 3; ++k) {
      const double duty = std::clamp(0.5 + (v[k] + zero_sequence) / v_dc, 0.0, 1.0);
      Leg& leg = legs[k];
      leg.high = duty >= 1.0;
      leg.switching = duty > 0.0 && duty < 1.0;
      if (!leg.switching) continue;
      leg.rise = 0.5 * (1.0 - duty) * Ts;
      leg.fall = 0.5 * (1.0 + duty) * Ts;
      leg.rise_end = leg.rise + inv.dead_time;
      leg.fall_end = std::min(Ts, leg.fall + inv.dead_time);
      for (double b : {leg.rise, leg.rise_end, leg.fall, leg.fall_end})
        if (b > 0.0 && b < Ts) breaks[break_count++] = b;
    }
    std::sort(breaks.begin(), breaks.begin() + static_cast<std::ptrdiff_t>(break_count));
    break_count = static_cast<std::size_t>(std::unique(breaks.begin(), breaks.begin() + static_cast<std::ptrdiff_t>(break_count)) -
                                           breaks.begin());
  }
  std::array<LegState, 3> legs_now{kLow, kLow, kLow};  // the legs' states in the segment being integrated
  // Within a dead time: each dead leg's freewheeling diode (high: the upper one, for a negative
  // current), and the pole voltage of a leg whose current has been driven to zero and is held there
  // (NaN: none; doc/simulator.md "switching-level PWM").
  std::array<bool, 3> dead_high{};
  std::array<double, 3> pinned_pole{NAN, NAN, NAN};
  const double v_on = inv.device_drop;
  const double r_on = inv.device_resistance;
  // The rotor-frame hold's vector is the same all period (its angle is the period's start).
  const Vec2 held_at_start = rotate(stator, -theta_start);
  // Applied d-q voltage for a plant state inside the period; `park` = e^{-j theta_e} of that state
  // (computed once per stage: the stage's every rotation shares it).
  const auto applied = [&](const PlantState& x, Phasor park) -> Vec2 {
    if (inv.switching) {
      const std::array<double, 3> i = phaseFromDq(x.i_d, x.i_q, x.theta_e);
      std::array<double, 3> pole{};
      for (std::size_t k = 0; k < 3; ++k) {
        const double sgn = i[k] > 0 ? 1.0 : (i[k] < 0 ? -1.0 : 0.0);
        LegState st = legs_now[k];
        if (st == kDead && std::isfinite(pinned_pole[k])) {  // no current: no diode conducts, no drop
          pole[k] = pinned_pole[k];
          continue;
        }
        if (st == kDead) st = dead_high[k] ? kHigh : kLow;  // the diode that carries the current
        pole[k] = (st == kHigh ? v_dc : 0.0) - v_on * sgn - r_on * i[k];
      }
      return rotate(clarke(pole[0], pole[1], pole[2]), park);  // the zero sequence drops out
    }
    Vec2 u = inv.stationary_hold ? rotate(stator, park) : held_at_start;
    if (v_err > 0) {  // dead time and device drops: each pole voltage loses v_err against its current
      const std::array<double, 3> abc = phaseFromDq(x.i_d, x.i_q, x.theta_e);
      const Vec2 e = rotate(clarke(std::tanh(abc[0] / i0), std::tanh(abc[1] / i0), std::tanh(abc[2] / i0)), park);
      u.x -= v_err * e.x;
      u.y -= v_err * e.y;
    }
    u.x -= r_on * x.i_d;  // the devices' on-state resistance, in series with every phase
    u.y -= r_on * x.i_q;
    return u;
  };
  // The period's integration steps: integration_substeps equal ones, and with the switching model
  // each segment between switching instants in steps no longer than those.
  const int n = s.drive.integration_substeps;
  const double h_max = Ts / n;

  // Plant over [t, t + Ts]: classical RK4 with the applied voltage evaluated at every stage.
  // The period's mean applied voltage and the held vector's (what an inverter without error applies),
  // by the RK4 weights of the stage values: the same quadrature as the plant's.
  double applied_d = 0.0, applied_q = 0.0;
  Vec2 ideal{0.0, 0.0};
  Vec2 stage_u[4], stage_ideal[4];
  int stage = 0;
  // (A Park rotation only where a stage needs one: the rotor-frame hold without switching needs none.)
  const bool stage_rotates = inv.switching || inv.stationary_hold || v_err > 0;
  const auto voltageAt = [&](const PlantState& x) {
    const Phasor park = stage_rotates ? phasorOf(-x.theta_e) : Phasor{1.0, 0.0};
    const Vec2 u = applied(x, park);
    stage_u[stage] = u;
    stage_ideal[stage] = inv.stationary_hold ? rotate(stator, park) : held_at_start;
    stage = (stage + 1) & 3;
    return u;
  };
  const auto accumulate = [&](double h) {
    const double w = h / (6.0 * Ts);
    applied_d += w * (stage_u[0].x + 2 * stage_u[1].x + 2 * stage_u[2].x + stage_u[3].x);
    applied_q += w * (stage_u[0].y + 2 * stage_u[1].y + 2 * stage_u[2].y + stage_u[3].y);
    ideal.x += w * (stage_ideal[0].x + 2 * stage_ideal[1].x + 2 * stage_ideal[2].x + stage_ideal[3].x);
    ideal.y += w * (stage_ideal[0].y + 2 * stage_ideal[1].y + 2 * stage_ideal[2].y + stage_ideal[3].y);
  };
  // forEachStep(f, save, load, phases): f(h) for each step in order, with legs_now set to the legs'
  // states in it; save() and load() keep and restore the plant's state, phases() its phase currents.
  // In a dead time each dead leg's diode is the one its current's sign at the segment's start
  // chooses. A current that the diode's voltage drives through zero is located (linear
  // interpolation over the step, then integrated up to it); there the other diode takes over,
  // unless its voltage drives the current back: then neither conducts, the current stays at zero
  // and the pole floats to the voltage that holds it there (found from the current's slope with
  // the pole low and high, by two probing steps), until the switch turns on.
  const auto steps = [&](const auto& f, double length) {
    const int m = std::max(1, static_cast<int>(std::ceil(length / h_max - 1e-9)));
    for (int j = 0; j < m; ++j) f(length / m);
  };
  const auto forEachStep = [&](const auto& f, const auto& save, const auto& load, const auto& phases) {
    for (std::size_t b = 0; b + 1 < break_count; ++b) {
      const double length = breaks[b + 1] - breaks[b];
      if (!(length > 0)) continue;
      const double mid = 0.5 * (breaks[b] + breaks[b + 1]);
      legs_now = {legs[0].at(mid), legs[1].at(mid), legs[2].at(mid)};
      if (legs_now[0] != kDead && legs_now[1] != kDead && legs_now[2] != kDead) {
        steps(f, length);
        continue;
      }
      pinned_pole.fill(std::numeric_limits<double>::quiet_NaN());
      const std::array<double, 3> i_start = phases();
      for (std::size_t k = 0; k < 3; ++k) dead_high[k] = i_start[k] < 0;
      // The plant's state with the period's sums so far: a step taken past a crossing is taken back whole.
      const auto keep = [&] { return std::make_tuple(save(), applied_d, applied_q, ideal); };
      const auto restore = [&](const auto& kept) {
        load(std::get<0>(kept));
        applied_d = std::get<1>(kept), applied_q = std::get<2>(kept), ideal = std::get<3>(kept);
      };
      double done = 0.0;
      for (int event = 0; event < 8 && done < length; ++event) {
        const double rest = length - done;
        const auto at_start = keep();
        const std::array<double, 3> ia = phases();
        steps(f, rest);
        const std::array<double, 3> ib = phases();
        double first = 2.0;  // the earliest crossing, as a share of the rest
        std::size_t leg = 3;
        for (std::size_t k = 0; k < 3; ++k) {
          if (legs_now[k] != kDead || std::isfinite(pinned_pole[k])) continue;
          if (dead_high[k] ? !(ib[k] > 0) : !(ib[k] < 0)) continue;
          const double share = ia[k] == ib[k] ? 0.0 : std::clamp(ia[k] / (ia[k] - ib[k]), 0.0, 1.0);
          if (share < first) first = share, leg = k;
        }
        if (leg == 3) break;  // no crossing: the rest is done
        restore(at_start);
        if (first * rest > 0) steps(f, first * rest);
        done += first * rest;
        // At zero: the current's slope with the pole low and with it high (held, as no diode conducts).
        const double probe = 1e-3 * std::max(rest, 1e-9);
        double slope[2];
        const auto at_zero = keep();
        for (int high = 0; high < 2; ++high) {
          pinned_pole[leg] = high ? v_dc : 0.0;
          const double before = phases()[leg];
          f(probe);
          slope[high] = (phases()[leg] - before) / probe;
          restore(at_zero);
        }
        pinned_pole[leg] = std::numeric_limits<double>::quiet_NaN();
        // It crossed from the old diode's sign; the other diode keeps it going unless its slope turns it back.
        const bool now_negative = !dead_high[leg];  // was low (positive current), now below zero
        const double s_new = slope[now_negative ? 1 : 0];
        if ((now_negative && s_new > 0) || (!now_negative && s_new < 0)) {
          const double s_lo = slope[0], s_hi = slope[1];
          pinned_pole[leg] = s_hi != s_lo ? std::clamp(-s_lo / (s_hi - s_lo), 0.0, 1.0) * v_dc : 0.5 * v_dc;
        } else {
          dead_high[leg] = now_negative;
        }
      }
      pinned_pole.fill(std::numeric_limits<double>::quiet_NaN());
    }
  };
  if (s.saturation.enabled) {
    // Saturating magnetics: the flux linkages are the state (the currents follow from them at each
    // stage, model/magnetics.hpp). A period starts from the flux of the present currents, so a step
    // of a parameter profile keeps the currents continuous.
    struct State {
      double psi_d, psi_q, omega_m, theta_e;
    };
    double i_d_guess = x_.i_d, i_q_guess = x_.i_q;
    const auto derivative = [&](const State& y) {
      currentsFromFlux(plant, s.saturation, y.psi_d, y.psi_q, i_d_guess, i_q_guess);
      const Vec2 u = voltageAt(PlantState{i_d_guess, i_q_guess, y.omega_m, y.theta_e});
      FluxDerivative d = saturatedPlantDerivative(plant, y.psi_d, y.psi_q, i_d_guess, i_q_guess, y.omega_m, u.x, u.y,
                                                  out.load_torque);
      if (s.drive.torque_control) d.domega_m = 0.0;  // held by the load machine
      return d;
    };
    const auto add = [](const State& a, const FluxDerivative& d, double k) {
      return State{a.psi_d + k * d.dpsi_d, a.psi_q + k * d.dpsi_q, a.omega_m + k * d.domega_m, a.theta_e + k * d.dtheta_e};
    };
    const MagneticState start = magneticState(plant, s.saturation, x_.i_d, x_.i_q);
    State y{start.psi_d, start.psi_q, x_.omega_m, x_.theta_e};
    forEachStep([&](const double h) {
      const FluxDerivative k1 = derivative(y);
      const FluxDerivative k2 = derivative(add(y, k1, h / 2));
      const FluxDerivative k3 = derivative(add(y, k2, h / 2));
      const FluxDerivative k4 = derivative(add(y, k3, h));
      accumulate(h);
      y.psi_d += h / 6 * (k1.dpsi_d + 2 * k2.dpsi_d + 2 * k3.dpsi_d + k4.dpsi_d);
      y.psi_q += h / 6 * (k1.dpsi_q + 2 * k2.dpsi_q + 2 * k3.dpsi_q + k4.dpsi_q);
      y.omega_m += h / 6 * (k1.domega_m + 2 * k2.domega_m + 2 * k3.domega_m + k4.domega_m);
      y.theta_e += h / 6 * (k1.dtheta_e + 2 * k2.dtheta_e + 2 * k3.dtheta_e + k4.dtheta_e);
      currentsFromFlux(plant, s.saturation, y.psi_d, y.psi_q, x_.i_d, x_.i_q);
      x_.omega_m = y.omega_m;
      x_.theta_e = y.theta_e;
    }, [&] { return std::make_pair(y, x_); }, [&](const std::pair<State, PlantState>& z) { y = z.first, x_ = z.second; },
       [&] { return phaseFromDq(x_.i_d, x_.i_q, x_.theta_e); });
  } else {
    const auto derivative = [&](const PlantState& x) {
      const Vec2 u = voltageAt(x);
      PlantDerivative d = plantDerivative(plant, x, u.x, u.y, out.load_torque);
      if (s.drive.torque_control) d.domega_m = 0.0;  // held by the load machine
      return d;
    };
    const auto add = [](const PlantState& a, const PlantDerivative& d, double k) {
      return PlantState{a.i_d + k * d.di_d, a.i_q + k * d.di_q, a.omega_m + k * d.domega_m, a.theta_e + k * d.dtheta_e};
    };
    forEachStep([&](const double h) {
      const PlantDerivative k1 = derivative(x_);
      const PlantDerivative k2 = derivative(add(x_, k1, h / 2));
      const PlantDerivative k3 = derivative(add(x_, k2, h / 2));
      const PlantDerivative k4 = derivative(add(x_, k3, h));
      accumulate(h);
      x_.i_d += h / 6 * (k1.di_d + 2 * k2.di_d + 2 * k3.di_d + k4.di_d);
      x_.i_q += h / 6 * (k1.di_q + 2 * k2.di_q + 2 * k3.di_q + k4.di_q);
      x_.omega_m += h / 6 * (k1.domega_m + 2 * k2.domega_m + 2 * k3.domega_m + k4.domega_m);
      x_.theta_e += h / 6 * (k1.dtheta_e + 2 * k2.dtheta_e + 2 * k3.dtheta_e + k4.dtheta_e);
    }, [&] { return x_; }, [&](const PlantState& z) { x_ = z; }, [&] { return phaseFromDq(x_.i_d, x_.i_q, x_.theta_e); });
  }
  out.u_d_applied = applied_d;
  out.u_q_applied = applied_q;
  out.u_d_ideal = ideal.x;
  out.u_q_ideal = ideal.y;
  out.inverter_error_voltage = inv.switching ? v_dc * inv.dead_time / Ts + v_on : v_err;
  const ThermalModelSettings& th = s.thermal;
  if (th.enabled) {  // explicit Euler over the period: thermal time constants are seconds to minutes
    out.winding_temperature = winding_temperature_;
    out.magnet_temperature = magnet_temperature_;
    const double copper_loss = 1.5 * plant.R_s * (x_.i_d * x_.i_d + x_.i_q * x_.i_q);
    const double magnet_loss = th.magnet_loss_coefficient * x_.omega_m * x_.omega_m;
    const double to_magnet = (winding_temperature_ - magnet_temperature_) / th.winding_to_magnet;
    const double dTw = (copper_loss - (winding_temperature_ - th.ambient_temperature) / th.winding_to_ambient - to_magnet) /
                       th.winding_capacity;
    const double dTm = (magnet_loss + to_magnet - (magnet_temperature_ - th.ambient_temperature) / th.magnet_to_ambient) /
                       th.magnet_capacity;
    winding_temperature_ += Ts * dTw;
    magnet_temperature_ += Ts * dTm;
  }
  ++k_;
  return out;
}

CurrentDifference currentDifference(const std::vector<SimulatedSample>& a, const std::vector<SimulatedSample>& b) {
  double diff = 0.0, norm = 0.0;
  CurrentDifference out;
  for (std::size_t k = 0; k < a.size() && k < b.size(); ++k) {
    const double dd = b[k].i_d_true - a[k].i_d_true, dq = b[k].i_q_true - a[k].i_q_true;
    diff += dd * dd + dq * dq;
    norm += a[k].i_d_true * a[k].i_d_true + a[k].i_q_true * a[k].i_q_true;
    out.largest = std::max(out.largest, std::hypot(dd, dq));
  }
  out.relative_rms = norm > 0 ? std::sqrt(diff / norm) : std::numeric_limits<double>::quiet_NaN();
  return out;
}

}  // namespace pmsm_param_id
