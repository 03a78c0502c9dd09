// The inverter's error voltage edge by edge: a centre-aligned PWM leg loses or gains its dead time at
// each of its two commutations by the sign of the phase current *at that edge*, and the current
// there is the sampled one plus the switching ripple, which the period's voltage vector and the
// inductances set (doc/algorithm.md section 8, "switching edges").
//
// With the carrier's valley at the sampling instants (t = 0 and T_s) and the min-max zero sequence,
// leg k rises at tau_r = T_s/2 (1/2 - (v_k + v_0) / V_dc) and falls at T_s - tau_r. Between the
// valley and its rise the legs with a larger voltage are already high, so the ripple of the
// stator-frame current there is L^-1 [ sum_j max(0, (T_s/2)(v_j - v_k) - V_dc t_d loss_j) e_j
// - tau_r v_mean ]: the voltage differences, not V_dc, set it; V_dc enters only through tau_r's
// second-order term and through the current's slope within the dead time itself. The same from the
// period's end backwards gives the current at the falling edge.
#pragma once
#include <array>

#include "pmsm_param_id/model/frames.hpp"

namespace pmsm_param_id {

struct InverterEdgePeriod {
  Vec2 voltage;                   ///< the commanded vector acting over the period, stator frame [V]
  double period = 0.0;            ///< T_s [s]
  double dead_volt_seconds = 0.0; ///< V_dc t_dead = V T_s, what one edge loses or gains [V s]
  double bus_voltage = 0.0;       ///< V_dc [V]; not finite or <= 0: unknown (then the second-order
                                  ///< term of the edge times and the current's slope within the dead time are dropped)
  double L_d = 0.0, L_q = 0.0;    ///< [H]: the ripple's inductances
  Phasor rotor;                   ///< e^{j theta_e} within the period (the salient inductance's angle)
  /// [A]: how well the edge current is known. With the bus voltage, each edge's share is the mean
  /// of its ramp (the current's slope within the dead time) over i + N(0, width^2); without it, the
  /// sign of the edge current as tanh(i / width). 0: exact.
  double width = 0.0;
  /// [A]: each phase current's departure from the chord between the samples at mid-period (the
  /// held vector's bend, a parabola through the period's ends: the back EMF turns within the period
  /// while the stator-frame vector is held). 0: the chord.
  std::array<double, 3> mid_bend{};
};

/// Each leg's mean error over the period in units of the dead time's volt-seconds per period
/// (V T_s / T_s = V): the share of its rising edge's dead time spent low minus the share of its
/// falling edge's spent high, in [-1, 1]; the pole voltage loses V times it. A current of one sign
/// all period gives its sign, as the average model's sign(i_k). i_start, i_end: the phase currents
/// at the period's sampling instants [A]. A leg whose duty saturates (known bus) gives 0.
std::array<double, 3> inverterEdgeShape(const InverterEdgePeriod& period, const std::array<double, 3>& i_start,
                                        const std::array<double, 3>& i_end);

/// The same, replayed: with the bus voltage, the period is followed segment by segment between the
/// legs' switching instants, each phase current moving at its slope (the chord's plus L^-1 times the
/// legs' vector less the period's mean) for the legs' states; a dead leg's diode is the one its
/// current's sign chooses, a current a diode drives to zero within the dead time is taken over by the
/// other diode or, where that one would drive it back, held at zero with its pole floating to the
/// voltage that holds it (one held leg at a time); the period's mean vector, which the slopes are
/// measured from and which the losses move, is solved for by Broyden's method to 1e-7 of the dead
/// time's voltage (one replay where no current comes near zero; at most 40). Exact for currents that
/// follow the chord's slope and the ripple; the width is not used. Without the bus voltage:
/// inverterEdgeShape.
/// The currents follow the chord plus `mid_bend`'s parabola. Where no phase current can reach zero
/// within the period (its ends beyond the ripple's bound), the result follows from the currents'
/// signs and the period is not replayed.
/// `moments` (if given): each leg's lost volt-seconds weighted by their time from mid-period, over
/// V T_s [s]: where a loss falls off the period's middle (one edge of a leg whose current crosses
/// zero) the rotor has turned by omega_e times that, so its rotor-frame image at mid-period takes
/// -j omega_e times the moments' Clarke vector as well.
/// `forward` (if given): the period followed forward from `i_start` alone (no chord, `i_end` unused,
/// never skipped, one pass): the currents move at L^-1 (legs' vector - drift(t) - R (i -
/// drift_current)), drift(t) = drift + (t - T/2) drift_rate, the resistive drop taken at each
/// step's midpoint (a predictor step).
struct InverterEdgeForward {
  Vec2 drift{};       ///< stator frame, mid-period: the voltage that holds the currents still [V]
  Vec2 drift_rate{};  ///< [V/s]: the back EMF's turn
  double resistance = 0.0;                ///< [ohm]
  std::array<double, 3> drift_current{};  ///< the phase currents the drift's R i is taken at [A]
  std::array<double, 3> i_end{};          ///< out: the phase currents at the period's end (NaN: not replayed) [A]
  std::array<double, 3> integral{};       ///< out: each phase current's integral over the period [A s]
};

std::array<double, 3> inverterEdgeReplay(const InverterEdgePeriod& period, const std::array<double, 3>& i_start,
                                         const std::array<double, 3>& i_end, std::array<double, 3>* moments = nullptr,
                                         InverterEdgeForward* forward = nullptr);

/// The legs' mean errors (inverterEdgeReplay's shares, in units of V) as a rotor-frame vector at
/// mid-period (`mid`: the rotor angle's phasor there): their Clarke vector turned into the rotor
/// frame, less j omega_e times the moments' (each loss acts where the rotor has turned by omega_e t).
Vec2 inverterEdgeImage(const std::array<double, 3>& shares, const std::array<double, 3>& moments, double omega_e,
                       Phasor mid);

}  // namespace pmsm_param_id
