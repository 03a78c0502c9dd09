// The exact minimiser of the block fitness and its relatives, from BlockStatistics alone.
//
// Every block residual is linear in a parameter vector beta once it is written as a voltage
// equation, e.g. U_d = R_s int(i_d) + L_d Di_d - L_q int(omega_e i_q); the fitness divides it by
// the axis inductance (r = e / L). BlockLeastSquares minimises the fitness exactly: iteratively
// reweighted least squares for a start, then Gauss-Newton on r itself. Directions the data do not
// determine (a rank-deficient normal matrix, e.g. L_d without d-axis excitation) are left at the
// starting values instead of being filled with noise.
//
// Besides the paper's four-parameter model, extended models serve the fit diagnosis:
//   speed scale: the inductances and the flux in the speed terms are free (a speed logged in rpm
//                or mechanical rad/s, or time in ms, shows as their ratio to the Di terms);
//   delay:       a multiple a of int(u_k - u_k-1) (a = 1: the voltage acts one sample late);
//   inverter:    a voltage V along the current vector (dead time, device drops), and with the
//                zero-crossing shape as a mix of two widths, and with the dead-time part following
//                a logged DC-bus voltage;
//   cross saturation: the incremental L_qq and the cross inductance L_dq of a saturating machine;
//   voltage angle: the acting vector turned by a omega_e T_s (the drive's angle prediction).
#pragma once
#include <Eigen/Core>
#include <string>
#include <vector>

#include "pmsm_param_id/identification/block_statistics.hpp"

namespace pmsm_param_id {

/// A model linear in beta: per axis, int(u) = sum_j beta_j (g_j . z).
struct LinearBlockModel {
  std::string name;
  std::vector<std::string> parameter_names;
  Eigen::MatrixXd G_d;  ///< kBlockSizeD x n
  Eigen::MatrixXd G_q;  ///< kBlockSizeQ x n
  int d_inductance = kLd;  ///< index in beta of the inductance multiplying Di_d (divides r_d)
  int q_inductance = kLq;  ///< ... Di_q (divides r_q)
  int size() const { return static_cast<int>(parameter_names.size()); }

  static const LinearBlockModel& paper();        ///< {R_s, L_d, L_q, psi_f}: the fitness the swarm minimises
  static const LinearBlockModel& speedScale();   ///< + {L_q in speed terms, L_d in speed terms}; psi_f in speed terms
  static const LinearBlockModel& delay();        ///< + {a}: voltage delay [samples]
  static const LinearBlockModel& inverter();     ///< + {V}: inverter voltage along the current [V]
  /// + {V, V_wide}: the inverter voltage with its zero-crossing shape, a mix of the shape over the
  /// configured current (share V - V_wide) and over twice it (share V_wide).
  static const LinearBlockModel& inverterWithShape();
  /// + {V_bus}: the part of V that scales with the logged DC-bus voltage (the dead time's; the device
  /// drops do not), at the first logged bus voltage [V] (block entries kIntegralInverterBus*).
  static const LinearBlockModel& inverterWithShapeAndBus();
  /// + {L_qq, L_dq}: a saturating machine about the q current i_bar (WindowSums::
  /// crossLinearisationCurrent()); L_q is then the secant inductance psi_q(0, i_bar) / i_bar, psi_f
  /// the flux psi_d(0, i_bar), L_qq the incremental q inductance, L_dq the cross-saturation (section 11).
  static LinearBlockModel crossSaturation(double i_bar);
  /// The same with L_d free in the speed term (the unit check on a saturating machine).
  static LinearBlockModel crossSaturationSpeedScale(double i_bar);
  /// Any model + {a}: a multiple a of int(u_k - u_k-1), as delay() (a = 1: one sample late).
  static LinearBlockModel withDelay(const LinearBlockModel& model);
  /// Any model + {a}: the acting voltage turned by a omega_e T_s against the declared timing (an
  /// unrecorded angle prediction, doc/algorithm.md section 8), appended after its own parameters.
  static LinearBlockModel withVoltageAngle(const LinearBlockModel& model);
  /// Any model + {rho, kappa}: R_s changing at rho [ohm/s] and at kappa [ohm/(A^2 s)] times the
  /// copper loss's clock i_d^2 + i_q^2 about the slow window's newest snapshot (the entries
  /// kIntegralIdRate, kIntegralIdHeat and their q twins; only the slow window holds them), appended
  /// after its own parameters. R_s is then the value at that snapshot.
  static LinearBlockModel withResistanceRate(const LinearBlockModel& model);
  /// Any model + {L_qq, L_dq} (appended after its own parameters).
  static LinearBlockModel withCrossSaturation(const LinearBlockModel& model, double i_bar);
};

struct BlockFit {
  bool ok = false;                  ///< a solution with positive inductances exists
  Eigen::VectorXd beta;             ///< minimiser (undetermined directions: the starting values)
  std::vector<bool> determined;     ///< the data moved / determine this entry
  double mean_square_d = 0.0;       ///< mean r_d^2 at beta [A^2]
  double mean_square_q = 0.0;       ///< mean r_q^2 at beta [A^2]
  double noise_variance_d = 0.0;    ///< block-residual variance that white current noise explains [A^2]
  double noise_variance_q = 0.0;
  double current_noise_variance_d = 0.0;  ///< the currents' own noise, from the block ends alone [A^2]
  double current_noise_variance_q = 0.0;
  Eigen::VectorXd standard_deviation;  ///< of beta from the window's information (inf: undetermined)
  /// The correlations of the determined entries (1 on the diagonal, 0 where undetermined) [-].
  Eigen::MatrixXd correlation;
  double fitness() const { return mean_square_d + mean_square_q; }
};

class BlockLeastSquares {
 public:
  /// Minimises sum of (r_d^2 + r_q^2) over the window for `model`. `start` must have positive
  /// inductances; entries with fixed[j] = true are kept. variance_inflation multiplies the
  /// information-based variances (doc/algorithm.md section 4).
  static BlockFit fit(const WindowSums& window, const LinearBlockModel& model, const Eigen::VectorXd& start,
                      const std::vector<bool>& fixed = {}, double variance_inflation = 1.0);
  static BlockFit fit(const BlockStatistics& stats, const LinearBlockModel& model, const Eigen::VectorXd& start,
                      const std::vector<bool>& fixed = {}, double variance_inflation = 1.0) {
    return fit(stats.window(), model, start, fixed, variance_inflation);
  }
  /// Mean squares of r_d, r_q and of their block-to-block differences at beta.
  static void residuals(const WindowSums& window, const LinearBlockModel& model, const Eigen::VectorXd& beta,
                        double& ms_d, double& ms_q, double& diff_ms_d, double& diff_ms_q);
};

}  // namespace pmsm_param_id
