// The reference optimum of the paper's output-error fitness over one window: a local least-squares
// solve (Ceres, Levenberg-Marquardt, automatic derivatives) started at the true parameters. It
// tells "the swarm did not find the optimum" from "the optimum itself is off the truth" (the
// forward-Euler model's bias, noise). Tool-only: the core and the nodes do not need Ceres.
#pragma once
#include <string>
#include <vector>

#include "pmsm_param_id/model/motor_model.hpp"
#include "pmsm_param_id/model/sample.hpp"

namespace pmsm_param_id {

struct ReferenceOptimum {
  bool available = false;  ///< false: built without Ceres, or the solve failed (see message)
  ParameterVector parameters{};
  double fitness = 0.0;    ///< Eq. (12) at the optimum [A^2]
  int iterations = 0;
  std::string message;
};

/// window: the samples the fitness runs over, oldest first, with the acting voltages.
ReferenceOptimum paperReferenceOptimum(const std::vector<Sample>& window, const ParameterVector& start);

}  // namespace pmsm_param_id
