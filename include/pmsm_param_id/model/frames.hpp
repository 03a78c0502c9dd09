// Reference-frame transforms shared by the simulator and the identifier (amplitude-invariant).
#pragma once
#include <array>
#include <cmath>

namespace pmsm_param_id {

/// A two-component vector: (alpha, beta) in the stator frame or (d, q) in the rotor frame.
struct Vec2 {
  double x = 0.0, y = 0.0;
};

/// e^{j angle} v: rotor -> stator frame with the electrical angle (Park inverse); -angle: Park.
inline Vec2 rotate(Vec2 v, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  return {c * v.x - s * v.y, s * v.x + c * v.y};
}

/// Amplitude-invariant Clarke transform of three phase quantities (the zero sequence drops out).
inline Vec2 clarke(double a, double b, double c) { return {(2.0 * a - b - c) / 3.0, (b - c) / std::sqrt(3.0)}; }

/// Phase quantities of a stator-frame vector (no zero sequence).
inline std::array<double, 3> inverseClarke(Vec2 v) {
  const double h = std::sqrt(3.0) / 2.0;
  return {v.x, -0.5 * v.x + h * v.y, -0.5 * v.x - h * v.y};
}

/// Phase currents a, b, c from d-q currents and the electrical angle.
inline std::array<double, 3> phaseFromDq(double d, double q, double theta_e) { return inverseClarke(rotate({d, q}, theta_e)); }

}  // namespace pmsm_param_id
