// The points one fitness evaluation is timed at, shared by `pmsm_tool perf` and perf_bench: as a
// swarm iteration evaluates, `count` points around `centre` that differ in every parameter (timed
// with only R_s varied, the compiler may hoist the rest of the quadratic form out of the loop).
#pragma once
#include <vector>

#include "pmsm_param_id/model/motor_model.hpp"

namespace pmsm_param_id {

inline std::vector<ParameterVector> perfPoints(const ParameterVector& centre, int count) {
  std::vector<ParameterVector> points(static_cast<std::size_t>(count), centre);
  for (int k = 0; k < count; ++k)
    for (int j = 0; j < kParameterCount; ++j)
      points[static_cast<std::size_t>(k)][j] *= 1.0 + 0.002 * static_cast<double>((k * (j + 3)) % 21 - 10);
  return points;
}

}  // namespace pmsm_param_id
