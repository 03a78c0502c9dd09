// The seed paper's own fitness (doc/algorithm.md section 10): the adjustable model of Eq. (11),
// forward Euler, driven by the measured u_d, u_q and omega_e only and fed back its own currents,
// run over a sliding window of the last N samples from the measured current at the window's
// first sample; Eq. (12): the mean over the window of the squared current error. Eq. (13)
// (`paper_one_step`): the same model over one step from the measured current, at the newest
// sample only.
//
// An output-error fitness is non-convex in the parameters (the model's own currents sit on the
// right-hand side), unlike the block fitness, whose error is linear in them.
#pragma once
#include <cstddef>
#include <string>
#include <vector>

#include "pmsm_param_id/model/motor_model.hpp"
#include "pmsm_param_id/model/sample.hpp"

namespace pmsm_param_id {

enum class FitnessKind {
  Block,         ///< the integrated-equation block fitness (section 1; the default)
  Paper,         ///< Eq. (11) run over the window, Eq. (12)
  PaperOneStep,  ///< Eq. (11) one step from the measured current, Eq. (13)
};
const char* toString(FitnessKind k);  ///< "block", "paper", "paper_one_step"
/// Parses a name; false when unknown.
bool fitnessKindFrom(const std::string& name, FitnessKind& out);

class OutputErrorWindow {
 public:
  /// window_samples: N >= 2 (paper) ; voltage_delay_samples: 0 or 1, as time.voltage_delay_samples.
  OutputErrorWindow(FitnessKind kind, int window_samples, int voltage_delay_samples);

  /// Appends a sample (the oldest leaves once N are held).
  void push(const Sample& s);
  /// The previous sample is no valid predecessor (gap, reset, skipped sample): start again.
  void clear();
  /// Enough samples for the fitness: N (paper) or 2 (paper_one_step).
  bool ready() const;
  std::size_t size() const { return count_ < capacity_ ? count_ : capacity_; }
  FitnessKind kind() const { return kind_; }
  int windowSamples() const { return static_cast<int>(capacity_); }

  /// Fitness of one parameter vector [A^2]; 1e300 where the model diverges.
  double operator()(const ParameterVector& p) const;
  /// Fitness of n parameter vectors at once (all particles of an iteration; the inner loop runs
  /// over the particles, so it vectorises).
  void batch(const ParameterVector* p, std::size_t n, double* out) const;

  /// The window's samples, oldest first, with the acting voltage in u_d, u_q (delay applied).
  std::vector<Sample> samples() const;

 private:
  void kernel(const ParameterVector* p, std::size_t n, double* out) const;

  FitnessKind kind_;
  std::size_t capacity_;
  int delay_;
  // Structure of arrays, each written twice (at i and i + capacity) so that the window is
  // always one contiguous run [head, head + size).
  std::vector<double> t_, ud_, uq_, w_, id_, iq_;
  std::size_t count_ = 0;
  double previous_ud_ = 0.0, previous_uq_ = 0.0;
  bool have_previous_ = false;
};

}  // namespace pmsm_param_id
