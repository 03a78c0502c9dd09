// Sufficient statistics of the adjustable-model current error over blocks of M sampling periods.
//
// Integrating Eq. (1) over a block [t_j, t_k] gives, per axis, a residual in amperes that is zero
// for the true parameters and noise-free data:
//   r_d = Di_d + (R_s/L_d) int(i_d) - (L_q/L_d) int(omega_e i_q) - (1/L_d) int(u_d)
//   r_q = Di_q + (R_s/L_q) int(i_q) + (L_d/L_q) int(omega_e i_d) - (1/L_q) int(u_q) + (psi_f/L_q) int(omega_e)
// Di = i(t_k) - i(t_j); the voltage integrals are exact (u is held over each period); currents and
// speed are integrated by the trapezoidal rule (second order, unlike the paper's forward Euler).
// r is the current error of the adjustable model after M steps when it is driven by the measured
// voltages and (in its resistive and coupling terms) by the measured currents.
//
// Two more integrals per axis are kept for the fit diagnosis (doc/algorithm.md section 4):
//   int(u_k - u_{k-1}) dt   a voltage applied one sample late or early adds a multiple of it;
//   int(s) dt               an inverter voltage error V adds -V times it: s is the d-q image of the
//                           phase-current signs, Park(theta_e) Clarke(sign(i_a), sign(i_b), sign(i_c)),
//                           when the sample has the electrical angle, else its mean along the
//                           current vector, (4/pi) i/|i| (the 6 omega_e ripple is then unknown).
//
// The fitness is the exponentially forgotten mean of r_d^2 + r_q^2. Since r is linear in the block
// vector z with parameter-dependent weights, it only needs S = sum lambda^n z z^T, so one
// evaluation costs the same for any window length. The same is kept for the differences of
// consecutive blocks, z_k - z_(k-1): white current noise dominates those, which gives the noise
// level of the data without any configured sigma.
#pragma once
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "pmsm_param_id/identification/angle_quantum.hpp"
#include "pmsm_param_id/model/frames.hpp"
#include "pmsm_param_id/model/motor_model.hpp"
#include "pmsm_param_id/model/sample.hpp"

