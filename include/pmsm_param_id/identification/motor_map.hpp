// An online map of the motor (doc/algorithm.md section 12): as the drive visits operating points,
// every estimate is filed under the cell of its operating point (i_d, i_q), which keeps the latest
// estimate, its statuses, the latest value of each parameter that was reported identified, and
// when it was seen. The map exports the machine's flux linkages as a flux-map CSV grid
// (model/flux_map.hpp), the format the simulator reads.
#pragma once
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <limits>
#include <vector>

#include "pmsm_param_id/identification/online_identifier.hpp"
#include "pmsm_param_id/model/flux_map.hpp"

namespace pmsm_param_id {

struct MotorMapCell {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  double i_d = 0.0, i_q = 0.0;       ///< the cell's centre: the operating point that opened it [A]
  OperatingPoint latest_point;       ///< operating point of the latest estimate filed here
  ParameterVector latest{};          ///< the latest estimate filed here, whatever its status
  std::array<ParameterStatus, kParameterCount> latest_status{};
  /// Per parameter: the latest value reported identified here, its operating point and time
  /// (NaN / never when none was).
  ParameterVector identified{kNaN, kNaN, kNaN, kNaN};
  std::array<OperatingPoint, kParameterCount> identified_point{};
  ParameterVector identified_t{kNaN, kNaN, kNaN, kNaN};
  ParameterVector identified_uncertainty{kNaN, kNaN, kNaN, kNaN};  ///< relative [-]
  /// Cross-saturation d psi_q / d i_d from the extended fit (magnetics.cross_saturation), when its
  /// standard deviation is at most 1 % of L_q; with its operating point's L_q identified.
  double identified_L_dq = kNaN;
  double first_seen = kNaN, last_seen = kNaN;  ///< stamps of the first and latest estimate [s]
  std::uint64_t estimates = 0;       ///< estimates filed here
  bool hasIdentified(int p) const { return !std::isnan(identified[p]); }
};

/// The window's data lie within one cell of the map: its i_q spread (standard deviation, less the
/// current noise the data show: sqrt(spread^2 - noise_std^2)) is at most `share` of the cell
/// tolerance, cell_fraction times the larger of the operating current and 5 % of the largest
/// current seen (MotorMapSettings). The map files only such estimates (share 1/4);
/// on a saturating machine the identifier reports L_q, psi_f identified only then, and L_d only
/// within 1/8 (doc/algorithm.md section 12).
bool windowWithinOneCell(const OperatingPoint& op, double largest_current, const MotorMapSettings& settings,
                         double noise_std, double share = 0.25);

class MotorMap {
 public:
  explicit MotorMap(const MotorMapSettings& settings = {});
  /// Files the estimate under its operating point's cell (a new cell when none is near). An
  /// estimate stamped before the last one (the stream restarted) starts the map again.
  /// Returns the cell's index, or -1 when nothing was filed: the operating point is not finite, or
  /// the window's i_q moved across more than a cell (a load change: counted as transient).
  int add(const Estimate& e);
  std::uint64_t transientEstimates() const { return transient_; }
  /// Cells replaced because the map held settings().max_cells (the one seen longest ago goes).
  std::uint64_t replacedCells() const { return replaced_; }
  const std::vector<MotorMapCell>& cells() const { return cells_; }
  const MotorMapSettings& settings() const { return settings_; }
  /// The flux linkages on a grid, from the cells where L_d, L_q and psi_f were identified:
  ///   psi_d(i_d, i_q) = psi_f(i_q) + L_d(i_q) i_d,   psi_q(i_d, i_q) = L_q(i_q) i_q + L_dq(i_q) i_d
  /// (L_d incremental, L_q secant, psi_f = psi_d(0, i_q): what the estimates stand for, section 11;
  /// L_dq where the extended fit gave it, else 0), one grid row per such cell's i_q, linear in i_q
  /// between them. UserError when no cell qualifies.
  FluxTable fluxTable() const;
  /// Empty when every cell where L_q was identified also has L_d and psi_f; otherwise one line
  /// naming the operating points where the exported map is interpolated or extrapolated instead.
  std::string coverageNote() const;

 private:
  MotorMapSettings settings_;
  std::vector<MotorMapCell> cells_;
  double largest_current_ = 0.0;
  std::uint64_t transient_ = 0;
  std::uint64_t replaced_ = 0;
  double last_t_ = -std::numeric_limits<double>::infinity();  // stamp of the last estimate [s]
};

}  // namespace pmsm_param_id
