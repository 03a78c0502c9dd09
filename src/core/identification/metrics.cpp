#include "pmsm_param_id/identification/metrics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace pmsm_param_id {

double recognitionTime(const std::vector<TracePoint>& trace, const std::array<bool, kParameterCount>& selected,
                       double tolerance) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (trace.empty() || std::none_of(selected.begin(), selected.end(), [](bool b) { return b; })) return nan;
  const auto inside = [&](const TracePoint& p) {
    for (int i = 0; i < kParameterCount; ++i)
      if (selected[i] && !(std::abs(p.estimate[i] - p.truth[i]) <= tolerance * std::abs(p.truth[i]))) return false;
    return true;
  };
  std::size_t i = trace.size();
  while (i > 0 && inside(trace[i - 1])) --i;
  return i == trace.size() ? nan : trace[i].t;
}

double median(std::vector<double> v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return std::isnan(x); }), v.end());
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const std::size_t n = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(n), v.end());
  const double hi = v[n];
  if (v.size() % 2 == 1) return hi;
  return 0.5 * (hi + *std::max_element(v.begin(), v.begin() + static_cast<long>(n)));
}

}  // namespace pmsm_param_id