namespace pmsm_param_id {

struct InverterEdgePeriod;  // inverter_edges.hpp

struct WindowSettings {
  double block_length = 0.0;               ///< one fitness block [s]; 0 = max(5 ms, 10 sampling periods)
  double forgetting_time_constant = 0.0;   ///< forgetting of the fitness window [s]; 0 = max(50 ms, 500 periods)
  double long_time_constant = 10.0;        ///< forgetting of the long check window [s] (unit checks)
  /// The long check window keeps, besides the differences of consecutive blocks, the differences of
  /// blocks this far apart [s]: a load step or a speed change then enters through every pair that
  /// straddles it, not one, while a thermal drift (minutes) still cancels. 0 = consecutive only.
  double long_difference_spacing = 0.2;
  /// Forgetting of the slow window [s]: the fitness window's blocks (not differenced) averaged
  /// over this, for R_s and psi_f on a thermal time scale (doc/algorithm.md section 9).
  double slow_time_constant = 1.0;
  bool stationary_hold = false;            ///< the inverter holds the voltage in the stator frame
  double inverter_zero_crossing_current = 0.0;  ///< the inverter error passes zero as tanh(i / this) [A]; 0 = sign
                                                ///< (< 0: to be measured from the data, a sign until then)
  bool inverter_wide_shape = false;  ///< keep the twice-the-width shape column (the inverter model is on)
  /// The narrow shape is the switching edges' (inverter_edges.hpp): each leg's dead time lost or
  /// gained by the sign of its current at the edge, the ripple there set by the acting vector, the
  /// inductances and V of the data's last exact fit (setEdgeModel) and the logged bus voltage (needs
  /// the logged angle; until the model is set, tanh of the current as without it).
  bool inverter_edge_shape = false;
  int voltage_delay_samples = 0;           ///< 0: u(t_k) acts on [t_k, t_k+1); 1: on [t_k+1, t_k+2)
  /// The inverter error's shape takes its phase currents from a current observer (the data's exact
  /// fit driven by the logged voltages) corrected towards the measured currents by this fraction
  /// per sample; 0 or 1 = the measured currents (doc/algorithm.md section 8).
  double inverter_shape_observer_gain = 0.1;
  /// The phase-current sensors' offsets are profiled out of every fit (needs the logged angle): a
  /// constant stator-frame offset o adds o_a (cos theta) + o_b (sin theta) terms to each block
  /// residual, so the statistics are projected off Dcos, Dsin, int cos, int sin (a Schur complement).
  bool sensor_offsets = false;
  /// The same for the phase sensors' gain mismatch (terms at 2 theta times the currents; needs
  /// sensor_offsets' machinery and the logged angle).
  bool sensor_gains = false;
  /// Estimate the angle a omega_e T_s [rad] by which the acting voltage vector is turned against the
  /// declared timing (an inverter's angle prediction the log does not record, doc/algorithm.md
  /// section 8): u_acting = u + a omega_e T_s J u, to first order; the block entries
  /// kIntegralAngleUqInD and kIntegralAngleUdInQ carry it.
  bool estimate_voltage_angle = false;
  /// A declared angle prediction beyond the delay's own [periods of omega_e T_s]: the acting vector is
  /// turned by this times omega_e T_s (exactly) before the estimate above.
  double declared_voltage_angle = 0.0;
  /// The rotation int omega_e dt of the flux columns (kIntegralOmega, kIntegralOmegaInD) from a
  /// centred mean of the logged angle over 2 m + 1 samples, m this [samples]; 0 = the logged angle
  /// as it is. A quantised angle (an encoder) moves the drive's frame by its quantisation error, and
  /// in that frame the error cancels between the flux's derivative and omega_e psi_d, except in
  /// psi_f times the rotation: that wants the rotor's own angle (doc/algorithm.md section 8). The
  /// blocks then end m samples behind the newest (the mean needs m samples after the block's end).
  /// < 0: chosen by the identifier from the data (OnlineIdentifier::watchAngleQuantum; 0 here).
  int angle_smoothing_samples = -1;
  /// The logged angle's quantum (an encoder's count) [rad]; 0 = none. With one, the statistics
  /// track whether the count is locked to the sampling over slow_time_constant (CountLock).
  /// Found from the data (OnlineIdentifier::watchAngleQuantum), not configured.
  double angle_quantum = 0.0;
};

/// The inverter error as the block model carries it: the amplitude V split over the shapes' entries.
/// The shape over the zero-crossing current w carries V - V_wide, the one over 2w V_wide, and the
/// bus entry ((v_dc / v_ref - 1) times the shape over w) V_bus (doc/algorithm.md section 8). One
/// definition for the fitness, the compensated windows, the shape observer and the crossing term.
struct InverterMix {
  double narrow = 0.0, wide = 0.0, bus = 0.0;  ///< [V]
  static InverterMix of(double V, double V_wide, double V_bus) { return {V - V_wide, V_wide, V_bus}; }
};

/// Entries of the current-sensor error block vector (offsets, and gain mismatch), shared by both
/// axes (WindowSettings::sensor_offsets, sensor_gains).
enum OffsetEntry : int {
  kDeltaCos = 0,     ///< cos theta_e(t_k) - cos theta_e(t_j) [-]
  kDeltaSin,         ///< [-]
  kIntegralCos,      ///< int cos theta_e dt [s]
  kIntegralSin,      ///< [s]
  // Gain mismatch of the phase sensors (sensor_gains): a negative-sequence error A P + B Q in d and
  // B P - A Q in q, P = cos 2theta i_d - sin 2theta i_q, Q = sin 2theta i_d + cos 2theta i_q.
  kDeltaP,           ///< P(t_k) - P(t_j) [A]
  kDeltaQ,           ///< [A]
  kIntegralP,        ///< int P dt [A s]
  kIntegralQ,        ///< [A s]
  kIntegralOmegaP,   ///< int omega_e P dt [A]
  kIntegralOmegaQ,   ///< [A]
  kOffsetBlockSize
};

/// Entries of the d-axis block vector.
enum BlockEntryD : int {
  kDeltaId = 0,          ///< i_d(t_k) - i_d(t_j) [A]
  kIntegralId,           ///< int i_d dt [A s]
  kIntegralOmegaIq,      ///< int omega_e i_q dt [A]
  kIntegralUd,           ///< int u_d dt [V s] (the voltage acting: delay and hold applied)
  kIntegralInverterD,    ///< int s_d dt [s]: shape of the inverter voltage error (see below)
  kIntegralUdStep,       ///< int of the acting u_d's step [V s] (delay diagnosis: back, u_k - u_k-1, with no delay; forward, u_k+1 - u_k, with one)
  kIntegralInverterWideD,  ///< int s_d dt with twice the zero-crossing width (the fitted shape mix) [s]
  kIntegralInverterBusD,   ///< int (v_dc / v_dc,ref - 1) s_d dt: the dead-time part follows the logged bus [s]
  kDeltaIqInD,           ///< i_q(t_k) - i_q(t_j) [A] (cross-saturation: L_dq di_q/dt in the d axis)
  kIntegralOmegaIdInD,   ///< int omega_e i_d dt [A] (cross-saturation: omega_e L_dq i_d in psi_q)
  kIntegralOmegaInD,     ///< int omega_e dt [rad] (cross-saturation: psi_q(0, i_q) linear in a moving i_q)
  kIntegralAngleUqInD,   ///< int omega_e T_s u_q dt [V s]: the acting vector turned by a omega_e T_s adds -a times it
  /// int (t - t_ref) i_d dt [A s^2]: a resistance changing at a rate rho adds rho times it (R_s's own
  /// rate within the slow window, t_ref its newest snapshot). Only the slow window holds it, from its
  /// snapshots' times (BlockStatistics::slowWindow); the blocks themselves carry 0 (kRateEntries).
  kIntegralIdRate,
  /// int (Q(t) - Q_ref) i_d dt [A^3 s^2], Q = int (i_d^2 + i_q^2) dt the copper loss's clock: a
  /// winding heated by its copper loss changes its resistance at kappa (i_d^2 + i_q^2) besides a
  /// rate of its own (the heat it loses), so R_s(t) = R_s + rho (t - t_ref) + kappa (Q(t) - Q_ref)
  /// turns where the load does. As kIntegralIdRate, from the snapshots' Q.
  kIntegralIdHeat,
  kBlockSizeD
};
/// Entries of the q-axis block vector.
enum BlockEntryQ : int {
  kDeltaIq = 0,          ///< [A]
  kIntegralIq,           ///< [A s]
  kIntegralOmegaId,      ///< int omega_e i_d dt [A]
  kIntegralUq,           ///< [V s]
  kIntegralOmega,        ///< int omega_e dt [rad]
  kIntegralInverterQ,    ///< int s_q dt [s]
  kIntegralUqStep,       ///< [V s]
  kIntegralInverterWideQ,  ///< [s]
  kIntegralInverterBusQ,   ///< [s]
  kDeltaIdInQ,           ///< i_d(t_k) - i_d(t_j) [A] (cross-saturation: L_dq di_d/dt in the q axis)
  kIntegralOmegaIqInQ,   ///< int omega_e i_q dt [A] (cross-saturation: psi_d(0, i_q) linear in a moving i_q)
  kIntegralAngleUdInQ,   ///< int omega_e T_s u_d dt [V s]: ... adds +a times it (T_s the nominal period)
  kIntegralIqRate,       ///< int (t - t_ref) i_q dt [A s^2] (as kIntegralIdRate)
  kIntegralIqHeat,       ///< int (Q(t) - Q_ref) i_q dt [A^3 s^2] (as kIntegralIdHeat)
  kBlockSizeQ
};
/// The entries every block computes: all but the slow window's rate and heat entries, which are
/// last on both axes.
constexpr int kRateEntries = 2;
static_assert(kIntegralIdRate == kBlockSizeD - kRateEntries && kIntegralIqRate == kBlockSizeQ - kRateEntries,
              "the rate entries are the blocks' last");
using BlockD = Eigen::Matrix<double, kBlockSizeD, 1>;
using BlockQ = Eigen::Matrix<double, kBlockSizeQ, 1>;
using ProductD = Eigen::Matrix<double, kBlockSizeD, kBlockSizeD>;
using ProductQ = Eigen::Matrix<double, kBlockSizeQ, kBlockSizeQ>;
using OffsetBlock = Eigen::Matrix<double, kOffsetBlockSize, 1>;
using OffsetProduct = Eigen::Matrix<double, kOffsetBlockSize, kOffsetBlockSize>;
using OffsetCrossD = Eigen::Matrix<double, kBlockSizeD, kOffsetBlockSize>;
using OffsetCrossQ = Eigen::Matrix<double, kBlockSizeQ, kOffsetBlockSize>;

/// The inverter error shape s of a sample (see the header comment): from the angle when the sample
/// has it, else (4/pi) i/|i|. Unitless, |s| ~ 1. With the angle, `phase` (if given) receives the
/// phase currents a, b, c.
void inverterShape(const Sample& s, double& shape_d, double& shape_q, std::array<double, 3>* phase = nullptr);

/// The sums of one window as the solvers need them (means of z z^T, the effective block count).
struct WindowSums {
  ProductD mean_d = ProductD::Zero();
  ProductQ mean_q = ProductQ::Zero();
  ProductD mean_difference_d = ProductD::Zero();  ///< of consecutive block differences (short window)
  ProductQ mean_difference_q = ProductQ::Zero();
  double weight = 0.0;               ///< effective number of blocks [-]
  bool has_differences = false;
  double block_duration = 0.0;       ///< [s]
  int block_samples = 0;             ///< sampling periods per block, M [-] (0: unknown)
  double noise_variance_d = -1.0;    ///< known block-residual noise variance [A^2]; < 0: from the differences
  double noise_variance_q = -1.0;
  /// Floor of the noise variance behind the parameters' standard deviations [A^2]: the residual
  /// the fit check accepts as a fit on noise-free data (fit_floor_relative), so that what it cannot
  /// tell from zero does not state a weakly excited parameter as known.
  double min_noise_variance = 0.0;
  bool hasBlocks() const { return weight > 0; }
  /// The q current the cross-saturation model linearises psi(0, i_q) at: the speed-weighted mean
  /// over the window's blocks, int omega i_q . int omega / (int omega)^2 [A] (section 11).
  double crossLinearisationCurrent() const {
    const double w = mean_d(kIntegralOmegaInD, kIntegralOmegaInD);
    return w > 0 ? mean_d(kIntegralOmegaIq, kIntegralOmegaInD) / w : 0.0;
  }
};

/// With an encoder's quantum, the forward observer takes the rotor's speed from the counted angle's
/// increment over this many periods (BlockStatistics::observePeriodForward): a fourth of one
/// period's quantisation error, behind by 1.5 periods. Measured (robot_joint_pwm, FBDAPSO, seeds
/// 1-10): 1, 4, 8 periods put L_d within 1 % in 4, 7, 7 and L_q in 7, 7, 1; the logged speed (a
/// count difference over 1 ms, 0.5 ms behind) L_d in 7 and L_q in none (doc/algorithm.md section 8).
constexpr std::size_t kObserverRatePeriods = 4;

class BlockStatistics {
 public:
  explicit BlockStatistics(const WindowSettings& settings = {});

