#include "pmsm_param_id/identification/motor_map.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "pmsm_param_id/io/config_error.hpp"

namespace pmsm_param_id {

MotorMap::MotorMap(const MotorMapSettings& settings) : settings_(settings) {
  if (!(settings_.cell_fraction > 0.0 && settings_.cell_fraction < 1.0))
    throw ConfigError("map.cell_fraction must be in (0, 1)");
  if (settings_.max_cells < 1) throw ConfigError("map.max_cells must be >= 1");
}

bool windowWithinOneCell(const OperatingPoint& op, double largest_current, const MotorMapSettings& settings,
                         double noise_std, double share) {
  const double tolerance = settings.tolerance(std::hypot(op.i_d, op.i_q), largest_current);
  const double noise = std::isfinite(noise_std) ? noise_std : 0.0;
  const double moving = std::sqrt(std::max(0.0, op.i_q_spread * op.i_q_spread - noise * noise));
  return moving <= share * tolerance;
}

int MotorMap::add(const Estimate& e) {
  if (e.t < last_t_) {  // a new stream: its operating points are not the old one's
    cells_.clear();
    largest_current_ = 0.0;
    transient_ = replaced_ = 0;
  }
  last_t_ = e.t;
  const OperatingPoint& op = e.operating_point;
  if (!std::isfinite(op.i_d) || !std::isfinite(op.i_q)) return -1;
  const double magnitude = std::hypot(op.i_d, op.i_q);
  largest_current_ = std::max(largest_current_, magnitude);
  if (!windowWithinOneCell(op, largest_current_, settings_, e.fit.noise_std_q)) {
    ++transient_;
    return -1;
  }
  int found = -1;
  double nearest = INFINITY;
  for (std::size_t k = 0; k < cells_.size(); ++k) {
    const MotorMapCell& c = cells_[k];
    const double tolerance = settings_.tolerance(std::max(magnitude, std::hypot(c.i_d, c.i_q)), largest_current_);
    const double dd = std::abs(op.i_d - c.i_d), dq = std::abs(op.i_q - c.i_q);
    if (dd > tolerance || dq > tolerance) continue;
    if (std::hypot(dd, dq) < nearest) {
      nearest = std::hypot(dd, dq);
      found = static_cast<int>(k);
    }
  }
  if (found < 0) {
    MotorMapCell c;
    c.i_d = op.i_d;
    c.i_q = op.i_q;
    c.first_seen = e.t;
    if (cells_.size() < static_cast<std::size_t>(settings_.max_cells)) {
      cells_.push_back(c);
      found = static_cast<int>(cells_.size()) - 1;
    } else {  // full: the cell seen longest ago makes room
      const auto oldest = std::min_element(cells_.begin(), cells_.end(), [](const MotorMapCell& a, const MotorMapCell& b) {
        return a.last_seen < b.last_seen;
      });
      *oldest = c;
      found = static_cast<int>(oldest - cells_.begin());
      ++replaced_;
    }
  }
  MotorMapCell& c = cells_[static_cast<std::size_t>(found)];
  c.latest_point = op;
  c.latest = e.parameters;
  c.latest_status = e.status;
  c.last_seen = e.t;
  ++c.estimates;
  for (int p = 0; p < kParameterCount; ++p) {
    if (e.status[p] != ParameterStatus::Identified) continue;
    c.identified[p] = e.parameters[p];
    c.identified_point[p] = op;
    c.identified_t[p] = e.t;
    c.identified_uncertainty[p] = e.relative_uncertainty[p];
  }
  if (e.status[kLq] == ParameterStatus::Identified && e.fit.cross_saturation_modelled &&
      std::abs(e.fit.L_dq_std) <= 0.01 * e.parameters[kLq])
    c.identified_L_dq = e.fit.L_dq;
  return found;
}

std::string MotorMap::coverageNote() const {
  std::string where;
  for (const MotorMapCell& c : cells_)
    if (c.hasIdentified(kLq) && !(c.hasIdentified(kLd) && c.hasIdentified(kPsiF))) {
      char buf[48];
      std::snprintf(buf, sizeof buf, "%s%.3g", where.empty() ? "" : ", ", c.i_q);
      where += buf;
    }
  std::string replaced;
  if (replaced_ > 0) {
    char buf[120];
    std::snprintf(buf, sizeof buf, "%llu cell(s) replaced by newer operating points (map.max_cells = %d)",
                  static_cast<unsigned long long>(replaced_), settings_.max_cells);
    replaced = buf;
  }
  if (where.empty()) return replaced;
  return (replaced.empty() ? "" : replaced + "; ") + "visited but not mapped (L_d or psi_f never identified there), the map is interpolated or extrapolated "
         "there: i_q = " + where + " A";
}

FluxTable MotorMap::fluxTable() const {
  struct Line {
    double i_q, L_d, L_q, psi_f, L_dq;
  };
  std::vector<Line> lines;
  for (const MotorMapCell& c : cells_)
    if (c.hasIdentified(kLd) && c.hasIdentified(kLq) && c.hasIdentified(kPsiF))
      lines.push_back({c.identified_point[kLq].i_q, c.identified[kLd], c.identified[kLq], c.identified[kPsiF],
                       std::isfinite(c.identified_L_dq) ? c.identified_L_dq : 0.0});
  if (lines.empty())
    throw UserError("the motor map has no cell where L_d, L_q and psi_f were all identified: no flux map to export");
  std::sort(lines.begin(), lines.end(), [](const Line& a, const Line& b) { return a.i_q < b.i_q; });
  // Rows closer in i_q than a fifth of the smallest cell tolerance (cell_fraction x 5 % of the
  // largest current) would make a near-singular grid: keep the later one.
  std::vector<Line> kept;
  for (const Line& l : lines) {
    if (!kept.empty() && std::abs(l.i_q - kept.back().i_q) < 0.01 * settings_.cell_fraction * largest_current_) {
      kept.back() = l;
      continue;
    }
    kept.push_back(l);
  }
  double span = 0.0;  // i_d grid: psi_d is linear in i_d in every cell, so two lines extrapolate exactly
  for (const Line& l : kept) span = std::max(span, std::abs(l.i_q));
  if (!(span > 0)) throw UserError("the motor map's identified cells are all at i_q = 0: no flux map to export");
  if (kept.size() == 1) {  // one load level: psi_q linear through the origin, psi_d flat in i_q
    Line other = kept.front();
    other.i_q *= 1.2;
    kept.push_back(other);
    if (kept.front().i_q > other.i_q) std::swap(kept.front(), kept.back());
  }
  const std::vector<double> i_d{-0.25 * span, 0.0, 0.25 * span};
  std::vector<double> i_q, psi_d, psi_q;
  for (const Line& l : kept) {
    i_q.push_back(l.i_q);
    for (double d : i_d) {
      psi_d.push_back(l.psi_f + l.L_d * d);
      psi_q.push_back(l.L_q * l.i_q + l.L_dq * d);
    }
  }
  return FluxTable(i_d, i_q, psi_d, psi_q, "the motor map");
}

}  // namespace pmsm_param_id
