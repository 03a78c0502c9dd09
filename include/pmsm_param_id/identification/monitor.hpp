// Condition monitoring on top of the estimates: winding over-temperature, demagnetisation, sudden
// jumps and fast drift of R_s, L_d, L_q. Only identified parameters raise anything.
//
// Demagnetisation: a magnet's temperature estimated from psi_f alone cannot tell heat from lost
// magnetisation. The magnets are heated through the air gap and by their own losses, and in a
// running machine they stay within some kelvin of the winding, whose temperature R_s gives
// independently. A psi_f that reads as a magnet more than `magnet_above_winding` hotter than the
// winding, for `confirm_time`, is lost magnetisation (or, at a cold start, a magnet that was
// already weak). A psi_f that falls by more than `demagnetisation_drop` within `jump_window` raises
// it too, with or without temperatures: 2 % in a second is 17 K of NdFeB heating per second, which
// no machine's magnets do; it stays raised until psi_f comes back to within half the drop.
//
// On a machine declared saturating (magnetics.cross_saturation) the estimates stand for the
// present operating point and change with the load by design: jumps, drift and the psi_f drop are
// then judged only between estimates whose operating i_q share a cell of the map (map.cell_fraction).
#pragma once
#include <deque>
#include <limits>
#include <string>
#include <vector>

#include "pmsm_param_id/identification/monitor_settings.hpp"
#include "pmsm_param_id/identification/online_identifier.hpp"

namespace pmsm_param_id {


/// A fall of psi_f is judged by its rate against identified values up to this many jump windows
/// old (beyond: the level test against the winding's temperature remains).
constexpr double kDemagnetisationGapWindows = 5.0;

enum class AlarmKind { WindingOverTemperature = 0, Demagnetisation = 1, ParameterJump = 2, FastDrift = 3 };
const char* toString(AlarmKind k);  ///< "winding_over_temperature", "demagnetisation", ...

struct AlarmEvent {
  double t = 0.0;       ///< stamp of the estimate [s]
  AlarmKind kind{};
  bool raised = true;   ///< false: cleared
  std::string text;     ///< one line: what and why
};

class ConditionMonitor {
 public:
  /// operating_cell_fraction > 0: compare estimates only within one cell of operating points (a
  /// saturating machine, see above); 0: across every operating point.
  explicit ConditionMonitor(const AlarmSettings& settings = {}, double operating_cell_fraction = 0.0)
      : s_(settings), cell_fraction_(operating_cell_fraction) {}
  /// The monitor a config asks for (the cell rule when the machine is declared saturating).
  static ConditionMonitor forConfig(const IdentifierConfig& c) {
    return ConditionMonitor(c.alarms, c.magnetics.cross_saturation ? c.map.cell_fraction : 0.0);
  }
  /// Feeds an estimate (in stamp order); returns the alarms raised or cleared by it. An estimate
  /// stamped before the last one (the stream restarted: a looping bag) clears every active alarm
  /// and forgets the history first: estimates of two streams are never compared.
  std::vector<AlarmEvent> update(const Estimate& e);
  bool active(AlarmKind k) const { return active_[static_cast<int>(k)]; }

 private:
  struct Point {
    double t;
    ParameterVector p;
    std::array<bool, kParameterCount> ok;
    double i_q;
  };
  /// The two operating i_q are comparable (always, without the cell rule).
  bool sameCell(double i_q_a, double i_q_b) const;
  void set(AlarmKind k, bool on, double t, const std::string& text, std::vector<AlarmEvent>& out);
  AlarmSettings s_;
  double cell_fraction_ = 0.0;  // 0: no cell rule
  double largest_i_q_ = 0.0;
  std::array<bool, 4> active_{};
  double demag_since_ = -1.0, overtemp_since_ = -1.0;
  bool demag_by_temperature_ = false, demag_by_drop_ = false;
  double psi_f_before_drop_ = 0.0, psi_f_drop_ = 0.0;  // the value before a detected drop, the drop [-]
  std::string demag_text_;
  std::deque<Point> history_;
  struct LastValue {
    double t = -1.0, value = 0.0, i_q = 0.0;
  };
  std::array<LastValue, kParameterCount> last_{};
  // Identified psi_f, one every jump_window / 20, over kDemagnetisationGapWindows jump windows.
  std::deque<LastValue> psi_f_history_;
  double jump_at_ = -1.0;
  double last_t_ = -std::numeric_limits<double>::infinity();  // stamp of the last estimate [s]
};

}  // namespace pmsm_param_id