  /// Fixes the nominal sampling period: the block length in samples and the forgetting factor.
  /// Must be called before add(); calling it again forgets everything.
  void configure(double nominal_period);
  bool configured() const { return block_samples_ > 0; }
  /// Adds a sample that follows the previous one (dt > 0 checked by the caller).
  /// Returns true when a new block was completed and added to the statistics.
  bool add(const Sample& s);
  /// The stream was interrupted (gap, skipped sample): blocks restart, statistics are kept.
  void breakContinuity();
  /// Changes angle_smoothing_samples (WindowSettings) from here on: blocks restart (breakContinuity),
  /// the sums are kept.
  void setAngleSmoothing(int samples);
  /// Forget everything, including the nominal period.
  void reset();
  /// Forget the long check window and the slow window (the motor changed: their old blocks no
  /// longer apply).
  void resetLongWindow();
  /// Forget the slow window only.
  void resetSlowWindow();

  /// Mean squared block residual r_d^2 + r_q^2 [A^2] for parameters p; +inf before any block.
  /// Inline: the swarm calls it 20 times per sample.
  double fitness(const ParameterVector& p) const {
    if (weight_ <= 0) return std::numeric_limits<double>::infinity();
    const double inv = 1.0 / (p[kLd] * p[kLq]);  // one division for both 1/L_d and 1/L_q
    const double inv_Ld = p[kLq] * inv, inv_Lq = p[kLd] * inv;
    // The known drive terms (the inverter's error voltage with its shape's shares, the voltage
    // angle) are folded into the sums' voltage entry (fitnessSums()): the same four and five
    // entries as the paper's model, whatever the drive model (on a switching-level drive's log a
    // real drive's fitness cost three times the paper's with the terms as entries of their own).
    const double wd[4] = {1.0, p[kRs] * inv_Ld, -p[kLq] * inv_Ld, -inv_Ld};
    const double wq[5] = {1.0, p[kRs] * inv_Lq, p[kLd] * inv_Lq, -inv_Lq, p[kPsiF] * inv_Lq};
    // Quadratic forms on the upper triangles (the lower ones are not maintained), with the trip
    // counts fixed at compile time so that the compiler unrolls them.
    // (The q form continues the d form's sum: the same order of additions as one loop over both.)
    const auto [Sd, Sq] = fitnessSums();
    static_assert(kDeltaId == 0 && kIntegralId == 1 && kIntegralOmegaIq == 2 && kIntegralUd == 3 && kDeltaIq == 0 &&
                      kIntegralIq == 1 && kIntegralOmegaId == 2 && kIntegralUq == 3 && kIntegralOmega == 4,
                  "the fitness's weight arrays follow the block entries");
    return std::max(0.0, 2.0 * upperForm<5>(Sq, wq, upperForm<4>(Sd, wd, 0.0)) / fitnessWeight());
  }
  /// fitness() at n points in one call (the swarm evaluates every particle's move at once): the same
  /// values, each computed as fitness() computes it, without a call per point.
  void fitness(const ParameterVector* p, std::size_t n, double* out) const;
  /// f + sum_i w_i (S_ii w_i / 2 + sum_{j > i} S_ij w_j) over the first N entries.
  template <int N, class Matrix>
  static double upperForm(const Matrix& S, const double* w, double f) {
    for (int i = 0; i < N; ++i) {
      double row = 0.5 * S(i, i) * w[i];
      for (int j = i + 1; j < N; ++j) row += S(i, j) * w[j];
      f += w[i] * row;
    }
    return f;
  }
  /// The same with the cross-saturation terms of a saturating machine (doc/algorithm.md section 11):
  /// L_dq and the incremental L_qq known (profiled by the data's exact fit), p[kLq] the secant
  /// inductance (it enters through omega_e psi_q only), p[kPsiF] the flux psi_d(0, i_q).
  double fitnessWithCrossSaturation(const ParameterVector& p) const;
  void fitnessWithCrossSaturation(const ParameterVector* p, std::size_t n, double* out) const;

