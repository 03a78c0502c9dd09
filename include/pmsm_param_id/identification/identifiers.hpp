// The five methods behind OnlineIdentifier.
#pragma once
#include <Eigen/Core>
#include <memory>

#include "pmsm_param_id/identification/online_identifier.hpp"
#include "pmsm_param_id/identification/output_error.hpp"
#include "pmsm_param_id/identification/particle_swarm.hpp"

namespace pmsm_param_id {

/// The acceptance policy that config.method names (pso, sapso, fbdapso) with the config's constants.
std::shared_ptr<const AcceptancePolicy> makeAcceptancePolicy(const IdentifierConfig& config);

/// PSO, SAPSO or FBDAPSO on the block fitness or the paper's output-error fitness (config.fitness):
/// iterations_per_sample swarm iterations per sample once the search box exists (the paper's
/// "identify every sampling point").
class SwarmIdentifier : public OnlineIdentifier {
 public:
  explicit SwarmIdentifier(const IdentifierConfig& config);
  std::string method() const override { return config_.method; }
  const ParticleSwarm& swarm() const { return *swarm_; }

 protected:
  void update(const Sample& s, bool new_block, bool continuity_broken) override;
  ParameterVector current() const override;
  void restart() override;
  void searchBoxMoved() override;
  std::array<bool, kParameterCount> atBound() const override;
  std::uint64_t iterations() const override { return swarm_ ? swarm_->iterations() : 0; }
  double temperature() const override;
  double fitnessAt(const ParameterVector& p) const override;
  bool trailsWindowOptimum() const override { return !output_error_; }

 private:
  std::unique_ptr<ParticleSwarm> swarm_;
  std::unique_ptr<OutputErrorWindow> output_error_;  // the paper's fitness, when configured
  std::uint64_t face_restarts_ = 0;  // swarms started again off a face the data left since the start
  void newSwarm();
  template <class F>
  void iterate(const F& fitness);
};

using EkfState = Eigen::Matrix<double, 6, 1>;     ///< {i_d, i_q, R_s, L_d, L_q, psi_f}
using EkfJacobian = Eigen::Matrix<double, 6, 6>;
/// A saturating machine's known cross terms for the EKF (doc/algorithm.md section 11): the
/// incremental L_qq, the cross inductance L_dq and the q current i_bar the lines are taken about.
struct EkfCrossSaturation {
  bool on = false;
  double L_qq = 0.0, L_dq = 0.0, i_bar = 0.0;
};
/// The EKF's process model: the paper's forward Euler (Eq. 11) over T [s] with the inputs of the
/// previous sample k; jacobian (optional) receives d x_next / d x. With cross terms, the model of
/// section 11: psi_q = L_q i_bar + L_qq (i_q - i_bar) + L_dq i_d, psi_d = psi_f + L_dq (i_q - i_bar)
/// + L_d i_d, and the incremental matrix [[L_d, L_dq], [L_dq, L_qq]] on di/dt.
EkfState ekfPredict(const EkfState& x, const Sample& k, double T, EkfJacobian* jacobian,
                    const EkfCrossSaturation& cross = {});

/// Extended Kalman filter on x = {i_d, i_q, R_s, L_d, L_q, psi_f}: the paper's forward-Euler
/// model (Eq. 11) as process, the measured currents as measurement, random-walk parameters.
class EkfIdentifier : public OnlineIdentifier {
 public:
  explicit EkfIdentifier(const IdentifierConfig& config);
  std::string method() const override { return "ekf"; }

 protected:
  void update(const Sample& s, bool new_block, bool continuity_broken) override;
  ParameterVector current() const override;
  void restart() override;
  std::array<bool, kParameterCount> atBound() const override { return clamped_; }

 private:
  std::array<bool, kParameterCount> clamped_{};
  using Vec6 = Eigen::Matrix<double, 6, 1>;
  using Mat6 = Eigen::Matrix<double, 6, 6>;
  Vec6 x_ = Vec6::Zero();
  Mat6 P_ = Mat6::Identity();
  Sample previous_;
  bool have_previous_ = false;
};

/// Recursive least squares with exponential forgetting on the integrated voltage equations,
/// which are linear in the parameters:
///   U_d = R_s I_d + L_d Di_d - L_q W_d (+ V S_d),   U_q = R_s I_q + L_q Di_q + L_d W_q + psi_f Om (+ V S_q),
/// with the inverter voltage V as a fifth parameter when the config asks for it.
class RlsIdentifier : public OnlineIdentifier {
 public:
  explicit RlsIdentifier(const IdentifierConfig& config);
  std::string method() const override { return "rls"; }

 protected:
  void update(const Sample& s, bool new_block, bool continuity_broken) override;
  ParameterVector current() const override;
  void restart() override;

 private:
  using Vec5 = Eigen::Matrix<double, 5, 1>;
  using Mat5 = Eigen::Matrix<double, 5, 5>;
  Vec5 theta_ = Vec5::Zero();  // {R_s, L_d, L_q, psi_f, V}; V stays 0 unless inverter.model: estimate
  Mat5 P_ = Mat5::Identity();
  double last_t_ = 0.0;
  bool have_last_ = false;
};

/// The exact minimiser of the block fitness over the window (Gauss-Newton on the sufficient
/// statistics, section 4 of doc/algorithm.md): the reference optimum every other method is
/// measured against, and a method of its own. Refitted (warm-started, a few microseconds) whenever
/// its parameters are asked for after new blocks, so it is exact for the window at every estimate.
class WlsIdentifier : public OnlineIdentifier {
 public:
  explicit WlsIdentifier(const IdentifierConfig& config);
  std::string method() const override { return "wls"; }

 protected:
  void update(const Sample&, bool, bool) override {}
  ParameterVector current() const override;
  void restart() override;

 private:
  mutable ParameterVector parameters_{};
  mutable std::uint64_t blocks_at_fit_ = 0;
};

}  // namespace pmsm_param_id
