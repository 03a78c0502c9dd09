// Accuracy and speed metrics shared by the bench tool, the tests and the reports.
#pragma once
#include <array>
#include <vector>

#include "pmsm_param_id/model/motor_model.hpp"

namespace pmsm_param_id {

/// (estimate - truth) / truth in percent.
inline double errorPercent(double estimate, double truth) { return 100.0 * (estimate - truth) / truth; }

struct TracePoint {
  double t = 0.0;
  ParameterVector estimate{};
  ParameterVector truth{};
};

/// Recognition time [s]: the first trace time after which every selected parameter stays within
/// `tolerance` (relative, 0.01 = 1 %) of the truth until the end of the trace. NaN when the last
/// point is outside, or when no parameter is selected.
double recognitionTime(const std::vector<TracePoint>& trace, const std::array<bool, kParameterCount>& selected,
                       double tolerance = 0.01);

/// Median of a copy of v (NaN for an empty vector; NaN entries are ignored).
double median(std::vector<double> v);

}  // namespace pmsm_param_id