  /// The inverter voltage the fitness subtracts (0: none) [V], the part of it that builds up over
  /// twice the zero-crossing current [V], and the part that scales with the logged bus voltage (the
  /// dead time's, at the reference bus voltage) [V]; set from the data's exact fit.
  void setInverterVoltage(double v, double wide_share = 0.0, double bus_share = 0.0) {
    const double wide = v != 0.0 ? wide_share : 0.0, bus = v != 0.0 ? bus_share : 0.0;
    if (v != inverter_voltage_ || wide != inverter_wide_share_ || bus != inverter_bus_share_) folded_sums_stale_ = true;
    inverter_voltage_ = v;
    inverter_wide_share_ = wide;
    inverter_bus_share_ = bus;
  }
  double inverterVoltage() const { return inverter_voltage_; }
  /// The voltage angle coefficient a the fitness takes as known (acting vector turned by
  /// a omega_e T_s; 0: none) [-]; set from the data's exact fit (WindowSettings::estimate_voltage_angle).
  void setVoltageAngle(double a) {
    if (a != voltage_angle_) folded_sums_stale_ = true;
    voltage_angle_ = a;
  }
  double voltageAngle() const { return voltage_angle_; }
  double inverterWideShare() const { return inverter_wide_share_; }
  double inverterBusShare() const { return inverter_bus_share_; }
  InverterMix inverterMix() const { return InverterMix::of(inverter_voltage_, inverter_wide_share_, inverter_bus_share_); }
  /// The samples carried the DC-bus voltage (the bus entries are not all zero).
  bool busVoltageLogged() const { return std::isfinite(bus_reference_); }
  /// Inductances for the stationary hold's bending of the currents within a period [H] (0: none);
  /// set from the data's exact fit (the correction is a fraction of a per cent of the integrals).
  void setHoldInductances(double L_d, double L_q) {
    hold_L_d_ = L_d;
    hold_L_q_ = L_q;
  }
  /// The switching edges' model (WindowSettings::inverter_edge_shape): the inductances [H] and the
  /// inverter voltage V [V] whose V T_s is the dead time's volt-seconds per edge; set from the data's
  /// exact fit (0: not yet, the tanh shape stands in).
  void setEdgeModel(double L_d, double L_q, double V) {
    edge_L_d_ = L_d;
    edge_L_q_ = L_q;
    edge_V_ = V;
  }
  bool edgeModelSet() const { return settings_.inverter_edge_shape && edge_L_d_ > 0 && edge_L_q_ > 0 && edge_V_ > 0; }
  /// The shape's observer follows each period forward through the replayed edges (observePeriodForward).
  bool observerFollowsForward() const { return edgeModelSet() && busVoltageLogged(); }
  double edgeLd() const { return edge_L_d_; }  ///< setEdgeModel's L_d [H]
  double edgeLq() const { return edge_L_q_; }  ///< setEdgeModel's L_q [H]
  double edgeV() const { return edge_V_; }     ///< setEdgeModel's V [V]
  /// Parameters of the inverter shape's current observer (WindowSettings::inverter_shape_observer_gain),
  /// set from the data's exact fit; the observer also takes the inverter voltage set above.
  void setShapeObserverModel(const ParameterVector& p) { observer_model_ = p; }
  std::pair<double, double> observerCurrents() const { return {observer_i_d_, observer_i_q_}; }
  bool shapeObserverActive() const {
    return settings_.inverter_shape_observer_gain > 0 && settings_.inverter_shape_observer_gain < 1 &&
           observer_model_[kLd] > 0 && observer_model_[kLq] > 0;
  }
  /// Known cross-saturation inductance L_dq and incremental q inductance L_qq [H] (0: linear model);
  /// set from the data's exact fit when magnetics.cross_saturation is on.
  void setCrossSaturation(double L_dq, double L_qq) { cross_L_dq_ = L_dq; cross_L_qq_ = L_qq; }
  bool crossSaturationSet() const { return cross_L_qq_ > 0; }
  /// WindowSums::crossLinearisationCurrent() of the present window, from the stored sums [A].
  double crossLinearisationCurrent() const;
  double crossLdq() const { return cross_L_dq_; }
  double crossLqq() const { return cross_L_qq_; }
  bool hasBlocks() const { return weight_ > 0; }
  /// Sum of the forgetting weights of the blocks in the window [-] (the effective block count).
  double weight() const { return weight_; }
  std::uint64_t blocks() const { return blocks_; }          ///< blocks added since reset
  int blockSamples() const { return block_samples_; }       ///< M
  double nominalPeriod() const { return nominal_period_; }  ///< [s]
  /// WindowSettings::inverter_zero_crossing_current [A].
  double inverterZeroCrossingCurrent() const { return settings_.inverter_zero_crossing_current; }
  double blockDuration() const { return block_samples_ * nominal_period_; }  ///< [s]
  double forgettingTimeConstant() const { return forgetting_time_constant_; }  ///< in use [s]
  /// Forgotten means of z z^T (full symmetric): sum lambda^n z z^T / sum lambda^n.
  ProductD meanProductD() const;
  ProductQ meanProductQ() const;
  /// The same for the differences of consecutive blocks of one continuous stretch.
  ProductD meanDifferenceProductD() const;
  ProductQ meanDifferenceProductQ() const;
  bool hasDifferences() const { return difference_weight_ > 0; }
  /// The fitness window (overlapping blocks, forgetting_time_constant).
  WindowSums window() const;
  /// The sums the swarm's fitness reads (projected off the sensor terms, the known drive terms
  /// folded into the voltage entry) as a window the exact fit reads with the paper's model: its
  /// optimum is that of the fitness the swarm searches. (Empty with cross-saturation set.)
  WindowSums searchedWindow() const;
  /// The long check window: differences of non-overlapping blocks (consecutive, and
  /// long_difference_spacing apart), long_time_constant.
  WindowSums longWindow() const;
  /// The slow window: the fitness window's blocks averaged once more over slow_time_constant, with
  /// the rate entries (kIntegralIdRate, kIntegralIqRate) about its newest snapshot, slowWindowTime().
  WindowSums slowWindow() const;
  /// The reference of the slow window's rate entries: the end of the newest snapshot's newest block
  /// [s] (NaN: none).
  double slowWindowTime() const { return slow_time_ + slow_ahead_time_; }
  /// The copper loss's clock Q = int (i_d^2 + i_q^2) dt there, the reference of its heat entries
  /// [A^2 s] (counted since the statistics were configured).
  double slowWindowHeat() const { return slow_heat_ + slow_ahead_heat_; }
  double slowTimeConstant() const { return settings_.slow_time_constant; }
  /// The logged speed against the logged angle's rate over the long window, sum |omega_e| dt /
  /// sum sign(omega_e) dtheta_e (1 when the speed's unit is right); NaN without the angle or before
  /// two electrical turns.
  double loggedSpeedToAngleRatio() const;
  /// The electrical angle the ratio above is measured over [rad].
  double angleTravel() const { return angle_travel_; }
  const BlockD& lastBlockD() const { return last_d_; }
  const BlockQ& lastBlockQ() const { return last_q_; }
  const WindowSettings& settings() const { return settings_; }
  /// Whether the encoder's count has been locked to the sampling over slow_time_constant, with the
  /// d current's mean and spread over the same (nothing tracked without angle_quantum).
  const CountLock& countLock() const { return count_lock_; }
  /// Sets angle_quantum (WindowSettings) from here on.
  void setAngleQuantum(double quantum) { settings_.angle_quantum = quantum; }

