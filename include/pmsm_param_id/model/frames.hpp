// Reference-frame transforms shared by the simulator and the identifier (amplitude-invariant).
#pragma once
#include <array>
#include <cmath>

namespace pmsm_param_id {

/// A two-component vector: (alpha, beta) in the stator frame or (d, q) in the rotor frame.
struct Vec2 {
  double x = 0.0, y = 0.0;
};

/// e^{j angle} as its cosine and sine.
struct Phasor {
  double c = 1.0, s = 0.0;
};
inline Phasor phasorOf(double angle) { return {std::cos(angle), std::sin(angle)}; }
/// e^{-j angle} from e^{j angle}.
inline Phasor conjugate(Phasor e) { return {e.c, -e.s}; }

/// e^{j angle} v for the angle's phasor.
inline Vec2 rotate(Vec2 v, Phasor e) { return {e.c * v.x - e.s * v.y, e.s * v.x + e.c * v.y}; }
/// e^{j angle} v: rotor -> stator frame with the electrical angle (Park inverse); -angle: Park.
inline Vec2 rotate(Vec2 v, double angle) { return rotate(v, phasorOf(angle)); }

/// The angle wrapped to [-pi, pi]: std::remainder(angle, 2 pi), which returns an angle already within
/// [-pi, pi] unchanged (exactly); that case, a sample's turn, skips the call (2-4 % of a real drive's
/// sample).
inline double wrappedAngle(double angle) {
  return std::abs(angle) <= M_PI ? angle : std::remainder(angle, 2.0 * M_PI);
}

/// The phasor of angle + delta from that of angle: e^{j delta} by the Taylor series of cos and sin
/// (terms to delta^12; for |delta| <= 0.25 the remainder is below 1e-17, under half an ulp), then
/// the angle-sum identity. One period's turn of the rotor (delta = omega_e T / 2 at mid-period) is
/// small, and a cos/sin call (10-20 ns here) was a fifth of a sample's block update. A larger delta
/// (or NaN) takes cos and sin of angle + delta.
inline Phasor advance(Phasor e, double angle, double delta) {
  if (!(std::abs(delta) <= 0.25)) return phasorOf(angle + delta);
  const double d2 = delta * delta;
  const double sin_delta =
      delta * (1.0 + d2 * (-1.0 / 6 + d2 * (1.0 / 120 + d2 * (-1.0 / 5040 + d2 * (1.0 / 362880 + d2 * (-1.0 / 39916800))))));
  const double cos_delta =
      1.0 + d2 * (-0.5 + d2 * (1.0 / 24 + d2 * (-1.0 / 720 + d2 * (1.0 / 40320 + d2 * (-1.0 / 3628800 + d2 * (1.0 / 479001600))))));
  return {e.c * cos_delta - e.s * sin_delta, e.s * cos_delta + e.c * sin_delta};
}

/// The phasors of a sequence of angles (a logged rotor angle, sample by sample): each advanced from
/// the previous one by the angle's increment (advance()); computed with cos and sin at the first
/// angle, after a turn of more than 0.25 rad (a wrap of the logged angle, a gap, a NaN) and every
/// kExactEvery angles, so that rounding cannot accumulate (2.4e-15 at worst over a million steps of
/// 0.2 rad; 1.4e-11 without the exact ones).
class PhasorTracker {
 public:
  static constexpr int kExactEvery = 64;
  Phasor next(double angle) {
    const double delta = angle - angle_;
    if (steps_ < kExactEvery && std::abs(delta) <= 0.25) {
      phasor_ = advance(phasor_, angle_, delta);
      ++steps_;
    } else {
      phasor_ = phasorOf(angle);
      steps_ = 0;
    }
    angle_ = angle;
    return phasor_;
  }
  /// The next angle's phasor from cos and sin.
  void reset() { steps_ = kExactEvery; }

 private:
  double angle_ = 0.0;
  Phasor phasor_{};
  int steps_ = kExactEvery;
};

/// Amplitude-invariant Clarke transform of three phase quantities (the zero sequence drops out).
inline Vec2 clarke(double a, double b, double c) { return {(2.0 * a - b - c) / 3.0, (b - c) / std::sqrt(3.0)}; }

/// Phase quantities of a stator-frame vector (no zero sequence).
inline std::array<double, 3> inverseClarke(Vec2 v) {
  const double h = std::sqrt(3.0) / 2.0;
  return {v.x, -0.5 * v.x + h * v.y, -0.5 * v.x - h * v.y};
}

/// Phase currents a, b, c from d-q currents and the electrical angle (or its phasor).
inline std::array<double, 3> phaseFromDq(double d, double q, Phasor e) { return inverseClarke(rotate({d, q}, e)); }
inline std::array<double, 3> phaseFromDq(double d, double q, double theta_e) { return phaseFromDq(d, q, phasorOf(theta_e)); }

}  // namespace pmsm_param_id
