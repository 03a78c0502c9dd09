// Sufficient statistics of the adjustable-model current error over a sliding horizon.
//
// Integrating Eq. (1) over a block [t_j, t_k] of M sampling periods gives, per axis, a residual in
// amperes that is zero for the true parameters and noise-free data:
//   r_d = Di_d + (R_s/L_d) I_d - (L_q/L_d) W_d - (1/L_d) U_d
//   r_q = Di_q + (R_s/L_q) I_q + (L_d/L_q) W_q - (1/L_q) U_q + (psi_f/L_q) Om
// with Di = i(t_k) - i(t_j), I = int i dt, W_d = int omega_e i_q dt, W_q = int omega_e i_d dt,
// U = int u dt (exact: u is held over each period), Om = int omega_e dt. Currents and speed are
// integrated by the trapezoidal rule (second order, unlike the paper's forward Euler).
// r is the current error of the adjustable model after M steps when it is driven by the measured
// voltages and (in its resistive and coupling terms) by the measured currents.
// The fitness is the exponentially forgotten mean of r_d^2 + r_q^2; since r is linear in the
// block vector z with parameter-dependent weights, it only needs S = sum lambda^n z z^T:
// evaluating it costs the same for any window length.
#pragma once
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <limits>
#include <cstdint>
#include <vector>

#include "pmsm_param_id/motor_model.hpp"
#include "pmsm_param_id/sample.hpp"

namespace pmsm_param_id {

struct HorizonSettings {
  double horizon = 0.005;          ///< block length [s] (rounded to whole sampling periods)
  double time_constant = 0.05;     ///< forgetting time constant of the fitness window [s]
};

using BlockD = Eigen::Matrix<double, 4, 1>;  ///< {Di_d, I_d, W_d, U_d}
using BlockQ = Eigen::Matrix<double, 5, 1>;  ///< {Di_q, I_q, W_q, U_q, Om}

class HorizonStatistics {
 public:
  explicit HorizonStatistics(const HorizonSettings& settings = {});

  /// Adds a sample that follows the previous one without a gap (dt > 0 checked by the caller).
  /// Returns true when a new block was completed and added to the statistics.
  bool add(const Sample& s);
  /// The stream was interrupted (gap, skipped sample): blocks restart, statistics are kept.
  void breakContinuity();
  /// Forget everything.
  void reset();

  /// Mean squared block residual r_d^2 + r_q^2 [A^2] for parameters p; +inf before any block.
  /// Inline: the swarm calls it 20 times per sample.
  double fitness(const ParameterVector& p) const {
    if (weight_ <= 0) return std::numeric_limits<double>::infinity();
    const double inv = 1.0 / (p[kLd] * p[kLq]);  // one division for both 1/L_d and 1/L_q
    const double inv_Ld = p[kLq] * inv, inv_Lq = p[kLd] * inv;
    const double wd[4] = {1.0, p[kRs] * inv_Ld, -p[kLq] * inv_Ld, -inv_Ld};
    const double wq[5] = {1.0, p[kRs] * inv_Lq, p[kLd] * inv_Lq, -inv_Lq, p[kPsiF] * inv_Lq};
    // Quadratic forms on the upper triangles (the lower ones are not maintained).
    double f = 0.0;
    for (int i = 0; i < 4; ++i) {
      double row = 0.5 * S_d_(i, i) * wd[i];
      for (int j = i + 1; j < 4; ++j) row += S_d_(i, j) * wd[j];
      f += wd[i] * row;
    }
    for (int i = 0; i < 5; ++i) {
      double row = 0.5 * S_q_(i, i) * wq[i];
      for (int j = i + 1; j < 5; ++j) row += S_q_(i, j) * wq[j];
      f += wq[i] * row;
    }
    return std::max(0.0, 2.0 * f / weight_);
  }
  /// Fisher information (up to the residual variance) of {R_s, L_d, L_q, psi_f} at p: the
  /// Gauss-Newton matrix sum(grad r grad r^T) of the window.
  Eigen::Matrix4d information(const ParameterVector& p) const;

  bool hasBlocks() const { return weight_ > 0; }
  double weight() const { return weight_; }               ///< sum of forgetting weights [-]
  std::uint64_t blocks() const { return blocks_; }        ///< blocks added since reset
  int horizonSamples() const { return horizon_samples_; } ///< M, fixed by the first period seen
  /// The forgotten sums S_d = sum lambda^n z_d z_d^T and S_q (full symmetric matrices).
  Eigen::Matrix4d matrixD() const { return S_d_.selfadjointView<Eigen::Upper>(); }
  Eigen::Matrix<double, 5, 5> matrixQ() const { return S_q_.selfadjointView<Eigen::Upper>(); }
  const BlockD& lastBlockD() const { return last_d_; }
  const BlockQ& lastBlockQ() const { return last_q_; }

 private:
  struct Cumulative {  // running integrals since the last continuity break
    double t, i_d, i_q, omega_e, u_d, u_q;  // the sample itself
    double I_d, I_q, W_d, W_q, U_d, U_q, Om;
  };
  HorizonSettings settings_;
  int horizon_samples_ = 0;
  std::vector<Cumulative> ring_;  // capacity horizon_samples_ + 1
  std::size_t head_ = 0, count_ = 0;
  Eigen::Matrix4d S_d_ = Eigen::Matrix4d::Zero();
  Eigen::Matrix<double, 5, 5> S_q_ = Eigen::Matrix<double, 5, 5>::Zero();
  double weight_ = 0.0;
  double lambda_dt_ = -1.0, lambda_ = 1.0;  // forgetting factor cached for the last period seen
  std::uint64_t blocks_ = 0;
  BlockD last_d_ = BlockD::Zero();
  BlockQ last_q_ = BlockQ::Zero();
};

}  // namespace pmsm_param_id