 private:
  struct Cumulative {      // running integrals since the last continuity break
    double t, i_d, i_q, omega_e;
    double applied_d, applied_q;            // voltage acting on [t, t_next)
    double applied_prev_d, applied_prev_q;  // voltage that acted on the period before
    double u_d, u_q;                        // the sample's own (commanded) voltage
    double I_d, I_q, OmIq, OmId, U_d, U_q, Om, Ustep_d, Ustep_q, Inv_d, Inv_q, Wide_d, Wide_q, Bus_d, Bus_q;
    double bus_ratio;                       // v_dc / bus_reference_ - 1 at the sample (0: not logged)
    double cos_theta, sin_theta, I_cos, I_sin;  // cos, sin of the logged angle (0 without it); their integrals (sensor offsets)
    double P, Q, I_P, I_Q, W_P, W_Q;            // sensor gains: P, Q of the sample and their integrals
    double A_d, A_q;                        // int omega_e T_s u_q, int omega_e T_s u_d of the acting voltage (voltage angle)
    double shape_d, shape_q;                // inverter error shape s at the sample
    double theta_e;                         // electrical angle (NaN when not logged)
    double Om_mean;                         // Om's centred mean over 2 m + 1 samples (angle_smoothing_samples)
    double heat;                            // the copper loss's clock int (i_d^2 + i_q^2) dt (heat_), not rebased
    std::array<double, 3> phase;            // phase currents a, b, c (when theta_e is known)
  };
  /// `mid`: the phasor of the rotor angle at mid-period.
  /// With `wide` (not null), the same integral of the shape over twice the width as well (from the
  /// same tanh values: tanh(x) = 2 t / (1 + t^2) with t = tanh(x / 2)).
  void inverterShapeIntegral(const Cumulative& previous, const Cumulative& current, const Sample& s, double dt,
                             double width, const std::array<double, 3>& mid_bend, Phasor mid, double& int_d,
                             double& int_q, std::array<double, 2>* wide = nullptr) const;
  /// One period of the inverter shape's current observer (advances its state): its phase currents
  /// at the sample, the period's integrals of the narrow and wide shapes along its path, and its
  /// currents' integrals less the trapezoid of the path's ends (what chords of the currents miss).
  struct ObservedPeriod {
    bool valid = false;
    std::array<double, 3> phase{};
    double narrow_d = 0.0, narrow_q = 0.0, wide_d = 0.0, wide_q = 0.0;  // [s]
    double missed_d = 0.0, missed_q = 0.0;                              // [A s]
  };
  /// `at_sample`: the phasor of the sample's angle (the previous one's is in `previous`);
  /// `rotor_rate`: the rotor's electrical speed the forward observer's back EMF turns at [rad/s].
  ObservedPeriod observePeriod(const Cumulative& previous, const Sample& s, double dt, double angle_increment,
                               Phasor at_sample, double rotor_rate);
  /// observePeriod with the switching edges replayed from the logged bus voltage: the period
  /// followed forward from the observer's current through each edge (inverterEdgeReplay's
  /// `forward`), the rotor-frame model's drift (R i, the cross-coupling, the back EMF turning
  /// within the period) against the legs' voltages; its end, pulled towards the sample by the
  /// gain, starts the next period.
  ObservedPeriod observePeriodForward(const Cumulative& previous, const Sample& s, double dt, double angle_increment,
                                      Phasor at_sample, double rotor_rate);
  /// The period after `previous` as the switching edges' models take it: the acting vector in the
  /// stator frame (the voltage angle turned at omega_e, held from the start or at mid-period), the
  /// fitted V as the dead time's volt-seconds, the logged bus voltage (NaN without), L_d and L_q.
  InverterEdgePeriod edgePeriod(const Cumulative& previous, double dt, double omega_e, Phasor mid, double L_d,
                                double L_q) const;
  /// The observer's next state: the period's end (end_d, end_q) pulled towards the sample by the
  /// gain; a non-finite result restarts it from the sample and drops the period's terms.
  ObservedPeriod finishPeriod(ObservedPeriod out, double end_d, double end_q, const Sample& s, Phasor at_sample);
  /// The switching edges' shape integrated over the period after `previous` (edgeModelSet()), in
  /// the rotor frame at mid-period [s]: each leg's mean error in units of V, from its phase currents
  /// at the period's two sampling instants; `mid`: the rotor angle's phasor at mid-period;
  /// `mid_bend`: the phase currents' departure from their chord there (the held vector's bend).
  Vec2 edgeShapeIntegral(const Cumulative& previous, const std::array<double, 3>& i_start,
                         const std::array<double, 3>& i_end, double dt, Phasor mid,
                         const std::array<double, 3>& mid_bend) const;
  void rescale();
  /// The projection is computed when a fit first reads it after new data (RLS, the EKF and the
  /// exact fit read it every few hundred samples, the swarm's fitness every sample).
  void updateOffsetProjection() const;
  void refreshProjection() const {
    if (projection_stale_) updateOffsetProjection();
  }
  /// The (upper-triangle) sums every fitness reads: projected off the sensor errors when they are
  /// fitted out.
  /// With a known voltage angle a and a known inverter error (V's narrow, wide and bus parts), the
  /// sums of the acting voltage's entries instead of the logged ones (U_d - a A_d - V_n Inv_d -
  /// V_w Wide_d - V_b Bus_d, U_q + a A_q - ... in q): the fitness then reads the entries it reads
  /// without them.
  std::pair<const ProductD&, const ProductQ&> fitnessSums() const {
    const ProductD* d = &S_d_;
    const ProductQ* q = &S_q_;
    if (settings_.sensor_offsets) {
      // For the swarm's fitness the projection is refreshed once per block length of new data (at
      // most M samples old, of a window of hundreds); the exact fit and the assessment read it
      // fresh (meanProductD). Its pseudo-inverse was half of a real-drive sample's cost.
      if (projection_stale_ && !(projected_weight_ > 0 && blocks_ - projected_blocks_ < static_cast<std::uint64_t>(block_samples_)))
        updateOffsetProjection();
      d = &P_d_;
      q = &P_q_;
    }
    if (voltage_angle_ == 0.0 && inverter_voltage_ == 0.0) return {*d, *q};
    if (folded_sums_stale_) updateFoldedSums(*d, *q);
    return {folded_d_, folded_q_};
  }
  void updateFoldedSums(const ProductD& d, const ProductQ& q) const;
  /// The stored weight of the sums fitnessSums() returned (the projection's, when it is read).
  double fitnessWeight() const { return settings_.sensor_offsets ? projected_weight_ : stored_weight_; }

