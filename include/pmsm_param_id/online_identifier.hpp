// Sample-by-sample identification of {R_s, L_d, L_q, psi_f}: the one code path for live data,
// bag replay and CSV logs. Concrete methods: SwarmIdentifier (pso, sapso, fbdapso),
// EkfIdentifier, RlsIdentifier.
#pragma once
#include <cstdint>
#include <memory>
#include <string>

#include "pmsm_param_id/horizon_statistics.hpp"
#include "pmsm_param_id/identifier_config.hpp"
#include "pmsm_param_id/sample.hpp"

namespace pmsm_param_id {

/// What happened to one sample.
enum class SampleStatus {
  Used,              ///< processed
  SkippedNonFinite,  ///< a NaN or inf field: not used, blocks restart after it
  SkippedDuplicate,  ///< same stamp as the previous sample: not used
  TimeReset,         ///< stamp went backwards: the identifier restarted from scratch with it
  Gap                ///< processed after a gap longer than max_gap_periods: blocks restarted
};
const char* toString(SampleStatus s);

struct IdentifierCounters {
  std::uint64_t used = 0, skipped_nonfinite = 0, skipped_duplicate = 0, time_resets = 0, gaps = 0;
  std::uint64_t skipped() const { return skipped_nonfinite + skipped_duplicate; }
};

struct Estimate {
  std::string method;
  double t = 0.0;                   ///< stamp of the last sample used [s]
  ParameterVector parameters{};     ///< {R_s [ohm], L_d [H], L_q [H], psi_f [Wb]}
  std::array<bool, kParameterCount> identifiable{};  ///< the data determine this parameter
  ParameterVector relative_std{};   ///< estimated standard deviation / value [-]
  double fitness = 0.0;             ///< mean squared block current error at the estimate [A^2]
  std::uint64_t iteration = 0;      ///< swarm iterations (0 for ekf, rls)
  double temperature = 0.0;         ///< mean particle temperature (NaN where there is none)
  IdentifierCounters counters;
};

class OnlineIdentifier {
 public:
  explicit OnlineIdentifier(const IdentifierConfig& config);
  virtual ~OnlineIdentifier() = default;

  /// Feeds one sample. Never throws on bad data: the status says what was done with it.
  SampleStatus process(const Sample& s);
  /// Current estimate with observability flags (computed on demand, O(1)).
  Estimate estimate() const;
  /// Forget all data and start again from the configured initial values.
  void reset();

  const IdentifierConfig& config() const { return config_; }
  const IdentifierCounters& counters() const { return counters_; }
  /// Current parameter vector only (cheaper than estimate()).
  ParameterVector parameters() const { return current(); }
  const HorizonStatistics& statistics() const { return stats_; }
  virtual std::string method() const = 0;

 protected:
  /// Method-specific update with a sample that follows the previous one. new_block: the horizon
  /// statistics completed a block with this sample. continuity_broken: the previous sample is not
  /// a valid predecessor (first sample, gap, or a skipped sample in between).
  virtual void update(const Sample& s, bool new_block, bool continuity_broken) = 0;
  virtual ParameterVector current() const = 0;
  virtual void restart() = 0;
  virtual std::uint64_t iterations() const { return 0; }
  virtual double temperature() const;

  IdentifierConfig config_;
  HorizonStatistics stats_;

 private:
  IdentifierCounters counters_;
  double last_t_ = 0.0;
  double nominal_dt_ = 0.0;
  bool have_last_ = false;
  bool broken_ = true;
};

/// Builds the identifier named by config.method. ConfigError on an unknown method or bad values.
std::unique_ptr<OnlineIdentifier> makeIdentifier(const IdentifierConfig& config);

}  // namespace pmsm_param_id
