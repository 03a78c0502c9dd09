#include "pmsm_param_id/identification/monitor.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace pmsm_param_id {

const char* toString(AlarmKind k) {
  switch (k) {
    case AlarmKind::WindingOverTemperature: return "winding_over_temperature";
    case AlarmKind::Demagnetisation: return "demagnetisation";
    case AlarmKind::ParameterJump: return "parameter_jump";
    case AlarmKind::FastDrift: return "fast_drift";
  }
  return "?";
}

void ConditionMonitor::set(AlarmKind k, bool on, double t, const std::string& text, std::vector<AlarmEvent>& out) {
  bool& a = active_[static_cast<int>(k)];
  if (a == on) return;
  a = on;
  out.push_back({t, k, on, text});
}

bool ConditionMonitor::sameCell(double i_q_a, double i_q_b) const {
  if (!(cell_fraction_ > 0)) return true;
  const MotorMapSettings cells{cell_fraction_};
  return std::abs(i_q_a - i_q_b) <= cells.tolerance(std::max(std::abs(i_q_a), std::abs(i_q_b)), largest_i_q_);
}

std::vector<AlarmEvent> ConditionMonitor::update(const Estimate& e) {
  std::vector<AlarmEvent> out;
  const double t = e.t;
  if (t < last_t_) {  // a new stream: clear what the old one raised, forget what it showed
    for (AlarmKind k : {AlarmKind::WindingOverTemperature, AlarmKind::Demagnetisation, AlarmKind::ParameterJump,
                        AlarmKind::FastDrift})
      set(k, false, t, "cleared: the stream restarted (stamps went backwards)", out);
    const AlarmSettings settings = s_;
    const double cells = cell_fraction_;
    *this = ConditionMonitor(settings, cells);
  }
  last_t_ = t;
  const double i_q = std::isfinite(e.operating_point.i_q) ? e.operating_point.i_q : 0.0;
  largest_i_q_ = std::max(largest_i_q_, std::abs(i_q));
  char buf[256];
  // Winding over-temperature, with hysteresis.
  const Temperature& tw = e.winding_temperature;
  if (std::isfinite(tw.value)) {
    if (tw.value > s_.winding_max_temperature) {
      if (overtemp_since_ < 0) overtemp_since_ = t;
      if (t - overtemp_since_ >= s_.confirm_time) {
        std::snprintf(buf, sizeof buf, "winding at %.1f degC (+-%.1f K) above %.1f degC", tw.value, tw.uncertainty,
                      s_.winding_max_temperature);
        set(AlarmKind::WindingOverTemperature, true, t, buf, out);
      }
    } else {
      overtemp_since_ = -1.0;
      if (tw.value < s_.winding_max_temperature - s_.winding_hysteresis)
        set(AlarmKind::WindingOverTemperature, false, t, "winding temperature back to normal", out);
    }
  }
  // Demagnetisation (1): the magnet reads hotter than the winding by more than heat explains.
  const Temperature& tm = e.magnet_temperature;
  if (std::isfinite(tw.value) && std::isfinite(tm.value)) {
    const double excess = tm.value - tw.value - tm.uncertainty - tw.uncertainty;
    if (excess > s_.magnet_above_winding) {
      if (demag_since_ < 0) demag_since_ = t;
      if (t - demag_since_ >= s_.confirm_time && !demag_by_temperature_) {
        demag_by_temperature_ = true;
        std::snprintf(buf, sizeof buf,
                      "psi_f reads as a magnet at %.1f degC while the winding is at %.1f degC: %.0f K more than "
                      "heat explains: lost magnetisation", tm.value, tw.value, tm.value - tw.value);
        demag_text_ = buf;
      }
    } else {
      demag_since_ = -1.0;
      if (excess < 0.5 * s_.magnet_above_winding) demag_by_temperature_ = false;
    }
  }
  history_.push_back({t, e.parameters, e.identifiable, i_q});
  const double memory = std::max(s_.drift_window, s_.jump_window);
  while (history_.size() > 2 && history_.front().t < t - memory) history_.pop_front();
  while (!psi_f_history_.empty() && psi_f_history_.front().t < t - kDemagnetisationGapWindows * s_.jump_window)
    psi_f_history_.pop_front();
  // Demagnetisation (2): psi_f falling faster than any thermal cause allows: against the largest
  // identified value within jump_window.
  if (e.identifiable[kPsiF]) {
    const double now = e.parameters[kPsiF];
    if (demag_by_drop_) {
      if (now > psi_f_before_drop_ * (1.0 - 0.5 * psi_f_drop_)) demag_by_drop_ = false;
    } else {
      double highest = 0.0, highest_t = t;
      for (const Point& old : history_)
        if (old.ok[kPsiF] && t - old.t <= s_.jump_window && old.p[kPsiF] > highest && sameCell(old.i_q, i_q)) {
          highest = old.p[kPsiF];
          highest_t = old.t;
        }
      // Older identified values count by rate (after a step the fit is poor for a while, and a
      // swarm may take a second to follow: measured 1.1 s without an identified psi_f for FBDAPSO
      // in one seed of a 4 % fall): a fall by more than demagnetisation_drop at more than
      // demagnetisation_drop per jump_window.
      for (const LastValue& old : psi_f_history_) {
        const double gap = t - old.t;
        if (gap <= s_.jump_window || old.value <= highest || !sameCell(old.i_q, i_q)) continue;
        const double drop = 1.0 - now / old.value;
        if (drop > s_.demagnetisation_drop && drop / gap > s_.demagnetisation_drop / s_.jump_window) {
          highest = old.value;
          highest_t = old.t;
        }
      }
      if (highest > 0 && now < highest * (1.0 - s_.demagnetisation_drop)) {
        demag_by_drop_ = true;
        psi_f_before_drop_ = highest;
        psi_f_drop_ = 1.0 - now / highest;
        std::snprintf(buf, sizeof buf, "psi_f fell by %.1f %% within %.3f s, faster than any heating: lost magnetisation",
                      100 * psi_f_drop_, t - highest_t);
        demag_text_ = buf;
      }
    }
  }
  if (e.identifiable[kPsiF] && (psi_f_history_.empty() || t - psi_f_history_.back().t >= s_.jump_window / 20))
    psi_f_history_.push_back({t, e.parameters[kPsiF], i_q});
  if (demag_by_temperature_ || demag_by_drop_) set(AlarmKind::Demagnetisation, true, t, demag_text_, out);
  else set(AlarmKind::Demagnetisation, false, t, "psi_f consistent with heat", out);

  // Jumps: an identified value against the last identified one, however long the estimate was
  // not identified in between (a step makes the fit poor for a few window lengths), up to
  // jump_window. Drift: the change over drift_window of identified values.
  bool drift = false;
  std::string drift_text;
  for (int p : {kRs, kLd, kLq}) {
    if (!e.identifiable[p]) continue;
    LastValue& last = last_[p];
    if (last.t >= 0 && t - last.t <= s_.jump_window && sameCell(last.i_q, i_q)) {
      const double change = e.parameters[p] / last.value - 1.0;
      if (std::abs(change) > s_.jump_fraction) {
        std::snprintf(buf, sizeof buf, "%s changed by %+.1f %% within %.3f s", parameterNames()[p].c_str(), 100 * change,
                      t - last.t);
        set(AlarmKind::ParameterJump, true, t, buf, out);
        jump_at_ = t;
      }
    }
    last = {t, e.parameters[p], i_q};
    for (const Point& old : history_) {
      if (!old.ok[p] || t - old.t < 0.9 * s_.drift_window || !sameCell(old.i_q, i_q)) continue;
      const double rate = (e.parameters[p] / old.p[p] - 1.0) / (t - old.t);
      if (std::abs(rate) > s_.drift_rate && !drift) {
        drift = true;
        std::snprintf(buf, sizeof buf, "%s drifting at %+.2f %%/s", parameterNames()[p].c_str(), 100 * rate);
        drift_text = buf;
      }
      break;
    }
  }
  if (active(AlarmKind::ParameterJump) && t - jump_at_ > s_.jump_window)
    set(AlarmKind::ParameterJump, false, t, "no jump for a while", out);
  if (drift) set(AlarmKind::FastDrift, true, t, drift_text, out);
  else set(AlarmKind::FastDrift, false, t, "no fast drift", out);
  return out;
}

}  // namespace pmsm_param_id