  WindowSettings settings_;
  int block_samples_ = 0;
  double nominal_period_ = 0.0;
  double forgetting_time_constant_ = 0.0;
  double lambda_ = 1.0;
  std::vector<Cumulative> ring_;  // capacity block_samples_ + 1 + smoothing_samples_
  std::size_t head_ = 0, count_ = 0;
  int smoothing_samples_ = 0;         // m of angle_smoothing_samples (at most the block length)
  std::uint64_t stretch_samples_ = 0;  // samples since the last continuity break
  PhasorTracker angle_phasor_;  // cos and sin of the logged angle, sample by sample
  CountLock count_lock_;        // the encoder's count against the sampling (settings_.angle_quantum)
  // Stored sums are scaled by 1 / (product of the forgetting factors so far): adding a block is
  // then one rank-1 update with no pass over the matrices; rescaled before the scale overflows.
  ProductD S_d_ = ProductD::Zero(), dS_d_ = ProductD::Zero();
  ProductQ S_q_ = ProductQ::Zero(), dS_q_ = ProductQ::Zero();
  // Sensor offsets (settings_.sensor_offsets): the offset entries' own sums and their cross sums
  // with each axis, and the axis sums projected off them (what every fit then sees). N_ and slow_N_
  // hold their upper triangle only.
  OffsetProduct N_ = OffsetProduct::Zero();
  OffsetCrossD C_d_ = OffsetCrossD::Zero();
  OffsetCrossQ C_q_ = OffsetCrossQ::Zero();
  mutable ProductD P_d_ = ProductD::Zero();
  mutable ProductQ P_q_ = ProductQ::Zero();
  mutable bool projection_stale_ = true;
  mutable std::uint64_t projected_blocks_ = 0;  // blocks_ when the projection was last computed
  mutable double projected_weight_ = 0.0;       // stored_weight_ then
  OffsetProduct long_N_ = OffsetProduct::Zero();
  OffsetCrossD long_C_d_ = OffsetCrossD::Zero();
  OffsetCrossQ long_C_q_ = OffsetCrossQ::Zero();
  OffsetBlock long_last_n_ = OffsetBlock::Zero();
  // The logged speed against the logged angle (long window; the pending sums since the last long block).
  double speed_travel_ = 0.0, angle_travel_ = 0.0, pending_speed_travel_ = 0.0, pending_angle_travel_ = 0.0;
  double stored_weight_ = 0.0, stored_difference_weight_ = 0.0;
  double scale_ = 1.0;   // 1 / product of forgetting factors
  double weight_ = 0.0, difference_weight_ = 0.0;
  std::uint64_t blocks_ = 0;
  double inverter_voltage_ = 0.0, inverter_wide_share_ = 0.0, inverter_bus_share_ = 0.0;
  double voltage_angle_ = 0.0;
  mutable ProductD folded_d_ = ProductD::Zero();  // fitnessSums() with the known drive terms folded in
  mutable ProductQ folded_q_ = ProductQ::Zero();
  mutable bool folded_sums_stale_ = true;
  double bus_reference_ = std::numeric_limits<double>::quiet_NaN();
  double hold_L_d_ = 0.0, hold_L_q_ = 0.0;
  double edge_L_d_ = 0.0, edge_L_q_ = 0.0, edge_V_ = 0.0;  // setEdgeModel()
  ParameterVector observer_model_{};          // R_s, L_d, L_q, psi_f of the shape's observer (0: none yet)
  double observer_i_d_ = 0.0, observer_i_q_ = 0.0;  // its currents at the last sample [A]
  double cross_L_dq_ = 0.0, cross_L_qq_ = 0.0;
  bool have_previous_block_ = false;
  /// The mean products of a window's sums (offsets projected out where they are estimated).
  WindowSums windowOf(const ProductD& d, const ProductQ& q, const OffsetProduct& N, const OffsetCrossD& C_d,
                      const OffsetCrossQ& C_q, double weight) const;
  // The slow window (the fitness window's blocks averaged once more) and its offset terms.
  ProductD slow_d_ = ProductD::Zero();
  ProductQ slow_q_ = ProductQ::Zero();
  OffsetProduct slow_N_ = OffsetProduct::Zero();
  OffsetCrossD slow_C_d_ = OffsetCrossD::Zero();
  OffsetCrossQ slow_C_q_ = OffsetCrossQ::Zero();
  double slow_weight_ = 0.0, slow_lambda_ = 1.0;
  double slow_time_ = std::numeric_limits<double>::quiet_NaN();  // slowWindowTime()
  // The newest snapshot's weighted mean block time and copper-loss clock, the stored rate and heat
  // entries' reference, and how far the newest block's end lies beyond them.
  double slow_heat_ = 0.0, slow_ahead_time_ = 0.0, slow_ahead_heat_ = 0.0;
  double heat_ = 0.0;       // int (i_d^2 + i_q^2) dt over every sample that followed another [A^2 s]
  // The fitness window's blocks: forgotten sums of 1, of their mid times and of their mid Q.
  double fast_block_weight_ = 0.0, fast_time_sum_ = 0.0, fast_heat_sum_ = 0.0;
  /// Moves the rate and heat entries' reference on by by_time [s] and by_heat [A^2 s].
  void moveSlowReference(ProductD& d, ProductQ& q, OffsetCrossD& C_d, OffsetCrossQ& C_q, double by_time,
                         double by_heat) const;
  ProductD long_d_ = ProductD::Zero();
  ProductQ long_q_ = ProductQ::Zero();
  double long_weight_ = 0.0, long_lambda_ = 1.0;
  BlockD long_last_d_ = BlockD::Zero();
  BlockQ long_last_q_ = BlockQ::Zero();
  // The last long_spacing_blocks_ long-window blocks of this stretch (oldest first), for the spaced differences.
  struct LongBlock {
    BlockD d;
    BlockQ q;
    OffsetBlock n;
  };
  std::vector<LongBlock> long_history_;
  std::size_t long_history_head_ = 0;  // the oldest entry once the ring is full
  int long_spacing_blocks_ = 0;        // 0: consecutive differences only
  bool have_long_block_ = false;
  std::uint64_t blocks_since_long_block_ = 0;  // blocks of this stretch since its last long-window block (< M)
  std::size_t blocks_since_rebase_ = 0;        // blocks since the running integrals were last rebased (< M + 1)
  BlockD last_d_ = BlockD::Zero();
  BlockQ last_q_ = BlockQ::Zero();
};

}  // namespace pmsm_param_id
